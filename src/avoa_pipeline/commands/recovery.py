"""``recovery``: every algorithm on noise-free data, and the errors of the parameters found."""

from __future__ import annotations

from ..errors import UserError
from .options import SCENARIO_CASE, config_path, int_in
from .registry import register


def arguments(r) -> None:
    r.add_argument("--seeds", type=int_in("seeds"), default=5, help="seeds 1..N")
    r.add_argument("--iterations", type=int_in("iterations"), default=None)
    r.add_argument("--out", required=True, help="CSV of runs; a .md summary goes beside it")
    r.add_argument("--config", default=None)


@register("recovery", "every algorithm on noise-free data: parameter errors",
          arguments=arguments, parents=(SCENARIO_CASE,))  # fmt: skip
def run_recovery(args) -> None:
    from pathlib import Path

    from .. import config, fit, recovery
    from ..io import atomic_paths, check_output

    out = Path(args.out)
    if out.suffix.lower() != ".csv":
        raise UserError(f"--out {out}: must end .csv (its summary {out.stem}.md goes beside it)")
    check_output(out, inputs=[config_path(args)])
    check_output(out.with_suffix(".md"), inputs=[config_path(args)], what="--out's summary")
    cfg = config.load(args.config)
    if args.seeds < 1:
        raise UserError(f"--seeds must be positive, got {args.seeds}")
    budget = fit.budget_from(cfg, iterations=args.iterations)
    runs = recovery.recover(cfg, args.scenario, args.case, range(1, args.seeds + 1), budget)
    table = recovery.summary(runs)
    md = recovery.to_markdown(table)
    with atomic_paths(out, out.with_suffix(".md")) as (csv_tmp, md_tmp):
        runs.to_csv(csv_tmp, index=False)
        md_tmp.write_text(md + "\n")
    print(md)
