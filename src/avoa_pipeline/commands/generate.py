"""``generate``: write the synthetic dataset of one scenario × case (CSV + JSON sidecar)."""

from __future__ import annotations

from .options import SCENARIO_CASE, config_path, csv_and_sidecar
from .registry import register


def arguments(g) -> None:
    g.add_argument("--out", required=True, help="CSV path; the JSON sidecar goes beside it")
    g.add_argument("--config", default=None)
    g.add_argument("--noise-free", action="store_true")


@register("generate", "write the synthetic dataset of one scenario × case", arguments=arguments,
          parents=(SCENARIO_CASE,))  # fmt: skip
def run_generate(args) -> None:
    from .. import config, synthetic

    out, _ = csv_and_sidecar(args.out, [config_path(args)])
    cfg = config.load(args.config)
    synthetic.write(
        synthetic.generate(cfg, args.scenario, args.case, noise=not args.noise_free), out
    )
