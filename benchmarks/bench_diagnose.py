"""Seconds per gap diagnosis for records of 2,000, 15,000 and 200,000 samples; with ``--sweep``,
the verdicts on a small grid of the diagnosis' own effects (a self-check, not the validation:
that is the independent generator of ``gap/withheld.py``).

Records are simulated from the diagnosis' own base model (plus, with ``--effect``, one effect)
with 1 mV noise quantised to 1 mV: a pulse/rest/charge profile at 1 Hz for 2k and 15k samples, a
drive-cycle-like random current at 10 Hz for 200k. Prints measured times; asserts nothing.

    nice -n 19 .venv/bin/python benchmarks/bench_diagnose.py
    ... --sizes 15000 --effect hysteresis --repeat 3
    ... --sweep 6        # 6 replicates x (control + 8 effects x 2 magnitudes)
    ... --stages A.csv B.csv   # where each diagnosis's time goes (fits, held-out fits, Jacobians)
    ... --long 1000000 2000000   # issue 25's long records through the CLI, in a child process
    ... --thinned 1000000   # the simulator's CPU ns per sample-row, full and thinned passes
    ... --long-ocv 200000 1000000   # issue 37: the long record diagnosed with its true OCV

``--long``: the issue's clean synthetic record (:func:`issue_record`: 10 Hz, current held 1-30 s
at 0, ±0.5, ±1 or ±2 A with SOC kept in 0.2-0.9, OCV 3.0 + 0.7·s + 0.5·s² V, R0 30 mΩ, R1 15 mΩ,
τ1 30 s, 2.9 Ah, 1 mV noise) written as a CSV and diagnosed by ``python -m avoa_pipeline
diagnose`` in a child process; prints its wall and CPU seconds, its peak RSS (the whole process,
from ``os.wait4``), the load average before and after, and what ``diagnosis.json`` says it did.

``--long-ocv``: the same record diagnosed in this process with its true OCV as a table (the
quadratic at 201 points, ``ocv.from_table``: no slow test, so the offset's prior is the named
default ``ocv.OFFSET_SD_V``); prints CPU seconds, the verdict, the base's RMSE against the noise
floor, its offset (95 % interval), capacity and initial SOC against the truth (0 V, 2.9 Ah,
0.55), and the pairs the base's intervals cannot tell apart.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as the CLI (before numpy loads)
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from avoa_pipeline.gap import diagnose
from avoa_pipeline.model import ecm

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
    v = ecm.simulate_params(frame, {**params, **EFFECT[effect]})
    frame["voltage_v"] = np.round((v + 1e-3 * rng.standard_normal(n)) / 1e-3) * 1e-3
    frame["current_a"] = np.round((cur + 1e-3 * rng.standard_normal(n)) / 1e-3) * 1e-3
    return frame


def issue_record(n: int, seed: int = 0, hz: float = 10.0) -> pd.DataFrame:
    """Issue 25's clean synthetic long record (an independent simulation, not the library's:
    its OCV is a quadratic the rational curve cannot follow exactly)."""
    from scipy.signal import lfilter

    rng = np.random.default_rng(seed)
    q_ah, r0, r1, tau1, soc0 = 2.9, 0.030, 0.015, 30.0, 0.55
    levels = np.array([0.0, 0.5, -0.5, 1.0, -1.0, 2.0, -2.0])
    cur = np.empty(n)
    k, soc = 0, soc0
    while k < n:
        m = min(n - k, round(rng.uniform(1.0, 30.0) * hz))
        a = rng.choice(levels)
        if not 0.2 <= soc - a * m / hz / 3600.0 / q_ah <= 0.9:
            a = -a  # the other direction keeps SOC inside 0.2-0.9
        cur[k : k + m] = a
        soc -= a * m / hz / 3600.0 / q_ah
        k += m
    s = soc0 - np.concatenate([[0.0], np.cumsum(cur[:-1])]) / hz / 3600.0 / q_ah
    a1 = np.exp(-1.0 / hz / tau1)
    v1 = lfilter([0.0, r1 * (1.0 - a1)], [1.0, -a1], cur)  # v1[k+1] = a·v1[k] + R1(1 − a)·i[k]
    v = 3.0 + 0.7 * s + 0.5 * s**2 - r0 * cur - v1 + 1e-3 * rng.standard_normal(n)
    return pd.DataFrame({"time_s": np.arange(n) / hz, "current_a": cur, "voltage_v": v})


def long_with_ocv(sizes) -> None:
    """Issue 37: :func:`issue_record` diagnosed with its true OCV table (module docstring)."""
    from avoa_pipeline.model import ocv

    s = np.linspace(0.0, 1.0, 201)
    table = ocv.from_table(pd.DataFrame({"soc": s, "ocv_v": 3.0 + 0.7 * s + 0.5 * s**2}), "true")
    print(f"{'samples':>9} {'cpu s':>7} {'verdict':>14} {'rmse/noise':>10} {'offset mV (95 %)':>24}"
          f" {'Ah':>7} {'soc0':>7}  degenerate")  # fmt: skip
    for n in sizes:
        frame = issue_record(n)
        c0 = time.process_time()
        rep, _, _ = diagnose.diagnose_records(frame, ocv_table=table, progress=False)
        cpu = time.process_time() - c0
        b, iv = rep["base"], rep["intervals"]["parameters"]
        p = b["parameters"]
        off = iv.get("voltage_offset_v", {})
        ends = (f"{1e3 * off['low95']:.1f}..{1e3 * off['high95']:.1f}"
                if off.get("low95") is not None else "none")  # fmt: skip
        print(f"{n:9d} {cpu:7.1f} {rep['verdict']['effect']:>14} {b['rmse_to_noise']:10.4f} "
              f"{1e3 * p['voltage_offset_v']:7.2f} ({ends:>14}) {p['capacity_ah']:7.4f} "
              f"{p['soc0']:7.4f}  {b['degenerate']}", flush=True)  # fmt: skip


def long_records(sizes, timeout_s: float) -> None:
    """Each size diagnosed by the CLI in a child process: wall, CPU, peak RSS, load."""
    print(f"{'samples':>9} {'wall s':>7} {'cpu s':>7} {'peak RSS MB':>11} {'load before/after':>17}"
          f" {'fitted':>7} {'stride':>6} {'verdict':>12}  exit")  # fmt: skip
    for n in sizes:
        with tempfile.TemporaryDirectory() as tmp:
            csv = Path(tmp) / f"issue25_{n}.csv"
            issue_record(n).to_csv(csv, index=False)
            out = Path(tmp) / "out"
            load0 = os.getloadavg()[0]
            t0 = time.perf_counter()
            proc = subprocess.Popen([sys.executable, "-m", "avoa_pipeline", "diagnose", str(csv),
                                     "--out", str(out)], stdout=subprocess.DEVNULL)  # fmt: skip
            # wait4 reaps this child only and returns its own resource use (ru_maxrss in kB)
            while True:
                pid, status, ru = os.wait4(proc.pid, os.WNOHANG)
                if pid:
                    break
                if time.perf_counter() - t0 > timeout_s:  # running away: stop it, say so
                    proc.kill()
                    _, status, ru = os.wait4(proc.pid, 0)
                    break
                time.sleep(0.2)
            wall = time.perf_counter() - t0
            code = proc.returncode = os.waitstatus_to_exitcode(status)
            rep = (json.loads((out / "diagnosis.json").read_text())
                   if (out / "diagnosis.json").exists() else None)  # fmt: skip
            smp = rep.get("samples", {}) if rep else {}  # absent before issue 25
            print(
                f"{n:9d} {wall:7.1f} {ru.ru_utime + ru.ru_stime:7.1f} "
                f"{ru.ru_maxrss / 1024:11.0f} {load0:8.2f}/{os.getloadavg()[0]:<8.2f} "
                f"{smp.get('fitted', '-'):>7} {smp.get('stride', '-'):>6} "
                f"{rep['verdict']['effect'] if rep else '-':>12}  {code}",
                flush=True,
            )


def thinned(n: int, rows: int = 9, returned: int = 20000, repeat: int = 3) -> None:
    """CPU ns per sample and parameter row of ``ecm.simulate_physical`` on :func:`issue_record`'s
    current: the full pass (every voltage) and a fit's thinned pass (``returned`` voltages)."""
    rec = ecm.Record.from_frame(issue_record(n))
    params = {**TRUTH, "capacity_ah": 30.0, "soc0": 0.8}
    idx = np.arange(0, n, max(1, n // returned))
    configs = {
        "base": {},
        "ocv_shape": {"ocv_shape_u0_v": 0.005},
        "hysteresis": {"hysteresis_m_v": 0.01, "hysteresis_gamma": 50.0},
    }
    for name, extra in configs.items():
        P = ecm.to_physical(np.repeat(ecm.vector({**params, **extra})[None, :], rows, axis=0))
        for label, sel in (("full", None), ("thinned", idx)):
            best = np.inf
            for _ in range(repeat):
                c0 = time.process_time()
                ecm.simulate_physical(rec, P, ecm.Knots(0.0, 0.2), idx=sel)
                best = min(best, time.process_time() - c0)
            print(f"{name:>10} {label:>8} {1e9 * best / n / rows:6.2f} ns per sample-row")


SWEEP = {
    "none": [{}],
    "second_rc": [{"r2_ohm": 0.005, "tau2_s": 600.0}, {"r2_ohm": 0.015, "tau2_s": 2000.0}],
    "hysteresis": [
        {"hysteresis_m_v": 0.003, "hysteresis_gamma": 50.0},
        {"hysteresis_m_v": 0.01, "hysteresis_gamma": 200.0},
    ],
    "butler_volmer": [{"bv_inv_i0_per_a": 1.0}, {"bv_inv_i0_per_a": 3.0}],
    "thermal": [
        {"thermal_theta_r0_k": 2000.0, "thermal_theta_rc_k": 2000.0},
        {"thermal_theta_r0_k": 5000.0},
    ],
    "ocv_shape": [{"ocv_shape_u0_v": 0.005}, {"ocv_shape_u1_v": 0.01, "ocv_shape_u2_v": -0.005}],
    "current_offset": [{"current_offset_a": 0.01}, {"current_offset_a": 0.03}],
    "voltage_offset": [{"voltage_offset_v": 0.005}, {"voltage_offset_v": 0.02}],
    "coulombic_efficiency": [{"coulombic_efficiency": 0.99}, {"coulombic_efficiency": 0.96}],
}


def sweep(replicates: int) -> None:
    """Replicate r: 6,000 or 15,000 samples, 0.5/1/2 mV noise, its own profile and SOC0."""
    print(f"{'rep':>3} {'effect':>20} {'mag':>3} {'excess/noise':>12} {'verdict':>20} {'cpu s':>6}")
    right = total = right_d = total_d = 0
    for rep in range(replicates):
        for effect, mags in SWEEP.items():
            for m, extra in enumerate(mags):
                rng = np.random.default_rng(1000 + rep)
                n = (6000, 15000)[rep % 2]
                noise = (0.5e-3, 1e-3, 2e-3)[rep % 3]
                cur = pulse_profile(n, rng)
                t = np.arange(n, dtype=float)
                frame = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": 0.0})
                frame["temperature_c"] = 25.0 + 4 * np.sin(t / 5000 + rep)
                truth = {**TRUTH, "soc0": rng.uniform(0.6, 1.0), **extra}
                v = ecm.simulate_params(frame, truth)
                frame["voltage_v"] = np.round((v + noise * rng.standard_normal(n)) / 1e-3) * 1e-3
                frame["current_a"] = np.round((cur + 1e-3 * rng.standard_normal(n)) / 1e-3) * 1e-3
                c0 = time.process_time()
                r = diagnose.diagnose(frame)
                base, floor = r["base"]["rmse_mv"], r["base"]["noise_floor_mv"]
                excess = np.sqrt(max(base**2 - floor**2, 0.0)) / floor
                ok = r["verdict"]["effect"] == effect
                total += 1
                right += ok
                if effect == "none" or excess >= 1.5:
                    total_d += 1
                    right_d += ok
                print(
                    f"{rep:3d} {effect:>20} {m:3d} {excess:12.2f} {r['verdict']['effect']:>20} "
                    f"{time.process_time() - c0:6.1f}",
                    flush=True,
                )
    print(
        f"right: {right}/{total} in all; {right_d}/{total_d} of the controls and the effects "
        "whose base residual exceeds the noise by >= 1.5x (excess = sqrt(rmse^2 - floor^2))"
    )


def stages(paths) -> None:
    """Where one diagnosis's time goes, per CSV of ``paths`` (canonical records): CPU seconds of
    the full fits (``Context.fit``: multi-start, coarse trials and the refinement) and of the
    held-out fits (``Context.cross_validate``: one per fold or held-out record), the least-squares
    problems solved, their residual and Jacobian evaluations, and the ladder's length."""
    from scipy.optimize import _lsq

    from avoa_pipeline import inputs, selection
    from avoa_pipeline.model import fitting

    spent: dict[str, list[float]] = {}

    def timed(owner, name):
        f = getattr(owner, name)

        def run(*a, **k):
            c0 = time.process_time()
            try:
                return f(*a, **k)
            finally:
                spent.setdefault(name, [0, 0.0])
                spent[name][0] += 1
                spent[name][1] += time.process_time() - c0

        setattr(owner, name, run)
        return f

    solved = {"problems": 0, "residuals": 0, "jacobians": 0}
    least_squares = fitting.least_squares

    def counted(*a, **k):
        res = least_squares(*a, **k)
        solved["problems"] += 1
        solved["residuals"] += res.nfev
        solved["jacobians"] += res.njev or 0
        return res

    assert _lsq  # scipy's solver, counted through fitting's reference to it
    fit, cv = timed(selection.Context, "fit"), timed(selection.Context, "cross_validate")
    fitting.least_squares = counted
    try:
        for path in paths:
            spent.clear()
            solved.update(problems=0, residuals=0, jacobians=0)
            rec = inputs.read_record(path)
            c0 = time.process_time()
            r = diagnose.diagnose(rec)
            total = time.process_time() - c0
            held = sum(1 for c in r["candidates"] if c.get("heldout_rmse_mv") is not None)
            tried = sum(1 for c in r["candidates"] if c.get("applicable"))
            print(f"{path}: {total:.1f} s CPU, selected {r['selected']['name']}, "
                  f"{len(r['ladder'])} rungs, {len(r.get('pruned', []))} pruned")  # fmt: skip
            for name, (n, sec) in spent.items():
                print(f"  {name:15s} {n:4d} calls {sec:7.1f} s ({sec / total:.0%})")
            print(f"  least squares   {solved['problems']:4d} problems, {solved['residuals']} "
                  f"residual and {solved['jacobians']} Jacobian evaluations; first rung: "
                  f"{tried} candidates, {held} held out")  # fmt: skip
    finally:
        selection.Context.fit, selection.Context.cross_validate = fit, cv
        fitting.least_squares = least_squares


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[2000, 15000, 200000])
    p.add_argument("--effect", default="hysteresis", choices=sorted(EFFECT))
    p.add_argument("--repeat", type=int, default=1)
    p.add_argument("--sweep", type=int, default=0, metavar="REPLICATES")
    p.add_argument(
        "--stages",
        nargs="+",
        default=None,
        metavar="CSV",
        help="where the time of each CSV's diagnosis goes (full and held-out fits)",
    )
    p.add_argument(
        "--long",
        type=int,
        nargs="+",
        default=None,
        metavar="SAMPLES",
        help="issue 25's long records through the CLI (wall, CPU, peak RSS)",
    )
    p.add_argument(
        "--timeout", type=float, default=1800.0, help="--long: seconds before the child is killed"
    )
    p.add_argument(
        "--long-ocv",
        type=int,
        nargs="+",
        default=None,
        metavar="SAMPLES",
        help="issue 37: the long record diagnosed with its true OCV table",
    )
    p.add_argument(
        "--thinned",
        type=int,
        default=0,
        metavar="SAMPLES",
        help="the simulator's CPU ns per sample-row, full and thinned passes",
    )
    args = p.parse_args()
    if args.thinned:
        thinned(args.thinned)
        return
    if args.long:
        long_records(args.long, args.timeout)
        return
    if args.long_ocv:
        long_with_ocv(args.long_ocv)
        return
    if args.stages:
        diagnose.diagnose(record(2000, "none"))  # the numba cache, outside the timing
        stages(args.stages)
        return
    if args.sweep:
        sweep(args.sweep)
        return
    diagnose.diagnose(record(2000, "none"))  # compile / load the numba cache outside the timing
    # CPU seconds beside wall seconds: on a shared machine the wall time measures the neighbours
    print(f"{'samples':>8} {'effect':>14} {'verdict':>22} {'fits':>5} {'wall s':>7} {'cpu s':>6}")
    for n in args.sizes:
        frame = record(n, args.effect)
        for _ in range(args.repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            rep = diagnose.diagnose(frame)
            dt, dc = time.perf_counter() - t0, time.process_time() - c0
            print(
                f"{n:8d} {args.effect:>14} {rep['verdict']['effect']:>22} "
                f"{rep['method']['fits']:5d} {dt:7.1f} {dc:6.1f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
