"""``real drive-cycles``: experiment 1 into a folder, in one process (``jobs.drive_cycles``)."""

from __future__ import annotations

from pathlib import Path

from ..registry import register
from .common import config, no_lock


def arguments(d) -> None:
    d.add_argument("--out-dir", required=True, type=Path)
    d.add_argument(
        "--temperature",
        action="append",
        help="only this one (repeatable; a negative one as --temperature=-10degC)",
    )


@register("drive-cycles", "experiment 1 into a folder", arguments=arguments, group="real",
          output=no_lock)  # fmt: skip
def run_drive_cycles(args) -> None:
    from ...jobs import drive_cycles

    print(f"wrote {drive_cycles.run_experiment(config(args), args.out_dir, args.temperature)}")
