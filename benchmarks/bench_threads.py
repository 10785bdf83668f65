"""Where the population kernel's threads pay: one thread against two per call, over rows × samples;
and one AVOA run with the thread policy against one thread (``--avoa``), quiet or under load.

    .venv/bin/python benchmarks/bench_threads.py                      # rows 20 ... 600 x 5,701
    .venv/bin/python benchmarks/bench_threads.py --rows 20 24 32 40 80 --samples 500 2000 20000
    chrt -f 1 .venv/bin/python benchmarks/bench_threads.py  # the cores free of other work
    .venv/bin/python benchmarks/bench_threads.py --avoa --busy 1      # another core held busy

On a machine shared with other work, ``chrt -f 1`` (real-time priority, root) gives the
measurement the cores as a quiet machine would: nothing else runs while it does (the kernel
keeps 5 % of each second for the rest, ``sched_rt_runtime_us``); keep such runs short.

The table: per rows × samples, the kernel's ns per candidate-sample on the calling thread
(``kernel.ise_serial``) and in two blocks on two numba threads (``kernel.ise_population``), the
minimum and median over ``--repeat`` interleaved timings, and the median of the per-repeat ratios
two ÷ one. The break-even: among the cells whose blocks hold ``threads.MIN_BLOCK_ROWS`` rows or
more, the smallest work (rows × samples per call) from which two threads are faster in every
larger cell (``threads.PARALLEL_MIN_WORK`` carries the value chosen from it); and how the cells
with smaller blocks fared (their SIMD lanes half empty: ``MIN_BLOCK_ROWS``).

``--avoa``: one AVOA run on scenario 4 case 4 (the paper's 20 × 500 budget) timed three ways,
interleaved: the policy (``threads.kernel_blocks``, numba's default threads), one numba thread,
and the rule before the policy (two blocks for any call of 8 rows or more). ``--busy N`` (either
mode) runs N busy loops in other processes during the measurement (a machine whose cores are
taken). The load average is printed before and after. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from contextlib import contextmanager

import numba
import numpy as np

from avoa_pipeline import config, problem, seeds, threads
from avoa_pipeline.model import battery, kernel
from avoa_pipeline.optimizers import Budget, minimize


def load() -> str:
    return f"load {os.getloadavg()[0]:.2f} ({len(os.sched_getaffinity(0))} cores)"


@contextmanager
def busy(n: int):
    """``n`` busy loops in processes of their own, stopped (by their ids) on leaving."""
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        time.sleep(0.5 if n else 0.0)  # let the scheduler see them
        yield
    finally:
        for p in procs:
            p.kill()
            p.wait()


def record_of(prob, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """The record's current and voltage cut or repeated to ``samples`` samples."""
    reps = -(-samples // prob.time_s.size)
    return (np.tile(prob.current_a, reps)[:samples], np.tile(prob.voltage_v, reps)[:samples])


def per_call(fn, seconds: float, work: int) -> float:
    """Seconds per call of ``fn`` (about ``seconds`` of calls, sized by ``work``)."""
    reps = max(3, int(seconds / (work * 1e-9)))
    t0 = time.perf_counter()
    for _ in range(reps):
        fn()
    return (time.perf_counter() - t0) / reps


def cell(prob, rows: int, samples: int, repeat: int, seconds: float) -> dict:
    """One thread against two blocks on two threads, interleaved ``repeat`` times."""
    rng = np.random.default_rng(rows)
    X = prob.lb + rng.random((rows, prob.lb.size)) * (prob.ub - prob.lb)
    i, v = record_of(prob, samples)
    args = battery.kernel_args(prob.full(X), i, v, prob.ts, prob.spec)
    one = lambda: kernel.ise_serial(*args)  # noqa: E731
    two = lambda: kernel.ise_population(*args, 2)  # noqa: E731
    assert np.array_equal(one(), two())  # the kernel is deterministic per row
    work = rows * samples
    t1, t2 = [], []
    for _ in range(repeat):
        t1.append(per_call(one, seconds, work))
        t2.append(per_call(two, seconds, work))
    ns1, ns2 = np.array(t1) / work * 1e9, np.array(t2) / work * 1e9
    return {"rows": rows, "samples": samples, "work": work, "ns1": ns1, "ns2": ns2,
            "ratio": float(np.median(ns2 / ns1))}  # fmt: skip


def break_even(cells: list[dict]) -> tuple[int | None, int | None]:
    """(largest work where one thread won, smallest work from which two always win)."""
    cells = sorted(cells, key=lambda c: c["work"])
    lost = [c["work"] for c in cells if c["ratio"] >= 1.0]
    last_lost = max(lost) if lost else None
    won = [c["work"] for c in cells if c["ratio"] < 1.0 and (last_lost is None or
                                                            c["work"] > last_lost)]  # fmt: skip
    return last_lost, (min(won) if won else None)


def summary(cells: list[dict]) -> str:
    """The break-even in work among the cells whose two blocks hold ``MIN_BLOCK_ROWS`` rows or
    more, and how the cells with smaller blocks fared."""
    small = [c for c in cells if c["rows"] // 2 < threads.MIN_BLOCK_ROWS]
    big = [c for c in cells if c["rows"] // 2 >= threads.MIN_BLOCK_ROWS]
    out = []
    if small:
        r = [c["ratio"] for c in small]
        out.append(f"blocks under {threads.MIN_BLOCK_ROWS} rows: two threads slower in "
                   f"{sum(x >= 1 for x in r)} of {len(r)} cells "
                   f"(2/1 {min(r):.2f}-{max(r):.2f})")  # fmt: skip
    if big:
        lost, won = break_even(big)
        out.append(f"blocks of {threads.MIN_BLOCK_ROWS} rows or more: one thread won up to "
                   f"{lost or 0:.3g} candidate-samples per call, two won from "
                   f"{won or float('nan'):.3g} on")  # fmt: skip
    return "; ".join(out)


def table(args) -> None:
    numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
    prob = problem.build(config.load(), 4, 4)
    print(f"scenario 4 case 4, record {prob.time_s.size} samples; numba threads "
          f"{numba.get_num_threads()}; {args.busy} busy loops; {load()}")  # fmt: skip
    print(f"{'rows':>5s} {'samples':>7s} {'work':>10s} {'1 thr min':>9s} {'med':>6s} "
          f"{'2 thr min':>9s} {'med':>6s} {'2/1 med':>8s}")  # fmt: skip
    cells = []
    with busy(args.busy):
        for samples in args.samples:
            for rows in args.rows:
                c = cell(prob, rows, samples, args.repeat, args.seconds)
                cells.append(c)
                n1, n2 = c["ns1"], c["ns2"]
                print(f"{rows:5d} {samples:7d} {c['work']:10.3e} {n1.min():9.3f} "
                      f"{np.median(n1):6.3f} {n2.min():9.3f} {np.median(n2):6.3f} "
                      f"{c['ratio']:8.3f}", flush=True)  # fmt: skip
        end = load()
    print(f"break-even: {summary(cells)}; the policy: PARALLEL_MIN_WORK "
          f"{threads.PARALLEL_MIN_WORK:.3g}, MIN_BLOCK_ROWS {threads.MIN_BLOCK_ROWS}; threading "
          f"layer {numba.threading_layer()}; {end}")  # fmt: skip


def _old_rule(rows: int, samples: int) -> int:  # the rule before the policy
    return max(1, min(numba.get_num_threads(), rows // 4))


def avoa(args) -> None:
    prob = problem.build(config.load(), 4, 4)
    budget = Budget(pop_size=20, iterations=500)
    policy, default_threads = threads.kernel_blocks, numba.get_num_threads()

    def run(n_threads: int, rule) -> float:
        numba.set_num_threads(n_threads)
        threads.kernel_blocks = rule
        try:
            t0 = time.perf_counter()
            minimize("avoa", prob.objective, prob.lb, prob.ub, budget, seeds.stream(1, "bench", 0))
            return time.perf_counter() - t0
        finally:
            threads.kernel_blocks = policy

    ways = {"policy": (default_threads, policy), "one thread": (1, policy),
            "two blocks (before)": (default_threads, _old_rule)}  # fmt: skip
    for way in ways.values():  # compile and warm every path
        run(*way)
    print(f"one AVOA run, s4 c4, 20 x 500; numba default threads {default_threads}; "
          f"{args.busy} busy loops; {load()}")  # fmt: skip
    with busy(args.busy):
        times = {k: [] for k in ways}
        for _ in range(args.repeat):
            for k, way in ways.items():
                times[k].append(run(*way))
        end = load()
    base = np.array(times["one thread"])
    for k, t in times.items():
        t = np.array(t)
        print(f"{k:20s} min {t.min():.3f} s, median {np.median(t):.3f} s, "
              f"÷ one thread (median of pairs) {np.median(t / base):.2f}")  # fmt: skip
    print(end)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, nargs="*", default=[20, 40, 80, 160, 320, 600])
    ap.add_argument("--samples", type=int, nargs="*", default=[5701])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--seconds", type=float, default=0.2, help="per timing (the table)")
    ap.add_argument("--avoa", action="store_true", help="time one AVOA run three ways")
    ap.add_argument("--busy", type=int, default=0, help="busy loops beside the measurement")
    args = ap.parse_args()
    (avoa if args.avoa else table)(args)


if __name__ == "__main__":
    main()
