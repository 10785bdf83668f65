"""What the commands share: the parser (one-line usage errors), the argument types, the parent
parsers of options several commands take, the output checks. Imports nothing numerical
(``python -m avoa_pipeline --help`` stays fast; tested)."""

from __future__ import annotations

import argparse
import re

from ..errors import UserError
from ..names import CURRENT_SIGNS, CYCLERS

CYCLER_HELP = (
    "the data files (and --ocv, --validate) are this cycler's raw exports; a file already in the "
    "canonical columns is read as it is"
)


NUMBERS = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?(,\s*[-+]?(\d+\.?\d*|\.\d+)"
                     r"([eE][-+]?\d+)?)*,?$")  # fmt: skip
"""An argument that starts with a minus and is a number or a comma-separated list of them
(``-10,0,10``, ``-1e-3``): a value, not an option (argparse's own rule takes only ``-10`` and
``-.5``, so ``--temperatures -10,0,10`` was "expected one argument")."""


class Parser(argparse.ArgumentParser):
    """argparse with usage errors as one-line :class:`UserError` (exit 2, no usage block), and
    negative numbers and lists of numbers taken as values (:data:`NUMBERS`)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NUMBERS  # argparse's hook for what looks like a number

    def error(self, message):  # one line, exit 2 (argparse prints the usage block otherwise)
        raise UserError(f"{self.prog}: {message}")


def int_in(name: str, allowed=None):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if allowed is not None and value not in allowed:
            raise argparse.ArgumentTypeError(
                f"unknown {name} {value}; choose from {', '.join(map(str, allowed))}"
            )
        return value

    return parse


def number(name: str):
    def parse(text: str) -> float:
        try:
            return float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None

    return parse


def _parent() -> Parser:
    return Parser(add_help=False)  # a parent's -h would clash with its child's


SCENARIO_CASE = _parent()
"""The paper's grid cell (``fit``, ``generate``, ``recovery``)."""
SCENARIO_CASE.add_argument("--scenario", type=int_in("scenario", (1, 2, 3, 4)), required=True)
SCENARIO_CASE.add_argument("--case", type=int_in("case", (1, 2, 3, 4)), required=True)

CURRENT_SIGN = _parent()
"""The canonical CSVs' current convention (``simulate``, ``export``, ``estimate``; ``diagnose``
says more in its own help)."""
CURRENT_SIGN.add_argument("--current-sign", choices=CURRENT_SIGNS, default=CURRENT_SIGNS[0])

THREADS = _parent()
"""The commands whose work runs on threads (``fit``: the kernel's blocks; ``diagnose``: the
independent fits): the threads they may use (``threads.use``)."""
THREADS.add_argument("--threads", type=int_in("threads"), default=None,
                     help="threads to use (default: the cores this process may use)")  # fmt: skip


def use_threads(args) -> int:
    """Give the process ``--threads`` (``threads.use``; None: its cores), refused below 1."""
    from .. import threads

    if args.threads is not None and args.threads < 1:
        raise UserError(f"--threads must be positive, got {args.threads}")
    return threads.use(args.threads)


CYCLER = _parent()
"""Every command that reads a measured record reads a cycler's raw export too."""
CYCLER.add_argument("--cycler", choices=CYCLERS, default=None, help=CYCLER_HELP)


def config_path(args):
    """The config file a command reads (an input: no output may replace it)."""
    from .. import config

    return args.config if args.config is not None else config.DEFAULT_CONFIG


def csv_and_sidecar(out, inputs):
    """A command writing a CSV and its JSON sidecar: ``--out`` ends .csv, and neither file is an
    input (nor an input's sidecar) or unwritable. Both paths, checked before any work."""
    from pathlib import Path

    from ..io import check_output, sidecar_of

    out = Path(out)
    if out.suffix.lower() != ".csv":
        raise UserError(
            f"--out {out}: must end .csv (its JSON sidecar {out.stem}.json goes beside it)"
        )
    check_output(out, inputs=inputs)
    check_output(sidecar_of(out), inputs=inputs, what="--out's sidecar")
    return out, sidecar_of(out)
