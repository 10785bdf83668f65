"""A thinned simulation with its rests merged into single steps against the same without.

    .venv/bin/python benchmarks/bench_merged_rests.py RECORD.csv [RECORD.csv ...]

For each record (a canonical CSV) and 1,250 and 10,000 samples returned, the time of one
``ecm.simulate_physical`` call on 12 rows (a Jacobian's: a 2RC model with ``soc_resistance``,
whose SOC-dependent factor keeps the held-current shortcut off, as on the Panasonic diagnoses),
merged (``ecm._rests_merged``) and not, the median of 20 calls after one warm call, and their
ratio; plus the largest difference of the voltages. Run it with ``NUMBA_NUM_THREADS=1``. Nothing
is asserted.
"""

from __future__ import annotations

import sys
import time

import numpy as np
import pandas as pd

from avoa_pipeline.model import ecm, fitting

ROWS = 12
PARAMS = {"vnom_v": 4.2, "beta": 0.7, "capacity_ah": 3.0, "soc0": 0.9, "r0_ohm": 0.02,
          "r1_ohm": 0.01, "tau1_s": 20.0, "r2_ohm": 0.01, "tau2_s": 300.0,
          "soc_resistance_k": 0.5, "soc_resistance_sigma": 0.1}  # fmt: skip


def _median_ms(rec, P, knots, idx, n: int = 20) -> float:
    ecm.simulate_physical(rec, P, knots, idx=idx)
    times = []
    for _ in range(n):
        t = time.perf_counter()
        ecm.simulate_physical(rec, P, knots, idx=idx)
        times.append(time.perf_counter() - t)
    return 1e3 * float(np.median(times))


def main(paths: list[str]) -> None:
    X = np.repeat(ecm.vector(PARAMS)[None, :], ROWS, axis=0)
    X[:, ecm.IDX["r0"]] *= np.linspace(1.0, 1.01, ROWS)  # rows differ, as a Jacobian's do
    P, knots = ecm.to_physical(X), ecm.Knots(0.0, 0.2)
    merged = ecm._rests_merged
    for path in paths:
        rec = ecm.Record.from_frame(pd.read_csv(path))
        for points in (1250, 10000):
            idx = fitting.fit_indices(rec.n, None, points)
            ms, v = [], []
            for merge in (False, True):
                ecm._rests_merged = merged if merge else (lambda r, i: None)
                ms.append(_median_ms(rec, P, knots, idx))
                v.append(ecm.simulate_physical(rec, P, knots, idx=idx))
            ecm._rests_merged = merged
            print(
                f"{path}: {rec.n} samples, {np.mean(rec.i == 0.0):.1%} at rest, {idx.size} "
                f"returned: {ms[0]:.2f} ms unmerged, {ms[1]:.2f} ms merged "
                f"({ms[1] / ms[0]:.2f}); voltages within {np.abs(v[0] - v[1]).max():.1e} V"
            )


if __name__ == "__main__":
    main(sys.argv[1:])
