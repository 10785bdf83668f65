"""``fit``: identify the parameters of one scenario × case (one seed's record)."""

from __future__ import annotations

import argparse
import sys

from ..errors import UserError
from ..names import ALGORITHMS
from .options import SCENARIO_CASE, THREADS, config_path, int_in, use_threads
from .registry import register


def _algorithm(text: str) -> str:
    if text not in ALGORITHMS:
        raise argparse.ArgumentTypeError(
            f"unknown algorithm {text!r}; choose from {', '.join(ALGORITHMS)}"
        )
    return text


def arguments(f) -> None:
    f.add_argument("--algorithm", type=_algorithm, required=True)
    f.add_argument("--seed", type=int_in("seed"), required=True)
    f.add_argument("--out", required=True, help="record file (JSON)")
    f.add_argument("--config", default=None, help="config file (default config/config.yaml)")
    f.add_argument("--data", default=None, help="dataset CSV (default: generated in memory)")
    f.add_argument("--pop-size", type=int_in("pop-size"), default=None)
    f.add_argument("--iterations", type=int_in("iterations"), default=None)
    f.add_argument("--max-nfe", type=int_in("max-nfe"), default=None)
    f.add_argument("--noise-free", action="store_true", help="generated data without noise")


@register("fit", "identify the parameters of one scenario × case", arguments=arguments,
          parents=(SCENARIO_CASE,), parents_after=(THREADS,))  # fmt: skip
def run_fit(args) -> None:
    from .. import config, fit, problem
    from ..io import check_output, write_json

    if args.seed < 0:
        raise UserError(f"--seed must be 0 or more, got {args.seed}")
    check_output(args.out, inputs=[args.data, config_path(args)])
    cfg = config.load(args.config)
    budget = fit.budget_from(cfg, args.pop_size, args.iterations, args.max_nfe)
    use_threads(args)
    prob = problem.build(cfg, args.scenario, args.case, args.data, noise=not args.noise_free)
    record = fit.run(cfg, prob, args.algorithm, args.seed, budget)
    write_json(record, args.out)
    for note in prob.notes:
        print(f"warning: {note}", file=sys.stderr)
