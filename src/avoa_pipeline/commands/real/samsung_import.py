"""``real samsung-import``: one Samsung HPPC file into the canonical form."""

from __future__ import annotations

from ..registry import register
from . import load_config


def arguments(s) -> None:
    s.add_argument("--temperature", required=True, help="key of real.samsung.hppc, e.g. 20degC")
    s.add_argument("--out", required=True, help="canonical CSV (sidecar .json beside it)")


@register("samsung-import", "one Samsung HPPC file into the canonical form",
          arguments=arguments, group="real", output=None)  # fmt: skip
def run_samsung_import(args) -> None:
    from ...jobs import real as jobs

    jobs.samsung_import(load_config(args), args.temperature, args.out)
