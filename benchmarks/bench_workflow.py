"""Time a Snakemake run of this workflow: where the time went, and the fits' kernel bound.

    .venv/bin/python benchmarks/bench_workflow.py                 # `snakemake -j2 paper` here
    .venv/bin/python benchmarks/bench_workflow.py --target all --cores 2 --workdir /work/clone

Run it in a fresh clone (``results/`` absent) for the full cost; in a directory with results it
times whatever is out of date. First it measures the population kernel's ns per candidate-sample
on this machine (``bench_kernel.ns_per_candidate_sample``: each configured scenario, on as many
rows as a fit block's seeds stepped together), then runs Snakemake and prints, for the same run:

- the wall time, the Snakemake process's own CPU time (its per-job overhead) and the CPU time of
  everything it started (exact: the children Snakemake waited for);
- the CPU time of each job kind: every process under Snakemake is sampled every ``--sample``
  seconds and given the rule of its job (the rule's name from the job's script for ``script:``
  rules; ``notebook`` for papermill and its kernel); a process's CPU after its last sample is
  missed, so the kinds add up to a little less than the children's total (the rest is printed);
- the kernel bound of the fits actually run (records written by this run): their
  candidate-samples (evaluations × samples) × the kernel's ns per candidate-sample of their
  scenario, and the ratios wall ÷ (kernel bound ÷ cores) and fit CPU ÷ kernel bound;
- the whole run split by job kind in one table (``KINDS``: fits, real-data fits, notebooks,
  datasets, aggregates, diagnoses, Snakemake itself, unattributed): each kind's processes, CPU
  seconds, share of the run's CPU and, where one exists, its bound (fits: the kernel bound) and
  CPU ÷ bound;
- the jobs per rule and the optimizer time per algorithm from ``results/aggregate/runs.parquet``.

Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parents[1]
# the rule's name in the pickled job object of a `script:` rule's script ("rule": "<name>")
_RULE = re.compile(r"\\x8c\\x04rule\\x94\\x8c(?:\\x[0-9a-f]{2}|\\[tnr]|[ -~])([A-Za-z_]\w*)\\x94")


# Job kind of each rule (the rule's name as ``job_kind`` gives it): a fit computes records
# with an optimizer (the paper grid's, with a kernel bound, or the real data's), a dataset job
# makes or imports data, a diagnosis job diagnoses one record, an aggregate job reads records or
# diagnoses and writes tables; notebooks are papermill's processes. A rule not matched lands in
# "other" (printed, so a new rule is never silently lost).
KINDS = (
    ("fits", re.compile(r"fit")),  # the paper grid's fit blocks: the kernel bound is theirs
    ("real-data fits", re.compile(r"panasonic_fit_\w+|panasonic_joint|real_samsung_arrhenius"
                                  r"|real_nasa_fade|panasonic_cross_cycle"
                                  r"|panasonic_soc_estimation")),
    ("notebooks", re.compile(r"notebook")),
    ("datasets", re.compile(r"dataset|gap_\w*data|gap_controls|\w+_import|panasonic_ocv")),
    ("diagnoses", re.compile(r"gap_diagnose\w*|\w+_diagnose")),
    ("aggregates", re.compile(r"aggregate_\w+|effective_config|gap_\w+_table|gap_evaluate"
                              r"|\w+_table")),
)  # fmt: skip


def kind_of(rule: str) -> str:
    """The job kind (``KINDS``) of a rule as ``job_kind`` names it."""
    return next((k for k, pat in KINDS if pat.fullmatch(rule)), "other")


def kernel_ns(workdir: Path, configfile: str | None) -> tuple[dict[int, float], int]:
    """ns per candidate-sample of each configured scenario, on a fit block's rows (the seeds of a
    block stepped together), with the configuration Snakemake will use in ``workdir``."""
    import yaml
    from bench_kernel import ns_per_candidate_sample

    from avoa_pipeline import config, problem

    def merge(base: dict, over: dict) -> dict:  # as Snakemake's --configfile over the Snakefile's
        for k, v in over.items():
            if isinstance(v, dict) and isinstance(base.get(k), dict):
                merge(base[k], v)
            else:
                base[k] = v
        return base

    cfg = yaml.safe_load((workdir / "config" / "config.yaml").read_text())
    if configfile:
        merge(cfg, yaml.safe_load((workdir / configfile).read_text()))
    config.validate(cfg)
    rows = min(cfg.get("fit_seeds_per_job", 30), len(cfg["seeds"])) * cfg["budget"]["pop_size"]
    case = 4 if 4 in cfg["cases"] else cfg["cases"][0]
    ns = {
        int(s): ns_per_candidate_sample(problem.build(cfg, s, case), rows, seconds=1.0)
        for s in cfg["scenarios"]
    }
    return ns, rows


def job_kind(proc: psutil.Process) -> str | None:
    """The rule a process works for (None: a shell wrapper or a process that is gone)."""
    try:
        cmd = proc.cmdline()
    except (psutil.NoSuchProcess, psutil.AccessDenied, psutil.ZombieProcess):
        return None
    text = " ".join(cmd)
    if "avoa_pipeline.notebook" in text or "papermill" in text or "ipykernel" in text:
        return "notebook"
    if not cmd or Path(cmd[0]).name in ("bash", "sh"):
        return None
    for arg in cmd[1:]:
        if arg.endswith(".py") and "/.snakemake/scripts/" in "/" + arg:
            try:
                script = Path(arg if os.path.isabs(arg) else Path(proc.cwd()) / arg).read_text()
            except (OSError, UnicodeDecodeError, psutil.Error):
                return "script (rule unknown)"
            m = _RULE.search(script)
            rule = m.group(1) if m else "script (rule unknown)"
            return "fit" if re.fullmatch(r"fit_\d+", rule) else rule
    if "-m" in cmd:  # `shell: python -m package ...` rules
        i = cmd.index("-m")
        return " ".join(cmd[i + 1 : i + 3])
    return Path(cmd[0]).name


def fits_run_since(workdir: Path, t0: float) -> dict[int, float]:
    """Candidate-samples (evaluations × samples) per scenario of the records written since t0."""
    out: dict[int, float] = defaultdict(float)
    for p in (workdir / "results" / "fits").glob("s*/c*/*/seed*.json"):
        if p.stat().st_mtime >= t0:
            rec = json.loads(p.read_text())
            out[int(rec["scenario"])] += rec["nfe"] * rec["n_samples"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--target", default="paper")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--workdir", type=Path, default=ROOT)
    ap.add_argument("--configfile", default=None)
    ap.add_argument("--log", type=Path, default=None, help="Snakemake's output (default: temp)")
    ap.add_argument("--sample", type=float, default=0.25, help="seconds between CPU samples")
    args = ap.parse_args()

    wd = args.workdir.resolve()
    print(f"load before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    ns, rows = kernel_ns(wd, args.configfile)
    print("population kernel, ns per candidate-sample at "
          f"{rows} rows: " + ", ".join(f"scenario {s} {v:.2f}" for s, v in ns.items()))  # fmt: skip

    snakemake = Path(sys.executable).with_name("snakemake")
    cmd = [str(snakemake), f"-j{args.cores}", args.target]
    if args.configfile:
        cmd += ["--configfile", args.configfile]
    env = dict(os.environ, XDG_CACHE_HOME=str(wd / ".cache"))
    log = args.log or wd / "logs" / "bench_workflow.log"
    log.parent.mkdir(parents=True, exist_ok=True)

    seen: dict[tuple[int, float], tuple[str | None, float]] = {}  # (pid, start) -> kind, CPU
    t_start = time.time()
    t0 = time.perf_counter()
    with log.open("w") as out:
        proc = subprocess.Popen(cmd, cwd=wd, env=env, stdout=out, stderr=subprocess.STDOUT)
        main_proc = psutil.Process(proc.pid)
        main_cpu = 0.0
        while proc.poll() is None:
            try:
                t = main_proc.cpu_times()
                main_cpu = t.user + t.system  # the scheduler, bookkeeping and `run:` threads
                children = main_proc.children(recursive=True)
            except psutil.NoSuchProcess:
                break
            for child in children:
                try:
                    key = (child.pid, child.create_time())
                    kind = seen[key][0] if key in seen else job_kind(child)
                    ct = child.cpu_times()
                    seen[key] = (kind, ct.user + ct.system)
                except (psutil.NoSuchProcess, psutil.ZombieProcess, psutil.AccessDenied):
                    continue
            time.sleep(args.sample)
        rc = proc.wait()
    wall = time.perf_counter() - t0
    children_cpu = (lambda t: t.children_user + t.children_system)(os.times())

    text = log.read_text()
    jobs = Counter(re.findall(r"^(?:local)?rule (\w+):", text, flags=re.M))
    n_jobs = sum(jobs.values())
    cores = args.cores
    print(f"command: {' '.join(cmd)}  (in {wd})")
    print(f"exit code {rc}; wall {int(wall // 60)} min {wall % 60:.0f} s ({wall:.0f} s); "
          f"load after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")  # fmt: skip
    print(
        f"Snakemake process CPU: {main_cpu:.0f} s"
        + (f" = {main_cpu / n_jobs * 1000:.0f} ms per job over {n_jobs} jobs" if n_jobs else "")
    )
    print(f"CPU of all child processes: {children_cpu:.0f} s (Snakemake's own included)")
    by_kind: dict[str, list[float]] = defaultdict(list)
    for kind, cpu in seen.values():
        if kind is not None:
            by_kind[kind].append(cpu)
    print(f"CPU per job kind (sampled every {args.sample} s; processes, CPU s):")
    for kind, cpus in sorted(by_kind.items(), key=lambda kv: -sum(kv[1])):
        print(f"  {kind:28s} {len(cpus):5d} {sum(cpus):8.1f}")
    attributed = sum(sum(c) for c in by_kind.values())
    # Snakemake is this process's child: its own CPU is in children_cpu too, beside its jobs'
    unattributed = children_cpu - attributed - main_cpu
    print(f"  {'(between samples, shells)':28s} {'':5s} {unattributed:8.1f}")

    cs = fits_run_since(wd, t_start)
    bound = sum(cs[s] * ns.get(s, max(ns.values())) * 1e-9 for s in cs) if cs else 0.0
    if cs:
        fit_cpu = sum(by_kind.get("fit", []))
        print(f"fits run: {sum(cs.values()):.3e} candidate-samples; kernel bound {bound:.1f} s, "
              f"÷ {cores} cores = {bound / cores:.1f} s")  # fmt: skip
        print(f"wall ÷ (kernel bound ÷ cores) = {wall / (bound / cores):.2f}; "
              f"fit jobs' CPU ÷ kernel bound = {fit_cpu:.0f} / {bound:.0f} = "
              f"{fit_cpu / bound:.2f}")  # fmt: skip

    # the whole run by job kind: every CPU second of the run is in exactly one row
    split: dict[str, list[float]] = defaultdict(list)
    for rule, cpus in by_kind.items():
        split[kind_of(rule)] += cpus
    rows = [(k, len(split[k]), sum(split[k])) for k, _ in KINDS]
    if split.get("other"):
        rows.append(("other", len(split["other"]), sum(split["other"])))
    rows += [("Snakemake itself", 1, main_cpu),
             ("unattributed", 0, unattributed)]  # fmt: skip
    total = children_cpu
    print(f"the run by job kind (CPU {total:.0f} s over {cores} cores = {total / cores:.0f} s "
          f"of the {wall:.0f} s wall):")  # fmt: skip
    print(f"  {'kind':18s} {'procs':>5s} {'CPU s':>8s} {'share':>6s} {'bound s':>8s} "
          f"{'CPU/bound':>9s}")  # fmt: skip
    for k, n, cpu in rows:
        b = f"{bound:8.1f} {cpu / bound:9.2f}" if k == "fits" and bound else f"{'-':>8s} {'-':>9s}"
        print(f"  {k:18s} {n:5d} {cpu:8.1f} {100 * cpu / total:5.1f}% {b}")
    if split.get("other"):
        print("  other: " + ", ".join(r for r in by_kind if kind_of(r) == "other"))
    for rule, n in sorted(jobs.items(), key=lambda kv: -kv[1]):
        print(f"  {rule:28s} {n:5d} jobs")

    runs = wd / "results" / "aggregate" / "runs.parquet"
    if runs.exists():
        import pandas as pd

        df = pd.read_parquet(runs)
        per = df.groupby("algorithm")["wall_s"].agg(["mean", "sum", "count"])
        total = per["sum"].sum()
        print(f"optimizer time in the records: {total:.0f} s over {len(df)} fits")
        for algo, row in per.sort_values("sum", ascending=False).iterrows():
            print(
                f"  {algo:14s} {row['mean']:.2f} s per fit  {row['sum']:7.0f} s "
                f"({100 * row['sum'] / total:.0f} %)"
            )
    sys.exit(rc)


if __name__ == "__main__":
    main()
