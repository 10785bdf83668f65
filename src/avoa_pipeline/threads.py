"""How many threads the package uses, decided in one place (issue 42, "A thread policy").

Two kinds of threads run the package's work:

- the paper's population kernel splits one call's rows into blocks on numba's threads
  (``kernel.ise_population``, through ``battery.ise``);
- a diagnosis fits independent models on Python threads (``selection.each``).

Both stay within what the process was given: :func:`use` sets it (a workflow job's ``threads:``,
by ``jobs.start``; the CLI's ``--threads``), ``NUMBA_NUM_THREADS`` caps numba's threads, and
the cores the process may run on (its CPU affinity: ``taskset``, a cluster's allocation) cap
both. The kernel's threads are used only where one call pays for them on free cores
(:data:`PARALLEL_MIN_WORK`, :data:`MIN_BLOCK_ROWS`, both measured). On cores that other work
holds, a call split over threads waits for the thread it holds (a population of 20 on two
threads took 24-49× as long as on one, 600 rows 2.2×), which no threshold avoids: a job's
threads must be cores it holds (Snakemake's ``threads:``).

Hand-written because numba's own setting is per Python thread (``numba.set_num_threads`` holds
for the thread that calls it; a diagnosis's worker threads would start again from
``NUMBA_NUM_THREADS``) and knows nothing of the affinity or of the work of a call. It imports
numba only where a kernel call asks (``jobs.start`` calls :func:`use` in every job, and a table
or an import job would pay numba's import, about 0.5 s, for nothing).
"""

from __future__ import annotations

import os

PARALLEL_MIN_WORK = 20_000
"""Candidate-samples (rows × samples) of one kernel call below which it runs on the calling
thread. Measured (``benchmarks/bench_threads.py`` under ``chrt -f 1``, the two cores free of
other work, docs/benchmarks.md "A thread policy"): in blocks of 16 rows or more, two threads
were as fast as one at 6,400 candidate-samples (32 rows × 200 samples, 1.01) and faster from
12,800 on (0.75; 0.45-0.57 from 2·10⁵ on); 20,000 keeps a margin. On a machine whose cores are
busy, two threads lost at every size measured (2.2× at 600 rows × 5,701 samples): a job's
threads should be cores it holds (``jobs.start``, Snakemake's ``threads:``)."""
MIN_BLOCK_ROWS = 16
"""Rows of a block at least. The kernel runs a block's candidates in SIMD lanes and ran the rows
past the last full vector one at a time, so blocks of 10-12 rows cost more than their half: 20
and 24 rows on two threads took 1.5-1.8× as long as on one, at every record length from 500 to
20,000 samples, while 32 rows (two blocks of 16) took 0.56-0.78× (same measurement). Measured
before the kernel padded its blocks to whole vectors (``kernel.LANES``, merged the same day),
which makes short blocks cheaper; not measured again since. Earlier 4, which split a
population of 20 in two."""

_given: int | None = None  # set by use(); None: every core this process may run on


def cores() -> int:
    """The cores this process may run on: its CPU affinity (``taskset``, a cluster's allocation),
    or the CPU count where the platform has no affinity."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def given() -> int:
    """The threads this process may use: what :func:`use` gave it, never more than its cores."""
    return min(_given or cores(), cores())


def use(n: int | None) -> int:
    """Give this process ``n`` threads (``None``: all its cores): the diagnosis's fits and the
    kernel's blocks then use at most that many. Returns the threads given (capped at the
    cores)."""
    global _given
    if n is not None and n < 1:
        raise ValueError(f"threads must be positive, got {n}")
    _given = None if n is None else int(n)
    return given()


def kernel_blocks(rows: int, samples: int) -> int:
    """Blocks, one per numba thread, for one population-kernel call of ``rows`` candidates on
    ``samples`` samples; 1: the calling thread alone, no thread pool (cheaper, and safe to run
    from several Python threads). Threads only where the call's work pays for them
    (:data:`PARALLEL_MIN_WORK`, :data:`MIN_BLOCK_ROWS`), never more than :func:`given` nor
    numba's threads (``NUMBA_NUM_THREADS``, ``numba.set_num_threads`` in the calling thread)."""
    if rows * samples < PARALLEL_MIN_WORK or rows < 2 * MIN_BLOCK_ROWS:
        return 1
    import numba  # loaded already: the caller runs the kernel

    return max(1, min(numba.get_num_threads(), given(), rows // MIN_BLOCK_ROWS))
