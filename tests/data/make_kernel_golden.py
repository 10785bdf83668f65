"""Writes tests/data/kernel_golden.npz: the compiled simulator's voltages for two small records x
every element alone and all of them together, with the rational OCV and a table (where the
element allows it) and under the paper's load; what ``tests/unit/test_kernel_golden.py`` holds
the generated loop to, bit for bit. The whole pass's voltages are stored as numbers (a failure
shows by how much); the thinned pass (the held-current shortcut), the traced pass and its traces
as SHA-256 digests of their bytes, which keeps the file small (about 200 kB).

Run it on the checkout whose voltages are the reference (issue 39: main at a81259e, before the
loop was generated from the elements' statements):

    PYTHONPATH=/work/ref/src python tests/data/make_kernel_golden.py tests/data/kernel_golden.npz
"""

from __future__ import annotations

import hashlib
import sys

import numpy as np
import pandas as pd

from avoa_pipeline.model import ecm, elements

N = 96
ACTIVE = {  # one non-neutral value per parameter, inside its limits (internal coordinates)
    "r2": 0.012, "ltau2": 2.3, "r3": 0.006, "ltau3": 3.1, "klow": 1.5, "lsig": -1.1,
    "kd": 0.02, "ltaud": 1.9, "hm": 0.02, "lgamma": 1.7, "h0": 0.3, "bvg": 0.4, "th0": 3000.0,
    "th1": 2500.0, "u0": 0.01, "u1": -0.02, "u2": 0.015, "u3": -0.01, "ioff": 0.05,
    "voff": 0.004, "eta": 0.97, "r0u0": 0.2, "r0u1": -0.3, "r0u2": 0.1, "r0u3": 0.05,
    "r0u4": -0.1, "r1u0": -0.2, "r1u1": 0.25, "r1u2": -0.1, "r1u3": 0.05, "r1u4": 0.1,
    "rho": 0.3, "thbv": 2000.0, "thtau": 1500.0, "dudt": 3e-4, "kq": 0.01,
}  # fmt: skip
BASE = {"vnom_v": 4.1, "beta": 0.5, "capacity_ah": 0.05, "soc0": 0.8, "r0_ohm": 0.03,
        "r1_ohm": 0.01, "tau1_s": 12.0}  # fmt: skip


def records() -> dict[str, ecm.Record]:
    """A uniform 1 s record of held steps and rests (temperature moving), and an uneven one."""
    rng = np.random.default_rng(39)
    cur = np.repeat(rng.choice([0.0, 0.0, 1.0, 2.0, -1.0, -0.5], N // 8), 8)
    t = np.arange(N, dtype=float)
    temp = 25.0 + 4.0 * np.sin(t / 17.0)
    temp[cur == 0.0] = np.round(temp[cur == 0.0], 1)
    uniform = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": 3.7,
                            "temperature_c": temp})  # fmt: skip
    t2 = np.cumsum(rng.uniform(0.5, 3.0, N))
    uneven = pd.DataFrame({"time_s": t2, "current_a": cur[::-1].copy(), "voltage_v": 3.7,
                           "temperature_c": 20.0 + 0.05 * t2})  # fmt: skip
    return {"uniform": ecm.Record.from_frame(uniform), "uneven": ecm.Record.from_frame(uneven)}


def mixes() -> dict[str, tuple[str, ...]]:
    out = {}
    for e in ecm.EFFECTS:
        req = elements.get(e).requires
        out[e] = (req, e) if req else (e,)
    core = tuple(e for e in ecm.EFFECTS if elements.get(e).compiled == "core")
    out["all_core"] = core
    out["all"] = tuple(ecm.EFFECTS)
    return {"base": (), **out}


def cases():
    """(name, record, rows X, table or None, load_ohm or None)."""
    soc = np.linspace(0, 1, 11)
    table = ecm.OcvTable.from_points(soc, 3.2 + 0.9 * soc**0.8)
    for rname, rec in records().items():
        for mname, effects in mixes().items():
            x = ecm.vector(BASE)
            for e in effects:
                for n in elements.get(e).params:
                    x[ecm.IDX[n]] = ACTIVE[n]
            X = np.repeat(x[None, :], 2, axis=0)
            X[1, ecm.IDX["r0"]] *= 1.3  # rows differ, as in a Jacobian
            X[1, ecm.IDX["soc0"]] = 0.35
            for ocv, tab in (("rational", None), ("table", table)):
                if any(elements.get(e).conflict(tab is not None, False) for e in effects):
                    continue
                yield f"{rname}/{mname}/{ocv}", rec, X, tab, None
            if not any(elements.get(e).conflict(False, True) for e in effects):
                yield f"{rname}/{mname}/load", rec, X, None, 8.0


def digest(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a, dtype=np.float64).tobytes()).hexdigest()


def simulate_all() -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """The whole pass's voltages by case, and the digests of the thinned pass's, the traced
    pass's and its traces."""
    knots = ecm.Knots(0.1, 0.15)
    idx = np.arange(7, N, 13)
    full, digests = {}, {}
    for name, rec, X, tab, load in cases():
        full[name] = ecm.simulate_rows(rec, X, knots, tab, load)
        digests[f"{name}/thinned"] = digest(ecm.simulate_rows(rec, X, knots, tab, load, idx=idx))
        v, tr = ecm.simulate_rows(rec, X, knots, tab, load, traces=True)
        digests[f"{name}/traced"] = digest(v)
        digests[f"{name}/traces"] = digest(tr)
    return full, digests


if __name__ == "__main__":
    full, digests = simulate_all()
    names = sorted(digests)
    np.savez_compressed(
        sys.argv[1],
        **full,
        digest_names=np.array(names),
        digests=np.array([digests[n] for n in names]),
    )
