"""``real arrhenius``: experiment 2, R0, Rtr and tau per pulse and their Arrhenius fits."""

from __future__ import annotations

import argparse

from ..registry import register
from . import load_config


def _pair(text: str) -> tuple[str, str]:
    key, sep, value = text.partition("=")
    if not sep or not key or not value:
        raise argparse.ArgumentTypeError(f"expected TEMPERATURE=CSV (e.g. 20degC=a.csv): {text!r}")
    return key, value


def arguments(a) -> None:
    a.add_argument("--hppc", type=_pair, nargs="+", required=True, metavar="TEMP=CSV")
    a.add_argument("--out-rc", required=True)
    a.add_argument("--out-arrhenius", required=True)


@register("arrhenius", "experiment 2: R0, Rtr, tau per pulse and Arrhenius fits",
          arguments=arguments, group="real", output=None)  # fmt: skip
def run_arrhenius(args) -> None:
    from ...jobs import real as jobs

    jobs.arrhenius(load_config(args), dict(args.hppc), args.out_rc, args.out_arrhenius)
