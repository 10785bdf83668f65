"""One identification run → one flat, JSON-serialisable record."""

from __future__ import annotations

import platform
import sys
from importlib import metadata

import numpy as np

from . import __version__, seeds
from .errors import ConfigError
from .optimizers import ALGORITHMS, Budget, minimize_together
from .problem import Problem

ISE_RTOL = 1e-9
PATH_RTOL = 1e-4
"""A record is bit for bit the same on one machine (same CPU, same libraries); across machines
records agree to these relative tolerances. The objective's last bits depend on the CPU's
floating-point path (vector width, fused multiply-add in numpy's and numba's code); L-BFGS-B's
finite-difference gradient divides such a difference by its step (about 1e-8), so on another
x86-64 CPU its path moves: measured on an AMD EPYC against references made on an AVX-512 Intel
(tests/unit/test_lockstep.py), best ISE by at most 5e-11 relative, the parameters by 1.2e-6, the
best-so-far history by 7.4e-6; the other six algorithms were equal bit for bit. The best ISE is a
minimum, first-order flat, hence ISE_RTOL; the path (parameters, history) gets PATH_RTOL, an order
above the largest difference seen and still two below what a change of an optimizer's moves does
to a record (percent). Counts (evaluations, iterations) are exact on any machine."""


def same_record(a: dict, b: dict, *, exact: bool = True) -> list[str]:
    """The numbers in which two records of one seed differ (empty: the same), timings and
    provenance aside: bit for bit (``exact``, one machine) or to ISE_RTOL / PATH_RTOL."""
    pairs = {
        "best_params": ([a["best_params"][k] for k in a["param_names"]],
                        [b["best_params"][k] for k in b["param_names"]], PATH_RTOL),
        "best_ise": (a["best_ise"], b["best_ise"], ISE_RTOL),
        "history.best_ise": (a["history"]["best_ise"], b["history"]["best_ise"], PATH_RTOL),
    }  # fmt: skip
    bad = [k for k in ("nfe", "iterations") if a[k] != b[k]]
    if a["param_names"] != b["param_names"] or a["history"]["nfe"] != b["history"]["nfe"]:
        bad.append("param_names or history.nfe")
        return bad
    for key, (x, y, rtol) in pairs.items():
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        same = np.array_equal(x, y) if exact else (
            x.shape == y.shape and np.allclose(x, y, rtol=rtol, atol=0.0))  # fmt: skip
        if not same:
            bad.append(key)
    return bad


def versions() -> dict:
    out = {
        "avoa_pipeline": __version__,
        "python": sys.version.split()[0],
        "platform": platform.platform(),
    }
    for lib in ("numpy", "scipy", "numba", "pandas"):
        try:
            out[lib] = metadata.version(lib)
        except metadata.PackageNotFoundError:  # pragma: no cover - all are dependencies
            out[lib] = None
    return out


def budget_from(cfg: dict, pop_size=None, iterations=None, max_nfe=None) -> Budget:
    b = cfg["budget"]
    pop = b["pop_size"] if pop_size is None else pop_size
    it = b["iterations"] if iterations is None else iterations
    nfe = b.get("max_nfe") if max_nfe is None else max_nfe
    for name, value in (("pop_size", pop), ("iterations", it), ("max_nfe", nfe)):
        if value is not None and value < 1:
            raise ConfigError(f"budget field {name}: must be positive, got {value}")
    if pop < 2:
        raise ConfigError(f"budget field pop_size: must be at least 2, got {pop}")
    return Budget(pop_size=pop, iterations=it, max_nfe=nfe)


def warm_up(problem: Problem, rows: int) -> None:
    """Load the compiled kernels before the clock starts (wall_s is optimizer time only): one
    candidate, and populations of ``rows`` (the largest ask of a step)."""
    x = (problem.lb + problem.ub) / 2
    problem.objective(np.tile(x, (max(rows, 1), 1)))
    problem.objective_one(x)
    problem.objective(x[None, :])


def run(cfg: dict, problem: Problem, algorithm: str, seed: int, budget: Budget) -> dict:
    """The record of one fit (the command line's ``fit``): :func:`run_seeds` with one seed."""
    return run_seeds(cfg, problem, algorithm, [seed], budget)[0]


def run_seeds(
    cfg: dict, problem: Problem, algorithm: str, seed_list: list[int], budget: Budget
) -> list[dict]:
    """The records of several seeds of one algorithm on one problem (a fit block), their runs
    stepped together: every step evaluates all the seeds' asks in one kernel call
    (:func:`.optimizers.minimize_together`). Each seed's numbers are those :func:`run` gives it
    alone; only its times differ (``docs/records.md``, "Time")."""
    if algorithm not in ALGORITHMS:
        raise ConfigError(f"unknown algorithm {algorithm!r}; choose from {', '.join(ALGORITHMS)}")
    keys = [
        [cfg["base_seed"], "fit", problem.scenario, problem.case, algorithm, s] for s in seed_list
    ]
    rngs = [seeds.stream(*k) for k in keys]
    warm_up(problem, budget.pop_size * len(seed_list))
    results = minimize_together(
        algorithm, problem.objective, problem.lb, problem.ub, budget, rngs, problem.objective_one
    )
    truth = problem.true_free()
    true_params = (
        None if truth is None else dict(zip(problem.names, map(float, truth), strict=True))
    )
    true_ise = None if truth is None else float(problem.objective(truth[None, :])[0])
    lib_versions = versions()
    records = []
    for seed, key, res in zip(seed_list, keys, results, strict=True):
        best = dict(zip(problem.names, map(float, res.best_x), strict=True))
        records.append(
            {
                "scenario": problem.scenario,
                "case": problem.case,
                "algorithm": algorithm,
                "seed": seed,
                "param_names": list(problem.names),
                "best_params": best,
                "best_ise": res.best_f,
                "true_params": None if true_params is None else dict(true_params),
                "true_ise": true_ise,
                "rel_error": None
                if truth is None
                else {
                    n: float((best[n] - t) / t) for n, t in zip(problem.names, truth, strict=True)
                },
                "lb": problem.lb.tolist(),
                "ub": problem.ub.tolist(),
                "nfe": res.nfe,
                "iterations": res.iterations,
                "n_samples": int(problem.time_s.size),
                "wall_s": res.wall_s,
                "budget": {
                    "pop_size": budget.pop_size,
                    "iterations": budget.iterations,
                    "max_nfe": budget.max_nfe,
                },
                "history": {
                    "best_ise": res.history_best.tolist(),
                    "nfe": res.history_nfe.tolist(),
                    "wall_s": res.history_time.tolist(),
                },
                "seed_keys": key,
                "versions": dict(lib_versions),
            }
        )
    return records
