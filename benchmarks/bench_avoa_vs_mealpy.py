"""Speed: our AVOA against mealpy 3.0.2's OriginalAVOA on scenario 4 case 4, same evaluations.

Both minimise the same objective (the package's compiled ISE of eq. 13). Ours hands the whole
population to the objective at once; mealpy calls it once per candidate, as its API does. The
script prints both wall times, the ratio (target: ours at least 5x faster) and the model's cost
per candidate-sample, so what limits the speed is visible.

Run: .venv/bin/python benchmarks/bench_avoa_vs_mealpy.py [--iterations 500] [--repeat 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from avoa_pipeline import config, fit, problem, seeds
from avoa_pipeline.optimizers import Budget, minimize


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--iterations", type=int, default=500)
    ap.add_argument("--pop-size", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    from mealpy import AVOA, FloatVar

    cfg = config.load()
    prob = problem.build(cfg, 4, 4)
    fit.warm_up(prob, args.pop_size)
    n_samples = prob.time_s.size

    ours, theirs, nfes = [], [], []
    for r in range(args.repeat):
        budget = Budget(pop_size=args.pop_size, iterations=args.iterations)
        t0 = time.perf_counter()
        res = minimize(
            "avoa", prob.objective, prob.lb, prob.ub, budget, seeds.stream(1, "bench", r)
        )
        ours.append(time.perf_counter() - t0)
        nfes.append(res.nfe)

        def one(x):  # mealpy evaluates a single candidate per call
            return float(prob.objective(x[None, :])[0])

        model = AVOA.OriginalAVOA(epoch=args.iterations, pop_size=args.pop_size)
        spec = {
            "bounds": FloatVar(lb=prob.lb.tolist(), ub=prob.ub.tolist()),
            "minmax": "min",
            "obj_func": one,
            "log_to": None,
        }
        t0 = time.perf_counter()
        model.solve(spec, seed=r + 1, termination={"max_fe": res.nfe})
        theirs.append(time.perf_counter() - t0)
        print(
            f"repeat {r}: ours {ours[-1]:.3f} s (nfe {res.nfe}, ISE {res.best_f:.6g}); "
            f"mealpy {theirs[-1]:.3f} s (nfe {model.nfe_counter}, "
            f"ISE {model.g_best.target.fitness:.6g})"
        )

    # the model's own cost, population-at-once and one candidate per call
    X = prob.lb + seeds.stream(2, "bench").random((args.pop_size, prob.lb.size)) * (
        prob.ub - prob.lb
    )
    reps = 200
    t0 = time.perf_counter()
    for _ in range(reps):
        prob.objective(X)
    pop_ns = (time.perf_counter() - t0) / (reps * args.pop_size * n_samples) * 1e9
    t0 = time.perf_counter()
    for _ in range(reps):
        for x in X:
            prob.objective(x[None, :])
    one_ns = (time.perf_counter() - t0) / (reps * args.pop_size * n_samples) * 1e9

    t_ours, t_theirs = float(np.median(ours)), float(np.median(theirs))
    print(
        f"scenario 4 case 4, {n_samples} samples, pop {args.pop_size} x {args.iterations} "
        f"iterations ({int(np.median(nfes))} evaluations), median of {args.repeat}"
    )
    print(f"ours   AVOA: {t_ours:.3f} s")
    print(f"mealpy AVOA: {t_theirs:.3f} s")
    print(f"ratio mealpy/ours: {t_theirs / t_ours:.1f}x (target >= 5x)")
    print(
        f"model cost: {pop_ns:.2f} ns per candidate-sample with the population at once, "
        f"{one_ns:.2f} ns one candidate per call"
    )


if __name__ == "__main__":
    main()
