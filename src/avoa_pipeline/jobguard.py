"""Kill safety for jobs: a job that outlives the Snakemake process that started it stops.

A job is a process of its own (a ``script:`` or ``shell:`` rule), so a ``kill -9`` of Snakemake
does not reach it: it would go on computing and write its outputs into a directory that nobody
is watching any more. :func:`watch` looks up the nearest ancestor process that is a Snakemake
and, if there is one, starts a daemon thread that polls it; when it is gone, the job kills its own
children (a notebook's kernel, a shell command) and exits at once (status 137, as a SIGKILL).
Outputs are written atomically (``io.atomic_path``), so what a stopped job leaves is at most a
temporary file, never half an output; Snakemake's ``rerun-incomplete`` (the workflow profile)
reruns the job next time.

On a cluster the job's ancestor is the Snakemake process the executor starts on the node, so
killing the submitting Snakemake leaves cluster jobs to the scheduler, as it should (``scancel``).
Without a Snakemake ancestor (the CLI run by hand, tests) nothing happens, unless the job was
started by a Snakemake that is already gone: a ``kill -9`` in the instant between a job's start
and its first look at its ancestors (on a loaded machine a Python job takes seconds to get
there) leaves it no Snakemake ancestor to find. The workflow therefore names its Snakemake in
the jobs' environment (:data:`ENV`, set by :func:`announce` in ``common.smk``): a job that finds
no ancestor but was started by a Snakemake of this host that no longer runs stops at once.

``python -m avoa_pipeline.jobguard CMD ...`` runs CMD under the same watch (for ``shell:`` rules
whose program is not the package's, e.g. papermill and its kernel).

Why hand-written: neither Snakemake's local executor nor Python's ``subprocess`` ties a child's
life to its grandparent's; ``prctl(PR_SET_PDEATHSIG)`` acts on the direct parent only, which for
a ``shell:`` job is the shell, not Snakemake.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
import time

POLL_S = 0.5
"""How often the job looks for its Snakemake (a stopped run computes on for at most this long)."""

_STARTED: list = []

ENV = "AVOA_SNAKEMAKE"
"""The Snakemake process that starts the jobs, as ``host:pid:create_time`` (create_time tells a
reused PID from the process itself)."""


def announce() -> None:
    """Name this (Snakemake) process in the environment its jobs inherit (:data:`ENV`)."""
    import socket

    import psutil

    me = psutil.Process()
    os.environ[ENV] = f"{socket.gethostname()}:{me.pid}:{me.create_time()!r}"


def _announced_gone() -> bool:
    """Whether the Snakemake named in :data:`ENV` ran on this host and no longer runs."""
    import socket

    import psutil

    host, _, rest = os.environ.get(ENV, "").partition(":")
    pid, _, created = rest.partition(":")
    if not pid or host != socket.gethostname():
        return False  # not started by the workflow, or by a Snakemake on another node
    try:
        return psutil.Process(int(pid)).create_time() != float(created)
    except (psutil.NoSuchProcess, ValueError):
        return True
    except psutil.Error:
        return False


def is_snakemake(cmdline) -> bool:
    """Whether a command line runs Snakemake (``snakemake ...``, ``python .../snakemake ...``,
    ``python -m snakemake ...``)."""
    return any(os.path.basename(c).startswith("snakemake") for c in list(cmdline)[:3])


def snakemake_ancestor():
    """The nearest ancestor process whose command line runs Snakemake, or None."""
    import psutil

    try:
        parents = psutil.Process().parents()
    except psutil.Error:
        return None
    for p in parents:
        try:
            cmd = p.cmdline()
        except psutil.Error:
            continue
        if is_snakemake(cmd):
            return p
    return None


def _kill_children() -> None:
    import psutil

    with contextlib.suppress(psutil.Error):
        for child in psutil.Process().children(recursive=True):
            with contextlib.suppress(psutil.Error):
                child.kill()


def watch(poll_s: float = POLL_S):
    """Start watching this process's Snakemake ancestor (once per process); returns it or None."""
    if _STARTED:
        return _STARTED[0]
    target = snakemake_ancestor()
    _STARTED.append(target)
    if target is None:
        if _announced_gone():  # its Snakemake died before the job looked: stop now
            _kill_children()
            os._exit(137)
        return None

    def loop():
        while True:
            time.sleep(poll_s)
            if not target.is_running():  # also false when the PID was reused by another process
                _kill_children()
                os._exit(137)

    threading.Thread(target=loop, name="avoa-jobguard", daemon=True).start()
    return target


def main(argv=None) -> int:
    """Run a command under the watch; its exit status is ours."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["--"]:
        argv = argv[1:]
    if not argv:
        print("usage: python -m avoa_pipeline.jobguard CMD [ARG ...]", file=sys.stderr)
        return 2
    watch()
    return subprocess.call(argv)


if __name__ == "__main__":
    sys.exit(main())
