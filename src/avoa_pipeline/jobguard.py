"""Kill safety for jobs: a job that outlives the Snakemake process that started it stops.

A job is a process of its own (a ``script:`` or ``shell:`` rule), so a ``kill -9`` of Snakemake
does not reach it: it would go on computing and write its outputs into a directory that nobody
is watching any more. :func:`watch` ties the job's life to the nearest ancestor process that is
a Snakemake, in one of two ways:

- **The kernel** (Linux, the job a direct child of Snakemake): ``prctl(PR_SET_PDEATHSIG)``, set
  in the job's own process, makes the kernel send the job a signal when the thread that started
  it exits, which a ``kill -9`` of Snakemake does. Nothing has to be scheduled for this: a job
  on a machine whose cores are all busy is killed as promptly as on an idle one. A ``script:``
  rule is such a child: Snakemake starts ``bash -c 'set -euo pipefail; python script.py'`` and
  bash (5.1 and later) execs the last command of its string, so the job replaces the shell. The
  notebooks' ``shell:`` command is written the same way (a single command, its log redirected
  by :func:`main`'s ``--log``, not by the shell). Which parent is Snakemake is told by its PID,
  named in the job's environment (:data:`ENV`), not by reading its command line: a Snakemake
  being killed at that instant has none left to read. The parent may die before the job sets
  its signal (the job takes seconds to get there on a loaded machine); it then has another
  parent already, so the job compares ``os.getppid()`` with its Snakemake after setting it and
  stops at once if they differ.
- **A poll** (another system, or a Snakemake further up: a shell command that does not end in
  one simple command, a cluster node's job step): a daemon thread looks every :data:`POLL_S`
  whether that Snakemake still runs and, when it is gone, kills the job's children and exits.

Either way the job exits with status 137 (as a SIGKILL). Outputs are written atomically
(``io.atomic_path``), so what a stopped job leaves is at most a temporary file, never half an
output; Snakemake's ``rerun-incomplete`` (the workflow profile) reruns the job next time.

``python -m avoa_pipeline.jobguard [--log FILE] CMD ...`` runs CMD under the same watch (for
``shell:`` rules whose program is not the package's: papermill and its kernel). The guard sets
each child's parent-death signal to SIGKILL (in the child, before it runs CMD) and becomes the
``PR_SET_CHILD_SUBREAPER`` of its descendants; its own parent-death signal is SIGTERM, caught:
it kills every descendant, the orphans of a killed papermill (its notebook kernel) included,
which are re-parented to it, and exits.

On a cluster the job's ancestor is the Snakemake process the executor starts on the node, so
killing the submitting Snakemake leaves cluster jobs to the scheduler, as it should (``scancel``).
Without a Snakemake ancestor (the CLI run by hand, tests) nothing happens, unless the job was
started by a Snakemake that is already gone: a ``kill -9`` in the instant between a job's start
and its first look at its ancestors leaves it no Snakemake ancestor to find. The workflow
therefore names its Snakemake in the jobs' environment (:data:`ENV`, set by :func:`announce` in
``common.smk``): a job that finds no ancestor but was started by a Snakemake of this host that
no longer runs stops at once.

Why hand-written: neither Snakemake's local executor nor Python's ``subprocess`` ties a child's
life to its parent's or grandparent's; ``prctl`` is a Linux system call that Python's standard
library does not wrap (it is called through ``ctypes``).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time

POLL_S = 0.5
"""How often the fallback looks for its Snakemake (a stopped run computes on for at most this
long where the kernel cannot tie the job to it)."""

PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
PR_SET_CHILD_SUBREAPER = 36  # <linux/prctl.h>, Linux 3.4

REAP_ROUNDS = 50
"""How many rounds of killing the guard's descendants it makes before it exits: each round kills
every descendant it sees, and a killed papermill's kernel is re-parented to the guard (its
subreaper) for the next round; a process tree of a notebook is 2-3 deep."""

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


def _announced() -> tuple[int, float] | None:
    """(pid, create_time) of the Snakemake named in :data:`ENV` if it runs on this host."""
    import socket

    host, _, rest = os.environ.get(ENV, "").partition(":")
    pid, _, created = rest.partition(":")
    if not pid or host != socket.gethostname():
        return None  # not started by the workflow, or by a Snakemake on another node
    try:
        return int(pid), float(created)
    except ValueError:
        return None


def _gone(pid: int, created: float) -> bool:
    """Whether that process no longer runs: no such process, another one under its PID, or a
    zombie (killed, not yet reaped: its command line can no longer be read)."""
    import psutil

    try:
        p = psutil.Process(pid)
        return p.create_time() != created or p.status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True
    except psutil.Error:
        return False


def _announced_gone() -> bool:
    """Whether the Snakemake named in :data:`ENV` ran on this host and no longer runs."""
    named = _announced()
    return named is not None and _gone(*named)


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


def _libc_prctl():
    """libc's ``prctl`` (Linux), or None."""
    if not sys.platform.startswith("linux"):
        return None
    import ctypes

    try:
        fn = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong]
    fn.restype = ctypes.c_int
    return fn


def die_with_parent(sig: int = signal.SIGKILL, parent: int | None = None, prctl=None) -> bool:
    """Ask the kernel to send this process ``sig`` when its parent (the thread that started it)
    exits. ``parent``: the PID the parent must have; if it already died (the process has
    another parent now) the process exits at once with status 137. False where the kernel
    offers no such thing (then nothing is set)."""
    prctl = prctl or _libc_prctl()
    if prctl is None or prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0) != 0:
        return False
    if parent is not None and os.getppid() != parent:  # it died before the signal was set
        os._exit(137)
    return True


def _kill_children() -> None:
    import psutil

    with contextlib.suppress(psutil.Error):
        for child in psutil.Process().children(recursive=True):
            with contextlib.suppress(psutil.Error):
                child.kill()


def _kill_descendants_and_exit(*_) -> None:
    """Kill every descendant, round after round (orphans come back to a subreaper), reap them,
    and exit with status 137. The signal comes once for each of the parent's threads as they
    exit (the child is handed to the next thread of the dying process each time), so later
    ones are ignored: a handler run again inside itself (within an import, say) would fail
    halfway and leave the descendants running. psutil is imported before the handler is set."""
    import psutil

    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    try:
        for _round in range(REAP_ROUNDS):
            _kill_children()
            with contextlib.suppress(ChildProcessError):
                while os.waitpid(-1, os.WNOHANG)[0] > 0:
                    pass
            with contextlib.suppress(psutil.Error):
                if not psutil.Process().children():
                    break
            time.sleep(0.01)
    finally:
        os._exit(137)


def _poll(target, poll_s: float) -> None:
    created = target.create_time()

    def loop():
        while True:
            time.sleep(poll_s)
            if _gone(target.pid, created):  # also a PID reused by another process
                _kill_children()
                os._exit(137)

    threading.Thread(target=loop, name="avoa-jobguard", daemon=True).start()


def watch(poll_s: float = POLL_S, sig: int = signal.SIGKILL):
    """Tie this process to its Snakemake (once per process): by the kernel where it is the
    parent (``sig`` is then what the job receives when it dies), by a poll otherwise. Returns
    the Snakemake's PID or None.

    The announced Snakemake (:data:`ENV`) is compared with the parent's PID first, before any
    look at command lines: a Snakemake that is being killed at that instant has no command line
    to read any more, and the job would take it for no Snakemake at all and run on unguarded."""
    if _STARTED:
        return _STARTED[0][0]
    named = _announced()
    if named is not None and named[0] == os.getppid() and die_with_parent(sig, named[0]):
        _STARTED.append((named[0], "kernel"))
        return named[0]
    if named is not None and _gone(*named):  # its Snakemake died before the job looked
        _kill_children()
        os._exit(137)
    target = snakemake_ancestor()
    if target is None:
        _STARTED.append((None, "none"))
        return None
    if target.pid == os.getppid() and die_with_parent(sig, target.pid):
        _STARTED.append((target.pid, "kernel"))
    else:
        _STARTED.append((target.pid, "poll"))
        _poll(target, poll_s)
    return target.pid


def how() -> str:
    """How this process is tied to its Snakemake: ``kernel``, ``poll``, ``none`` (no Snakemake
    above it) or ``""`` (:func:`watch` not called)."""
    return _STARTED[0][1] if _STARTED else ""


def _child_dies_with_guard(guard: int, prctl):
    """The function a child runs before CMD: SIGKILL when the guard's thread that started it
    exits; exit at once if the guard is already gone."""

    def preexec():
        if prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0 and os.getppid() != guard:
            os._exit(137)

    return preexec


def main(argv=None) -> int:
    """Run a command under the watch; its exit status is ours. ``--log FILE``: the command's
    standard output and error go to FILE (so that a ``shell:`` rule's command is one simple
    command, which bash execs: the guard is then Snakemake's own child)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    log = None
    if argv[:1] == ["--log"] and len(argv) >= 2:
        log, argv = argv[1], argv[2:]
    if argv[:1] == ["--"]:
        argv = argv[1:]
    if not argv:
        print("usage: python -m avoa_pipeline.jobguard [--log FILE] CMD [ARG ...]",
              file=sys.stderr)  # fmt: skip
        return 2
    import psutil  # noqa: F401  (the handler must not import it while a signal comes)

    prctl = _libc_prctl()
    if prctl is not None:
        prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)  # orphaned descendants come back to us
        signal.signal(signal.SIGTERM, _kill_descendants_and_exit)
    watch(sig=signal.SIGTERM if prctl is not None else signal.SIGKILL)
    preexec = _child_dies_with_guard(os.getpid(), prctl) if prctl is not None else None
    with open(log, "w") if log else contextlib.nullcontext() as out:
        kw = {"stdout": out, "stderr": subprocess.STDOUT} if out is not None else {}
        return subprocess.call(argv, preexec_fn=preexec, **kw)


if __name__ == "__main__":
    sys.exit(main())
