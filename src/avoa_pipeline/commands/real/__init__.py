"""``python -m avoa_pipeline real ...``: the real-data imports and experiments, one module per
command, registered in the group ``real`` (``python -m avoa_pipeline.real`` is its alias)."""

from __future__ import annotations

from importlib import import_module

from ..registry import register

DESCRIPTION = """\
``python -m avoa_pipeline.real``: every real-data import and experiment without Snakemake.

    python -m avoa_pipeline.real list
    python -m avoa_pipeline.real panasonic-import 25degC/us06 --out us06.csv
    python -m avoa_pipeline.real panasonic-import --out us06.csv -- -10degC/us06
    python -m avoa_pipeline.real drive-cycles --out-dir DIR [--temperature 25degC]
    python -m avoa_pipeline.real samsung-import --temperature 20degC --out s20.csv
    python -m avoa_pipeline.real arrhenius --hppc 20degC=s20.csv ... --out-rc R --out-arrhenius A
    python -m avoa_pipeline.real nasa-import --out b0005.csv
    python -m avoa_pipeline.real fade --record b0005.csv --out-states S --out-fits F

``drive-cycles`` imports what it needs into ``DIR`` and runs experiment 1 as the workflow does
(one process, no pool): paper models, C/20 circuits, the diagnosis (training cycle + HPPC, the
C/20 test as OCV, the unseen cycles as validation), the gap comparison, the cross-cycle
diagnostic and the table. Expected errors print one line on stderr and exit 2;
nothing is half-written.
"""
"""The group's ``--help``, in the alias's words (the docs call it so)."""


def load_config(args) -> dict:
    """The group's ``--config``. Its commands take no lock (``output=None``): each writes through
    ``jobs.real``'s atomic writers, as the workflow's rules do."""
    from ... import config

    return config.load(args.config)


def arguments(ap) -> None:
    ap.add_argument("--config", default=None, help="config file (default: config/config.yaml)")


register("real", "every real-data import and experiment without Snakemake", arguments=arguments,
         output=None, description=DESCRIPTION)(None)  # fmt: skip

COMMANDS = ("list_records", "panasonic_import", "drive_cycles", "samsung_import", "nasa_import",
            "arrhenius", "fade")  # fmt: skip
"""The group's command modules, imported (so registered) in the order ``--help`` lists them."""

for _module in COMMANDS:
    import_module(f".{_module}", __name__)
