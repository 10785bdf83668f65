"""Writes tests/data/filter_golden.npz: the SOC filter's state step and measurement
(``estimate.Model.transition`` / ``measurement``) on a sigma-point-like batch, and a short
filter run's SOC, for every element alone and all of them (rational OCV and table, the table
continued past its ends or not); what ``tests/unit/test_estimate.py`` holds the filter made from
the elements' statements (issue 39) to. Not bit for bit: the hand-written filter's exp was
numpy's, the compiled step's is LLVM's, and they differ in the last bit now and then; the step's
operations are otherwise the hand-written ones', so the two agree to rounding (1e-12).

Run it on the checkout whose numbers are the reference (issue 39: main at a81259e):

    PYTHONPATH=/work/ref/src python tests/data/make_filter_golden.py tests/data/filter_golden.npz
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

from avoa_pipeline import estimate as E
from avoa_pipeline.model import ecm, elements
from avoa_pipeline.model.elements.element import FARADAY, GAS_R

_spec = importlib.util.spec_from_file_location(
    "make_kernel_golden", Path(__file__).with_name("make_kernel_golden.py")
)
_kg = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_kg)
TREF_K = 298.15


def models():
    """(name, Model) for every mix, OCV and table continuation."""
    soc = np.linspace(0.0, 1.0, 41)
    table = ecm.OcvTable.from_points(soc, 3.3 + 0.8 * soc + 0.03 * np.sin(9 * soc))
    for mname, effects in _kg.mixes().items():
        x = ecm.vector(_kg.BASE)
        for e in effects:
            for n in elements.get(e).params:
                x[ecm.IDX[n]] = _kg.ACTIVE[n]
        x[ecm.IDX["h0"]] = 0.0
        P = ecm.to_physical(x)
        layout = E.layout_of(effects)
        for ocv, tab in (("rational", None), ("table", table)):
            if any(elements.get(e).conflict(tab is not None, False) for e in effects):
                continue
            model = E.Model(P, layout, ecm.Knots(0.1, 0.15), tab)
            yield f"{mname}/{ocv}", model
            if tab is not None:
                yield f"{mname}/{ocv}/extended", model.extended()


def batch(model, m: int = 9, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    L = model.layout
    X = np.zeros((m, L.n))
    X[:, L["soc"]] = np.linspace(-0.08, 1.08, m)  # past both ends of a table
    for name in L.names[1:]:
        spread = {"h": rng.uniform(-1, 1, m), "bias": rng.normal(0, 0.02, m),
                  "verr": rng.normal(0, 1e-3, m)}  # fmt: skip
        X[:, L[name]] = spread.get(name, rng.normal(0, 5e-3, m))
    return X


def values() -> dict[str, np.ndarray]:
    """By model: its measurement and state step at 305 K, the same with a parameter row per
    point, and a short filter run's SOC."""
    out = {}
    tk = 305.0
    dinv, rtf = 1.0 / tk - 1.0 / TREF_K, 2.0 * GAS_R * tk / FARADAY
    rec = ecm.Record.from_frame(_frame(), TREF_K)
    for name, model in models():
        X = batch(model)
        rows = model.rows(np.repeat(model.P, X.shape[0], axis=0)
                          * (1.0 + 0.01 * np.arange(X.shape[0]))[:, None])  # fmt: skip
        out[f"{name}/measurement"] = model.measurement(X, 1.3, dinv, rtf)
        out[f"{name}/transition"] = model.transition(X, 1.3, 1.5, dinv, rtf)
        out[f"{name}/rows"] = rows.transition(X, -0.7, 2.0, dinv, rtf)
        noise = E.Noise(2e-3, 5.0, model.P * 1.001, ("a",))
        out[f"{name}/filter"] = E.run_filter(model, noise, E.Inputs.of(rec), 0.6, 1.0).soc
    return out


def _frame():
    import pandas as pd

    rng = np.random.default_rng(5)
    cur = np.repeat(rng.choice([0.0, 0.5, 1.0, -0.5], 12), 10)
    t = np.arange(cur.size, dtype=float)
    return pd.DataFrame({"time_s": t, "current_a": cur,
                         "voltage_v": 3.7 + 0.01 * np.sin(t / 7.0),
                         "temperature_c": 25.0 + 3.0 * np.sin(t / 30.0)})  # fmt: skip


if __name__ == "__main__":
    np.savez_compressed(sys.argv[1], **values())
