"""``real list``: the Panasonic records the config names."""

from __future__ import annotations

from ..registry import register
from .common import config, no_lock


@register("list", "the Panasonic records the config names", arguments=lambda p: None,
          group="real", output=no_lock)  # fmt: skip
def run_list(args) -> None:
    from ...real.importers import panasonic

    for name, rec in panasonic.records(config(args)).items():
        print(f"{name}\t{rec['test_type']}\t{'; '.join(rec['keys'])}")
