"""Model cost per sample: one candidate per call and a population of 20, without (scenario 1)
and with (scenario 4) the 1 kOhm load, single-threaded (as in a workflow fit job).

Run: .venv/bin/python benchmarks/bench_kernel.py
"""

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


def main() -> None:
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


if __name__ == "__main__":
    main()
