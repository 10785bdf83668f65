"""``real nasa-import``: the 168 B0005 discharges into one canonical record."""

from __future__ import annotations

from ..registry import register
from . import load_config


def arguments(n) -> None:
    n.add_argument("--out", required=True)


@register("nasa-import", "the 168 B0005 discharges into one canonical record",
          arguments=arguments, group="real", output=None)  # fmt: skip
def run_nasa_import(args) -> None:
    from ...jobs import real as jobs

    jobs.nasa_import(load_config(args), args.out)
