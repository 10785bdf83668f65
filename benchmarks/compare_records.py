"""Compare two sets of fit records seed by seed, bit for bit, timings aside.

    .venv/bin/python benchmarks/compare_records.py A/results/fits B/results/fits

Every ``s*/c*/<algorithm>/seed*.json`` under the first folder is compared with the record of the
same path under the second: best parameters, best ISE, evaluations, iterations, and the history
of best ISE and evaluations (JSON floats round-trip exactly, so equal numbers are equal bits).
Prints how many are equal and which differ or are missing; exits 1 if any does.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

NUMBERS = ("best_params", "best_ise", "nfe", "iterations")


def same_numbers(a: dict, b: dict) -> bool:
    """Two records of one seed agree bit for bit, timings and provenance aside."""
    return all(a[k] == b[k] for k in NUMBERS) and all(
        a["history"][k] == b["history"][k] for k in ("best_ise", "nfe")
    )


def compare(a: Path, b: Path) -> tuple[int, list[str]]:
    """Number of records under ``a``, and the relative paths that differ or miss under ``b``."""
    paths = sorted(p.relative_to(a) for p in a.glob("s*/c*/*/seed*.json"))
    bad = []
    for rel in paths:
        try:
            other = json.loads((b / rel).read_text())
        except FileNotFoundError:
            bad.append(f"{rel} (missing)")
            continue
        if not same_numbers(json.loads((a / rel).read_text()), other):
            bad.append(str(rel))
    return len(paths), bad


def main() -> None:
    a, b = (Path(x) for x in sys.argv[1:3])
    n, bad = compare(a, b)
    print(f"{n - len(bad)}/{n} records under {a} equal to {b}'s (timings aside)")
    for rel in bad:
        print(f"  differs: {rel}")
    sys.exit(1 if bad or n == 0 else 0)


if __name__ == "__main__":
    main()
