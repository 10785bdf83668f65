"""``real panasonic-import``: one Panasonic test → canonical CSV + JSON sidecar."""

from __future__ import annotations

from ..registry import register
from . import load_config


def arguments(p) -> None:
    p.add_argument(
        "name",
        help="<temperature>/<test>, e.g. 25degC/us06 (see `list`); a "
        "negative temperature after `--`, as argparse reads -10degC as an option: "
        "`--out X.csv -- -10degC/us06`",
    )
    p.add_argument("--out", required=True)


@register("panasonic-import", "one Panasonic test → canonical CSV + JSON", arguments=arguments,
          group="real", output=None)  # fmt: skip
def run_panasonic_import(args) -> None:
    from pathlib import Path  # here, not above: --help stays without pathlib's imports

    from ...importers import panasonic

    out = Path(args.out)
    side = panasonic.import_named(load_config(args), args.name, out)
    print(f"wrote {out}: {side['n_samples']} samples")
