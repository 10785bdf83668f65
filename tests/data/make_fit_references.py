"""Write the reference fit numbers that tests/unit/test_lockstep.py holds the fit blocks to.

The references must come from the code before the seeds were stepped together (commit bec3407,
one seed at a time through ``fit.run``), so run this script against that code:

    git worktree add /tmp/avoa-bec3407 bec3407
    PYTHONPATH=/tmp/avoa-bec3407/src .venv/bin/python tests/data/make_fit_references.py \
        tests/data/fit_references_bec3407.json

It uses only what both versions share (``config.load``, ``problem.build``, ``fit.run``). For each
problem (scenario × case, the in-memory noisy dataset), budget and algorithm, seeds 1-3: the best
parameters, best ISE, evaluations, iterations and the history of best ISE and evaluations
(JSON floats round-trip exactly).
"""

import json
import sys
from importlib import metadata

import numba

from avoa_pipeline import config, fit, problem
from avoa_pipeline.optimizers import ALGORITHMS, Budget

PROBLEMS = [(4, 4), (1, 2)]  # load + fade with charge dynamics; neither load nor fade
BUDGETS = [
    {"pop_size": 20, "iterations": 12, "max_nfe": None},
    {"pop_size": 20, "iterations": None, "max_nfe": 333},  # ends inside an iteration
    {"pop_size": 8, "iterations": 40, "max_nfe": 301},  # both; the evaluations run out first
]
SEEDS = [1, 2, 3]


def numbers(rec: dict) -> dict:
    return {
        "seed": rec["seed"],
        "best_params": [rec["best_params"][n] for n in rec["param_names"]],
        "best_ise": rec["best_ise"],
        "nfe": rec["nfe"],
        "iterations": rec["iterations"],
        "history_best_ise": rec["history"]["best_ise"],
        "history_nfe": rec["history"]["nfe"],
    }


def main(out: str) -> None:
    numba.set_num_threads(1)
    cfg = config.load()
    runs = []
    for scenario, case in PROBLEMS:
        prob = problem.build(cfg, scenario, case)
        for b in BUDGETS:
            budget = Budget(**b)
            for algorithm in ALGORITHMS:
                recs = [fit.run(cfg, prob, algorithm, s, budget) for s in SEEDS]
                runs.append(
                    {
                        "scenario": scenario,
                        "case": case,
                        "budget": b,
                        "algorithm": algorithm,
                        "records": [numbers(r) for r in recs],
                    }
                )
    made_with = {lib: metadata.version(lib) for lib in ("numpy", "scipy", "numba")}
    with open(out, "w") as f:  # one run per line
        f.write('{"made_with": ' + json.dumps(made_with) + ', "runs": [\n')
        f.write(",\n".join(json.dumps(r) for r in runs))
        f.write("\n]}\n")


if __name__ == "__main__":
    main(sys.argv[1])
