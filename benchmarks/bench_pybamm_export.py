"""PyBaMM's Thevenin model from an exported module against the package's simulator, on records
longer than the unit tests': agreement (RMS and largest difference, mV) and seconds per record
(PyBaMM: the module's ``simulate``, model builds included; ours: ``FittedModel.simulate``).
Prints measurements; asserts nothing.

Records: the issue's profile (discharge, rest, charge, 6 A pulse, rests; 2,222 samples at 1 s)
and a 1 Hz drive-like current (15,000 samples, a new current every second), both with a measured
temperature that moves 10 °C; for the SOC-dependent resistance also the issue's profile with
steps of 1, 2 or 4 s (``2222@1-4s``, at 1e-8 only: our simulator holds its factor over each
step). Rows: IDAKLU at rtol = atol = 1e-8, 1e-7 and 1e-6 (the module's default) and at its own
defaults (rtol 1e-4, atol 1e-6); for the thermal stack, also at 1e-6 without the thermal lead
(THERMAL_LEAD_S = 0: the ambient switched at the sample time); with ``--chunks``, the stack at
1e-6 solved in pieces of each size given (the module's default: CHUNK_SAMPLES). ``--only``:
the configurations with any of these elements.

``--real MODEL.json RECORD.csv``: instead, a fitted model on a record of its cell, as ``export
--record`` runs it (initial SOC by the library's rule, the record's temperature; rtol = atol =
1e-6, then 1e-7 and 1e-8; the SOC where the difference is largest): the model, then
the model plus hysteresis (M = 10 mV, γ = 100, test_ecm's values), then plus hysteresis, a
coulombic efficiency of 0.98 and a current offset of 0.1 % of the record's largest current

    nice -n 10 .venv/bin/python benchmarks/bench_pybamm_export.py [--sizes 2222 15000]
    ... --sizes 15000 --chunks 250 500 1000 2000 15000
    ... --only diffusion hysteresis current_offset coulombic_efficiency
    ... --real results/real/panasonic/diagnosis/25degC/model.json \
        results/real/canonical/panasonic_25degC_us06.csv
"""

from __future__ import annotations

import os

os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")

import argparse
import time

import numpy as np
import pandas as pd

from avoa_pipeline.interop import pybamm as export_pybamm
from avoa_pipeline.model import ecm
from avoa_pipeline.model.fitted import FittedModel

SOC0 = 0.9
TREF_K = 298.15
BASE = {"vnom_v": 3.9, "beta": 0.93, "capacity_ah": 2.5, "r0_ohm": 0.03, "r1_ohm": 0.015,
        "tau1_s": 40.0, "voltage_offset_v": -0.01}  # fmt: skip
ELEMENT = {
    "second_rc": {"r2_ohm": 0.012, "tau2_s": 400.0},
    "third_rc": {"r3_ohm": 0.008, "tau3_s": 2000.0},
    "soc_resistance": {"soc_resistance_k": 3.0, "soc_resistance_sigma": 0.3},
    "thermal": {"thermal_theta_r0_k": 4000.0, "thermal_theta_rc_k": 3000.0},
    "butler_volmer": {"bv_inv_i0_per_a": 0.5},
    "ocv_shape": {"ocv_shape_u0_v": 0.01, "ocv_shape_u1_v": -0.006},
    "diffusion": {"diffusion_soc_per_a": 0.02, "diffusion_tau_s": 600.0},
    "hysteresis": {"hysteresis_m_v": 0.01, "hysteresis_gamma": 100.0},
    "coulombic_efficiency": {"coulombic_efficiency": 0.95},
    "current_offset": {"current_offset_a": 0.03},
}
CONFIGS = [
    ("table", ("second_rc",)),
    ("rational", ()),
    ("table", ("soc_resistance",)),
    ("table", ("second_rc", "third_rc", "soc_resistance", "thermal", "butler_volmer",
               "ocv_shape")),
    ("table", ("diffusion",)),
    ("rational", ("hysteresis",)),
    ("table", ("second_rc", "diffusion", "hysteresis", "thermal", "coulombic_efficiency",
               "current_offset")),
]  # fmt: skip


def table() -> ecm.OcvTable:
    soc = np.linspace(0.0, 1.0, 101)
    return ecm.OcvTable.from_points(soc, 3.3 + 0.8 * soc + 0.12 * np.tanh((soc - 0.1) / 0.05))


def model_of(kind: str, effects) -> FittedModel:
    config = ecm.Config(tuple(effects), table() if kind == "table" else None)
    names = config.names()
    values = {**BASE, **{k: v for e in effects for k, v in ELEMENT[e].items()}}
    x = ecm.vector({k: v for k, v in values.items() if ecm.BY_REPORT[k] in names})
    return FittedModel(config, x, ecm.Knots(0.3, 0.14), TREF_K, {})


def issue_profile(n: int) -> np.ndarray:
    seg = [(200, 0.0), (600, 2.5), (300, 0.0), (400, -2.0), (300, 0.0), (30, 6.0), (392, 0.0)]
    c = np.concatenate([np.full(d, a) for d, a in seg])
    return np.resize(c, n)


def drive_profile(n: int, rng) -> np.ndarray:
    """A new demand every 10 s, interpolated, clipped to [-3, 6] A, shifted to a mean of 0.1 A
    (0.4 Ah net over 15,000 s: the SOC stays inside [0, 1]), plus 50 mA of noise per second."""
    k = n // 10 + 2
    demand = np.interp(np.arange(n), 10.0 * np.arange(k), rng.normal(0.5, 2.0, k))
    demand = np.clip(demand, -3.0, 6.0) + rng.normal(0.0, 0.05, n)
    return demand - demand.mean() + 0.1


def record(n: int, rng, uneven: bool = False) -> pd.DataFrame:
    cur = issue_profile(n) if n == 2222 else drive_profile(n, rng)
    dt = rng.choice([1.0, 2.0, 4.0], n) if uneven else np.ones(n)
    t = np.concatenate([[0.0], np.cumsum(dt[:-1])])
    temp = 20.0 + 10.0 * t / t[-1] + 0.5 * np.sin(t / 30.0)
    return pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": 3.7, "temperature_c": temp})


def pybamm_voltage(cell, frame, rtol, atol, lead=True, chunk=None):
    saved = cell.THERMAL_LEAD_S
    if not lead:
        cell.THERMAL_LEAD_S = 0.0
    try:
        return cell.simulate(frame["time_s"], frame["current_a"], frame["temperature_c"],
                             rtol=rtol, atol=atol, chunk=chunk or cell.CHUNK_SAMPLES)  # fmt: skip
    finally:
        cell.THERMAL_LEAD_S = saved


def with_elements(model: FittedModel, values: dict) -> FittedModel:
    """``model`` plus the elements of report-named ``values`` (their bounds ±1 around them)."""
    config = model.config
    x = model.x.copy()
    bounds = dict(model.bounds)
    for key, value in values.items():
        name, v = ecm.internal_value(key, value)
        element = ecm.PARAMS[name].element
        if element not in config.effects:
            config = config.with_effect(element)
        x[ecm.IDX[name]] = v
        bounds[name] = (v - 1.0, v + 1.0)
    return FittedModel(config, x, model.knots, model.tref_k, bounds, model.provenance,
                       model.current_scale_a)  # fmt: skip


def real(model_path: str, record_path: str) -> None:
    """A fitted model on a record of its cell, as ``export --record`` runs it (rtol = atol =
    1e-6), and at 1e-7 and 1e-8; with the SOC where the difference is largest."""
    from avoa_pipeline import inputs

    model = FittedModel.load(model_path)
    frame = inputs.read_record(record_path).frame
    imax = float(np.max(np.abs(frame["current_a"])))
    hysteresis = {"hysteresis_m_v": 0.01, "hysteresis_gamma": 100.0}
    variants = [model, with_elements(model, hysteresis),
                with_elements(model, {**hysteresis, "coulombic_efficiency": 0.98,
                                      "current_offset_a": 0.001 * imax})]  # fmt: skip
    print(f"{'configuration':<72} {'rtol=atol':>9} {'RMS mV':>8} {'max mV':>8} {'at SOC':>6} "
          f"{'PyBaMM s':>8} {'effect mV':>9}")  # fmt: skip
    temp = frame["temperature_c"].to_numpy() if "temperature_c" in frame.columns else None
    for m in variants:
        soc0 = m.initial_soc(m.record(frame))
        module = export_pybamm.load_source(export_pybamm.export(m, model_path, frame=frame).text)
        ours, traces = m.simulate(frame, soc0=soc0, traces=True)
        # what the added elements move our voltage by (0 for the model as fitted)
        effect = 1e3 * np.sqrt(np.mean((ours - model.simulate(frame, soc0=soc0)) ** 2))
        for tol in (1e-6, 1e-7, 1e-8):
            t0 = time.perf_counter()
            v = module.simulate(frame["time_s"].to_numpy(), frame["current_a"].to_numpy(), temp,
                                initial_soc=soc0, rtol=tol, atol=tol)  # fmt: skip
            seconds = time.perf_counter() - t0
            d = 1e3 * np.abs(v - ours)
            print(f"{m.config.name:<72} {tol:>9g} {np.sqrt(np.mean(d**2)):>8.4f} {d.max():>8.4f} "
                  f"{traces[0][np.argmax(d)]:>6.3f} {seconds:>8.1f} {effect:>9.2f}",
                  flush=True)  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[2222, 15000])
    p.add_argument("--chunks", type=int, nargs="*", default=[], help="piece sizes to time")
    p.add_argument("--only", nargs="*", default=[], help="configurations with these elements")
    p.add_argument("--real", nargs=2, metavar=("MODEL", "RECORD"), default=None)
    args = p.parse_args()
    if args.real:
        real(*args.real)
        return
    rng = np.random.default_rng(1)
    print(f"{'record':>9} {'configuration':<72} {'solver':<22} {'RMS mV':>8} {'max mV':>8} "
          f"{'PyBaMM s':>8} {'ours s':>8}")  # fmt: skip
    records = [(f"{n}", record(n, rng)) for n in args.sizes]
    if 2222 in args.sizes:
        records.append(("2222@1-4s", record(2222, rng, uneven=True)))
    for name, frame in records:
        for kind, effects in CONFIGS:
            if name.endswith("s") and "soc_resistance" not in effects:
                continue
            if args.only and not set(args.only) & set(effects):
                continue
            model = model_of(kind, effects)
            cell = export_pybamm.load_source(export_pybamm.export(model, "m", soc0=SOC0).text)
            model.simulate(frame.iloc[:10], soc0=SOC0)  # compile once, outside the timing
            t0 = time.perf_counter()
            ours = model.simulate(frame, soc0=SOC0)
            t_ours = time.perf_counter() - t0
            rows = [(f"rtol=atol={tol:g}", tol, tol, True, None) for tol in (1e-8, 1e-7, 1e-6)]
            rows.append(("IDAKLU defaults", 1e-4, 1e-6, True, None))
            if name.endswith("s"):
                rows = rows[:1]
            elif "thermal" in effects:
                rows.append(("1e-06, no thermal lead", 1e-6, 1e-6, False, None))
                rows += [(f"1e-06, pieces of {c}", 1e-6, 1e-6, True, c) for c in args.chunks]
            for label, rtol, atol, lead, chunk in rows:
                t0 = time.perf_counter()
                v = pybamm_voltage(cell, frame, rtol, atol, lead, chunk)
                t_pb = time.perf_counter() - t0
                d = 1e3 * np.abs(v - ours)
                print(f"{name:>9} {model.config.name:<72} {label:<22} "
                      f"{np.sqrt(np.mean(d**2)):>8.4f} {d.max():>8.4f} {t_pb:>8.2f} "
                      f"{t_ours:>8.3f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
