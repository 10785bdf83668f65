"""Two workflow runs' outputs compared file by file, clocks aside.

    .venv/bin/python benchmarks/compare_results.py A/results B/results [--under gap real fits]

A refactor must leave what the workflow computes as it was. Every CSV under the first folder is
compared with the file of the same path under the second: the same columns, and every value
equal (text as read, so equal numbers are equal bits), columns that hold clocks left out
(:data:`CLOCK_COLUMNS`; the rows of claims about speed, :data:`CLOCK_ROWS`). Every
``diagnosis.json`` and ``model.json`` is compared as ``compare_diagnoses.py`` compares them;
fit records (``s*/c*/<algorithm>/seed*.json``) as ``compare_records.py`` does. Figures, tables
with timings and executed notebooks are not compared (their bytes carry dates and clocks).
Prints a count per kind and each file that differs or is missing; exits 1 if any does.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

from compare_diagnoses import _clockless, differences

from avoa_pipeline.fit import same_record

CLOCK_COLUMNS = {"wall_s", "seconds", "times_real_time", "wall_time_s"}
TIMING_FILES = ("table24",)  # the paper's Table 24 is wall-clock times
CLOCK_ROWS = {"claims.csv": ("claim_id", {"C5", "C6"})}  # claims about speed quote times


def _rows(path: Path) -> tuple[list[str], list[list[str]]]:
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    return (rows[0], rows[1:]) if rows else ([], [])


def compare_csv(a: Path, b: Path) -> str:
    """'' when equal, clocks aside; else what differs first."""
    (ha, ra), (hb, rb) = _rows(a), _rows(b)
    if ha != hb:
        return f"columns {ha} vs {hb}"
    if len(ra) != len(rb):
        return f"{len(ra)} vs {len(rb)} rows"
    keep = [j for j, h in enumerate(ha) if h not in CLOCK_COLUMNS]
    key, clocked = CLOCK_ROWS.get(a.name, ("", set()))
    for n, (x, y) in enumerate(zip(ra, rb, strict=True)):
        if key in ha and x[ha.index(key)] in clocked:
            continue
        bad = [ha[j] for j in keep if j < len(x) and j < len(y) and x[j] != y[j]]
        if bad or len(x) != len(y):
            return f"row {n + 1}: {', '.join(bad) or 'length'}"
    return ""


def compare_json(a: Path, b: Path) -> str:
    x, y = (json.loads(p.read_text()) for p in (a, b))
    if a.name.startswith("seed"):  # a fit record: compare_records.py's rule
        return ", ".join(same_record(x, y))
    return "; ".join(differences(_clockless(x), _clockless(y))[:3])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("a", type=Path)
    p.add_argument("b", type=Path)
    p.add_argument("--under", nargs="*", default=None, help="only these subfolders")
    args = p.parse_args(argv)
    roots = [args.a / u for u in args.under] if args.under else [args.a]
    counts, bad = {}, 0
    for root in roots:
        for path in sorted(root.rglob("*")):
            kind = path.suffix
            if kind not in (".csv", ".json") or any(t in path.name for t in TIMING_FILES):
                continue
            if kind == ".json" and path.name not in ("diagnosis.json", "model.json") \
                    and not path.name.startswith("seed"):  # fmt: skip
                continue
            other = args.b / path.relative_to(args.a)
            counts[kind] = counts.get(kind, 0) + 1
            if not other.exists():
                why = "missing in the second"
            else:
                why = (compare_csv if kind == ".csv" else compare_json)(path, other)
            if why:
                bad += 1
                print(f"{path.relative_to(args.a)}: {why}")
    print(f"{', '.join(f'{n} {k}' for k, n in sorted(counts.items()))} compared; {bad} differ "
          "(clocks aside)")  # fmt: skip
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
