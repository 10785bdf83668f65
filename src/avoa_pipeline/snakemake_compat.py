"""The workflow's two workarounds of Snakemake behaviours. Written for Snakemake 9.27.1 (its file
persistence keeps locks as ``.snakemake/locks/<n>.{input,output}.lock``; its scheduler's
``JobScheduler._schedule_reevalutation``); not future-proof: each does nothing where the
Snakemake at hand lacks what it works around.

Stale locks.

A ``kill -9`` of Snakemake leaves its lock files behind, and the next run refuses to start
("Directory cannot be locked") until ``snakemake --unlock``. The lock files name no process, so
Snakemake cannot tell a live run's lock from a killed run's. :func:`clear_stale_locks` removes
them when no live Snakemake process works in this directory: then they can only be left over.
It runs only in the main Snakemake process (not in job subprocesses or on cluster nodes, where
the main run may live on another machine) and never for a dry run.

The workflow runs correctly without it: after a killed run, ``snakemake --unlock`` once, as the
README says. With it, a plain rerun resumes (the workflow profile's ``rerun-incomplete`` reruns
the jobs the killed run left incomplete). Limit: it sees the processes of this machine only; a
second Snakemake started on another machine on the same shared directory is not seen.

Re-evaluation timers (:func:`coalesce_reevaluation`). Snakemake 9's job-rate limiter (default
100 jobs per second) makes every scheduling round start a ``threading.Timer`` of the limit's
timespan (1 s) whose firing starts another round, which starts another timer: every round that a
finished job triggers adds a timer that re-arms itself each second for the rest of the run. In
the whole study (issue 42) the Snakemake process had about 240 timer threads late in the run and
took 1,571 s of CPU in 76 min, 34 % of a core of the two, in rounds that stat the inputs of every
ready job (py-spy: ``JobScheduler.update_input_sizes``) while they wait for cores. One pending
timer gives the limiter the same re-evaluation. The timer is a daemon, so it never delays the
exit (Snakemake's own are not: with a 1,000-s timespan in the limit instead, the process waited
at exit for its timers). This was in the workflow from d559596 to 2d1017e (issue 11 dropped it
with the process pool, when the paper grid had become 81 jobs).
"""

from __future__ import annotations

import os
import threading
from pathlib import Path

WRITTEN_FOR = "9.27.1"


def live_snakemakes_here(workdir: Path) -> list[int]:
    """PIDs of other live Snakemake processes whose working directory is ``workdir``."""
    import psutil

    from .jobguard import is_snakemake

    me = os.getpid()
    ancestors = {p.pid for p in psutil.Process().parents()}
    found = []
    for p in psutil.process_iter(["pid", "cmdline", "cwd"]):
        try:
            cmd = p.info["cmdline"] or []
            if p.info["pid"] == me or p.info["pid"] in ancestors:
                continue
            if is_snakemake(cmd) and p.info["cwd"] and Path(p.info["cwd"]) == workdir:
                found.append(p.info["pid"])
        except (psutil.Error, OSError):
            continue
    return found


def clear_stale_locks(workdir, main_process: bool, dryrun: bool) -> list[str]:
    """Remove ``workdir/.snakemake/locks/*.lock`` when no other Snakemake works in ``workdir``;
    returns the removed file names (empty when nothing was stale or this is no main run)."""
    if not main_process or dryrun:
        return []
    workdir = Path(workdir).resolve()
    lockdir = workdir / ".snakemake" / "locks"
    locks = sorted(lockdir.glob("*.lock")) if lockdir.is_dir() else []
    if not locks or live_snakemakes_here(workdir):
        return []
    for f in locks:
        f.unlink(missing_ok=True)
    return [f.name for f in locks]


def clear_stale_locks_of(workflow) -> list[str]:
    """:func:`clear_stale_locks` for the Snakefile's ``workflow`` object (its attributes as of
    Snakemake 9.27: ``is_main_process``, ``dryrun``); does nothing if they are missing."""
    main = getattr(workflow, "is_main_process", None)
    try:
        dry = bool(getattr(workflow, "dryrun", True))
    except Exception:  # the executor is not set up yet in some modes: do nothing
        return []
    if main is not True:
        return []
    return clear_stale_locks(Path.cwd(), True, dry)


_REEVAL_LOCK = threading.Lock()


def coalesce_reevaluation() -> bool:
    """At most one of Snakemake's re-evaluation timers pending, a daemon (the module's second
    workaround; call from the Snakefile). It changes when a scheduling round runs, never which
    jobs run. Returns whether it applies (False where this Snakemake has no such method: then
    nothing is changed)."""
    from snakemake.scheduling import job_scheduler

    cls = job_scheduler.JobScheduler
    original = getattr(cls, "_schedule_reevalutation", None)
    if original is None or getattr(original, "coalesced", False):
        return original is not None

    def schedule_reevaluation(self, delay) -> None:
        with _REEVAL_LOCK:
            if getattr(self, "_reevaluation_pending", False):
                return
            self._reevaluation_pending = True

        def fire() -> None:
            with _REEVAL_LOCK:
                self._reevaluation_pending = False
            self._open_jobs.release()

        timer = threading.Timer(delay, fire)
        timer.daemon = True
        timer.start()

    schedule_reevaluation.coalesced = True
    cls._schedule_reevalutation = schedule_reevaluation
    return True
