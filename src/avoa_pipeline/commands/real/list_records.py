"""``real list``: the Panasonic records the config names."""

from __future__ import annotations

from ..registry import register
from . import load_config


@register("list", "the Panasonic records the config names", arguments=lambda p: None,
          group="real", output=None)  # fmt: skip
def run_list(args) -> None:
    from ...importers import panasonic

    for name, rec in panasonic.records(load_config(args)).items():
        print(f"{name}\t{rec['test_type']}\t{'; '.join(rec['keys'])}")
