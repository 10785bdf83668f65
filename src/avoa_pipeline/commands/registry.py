"""The command registry: a command is its name, its arguments and its run, registered by its own
module (as ``optimizers.register`` registers an algorithm), so the CLI's ``main`` knows none of
them by name."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import NamedTuple


def out_file(args) -> tuple[str, bool]:
    """Most commands write the file ``--out`` (and files named after it): its lock."""
    return args.out, False


class Command(NamedTuple):
    """One subcommand. ``parents`` are parent parsers whose options come before the command's
    own, ``parents_after`` those whose options come after them (so each ``--help`` lists its
    options in the order a reader needs them). ``output(args)`` is the (path, is a folder) whose
    lock the run holds (``io.output_lock``); ``output=None``: the command takes no lock. A
    command with ``run=None`` is a group: its subcommands are those registered with ``group=``
    its name. (A NamedTuple, not a dataclass: ``dataclasses`` costs ``--help`` its import.)"""

    name: str
    help: str
    arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], None] | None
    group: str | None = None
    parents: tuple = ()
    parents_after: tuple = ()
    output: Callable[[argparse.Namespace], tuple[str, bool]] | None = out_file
    description: str | None = None


REGISTRY: dict[tuple[str | None, str], Command] = {}
"""Every command keyed by (its group or None, its name), in the order ``--help`` lists them."""


def register(name: str, help: str, *, arguments, group=None, **options):
    """Register the decorated ``run(args)`` as the command ``name``; ``options`` are the other
    fields of :class:`Command`."""

    def deco(run):
        if (group, name) in REGISTRY:
            raise ValueError(f"command {name!r} registered twice")
        REGISTRY[group, name] = Command(name, help, arguments, run, group, **options)
        return run

    return deco


def add_commands(parser: argparse.ArgumentParser, group: str | None = None) -> None:
    """The subcommands of ``group`` (None: the top level) into ``parser``; each leaf's parser
    sets ``args.command_`` to its :class:`Command` (the innermost one wins)."""
    sub = parser.add_subparsers(dest="command", required=True, parser_class=type(parser))
    for cmd in (c for c in REGISTRY.values() if c.group == group):
        extra = {}
        if cmd.description is not None:
            extra = {"description": cmd.description,
                     "formatter_class": argparse.RawDescriptionHelpFormatter}  # fmt: skip
        p = sub.add_parser(cmd.name, help=cmd.help, parents=list(cmd.parents), **extra)
        cmd.arguments(p)
        for parent in cmd.parents_after:
            # what ArgumentParser(parents=...) does, after the command's own options
            p._add_container_actions(parent)
        if cmd.run is None:
            add_commands(p, cmd.name)
        else:
            p.set_defaults(command_=cmd)
