"""Seconds per raw-export conversion (``python -m avoa_pipeline convert``; the imports timed
apart) for Arbin exports of 10,000, 100,000 and 1,000,000 rows, a new step every 100 rows (10 Hz,
random currents, the test fixtures' writer). Prints measured times and the rows per second;
asserts nothing.

    nice -n 19 .venv/bin/python benchmarks/bench_convert.py [--sizes 10000 100000] [--rest-dt 30]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "unit"))
from cycler_fixtures import from_frame, write_arbin  # the tests' own writer

from avoa_pipeline.importers import cycler


def record(n: int, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    levels = rng.choice([0.0, 0.0, 1.0, 2.5, -1.5], size=n // 100 + 1)
    cur = np.repeat(levels, 100)[:n]
    t = 0.1 * np.arange(n)
    v = 3.7 - 0.05 * cur - 1e-6 * np.cumsum(cur)
    return pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": v, "temperature_c": 25.0})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    ap.add_argument("--rest-dt", type=float, default=None)
    args = ap.parse_args()
    t0 = time.perf_counter()  # imports, paid once per command: pyprobe and the checks
    cycler._reader(cycler.CYCLERS["arbin"])
    from avoa_pipeline.gap import diagnose  # noqa: F401

    print(f"imports: {time.perf_counter() - t0:.2f} s")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sizes:
            raw = write_arbin(from_frame(record(n)), Path(tmp) / f"a{n}.csv", restart_step=None)
            t0 = time.perf_counter()
            frame, info = cycler.convert(raw, "arbin", rest_dt=args.rest_dt)
            s = time.perf_counter() - t0
            steps = len(info["steps"]["kept"])
            print(f"{n:>9,} rows ({raw.stat().st_size / 1e6:.1f} MB, {steps} steps): {s:.2f} s, "
                  f"{n / s:,.0f} rows/s; {len(frame):,} rows written")  # fmt: skip


if __name__ == "__main__":
    main()
