"""Sim-to-real gap diagnosis: where a model misses measured voltage, which unmodelled effect
explains it, and how much adding that effect helps (see docs/gap-diagnosis.md)."""

from ..model import elements

EFFECTS = tuple(e.name for e in elements.REGISTRY.values() if e.withheld)
"""The elements the withheld-effect generator (``withheld.py``) makes records with, by the model
library's names (the diagnosis, the CLI, the JSON output and the workflow's file names use them)."""
VERDICTS = (*EFFECTS, "none")
"""What a withheld-effect dataset can hold (``withheld.py`` makes these, and controls)."""


def diagnoses() -> tuple[str, ...]:
    """What the diagnosis can name: every element of the model library, or none."""
    return (*elements.NAMES, "none")
