"""The functions Snakemake rules call: one per rule, arguments straight from the rule.

Fit jobs are ``run:`` blocks executed in Snakemake's own process (``force-use-threads`` in the
workflow profile), so a job starts no interpreter: at 3,360 fits an interpreter start plus
imports (about 1 s) would cost more than most fits. The fit itself does not run in that thread:
Python-heavy optimizers in two threads of one process fight over the GIL (measured: fits 5-10x
slower). Each job hands its fit to a pool of worker processes, started once per Snakemake run
with the package already imported, and waits for it. The pool has as many workers as Snakemake
has cores; each worker's kernel is single-threaded. Every function writes its outputs atomically
and a one-line log.
"""

from __future__ import annotations

import copy
import json
import multiprocessing
import os
import threading
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numba
import pandas as pd
import yaml

from . import aggregate, config, fit, problem, synthetic
from .io import atomic_path, write_json, write_log

_VALIDATED: dict[str, dict] = {}


def _checked(cfg) -> dict:
    """The validated config. Validation (~30 ms) runs once per distinct config and process, not
    once per fit job: every job of a run passes the same config."""
    key = json.dumps(cfg, sort_keys=True, default=str)
    if key not in _VALIDATED:
        checked = copy.deepcopy(dict(cfg))
        config.validate(checked, source="snakemake config")
        _VALIDATED[key] = checked
    return _VALIDATED[key]


def effective_config(cfg, out_yaml: str) -> None:
    """The configuration this run used, for notebooks and for the record."""
    cfg = _checked(cfg)
    with atomic_path(out_yaml) as tmp:
        tmp.write_text(yaml.safe_dump(cfg, sort_keys=False))


def dataset(cfg, scenario, case, out_csv: str, log: str | None = None) -> None:
    ds = synthetic.generate(_checked(cfg), int(scenario), int(case))
    synthetic.write(ds, out_csv)
    write_log(log, f"wrote {out_csv}: {ds.time_s.size} samples, truth {ds.meta['true_params']}")


_REEVAL_LOCK = threading.Lock()


def coalesce_snakemake_reevaluation() -> bool:
    """Keep at most one of Snakemake's re-evaluation timers pending (call from the Snakefile).

    Snakemake 9's job rate limiter (default 100 jobs/s) makes every scheduling round start a
    1-s ``threading.Timer`` whose firing triggers another round, which starts another timer: every
    finished job adds a timer that then re-arms itself once a second for the rest of the run. On
    the full grid this grew to ~360 live timer threads and 571 s of Snakemake CPU in a 20-minute
    run (``benchmarks/bench_workflow.py``). One pending timer gives the limiter the same
    re-evaluation; it is a daemon so it cannot delay exit. Returns whether the patch applied
    (False if this Snakemake has no such method: then nothing is changed).
    """
    from snakemake.scheduling import job_scheduler

    cls = job_scheduler.JobScheduler
    original = getattr(cls, "_schedule_reevalutation", None)
    if original is None or getattr(original, "_coalesced", False):
        return original is not None

    def schedule_reevaluation(self, delay) -> None:
        with _REEVAL_LOCK:
            if getattr(self, "_avoa_reeval_pending", False):
                return
            self._avoa_reeval_pending = True

        def fire():
            with _REEVAL_LOCK:
                self._avoa_reeval_pending = False
            self._open_jobs.release()

        timer = threading.Timer(delay, fire)
        timer.daemon = True
        timer.start()

    schedule_reevaluation._coalesced = True
    cls._schedule_reevalutation = schedule_reevaluation
    return True


_POOL: ProcessPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def _pool(workers: int) -> ProcessPoolExecutor:
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            # one BLAS thread per worker: scipy's L-BFGS-B calls BLAS on tiny vectors, and
            # spinning BLAS threads on a busy 2-core machine made it 7x slower (measured)
            for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
                os.environ[var] = "1"
            # forkserver: never fork the multi-threaded Snakemake process itself
            ctx = multiprocessing.get_context("forkserver")
            _POOL = ProcessPoolExecutor(max_workers=max(1, int(workers)), mp_context=ctx)
        return _POOL


def run_in_pool(workers: int, fn, *args):
    """``fn(*args)`` in the worker-process pool (made on first use with ``workers`` processes),
    waited for; what a Snakemake ``run:`` job with numerics calls, so the scheduler's process
    never computes and no job starts an interpreter."""
    return _pool(workers).submit(fn, *args).result()


def fit_job(cfg, data_csv, scenario, case, algorithm, seed, out_json, log=None, workers=1):
    """A Snakemake fit job: run :func:`fit_one` in the worker pool and wait for it."""
    args = (dict(cfg), data_csv, scenario, case, algorithm, seed, out_json, log)
    run_in_pool(workers, fit_one, *args)


def fit_one(
    cfg, data_csv: str, scenario, case, algorithm: str, seed, out_json: str, log: str | None = None
) -> None:
    numba.set_num_threads(1)
    cfg = _checked(cfg)
    budget = fit.budget_from(cfg)
    prob = problem.build(cfg, int(scenario), int(case), data=data_csv)
    rec = fit.run(cfg, prob, algorithm, int(seed), budget)
    write_json(rec, out_json)
    write_log(
        log,
        f"{algorithm} s{scenario} c{case} seed {seed}: ISE {rec['best_ise']:.6g}, "
        f"nfe {rec['nfe']}, {rec['wall_s']:.3f} s",
    )


def fit_key(cfg, data_csv, scenario, case, algorithm: str, seed) -> str:
    """What a fit record depends on, as one hash: the dataset's bytes, the budget, the bounds,
    the constants, the base seed, the run's wildcards, and the package's numerical code (its
    optimizer, model and problem sources). A batch job keeps an existing record whose key is
    the current one and computes every other (:func:`fit_batch`)."""
    import hashlib

    from .io import sha256

    parts = {
        "data": sha256(data_csv),
        "budget": cfg["budget"],
        "bounds": cfg.get("bounds_used"),
        "constants": cfg.get("constants"),
        "base_seed": cfg["base_seed"],
        "run": [int(scenario), int(case), str(algorithm), int(seed)],
        "code": _code_hash(),
    }
    text = json.dumps(parts, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


_CODE_HASH: list[str] = []


def _code_hash() -> str:
    """sha256 over the sources a fit's numbers come from (computed once per process)."""
    if not _CODE_HASH:
        import hashlib
        from pathlib import Path

        root = Path(__file__).resolve().parent
        files = sorted([*(root / "optimizers").glob("*.py"), *(root / "model").glob("*.py"),
                        root / "problem.py", root / "fit.py", root / "seeds.py",
                        root / "synthetic.py"])  # fmt: skip
        h = hashlib.sha256()
        for f in files:
            h.update(f.name.encode())
            h.update(f.read_bytes())
        _CODE_HASH.append(h.hexdigest())
    return _CODE_HASH[0]


def fit_batch(cfg, data_csv: str, scenario, case, algorithm: str, seeds, out_jsons,
              log: str | None = None) -> dict:  # fmt: skip
    """Several seeds of one scenario × case × algorithm in one job, one record per seed.

    A record already on disk whose ``job_key`` is this fit's current :func:`fit_key` is kept
    (Snakemake's ``update`` flag leaves it in place): adding seeds to a batch computes only the
    new ones, while a changed budget, dataset or code recomputes all. Returns the counts."""
    numba.set_num_threads(1)
    cfg = _checked(cfg)
    seeds, out_jsons = [int(s) for s in seeds], [str(p) for p in out_jsons]
    if len(seeds) != len(out_jsons):
        raise ValueError(f"{len(seeds)} seeds for {len(out_jsons)} records")
    budget = fit.budget_from(cfg)
    prob = None
    kept, lines = 0, []
    for seed, out in zip(seeds, out_jsons, strict=True):
        key = fit_key(cfg, data_csv, scenario, case, algorithm, seed)
        try:
            old = json.loads(Path(out).read_text())
        except (FileNotFoundError, json.JSONDecodeError, UnicodeDecodeError):
            old = None
        if isinstance(old, dict) and old.get("job_key") == key:
            kept += 1
            continue
        if prob is None:  # one problem (dataset read, kernels loaded) for the whole batch
            prob = problem.build(cfg, int(scenario), int(case), data=data_csv)
        rec = fit.run(cfg, prob, algorithm, seed, budget)
        rec["job_key"] = key
        write_json(rec, out)
        lines.append(f"{algorithm} s{scenario} c{case} seed {seed}: ISE {rec['best_ise']:.6g}, "
                     f"nfe {rec['nfe']}, {rec['wall_s']:.3f} s")  # fmt: skip
    lines.append(f"{len(seeds) - kept} computed, {kept} kept (current job_key)")
    write_log(log, "\n".join(lines))
    return {"computed": len(seeds) - kept, "kept": kept}


def aggregate_runs(records, runs_out: str, hist_out: str, log: str | None = None) -> None:
    runs, hist = aggregate.from_files(records)
    aggregate.write(runs, hist, runs_out, hist_out)
    write_log(log, f"{len(runs)} runs, {len(hist)} history rows")


def concat_aggregates(runs_in, hist_in, runs_out: str, hist_out: str, log: str | None = None):
    """The per-pair aggregates of a run in one runs table and one histories table."""
    lines = []
    for paths, out in ((runs_in, runs_out), (hist_in, hist_out)):
        df = pd.concat([pd.read_parquet(p) for p in paths], ignore_index=True)
        with atomic_path(out) as tmp:
            df.to_parquet(tmp, index=False)
        lines.append(f"{out}: {len(df)} rows from {len(paths)} files")
    write_log(log, "\n".join(lines))
