"""Fit back what was simulated (issue 37, part 1): per case (the base and each element the
withheld-effect check makes), records simulated by the model library and fitted back along the
diagnosis's path over many seeds (``avoa_pipeline.gap.fit_back``; docs/gap-diagnosis.md, "Fit back
what was simulated (issue 37)"). Prints, per case, the RMSE over the noise (median and largest
over the seeds) and, per parameter, how often its 95 % interval holds the truth; asserts nothing.

    nice -n 10 .venv/bin/python benchmarks/bench_fit_back.py --seeds 40
    ... --cases base second_rc --seeds 10 --rest-log-s 1   # rests logged every second
    ... --cases hysteresis butler_volmer --current-noise-a 0  # no current sensor noise
    ... --issue 1000000          # also bench_diagnose's issue-25 record, its OCV as a table
    ... --from-truth             # also each structure fitted from the truth
    ... --csv rows.csv           # one row per (case, seed, parameter)

Columns: ``rmse/noise`` is the fit's RMSE over the injected noise as drawn (the RMS of logged −
noise-free voltage), median and max over the seeds, and ``>1.02`` how many seeds exceed issue
37's goal; ``rmse/sd`` over the nominal sd and ``rmse/floor`` over the diagnosis's noise floor
estimate (medians); ``truth/noise`` the truth's own RMSE on the logged record (its noisy current
and temperature) and ``rule/noise`` the same started by the initial-SOC rule (medians).
Coverage: seeds whose interval holds the truth / seeds, ``none`` of them without an interval (a
parameter at a bound), and the verdict against 88-99 % (``fit_back.coverage_verdict``). With
``--from-truth``: the RMSE the same structure reaches started from the truth (started by the
rule), and on how many seeds the diagnosis's path ended worse (another basin).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as the CLI (before numpy loads)
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import sys
import time

import numpy as np
import pandas as pd

from avoa_pipeline.gap import fit_back as F
from avoa_pipeline.model import ecm
from avoa_pipeline.model import ocv as ocv_mod


def rows_of(r: F.FitBack) -> list[dict]:
    head = {"case": r.case, "seed": r.seed, "rmse_mv": r.rmse_mv, "noise_mv": r.noise_mv,
            "injected_mv": r.injected_mv, "floor_mv": r.floor_mv, "truth_mv": r.truth_mv,
            "truth_rule_mv": r.truth_rule_mv, "soc0_fit": r.soc0_fit, "soc0_true": r.soc0_true,
            "swapped": r.swapped}  # fmt: skip
    return [{**head, "parameter": name, "truth": t, "value": v, "low95": lo, "high95": hi,
             "covered": bool(c)}
            for name, t, v, lo, hi, c in zip(r.reports(), r.truth, r.value, r.low, r.high,
                                             r.covered(), strict=True)]  # fmt: skip


def from_truth(cases: list[F.Case], results: list[F.FitBack]) -> None:
    """The same structures fitted from the truth (``fit_back.refit_from_truth``)."""
    pairs = zip(cases, results, strict=True)
    ratio = np.array([F.refit_from_truth(c) / r.noise_mv for c, r in pairs])
    worse = int(np.sum([r.ratio > x * (1 + 1e-3) for r, x in zip(results, ratio, strict=True)]))
    print(f"  from the truth: rmse/noise median {np.median(ratio):.4f} max {ratio.max():.4f} "
          f"(>{F.RATIO_MAX}: {int(np.sum(ratio > F.RATIO_MAX))}/{ratio.size}); the path's fit "
          f"worse by > 0.1 % on {worse}")  # fmt: skip


def summary(results: list[F.FitBack]) -> None:
    ratio = np.array([r.ratio for r in results])
    med = {k: float(np.median([getattr(r, k) / r.noise_mv for r in results]))
           for k in ("truth_mv", "truth_rule_mv")}  # fmt: skip
    print(f"  rmse/noise median {np.median(ratio):.4f} max {ratio.max():.4f} "
          f"(>{F.RATIO_MAX}: {int(np.sum(ratio > F.RATIO_MAX))}/{ratio.size}); "
          f"rmse/sd {np.median([r.rmse_mv / r.injected_mv for r in results]):.4f}, "
          f"rmse/floor {np.median([r.rmse_mv / r.floor_mv for r in results]):.4f}, "
          f"truth/noise {med['truth_mv']:.4f}, rule/noise {med['truth_rule_mv']:.4f}; "
          f"branches swapped {sum(r.swapped for r in results)}")  # fmt: skip
    worst = max(results, key=lambda r: r.ratio)
    print(f"  worst seed {worst.seed}: rmse {worst.rmse_mv:.3f} mV, noise {worst.noise_mv:.3f} "
          f"mV, soc0 {worst.soc0_fit:.4f} (true {worst.soc0_true:.4f})")  # fmt: skip
    none = {}
    for r in results:
        for name, lo in zip(r.reports(), r.low, strict=True):
            none[name] = none.get(name, 0) + int(np.isnan(lo))
    for name, (hits, n) in F.coverage(results).items():
        print(f"    {name:<24} {hits:>3}/{n:<3} {100.0 * hits / n:5.1f} %  none {none[name]:>3}  "
              f"{F.coverage_verdict(hits, n)}")  # fmt: skip


def issue_case(n: int) -> F.Case:
    """bench_diagnose's issue-25 record (10 Hz, starts under load, 1 mV noise, no quantisation)
    with its true OCV (3.0 + 0.7·s + 0.5·s² V) as a table; the truth is the library's base."""
    from bench_diagnose import issue_record

    frame = issue_record(n)
    s = np.linspace(0.0, 1.0, 201)
    table = ocv_mod.from_table(pd.DataFrame({"soc": s, "ocv_v": 3.0 + 0.7 * s + 0.5 * s**2}),
                               "issue-25 OCV table")  # fmt: skip
    x = ecm.vector({"capacity_ah": 2.9, "soc0": 0.55, "r0_ohm": 0.030, "r1_ohm": 0.015,
                    "tau1_s": 30.0, "voltage_offset_v": 0.0})  # fmt: skip
    rec = ecm.Record.from_frame(frame)
    v_clean = ecm.simulate_rows(rec, x, ecm.Knots(0.0, 0.2), table)[:, 0]
    return F.Case("base", n, frame, table, x, ecm.Knots(0.0, 0.2), v_clean, 1.0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--cases", nargs="+", default=list(F.CASES), choices=F.CASES)
    ap.add_argument("--rest-log-s", type=float, default=F.REST_LOG_S)
    ap.add_argument("--noise-mv", type=float, default=F.NOISE_MV)
    ap.add_argument("--current-noise-a", type=float, default=F.withheld.CURRENT_NOISE_A)
    ap.add_argument("--issue", type=int, default=0, metavar="N",
                    help="also fit back the issue-25 record of N samples")  # fmt: skip
    ap.add_argument(
        "--from-truth",
        action="store_true",
        help="also fit each case from the truth (its starts or its structure?)",
    )
    ap.add_argument("--csv", default=None)
    args = ap.parse_args(argv)
    rows = []
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    print(f"fit back: {args.seeds} seeds, rests logged every {args.rest_log_s:g} s after "
          f"their first 10 s, {args.noise_mv:g} mV voltage noise, "
          f"{1e3 * args.current_noise_a:g} mA current noise")  # fmt: skip
    for case in args.cases if args.seeds > 0 else ():  # --seeds 0: the issue-25 record alone
        t0 = time.perf_counter()
        cases = [F.make_case(case, s, noise_mv=args.noise_mv, rest_log_s=args.rest_log_s,
                             current_noise_a=args.current_noise_a) for s in seeds]  # fmt: skip
        results = [F.fit_case(c) for c in cases]
        print(f"{case} ({time.perf_counter() - t0:.0f} s)")
        summary(results)
        if args.from_truth:
            from_truth(cases, results)
        rows += [row for r in results for row in rows_of(r)]
    if args.issue:
        t0 = time.perf_counter()
        c = issue_case(args.issue)
        r = F.fit_case(c)
        print(f"issue-25 record, {args.issue} samples ({time.perf_counter() - t0:.0f} s)")
        summary([r])
        if args.from_truth:
            from_truth([c], [r])
        rows += [{**row, "case": "issue25"} for row in rows_of(r)]
    if args.csv:
        pd.DataFrame(rows).to_csv(args.csv, index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
