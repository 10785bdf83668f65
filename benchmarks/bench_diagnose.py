"""Seconds per gap diagnosis for records of 2,000, 15,000 and 200,000 samples.

Records are simulated from the diagnosis' own base model (plus, with ``--effect``, one effect)
with 1 mV noise quantised to 1 mV: a pulse/rest/charge profile at 1 Hz for 2k and 15k samples, a
drive-cycle-like random current at 10 Hz for 200k. Prints measured times; asserts nothing.

    OPENBLAS_NUM_THREADS=1 nice -n 19 .venv/bin/python benchmarks/bench_diagnose.py
    ... --sizes 15000 --effect hysteresis --repeat 3
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as the CLI (before numpy loads)
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import time

import numpy as np
import pandas as pd

from avoa_pipeline.gap import diagnose, models

TRUTH = {
    "vnom_v": 3.73, "beta": 0.932, "capacity_ah": 2.57, "soc0": 0.95,
    "r0_ohm": 0.0536, "r1_ohm": 0.0153, "tau1_s": 109.7,
}  # fmt: skip
EFFECT = {
    "none": {},
    "second_rc": {"r2_ohm": 0.01, "tau2_s": 1000.0},
    "hysteresis": {"hysteresis_m_v": 0.01, "hysteresis_gamma": 100.0},
    "butler_volmer": {"bv_inv_i0_per_a": 2.0},
    "current_offset": {"current_offset_a": 0.02},
}


def pulse_profile(n: int, rng) -> np.ndarray:
    """Rests, discharge and charge pulses (1 Hz) whose charge roughly balances."""
    cur = []
    sign = 1.0
    while sum(map(len, cur)) < n:
        amp = rng.uniform(0.5, 3.0)
        dur = int(rng.uniform(120, 1200))
        cur.append(np.full(dur, sign * amp if sign > 0 else -0.8 * amp))
        cur.append(np.zeros(int(rng.uniform(120, 900))))
        sign = -sign if rng.random() < 0.5 else sign
    c = np.concatenate(cur)[:n]
    c[:300] = 0.0
    return c


def drive_profile(n: int, rng, hz: float = 10.0) -> np.ndarray:
    """A 10 Hz drive-cycle-like current: smooth random demand with regenerative braking."""
    k = int(np.ceil(n / (5 * hz)))  # a new demand every 5 s, interpolated
    knots = rng.normal(1.2, 1.5, k)
    c = np.interp(np.arange(n) / (5 * hz), np.arange(k), knots)
    c[: int(300 * hz)] = 0.0
    return c


def record(n: int, effect: str, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    if n > 50_000:
        hz = 10.0
        cur = drive_profile(n, rng, hz)
        net_ah = float(np.max(np.cumsum(cur)) / hz / 3600.0)
        params = {**TRUTH, "capacity_ah": 1.6 * net_ah}  # 60 % of the capacity discharged
    else:
        hz = 1.0
        cur = pulse_profile(n, rng)
        params = dict(TRUTH)
    t = np.arange(n) / hz
    frame = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": 0.0})
    frame["temperature_c"] = 25.0 + 0.002 * np.cumsum(np.abs(cur)) / hz / (1 + t / 3600)
    v = models.simulate_params(frame, {**params, **EFFECT[effect]})
    frame["voltage_v"] = np.round((v + 1e-3 * rng.standard_normal(n)) / 1e-3) * 1e-3
    frame["current_a"] = np.round((cur + 1e-3 * rng.standard_normal(n)) / 1e-3) * 1e-3
    return frame


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[2000, 15000, 200000])
    p.add_argument("--effect", default="hysteresis", choices=sorted(EFFECT))
    p.add_argument("--repeat", type=int, default=1)
    args = p.parse_args()
    diagnose.diagnose(record(2000, "none"))  # compile / load the numba cache outside the timing
    print(f"{'samples':>8} {'effect':>14} {'verdict':>22} {'fits':>5} {'seconds':>8}")
    for n in args.sizes:
        frame = record(n, args.effect)
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            rep = diagnose.diagnose(frame)
            dt = time.perf_counter() - t0
            print(
                f"{n:8d} {args.effect:>14} {rep['verdict']['effect']:>22} "
                f"{rep['method']['fits']:5d} {dt:8.1f}"
            )


if __name__ == "__main__":
    main()
