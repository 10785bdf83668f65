"""Transfer benchmark on PyBaMM physics cells (issue 26): the diagnosis's selected model against
fixed 1RC and 2RC circuits fitted to the same training records, on the cell's unseen records
(cells, profiles and protocol: ``avoa_pipeline.gap.transfer``, docs/transfer-benchmark.md).

Builds the records once into ``--data`` (PyBaMM runs are cached there), runs the protocol of
every cell and split, prints the table and writes ``transfer.csv`` (one row per unseen record),
``summary.csv``, ``summary_by_ambient.csv`` and ``summary.md`` into ``--out`` (default: ``--data``).

    PYBAMM_DISABLE_TELEMETRY=true nice -n 19 .venv/bin/python benchmarks/bench_transfer.py
    ... --quick                      # one cell, one split, shortened profiles (about a minute)
    ... --cells nmc lfp --splits hppc
    ... --reuse                      # tables from each split's rows.csv of an earlier run
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as the CLI (before numpy loads)
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")

import argparse
import sys
import time
from pathlib import Path

import pandas as pd

from avoa_pipeline import diagnosis, inputs
from avoa_pipeline.gap import transfer as T


def diagnose_split(paths, cell: str, split: str, out: Path, ambients, profiles) -> list[dict]:
    """Diagnose one cell's split as a user would (``diagnosis.diagnose``, the command's
    pipeline) and predict its unseen records; one row per unseen record with every model's RMSE
    (mV). Writes ``diagnosis.json`` and ``model.json`` (``Diagnosis.write``, no figure) and the
    fixed circuits' ``model_1rc.json``, ``model_2rc.json`` into ``out``."""
    train, unseen, slow = T.split_inputs(paths, cell, split, ambients, profiles)
    d = diagnosis.diagnose(train, unseen, slow)
    d.write(out, figure=False)
    fixed, train_mv = {}, {}
    for key, fit in T.fit_fixed([c.frame for c in d.inputs.train], inputs.read_ocv(slow)).items():
        fixed[key], train_mv[key] = fit.model, fit.train_rmse_mv
        fit.model.save(out / f"model_{key}.json")
    return T.unseen_rows(cell, split, d.report, d.inputs.validate, fixed, train_mv)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default="results/transfer", help="folder of the cached records")
    ap.add_argument("--out", help="folder of the tables and diagnoses (default: --data)")
    ap.add_argument("--quick", action="store_true", help="one cell, one split, short profiles")
    ap.add_argument("--cells", nargs="+", choices=list(T.CELLS))
    ap.add_argument("--splits", nargs="+", choices=list(T.SPLITS))
    ap.add_argument(
        "--reuse",
        action="store_true",
        help="reuse each split's rows.csv of an earlier run (default: diagnose again)",
    )
    ap.add_argument("--seed", type=int, default=0, help="base seed of the sensor noise")
    ap.add_argument(
        "--panasonic",
        type=Path,
        default=None,
        help="Panasonic 18650PF folder (drive-cycle currents)",
    )
    args = ap.parse_args(argv)
    if args.quick:
        cells, splits = T.QUICK["cells"], T.QUICK["splits"]
        ambients, profiles, scale = T.QUICK["ambients"], T.QUICK["profiles"], T.QUICK_SCALE
        data = Path(args.data) / "quick"
    else:
        cells, splits, ambients, profiles, scale = T.CELLS, T.SPLITS, T.AMBIENTS_C, T.PROFILES, 1.0
        data = Path(args.data)
    cells, splits = args.cells or cells, args.splits or splits
    out = Path(args.out) if args.out else data
    t0 = time.perf_counter()
    paths = T.build(
        data,
        cells,
        ambients,
        profiles,
        scale,
        args.seed,
        args.panasonic,
        log=lambda m: print(m, file=sys.stderr),
    )
    rows = []
    for cell in cells:
        for split in splits:
            t1 = time.perf_counter()
            cached = out / cell / split / "rows.csv"
            if args.reuse and cached.exists():
                rows += pd.read_csv(cached).to_dict("records")
                continue
            got = diagnose_split(paths, cell, split, out / cell / split, ambients, profiles)
            pd.DataFrame(got).to_csv(cached, index=False)
            rows += got
            print(f"{cell} {split}: {time.perf_counter() - t1:.0f} s", file=sys.stderr)
    per_record = pd.DataFrame(rows)
    summary = T.summarize(rows)
    out.mkdir(parents=True, exist_ok=True)
    per_record.to_csv(out / "transfer.csv", index=False, float_format="%.4g")
    summary.to_csv(out / "summary.csv", index=False, float_format="%.4g")
    by_ambient = ("cell", "split", "ambient_c")  # 10 °C records: a temperature never trained on
    per_ambient = T.summarize(rows, by_ambient)
    per_ambient.to_csv(out / "summary_by_ambient.csv", index=False, float_format="%.4g")
    text = T.markdown(summary) + "\nBy ambient:\n\n" + T.markdown(per_ambient, by_ambient)
    (out / "summary.md").write_text(text)
    print(text)
    print(
        f"wrote {out / 'transfer.csv'}, {out / 'summary.csv'}, {out / 'summary.md'} "
        f"({time.perf_counter() - t0:.0f} s)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
