"""Seconds to fit one Panasonic model over every temperature (issue 28's goal: ≤ 5 min on this
2-core machine): ``python -m avoa_pipeline diagnose`` of each experiment temperature's training
cycle and HPPC test together, the 25 °C C/20 test as ``--ocv``, in a child process (as rule
``panasonic_joint`` runs it, without the unseen cycles unless ``--validate``). Prints its wall and
CPU seconds, its peak RSS (the whole process, from ``os.wait4``), the load average before and
after, and what ``diagnosis.json`` says it selected and how long it took; asserts nothing.

The records are the canonical CSVs ``snakemake -j2 real`` writes (results/real/canonical).

    nice -n 19 .venv/bin/python benchmarks/bench_joint.py
    ... --validate    # also every temperature's unseen cycles (rule panasonic_joint does)
    ... --temperatures 25degC,0degC    # a smaller instance (two temperatures' records)
    ... --until "rung 1: 12 candidates"   # in this process, up to that stage; wall and CPU
    ... --until "rung 1: base held" --profile   # the same under cProfile: its top functions

``--until`` runs the diagnosis in this process (no figure, no files) and stops when its progress
line starts with the phrase: a part of the run, to compare code versions under the same load
(``PYTHONPATH=<a checkout of commit ce0cda2>/src`` runs the code before the speed-ups; its
``--threads`` needs the thread policy's code).

Also printed: the cores this process may use (the selection's threads: ``threads.given``).
Measured: docs/real-data.md, "Time of the joint fit" (before the speed-ups, commit ce0cda2,
1,802 s wall).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from avoa_pipeline.plan import canonical_name


def records(cfg: dict, canonical: Path) -> tuple[list[Path], list[Path], Path]:
    """(training records, unseen cycles, the C/20 test) of the config's experiment temperatures,
    by the rule of docs/real-data.md ("One model over temperature")."""
    pan = cfg["real"]["panasonic"]
    exp = pan["experiment"]
    temps = exp.get("temperatures") or list(exp["train"])

    def path(name: str) -> Path:
        return canonical / f"{canonical_name(name)}.csv"

    train = [path(f"{t}/{r}") for t in temps for r in (exp["train"][t], "hppc")]
    unseen = [path(f"{t}/{c}") for t in temps for c in pan["temperatures"][t]["drive_cycles"]
              if c != exp["train"][t]]  # fmt: skip
    return train, unseen, path("25degC/ocv_c20")


class _Stop(Exception):
    pass


def part(train: list[Path], ocv: Path, args) -> None:
    """The diagnosis in this process up to the first progress line starting with
    ``args.until``: wall and CPU seconds at every stage, optionally under cProfile."""
    import cProfile
    import pstats
    import resource

    from avoa_pipeline import inputs
    from avoa_pipeline.gap import diagnose

    def cpu() -> float:
        r = resource.getrusage(resource.RUSAGE_SELF)
        return r.ru_utime + r.ru_stime

    class Progress:
        def __init__(self, stream, t0):
            self.t0, self.c0 = time.perf_counter(), cpu()

        def __call__(self, what: str) -> None:
            print(f"wall {time.perf_counter() - self.t0:7.1f} s, CPU {cpu() - self.c0:7.1f} s: "
                  f"{what}", flush=True)  # fmt: skip
            if what.startswith(args.until):
                raise _Stop

    read = inputs.read_inputs([str(p) for p in train], [], str(ocv))
    diagnose.Progress = Progress
    if args.threads:  # code from before the thread policy has no threads module
        from avoa_pipeline import threads

        threads.use(args.threads)
    load0 = os.getloadavg()[0]
    prof = cProfile.Profile() if args.profile else None
    if prof:
        prof.enable()
    with contextlib.suppress(_Stop):
        diagnose.diagnose_records(read.train, ocv_table=read.ocv)
    if prof:
        prof.disable()
        pstats.Stats(prof).sort_stats("tottime").print_stats(12)
    print(f"load {load0:.2f} -> {os.getloadavg()[0]:.2f} ({len(os.sched_getaffinity(0))} cores)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--config", default="config/config.yaml")
    ap.add_argument("--canonical", default="results/real/canonical")
    ap.add_argument("--validate", action="store_true")
    ap.add_argument("--keep", help="a folder to copy diagnosis.json and model.json into")
    ap.add_argument("--until", help="in this process, stop at this progress phrase")
    ap.add_argument("--profile", action="store_true", help="with --until: under cProfile")
    ap.add_argument("--threads", type=int, help="with --until: the threads given (threads.use)")
    ap.add_argument("--temperatures", help="comma-separated, e.g. 25degC,0degC (default: all)")
    args = ap.parse_args()

    cfg = yaml.safe_load(Path(args.config).read_text())
    if args.temperatures:
        cfg["real"]["panasonic"]["experiment"]["temperatures"] = args.temperatures.split(",")
    train, unseen, ocv = records(cfg, Path(args.canonical))
    missing = [str(p) for p in (*train, *unseen, ocv) if not p.is_file()]
    if missing:
        sys.exit(f"error: {missing[0]}: no such file (run `snakemake -j2 real` first)")
    if args.until:
        part(train, ocv, args)
        return
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "avoa_pipeline", "diagnose", *map(str, train),
               "--ocv", str(ocv), "--out", out]  # fmt: skip
        if args.validate:
            cmd += ["--validate", *map(str, unseen)]
        load0 = os.getloadavg()[0]
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        if os.waitstatus_to_exitcode(status) != 0:
            sys.exit(f"error: diagnose exited with {os.waitstatus_to_exitcode(status)}")
        report = json.loads((Path(out) / "diagnosis.json").read_text())
        if args.keep:  # to compare a run with another
            Path(args.keep).mkdir(parents=True, exist_ok=True)
            for name in ("diagnosis.json", "model.json"):
                shutil.copy(Path(out) / name, Path(args.keep) / name)
    print(f"joint diagnosis of {len(train)} records ({report['n_samples']:,} samples)"
          f"{' + ' + str(len(unseen)) + ' unseen' if args.validate else ''}: "
          f"wall {wall:.1f} s, CPU {usage.ru_utime + usage.ru_stime:.1f} s, "
          f"peak RSS {usage.ru_maxrss / 1024:.0f} MB; load {load0:.2f} -> "
          f"{os.getloadavg()[0]:.2f} ({len(os.sched_getaffinity(0))} cores); "
          f"selected {report['selected']['name']}; "
          f"diagnosis.json wall_s {report['wall_s']:.1f} (goal: <= 300 s)")  # fmt: skip


if __name__ == "__main__":
    main()
