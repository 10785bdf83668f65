"""Model cost per sample: one candidate per call and a population of 20, without (scenario 1)
and with (scenario 4) the 1 kOhm load, single-threaded (as in a workflow fit job); and the
population kernel's cost per candidate-sample for other numbers of rows (``--rows``, e.g. the
600 rows of a fit block's 30 seeds stepped together).

Run: .venv/bin/python benchmarks/bench_kernel.py [--rows 20 600]

:func:`ns_per_candidate_sample` is the measurement the fit-block and workflow benchmarks use for
their kernel bound.
"""

import argparse
import time

import numba
import numpy as np

from avoa_pipeline import config, problem


def per_call(objective, X: np.ndarray, reps: int) -> float:
    objective(X)
    t0 = time.perf_counter()
    for _ in range(reps):
        objective(X)
    return (time.perf_counter() - t0) / reps


def ns_per_candidate_sample(prob, rows: int, seconds: float = 2.0, repeat: int = 3) -> float:
    """The population kernel's ns per candidate-sample on ``rows`` uniform random candidates of
    ``prob`` (single-threaded; the fastest of ``repeat`` timings of about ``seconds`` each)."""
    numba.set_num_threads(1)
    rng = np.random.default_rng(0)
    X = prob.lb + rng.random((rows, prob.lb.size)) * (prob.ub - prob.lb)
    n = prob.time_s.size
    reps = max(1, int(seconds / (rows * n * 2.5e-9)))
    best = min(per_call(prob.objective, X, reps) for _ in range(repeat))
    return best / (rows * n) * 1e9


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, nargs="*", default=[], help="population sizes to time")
    args = ap.parse_args()
    numba.set_num_threads(1)
    cfg = config.load()
    for scenario in (1, 4):
        prob = problem.build(cfg, scenario, 4)
        n = prob.time_s.size
        x = (prob.lb + prob.ub) / 2
        one = per_call(prob.objective, x[None], 2000)
        fast = per_call(prob.objective_one, x, 2000)
        pop = np.tile(x, (20, 1))
        many = per_call(prob.objective, pop, 300)
        print(
            f"scenario {scenario}: one candidate {one * 1e6:.1f} us/call "
            f"({one / n * 1e9:.2f} ns/sample), {fast * 1e6:.1f} us through objective_one "
            f"({fast / n * 1e9:.2f} ns/sample); population of 20 "
            f"{many / 20 / n * 1e9:.2f} ns/candidate-sample"
        )
        for rows in args.rows:
            ns = ns_per_candidate_sample(prob, rows)
            print(f"scenario {scenario}: {rows} random rows {ns:.2f} ns/candidate-sample")


if __name__ == "__main__":
    main()
