"""Time one fit block per algorithm (the workflow's fit job: every seed of one scenario × case ×
algorithm) against its kernel bound, single-threaded as in a workflow job (numba and BLAS).

    .venv/bin/python benchmarks/bench_fit_block.py                 # s4 c4, 7 algorithms x 30 seeds
    .venv/bin/python benchmarks/bench_fit_block.py --algorithms avoa gto --seeds 10
    .venv/bin/python benchmarks/bench_fit_block.py --out DIR        # keep the records
    .venv/bin/python benchmarks/bench_fit_block.py --compare DIR    # and check them against DIR's
    .venv/bin/python benchmarks/bench_fit_block.py --threads 2      # the job given two threads

First measures the population kernel's ns per candidate-sample on the block's rows (seeds ×
pop_size, all seeds' candidates in one call; ``bench_kernel.ns_per_candidate_sample``), then runs
``jobs.identify.fit_batch`` for each algorithm on the dataset the workflow would write, and prints
per algorithm and in total: wall time, process CPU, candidate-samples (evaluations × samples, from
the records), the kernel bound (candidate-samples × ns) and the ratio wall ÷ kernel bound.
``--compare`` checks each record's numbers (best parameters, best ISE, evaluations, iterations,
history of best ISE and evaluations) against the record of the same seed in another directory,
bit for bit (timings excepted). ``--threads``: the threads the job is given (``threads.use``, as
``jobs.start`` gives a rule's ``threads:``; default 1, as the fit rules declare); the kernel
measurement stays single-threaded. Nothing is asserted.
"""

from __future__ import annotations

import os

# one BLAS thread, as Snakemake gives a job of `threads: 1` (set before numpy is imported)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numba  # noqa: E402
from bench_kernel import ns_per_candidate_sample  # noqa: E402

from avoa_pipeline import config, problem, threads  # noqa: E402
from avoa_pipeline.fit import same_record  # noqa: E402
from avoa_pipeline.jobs import data as data_jobs  # noqa: E402
from avoa_pipeline.jobs import identify  # noqa: E402
from avoa_pipeline.names import ALGORITHMS  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", type=int, default=4)
    ap.add_argument("--case", type=int, default=4)
    ap.add_argument("--seeds", type=int, default=30, help="seeds 1..N")
    ap.add_argument("--algorithms", nargs="*", default=list(ALGORITHMS))
    ap.add_argument("--config", default=None, help="default: config/config.yaml")
    ap.add_argument("--out", type=Path, default=None, help="keep the records here")
    ap.add_argument("--compare", type=Path, default=None, help="records to compare with")
    ap.add_argument("--threads", type=int, default=1, help="threads the fit job is given")
    args = ap.parse_args()

    numba.set_num_threads(1)
    cfg = config.load(args.config)
    s, c, seeds = args.scenario, args.case, list(range(1, args.seeds + 1))
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp) / "fits"
        data = Path(tmp) / f"s{s}c{c}.csv"
        data_jobs.dataset(cfg, s, c, str(data))
        prob = problem.build(cfg, s, c, data=data)
        rows = len(seeds) * cfg["budget"]["pop_size"]
        ns = ns_per_candidate_sample(prob, rows)  # on one numba thread
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)  # the fits: as --threads says
        given = threads.use(args.threads)
        print(f"scenario {s} case {c}, {len(seeds)} seeds, budget {cfg['budget']}, "
              f"{given} threads given (kernel blocks at {rows} rows: "
              f"{threads.kernel_blocks(rows, prob.time_s.size)})")  # fmt: skip
        print(f"population kernel: {ns:.2f} ns per candidate-sample at {rows} rows")
        print(f"{'algorithm':14s} {'wall s':>8s} {'CPU s':>8s} {'cand-samples':>13s} "
              f"{'bound s':>8s} {'ratio':>6s}")  # fmt: skip
        total = {"wall": 0.0, "cpu": 0.0, "cs": 0.0}
        mismatched = []
        for alg in args.algorithms:
            paths = [out / f"s{s}/c{c}/{alg}/seed{k}.json" for k in seeds]
            for p in paths:
                p.unlink(missing_ok=True)  # a kept record would not be timed
            t0, cpu0 = time.perf_counter(), time.process_time()
            identify.fit_batch(cfg, str(data), s, c, alg, seeds, [str(p) for p in paths])
            wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
            recs = [json.loads(p.read_text()) for p in paths]
            cs = float(sum(r["nfe"] * r["n_samples"] for r in recs))
            bound = cs * ns * 1e-9
            print(f"{alg:14s} {wall:8.2f} {cpu:8.2f} {cs:13.3e} {bound:8.2f} {wall / bound:6.2f}")
            total["wall"] += wall
            total["cpu"] += cpu
            total["cs"] += cs
            if args.compare is not None:
                for k, r in zip(seeds, recs, strict=True):
                    ref = json.loads((args.compare / f"s{s}/c{c}/{alg}/seed{k}.json").read_text())
                    if same_record(r, ref):
                        mismatched.append(f"{alg} seed {k}")
        bound = total["cs"] * ns * 1e-9
        print(f"{'total':14s} {total['wall']:8.2f} {total['cpu']:8.2f} {total['cs']:13.3e} "
              f"{bound:8.2f} {total['wall'] / bound:6.2f}")  # fmt: skip
        if args.compare is not None:
            n = len(seeds) * len(args.algorithms)
            print(f"records equal to {args.compare}'s (timings aside): {n - len(mismatched)}/{n}"
                  + (f"; differ: {', '.join(mismatched)}" if mismatched else ""))  # fmt: skip


if __name__ == "__main__":
    main()
