"""Command line: ``python -m avoa_pipeline COMMAND ...``, one module ``commands/<command>.py`` each.

Commands: fit, generate, recovery, convert, diagnose, simulate, export, estimate, and the
real-data group ``real`` (``--help`` says more). ``main`` knows no command by name: each
declares its arguments, its run and the output it locks (``commands/registry.py``).

Expected errors (bad arguments, config or data) print one line on stderr and exit 2 without a
traceback, and write no output file.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys

os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")
# one BLAS thread (set before numpy loads): scipy's least_squares and L-BFGS-B call BLAS on small
# matrices, and spinning BLAS threads on a busy 2-core machine made a diagnosis up to 30x slower
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

# after the BLAS threads are set
from . import commands
from .commands.options import Parser
from .errors import UserError

PROG = "avoa_pipeline"


def build_parser(group: str | None = None, prog: str = PROG) -> Parser:
    """The parser of every registered command, or of one group's (``real``) on its own."""
    if group is None:
        p = Parser(prog=prog, description=__doc__.splitlines()[0])
    else:
        cmd = commands.REGISTRY[None, group]
        p = Parser(prog=prog, description=cmd.description,
                   formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
        cmd.arguments(p)
    commands.add_commands(p, group)
    return p


def main(argv=None, group: str | None = None, prog: str = PROG) -> int:
    """Run one command (of ``group`` alone, under ``prog``: the ``.real`` alias): 0, or 2 after
    one line on stderr."""
    from .io import output_lock

    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args = build_parser(group, prog).parse_args(argv)
        cmd = args.command_
        # one run at a time per output: the lock is held from before the first check to the
        # last rename (io.output_lock); what a command locks is its own declaration
        lock = contextlib.nullcontext()
        if cmd.output is not None:
            out, folder = cmd.output(args)
            lock = output_lock(out, folder=folder, command=" ".join([prog, *argv]))
        with lock:
            cmd.run(args)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        # a file the user named that the system refuses (a name too long, a symlink loop) where
        # no reader checked it first: still one line naming it; an OSError naming no file is a
        # bug and keeps its traceback
        if exc.filename is None:
            raise
        print(f"error: {exc.filename}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    return 0
