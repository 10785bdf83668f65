"""``convert``: a raw cycler export → the canonical CSV + JSON sidecar (docs/cyclers.md)."""

from __future__ import annotations

import sys

from ..errors import UserError
from ..names import CURRENT_FROM, CYCLERS
from .options import csv_and_sidecar, number
from .registry import register


def arguments(c) -> None:
    c.add_argument("raw", help="the cycler's export (docs/cyclers.md says which columns)")
    c.add_argument("--cycler", choices=CYCLERS, required=True)
    c.add_argument("--out", required=True, help="CSV path; the JSON sidecar goes beside it")
    c.add_argument(
        "--steps",
        default=None,
        metavar="A-B",
        help="keep one contiguous range of the cycler's step numbers (default: all)",
    )
    c.add_argument(
        "--rest-dt",
        type=number("rest-dt"),
        default=None,
        metavar="SECONDS",
        help="thin long rests: 10 samples per decade of rest time, at most this far "
        "apart (default: every sample)",
    )
    c.add_argument(
        "--current-from",
        choices=CURRENT_FROM,
        default=CURRENT_FROM[0],
        help="interval means from the charge counters (default, where the export has "
        "them) or the held current channel",
    )
    which = c.add_mutually_exclusive_group()
    which.add_argument(
        "--sheet",
        default=None,
        metavar="NAME",
        help="a workbook's data sheet to convert (needed when it has several)",
    )
    which.add_argument(
        "--sheets",
        choices=("each", "concat"),  # cycler.convert's two ways to read every data sheet
        default=None,
        help="every data sheet of a workbook: each to its own CSV (OUT's stem + '-' + the "
        "sheet's name), or concat into one record in sheet order, time continued",
    )


def _jobs(args, out, cycler) -> list[tuple]:
    """(output CSV, which sheet(s)) per record to write."""
    from pathlib import Path

    if args.sheets != "each":
        return [(out, {"sheet": args.sheet, "concat": args.sheets == "concat"})]
    # one record per data sheet, each named after its sheet
    if not Path(args.raw).is_file():
        raise UserError(f"{args.raw}: no such file")
    names = cycler.data_sheets(args.raw, args.cycler)
    if not names:
        raise UserError(f"{args.raw}: --sheets each: not a workbook (.xlsx); it has no sheets")
    jobs = [(cycler.sheet_path(out, n), {"sheet": n}) for n in names]
    if len({p for p, _ in jobs}) < len(jobs):
        raise UserError(f"{args.raw}: sheets {', '.join(map(repr, names))} give the same "
                        "file name; convert them one at a time with --sheet NAME")  # fmt: skip
    return jobs


@register("convert", "a raw cycler export → the canonical CSV + JSON sidecar",
          arguments=arguments)  # fmt: skip
def run_convert(args) -> None:
    from pathlib import Path

    from ..importers import cycler
    from ..io import unchanged_while_read

    out = Path(args.out)
    if out.suffix.lower() != ".csv":
        raise UserError(f"--out must be a .csv path, got {str(out)!r}")
    options = {
        "steps": cycler.parse_steps(args.steps),
        "rest_dt": args.rest_dt,
        "current_from": args.current_from,
    }
    jobs = _jobs(args, out, cycler)
    for path, _ in jobs:
        csv_and_sidecar(path, [args.raw])
    # every sheet converted before any is written: a bad sheet leaves no file; an export that
    # changes meanwhile (a cycler still writing it) is refused
    with unchanged_while_read(args.raw):
        done = [(path, *cycler.convert(args.raw, args.cycler, **options, **which))
                for path, which in jobs]  # fmt: skip
    for path, frame, info in done:
        side = cycler.write(frame, info, path)
        charge = info["charge"]["discharged_ah_output"]
        check = info["sign"]["voltage_check"]
        sheets = info.get("sheets", {}).get("read")
        print(
            f"{args.raw}" + (f" (sheet {', '.join(map(repr, sheets))})" if sheets else "")
            + f": {len(frame)} samples over {frame['time_s'].iloc[-1]:.0f} s, current from "
            f"the {info['current']['source']}, net discharge {charge:.4f} Ah, sign "
            + ("confirmed" if check["confirmed"] else "not confirmable (see the warning)")
            + f"; wrote {path}, {side}"
        )  # fmt: skip
        for note in info["warnings"]:
            print(f"warning: {note}", file=sys.stderr)
