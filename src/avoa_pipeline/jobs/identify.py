"""The fit jobs of ``workflow/rules/identify.smk``: a block of seeds of one scenario × case, every
algorithm, in one process (:func:`fit_algorithms`), since a process start (about 1 s) would cost
more than most single fits. Each writes its records atomically and a one-line log."""

from __future__ import annotations

import json
from pathlib import Path

from threadpoolctl import threadpool_limits

from .. import fit, problem
from ..io import sha256, write_json, write_log


def fit_key(cfg, data_sha256: str, scenario, case, algorithm: str, seed) -> str:
    """What a fit record depends on, as one hash: the dataset's bytes (their sha256, computed
    once per job), the budget, the bounds, the constants, the base seed, the run's wildcards,
    and the package's numerical code (its optimizer, model and problem sources). A batch job
    keeps an existing record whose key is the current one and computes every other
    (:func:`fit_algorithms`)."""
    import hashlib

    parts = {
        "data": data_sha256,
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

        root = Path(__file__).resolve().parents[1]  # the package
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
    """Several seeds of one scenario × case × algorithm in one job, one record per seed, the
    seeds stepped together (:func:`.fit.run_seeds`: one kernel call per step for all of them).

    A record already on disk whose ``job_key`` is this fit's current :func:`fit_key` is kept
    (Snakemake's ``update`` flag leaves it in place): adding seeds to a batch computes only the
    new ones, while a changed budget, dataset or code recomputes all. Returns the counts."""
    return fit_algorithms(cfg, data_csv, scenario, case, [algorithm], seeds, out_jsons, log)


def fit_algorithms(cfg, data_csv: str, scenario, case, algorithms, seeds, out_jsons,
                   log: str | None = None) -> dict:  # fmt: skip
    """:func:`fit_batch` for several algorithms in one process (the workflow's fit job: one per
    scenario × case × block of seeds, so that the process start, imports and kernel load are
    paid once for all algorithms, not once per algorithm). ``out_jsons`` is algorithm-major:
    the records of ``seeds`` for ``algorithms[0]``, then for ``algorithms[1]``, ... Each
    algorithm's seeds are stepped together as in :func:`fit_batch`; the records are the same.
    Returns the counts over all algorithms. The kernel's threads: those the process was given
    (``jobs.start``: the rule's ``threads: 1``), where a call's work pays for them
    (``threads.kernel_blocks``); the records are the same with any number."""
    seeds, out_jsons = [int(s) for s in seeds], [str(p) for p in out_jsons]
    algorithms = [str(a) for a in algorithms]
    if len(seeds) * len(algorithms) != len(out_jsons):
        raise ValueError(f"{len(seeds)} seeds × {len(algorithms)} algorithms for "
                         f"{len(out_jsons)} records")  # fmt: skip
    budget = fit.budget_from(cfg)
    data_sha256 = sha256(data_csv)
    prob, lines, computed = None, [], 0
    for k, algorithm in enumerate(algorithms):
        outs = out_jsons[k * len(seeds) : (k + 1) * len(seeds)]
        todo = []  # (seed, record path, job_key) of the records to compute
        for seed, out in zip(seeds, outs, strict=True):
            key = fit_key(cfg, data_sha256, scenario, case, algorithm, seed)
            try:
                old = json.loads(Path(out).read_text())
            except (FileNotFoundError, json.JSONDecodeError, UnicodeDecodeError):
                old = None
            if not (isinstance(old, dict) and old.get("job_key") == key):
                todo.append((seed, out, key))
        if todo:  # one problem (dataset read, kernels loaded); the seeds stepped together
            if prob is None:
                prob = problem.build(cfg, int(scenario), int(case), data=data_csv)
            with threadpool_limits(1):  # L-BFGS-B's BLAS threads would spin (Snakemake's jobs
                # get OPENBLAS_NUM_THREADS=threads anyway; this covers the other callers)
                recs = fit.run_seeds(cfg, prob, algorithm, [s for s, _, _ in todo], budget)
            for (seed, out, key), rec in zip(todo, recs, strict=True):
                rec["job_key"] = key
                write_json(rec, out)
                ise, nfe, wall = rec["best_ise"], rec["nfe"], rec["wall_s"]
                lines.append(f"{algorithm} s{scenario} c{case} seed {seed}: ISE {ise:.6g}, "
                             f"nfe {nfe}, {wall:.3f} s")  # fmt: skip
        computed += len(todo)
        if len(algorithms) > 1:
            lines.append(f"{algorithm}: {len(todo)} computed, {len(seeds) - len(todo)} kept")
    kept = len(out_jsons) - computed
    lines.append(f"{computed} computed, {kept} kept (current job_key)")
    write_log(log, "\n".join(lines))
    return {"computed": computed, "kept": kept}
