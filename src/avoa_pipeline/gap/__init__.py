"""Sim-to-real gap diagnosis: where a model misses measured voltage, which unmodelled effect
explains it, and how much adding that effect helps (see docs/gap-diagnosis.md)."""

# One name per effect, used by the withheld-effect generator, the diagnosis (the model library's
# element of the same name), the CLI, the JSON output and the workflow's file names.
EFFECTS = (
    "second_rc",
    "hysteresis",
    "butler_volmer",
    "thermal",
    "ocv_shape",
    "current_offset",
    "voltage_offset",
    "coulombic_efficiency",
)
VERDICTS = (*EFFECTS, "none")
"""What a withheld-effect dataset can hold (``withheld.py`` makes these, and controls)."""


def diagnoses() -> tuple[str, ...]:
    """What the diagnosis can name: every element of the model library, or none."""
    from ..model.ecm import EFFECTS as ELEMENTS

    return (*ELEMENTS, "none")
