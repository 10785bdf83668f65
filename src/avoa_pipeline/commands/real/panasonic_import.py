"""``real panasonic-import``: one Panasonic test → canonical CSV + JSON sidecar."""

from __future__ import annotations

from pathlib import Path

from ..registry import register
from . import load_config


def arguments(p) -> None:
    p.add_argument(
        "name",
        help="<temperature>/<test>, e.g. 25degC/us06 (see `list`); a "
        "negative temperature after `--`, as argparse reads -10degC as an option: "
        "`--out X.csv -- -10degC/us06`",
    )
    p.add_argument("--out", required=True, type=Path)


@register("panasonic-import", "one Panasonic test → canonical CSV + JSON", arguments=arguments,
          group="real", output=None)  # fmt: skip
def run_panasonic_import(args) -> None:
    from ...real.importers import panasonic

    side = panasonic.import_named(load_config(args), args.name, args.out)
    print(f"wrote {args.out}: {side['n_samples']} samples")
