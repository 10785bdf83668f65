"""What the hand-over rule (docs/handover-rule.md, ``avoa_pipeline.handover``) costs inside a
diagnosis: the diagnosis's CPU and wall seconds, the hand-over's share of them and the fits it
made, on the training records given (as ``diagnose`` reads them). Prints measured numbers;
asserts nothing.

    PYTHONPATH=src nice -n 10 .venv/bin/python benchmarks/bench_handover.py TRAIN.csv [MORE.csv]
    ... --ocv OCV.csv --repeat 3
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as the CLI (before numpy loads)
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")

import argparse
import sys
import time

from avoa_pipeline import handover, inputs
from avoa_pipeline.gap import diagnose


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", nargs="+", help="training CSV(s) of one cell")
    ap.add_argument("--ocv", default=None, help="the cell's slow test or OCV table (as --ocv)")
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args(argv)
    read = inputs.read_inputs(args.data, [], args.ocv)
    inner, got = handover.hand_over, {}

    def timed(ctx, *a, **k):
        c, w, fits = time.process_time(), time.perf_counter(), ctx.fits
        out = inner(ctx, *a, **k)
        got.update(cpu=time.process_time() - c, wall=time.perf_counter() - w,
                   fits=ctx.fits - fits)  # fmt: skip
        return out

    handover.hand_over = timed
    for _ in range(args.repeat):
        load = os.getloadavg()[0]
        c, w = time.process_time(), time.perf_counter()
        rep, _, _ = diagnose.diagnose_records(read.train, ocv_table=read.ocv, progress=None)
        cpu, wall = time.process_time() - c, time.perf_counter() - w
        print(f"diagnosis {cpu:.2f} s CPU, {wall:.2f} s wall, {rep['method']['fits']} fits; "
              f"hand-over {got['cpu']:.2f} s CPU ({got['cpu'] / cpu:.1%}), {got['wall']:.2f} s "
              f"wall, {got['fits']} fits; handed over {rep['handed_over']['name']} (verdict's "
              f"{rep['selected']['name']}); load {load:.1f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
