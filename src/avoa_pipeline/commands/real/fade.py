"""``real fade``: experiment 3, capacity and resistance per ageing state and the fade laws."""

from __future__ import annotations

from ..registry import register
from . import load_config


def arguments(f) -> None:
    f.add_argument("--record", required=True, help="canonical B0005 record (nasa-import)")
    f.add_argument("--out-states", required=True)
    f.add_argument("--out-fits", required=True)


@register("fade", "experiment 3: capacity/resistance per state and fade laws",
          arguments=arguments, group="real", output=None)  # fmt: skip
def run_fade(args) -> None:
    from ...jobs import real as jobs

    jobs.fade(load_config(args), args.record, args.out_states, args.out_fits)
