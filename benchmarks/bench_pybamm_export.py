"""PyBaMM's Thevenin model from an exported module against the package's simulator, on records
longer than the unit tests': agreement (RMS and largest difference, mV) and seconds per
record (PyBaMM: model build and solve, as the module's ``simulate`` does; ours:
``FittedModel.simulate``). Prints measurements; asserts nothing.

Records: the issue's profile (discharge, rest, charge, 6 A pulse, rests; 2,222 samples at 1 s)
and a 1 Hz drive-like current (15,000 samples, a new current every second), both with a measured
temperature that moves 10 °C. Rows: IDAKLU at rtol = atol = 1e-8, 1e-7 and 1e-6 (the module's
``simulate``) and at its defaults; for the thermal stack, also at 1e-6 without the thermal lead
(the ambient switched at the sample time instead of THERMAL_LEAD_S before it).

    nice -n 10 .venv/bin/python benchmarks/bench_pybamm_export.py [--sizes 2222 15000]
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
    "soc_resistance": {"soc_resistance_k": 3.0, "soc_resistance_sigma": 0.15},
    "thermal": {"thermal_theta_r0_k": 4000.0, "thermal_theta_rc_k": 3000.0},
    "butler_volmer": {"bv_inv_i0_per_a": 0.5},
    "ocv_shape": {"ocv_shape_u0_v": 0.01, "ocv_shape_u1_v": -0.006},
}
CONFIGS = [
    ("table", ("second_rc",)),
    ("rational", ()),
    ("table", ("second_rc", "third_rc", "soc_resistance", "thermal", "butler_volmer",
               "ocv_shape")),
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


def record(n: int, rng) -> pd.DataFrame:
    cur = issue_profile(n) if n == 2222 else drive_profile(n, rng)
    t = np.arange(n, dtype=float)
    temp = 20.0 + 10.0 * t / t[-1] + 0.5 * np.sin(t / 30.0)
    return pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": 3.7, "temperature_c": temp})


def pybamm_voltage(cell, frame, tol=None, lead=True):
    import pybamm

    values = pybamm.ParameterValues(cell.get_parameter_values())
    updates, t = cell.drive(frame["time_s"], frame["current_a"], frame["temperature_c"])
    if not lead:
        updates["Ambient temperature [K]"] = cell.held(t, frame["temperature_c"] + 273.15)
    values.update(updates)
    model = pybamm.equivalent_circuit.Thevenin(options=cell.OPTIONS)
    solver = pybamm.IDAKLUSolver() if tol is None else pybamm.IDAKLUSolver(rtol=tol, atol=tol)
    sim = pybamm.Simulation(model, parameter_values=values, solver=solver)
    return sim.solve(t_eval=t, t_interp=t)["Voltage [V]"].entries


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[2222, 15000])
    args = p.parse_args()
    rng = np.random.default_rng(1)
    print(f"{'record':>7} {'configuration':<72} {'solver':<22} {'RMS mV':>8} {'max mV':>8} "
          f"{'PyBaMM s':>8} {'ours s':>8}")  # fmt: skip
    for n in args.sizes:
        frame = record(n, rng)
        for kind, effects in CONFIGS:
            model = model_of(kind, effects)
            cell = export_pybamm.load_source(export_pybamm.export(model, "m", soc0=SOC0).text)
            model.simulate(frame.iloc[:10], soc0=SOC0)  # compile once, outside the timing
            t0 = time.perf_counter()
            ours = model.simulate(frame, soc0=SOC0)
            t_ours = time.perf_counter() - t0
            rows = [(f"rtol=atol={tol:g}", tol, True) for tol in (1e-8, 1e-7, 1e-6)]
            rows.append(("IDAKLU defaults", None, True))
            if "thermal" in effects:
                tol = export_pybamm.SOLVER_TOL
                rows.append((f"{tol:g}, no thermal lead", tol, False))
            for label, tol, lead in rows:
                t0 = time.perf_counter()
                v = pybamm_voltage(cell, frame, tol, lead)
                t_pb = time.perf_counter() - t0
                d = 1e3 * np.abs(v - ours)
                print(f"{n:>7} {model.config.name:<72} {label:<22} "
                      f"{np.sqrt(np.mean(d**2)):>8.4f} {d.max():>8.4f} {t_pb:>8.2f} "
                      f"{t_ours:>8.3f}")  # fmt: skip


if __name__ == "__main__":
    main()
