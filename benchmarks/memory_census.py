"""Bytes a sample each holder keeps alive during a diagnosis (issue 42: a long record's memory).

Runs ``python -m avoa_pipeline diagnose CSV --out DIR`` in this process and, at two points (the
first rung's judgement, after its hold-outs; the report's end, ``gap.diagnose._arrays``), counts
every array of at least 2 bytes a sample reachable from the running frames and from objects'
attributes, lists and dicts, each memory block once (an array's base chain followed to its
owner), and prints the bytes a sample per holder. Hand-written: tracemalloc sees the same arrays
but slows the fits about fourfold, and peak RSS alone does not say who holds what.

    PYTHONPATH=src .venv/bin/python benchmarks/memory_census.py REC.csv OUT_DIR
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as the CLI (before numpy loads)
os.environ.setdefault("OMP_NUM_THREADS", "1")

import collections
import gc
import sys

import numpy as np
import pandas as pd

from avoa_pipeline import selection
from avoa_pipeline.cli import main
from avoa_pipeline.gap import diagnose as gap_diagnose

MIN_BYTES_PER_SAMPLE = 2  # a block smaller than this is no per-sample holder (a fold's indices)


def _root(a: np.ndarray) -> np.ndarray:
    while isinstance(a.base, np.ndarray):
        a = a.base
    return a


def _holders(frame, n: int) -> dict[int, list]:
    """Per memory block (its owner's id): [bytes, the first name it was found under]."""
    seen: dict[int, list] = {}

    def add(a, label: str) -> None:
        if isinstance(a, np.ndarray) and (r := _root(a)).nbytes >= MIN_BYTES_PER_SAMPLE * n:
            seen.setdefault(id(r), [r.nbytes, label])

    def add_all(v, label: str) -> None:
        add(v, label)
        if isinstance(v, list | tuple):
            for x in v:
                add(x, f"{label}[]")

    while frame is not None:  # the frames' locals first: their names say most
        for k, v in list(frame.f_locals.items()):
            add_all(v, f"{frame.f_code.co_name}:{k}")
        frame = frame.f_back
    for o in gc.get_objects():
        d = None if isinstance(o, type) else getattr(o, "__dict__", None)
        if isinstance(d, dict):
            for k, v in d.items():
                add_all(v, f"{type(o).__name__}.{k}")
        elif isinstance(o, list | tuple):
            for x in o:
                add(x, type(o).__name__)
        elif isinstance(o, dict):
            for k, v in o.items():
                add(v, f"dict[{k!r}]"[:40])
    return seen


def census(tag: str, n: int) -> None:
    by, count = collections.Counter(), collections.Counter()
    for nbytes, label in _holders(sys._getframe(1), n).values():
        by[label] += nbytes
        count[label] += 1
    print(f"== {tag}: {sum(by.values()) / n:.0f} bytes a sample", flush=True)
    for label, nbytes in by.most_common(30):
        print(f"   {nbytes / n:7.1f} B/sample  x{count[label]:<3d} {label}", flush=True)


def run(csv: str, out: str) -> int:
    n = len(pd.read_csv(csv, usecols=[0]))
    judge, arrays, done = selection.judge, gap_diagnose._arrays, []

    def first_judge(ctx, ref, cands):
        if not done:
            done.append(True)
            census("first rung held out (its judgement)", n)
        return judge(ctx, ref, cands)

    def report_end(ctx, lad, rec, soc):
        census("the report's end", n)
        return arrays(ctx, lad, rec, soc)

    selection.judge, gap_diagnose._arrays = first_judge, report_end
    return main(["diagnose", csv, "--out", out])


if __name__ == "__main__":
    sys.exit(run(sys.argv[1], sys.argv[2]))
