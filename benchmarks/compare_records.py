"""Compare two sets of fit records seed by seed, bit for bit, timings aside.

    .venv/bin/python benchmarks/compare_records.py A/results/fits B/results/fits [--across-machines]

Records made on one machine agree bit for bit; made on two machines (another CPU rounds the
objective's last bits otherwise), ``--across-machines`` compares them to ``fit.ISE_RTOL`` and
``fit.PATH_RTOL`` (their reasons are there).

Every ``s*/c*/<algorithm>/seed*.json`` under the first folder is compared with the record of the
same path under the second: best parameters, best ISE, evaluations, iterations, and the history
of best ISE and evaluations (JSON floats round-trip exactly, so equal numbers are equal bits).
Prints how many are equal and which differ or are missing; exits 1 if any does.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from avoa_pipeline.fit import same_record


def compare(a: Path, b: Path, *, exact: bool = True) -> tuple[int, list[str]]:
    """Number of records under ``a``, and the relative paths that differ or miss under ``b``."""
    paths = sorted(p.relative_to(a) for p in a.glob("s*/c*/*/seed*.json"))
    bad = []
    for rel in paths:
        try:
            other = json.loads((b / rel).read_text())
        except FileNotFoundError:
            bad.append(f"{rel} (missing)")
            continue
        differ = same_record(json.loads((a / rel).read_text()), other, exact=exact)
        if differ:
            bad.append(f"{rel} ({', '.join(differ)})")
    return len(paths), bad


def main() -> None:
    args = sys.argv[1:]
    exact = "--across-machines" not in args
    a, b = (Path(x) for x in args if x != "--across-machines")
    n, bad = compare(a, b, exact=exact)
    how = "bit for bit" if exact else "to fit.ISE_RTOL / PATH_RTOL"
    print(f"{n - len(bad)}/{n} records under {a} equal to {b}'s {how} (timings aside)")
    for rel in bad:
        print(f"  differs: {rel}")
    sys.exit(1 if bad or n == 0 else 0)


if __name__ == "__main__":
    main()
