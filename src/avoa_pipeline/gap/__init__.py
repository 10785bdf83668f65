"""Sim-to-real gap diagnosis: where a model misses measured voltage, which unmodelled effect
explains it, and how much adding that effect helps (see docs/gap-diagnosis.md)."""

# One name per effect, used by the diagnosis (candidate models), the withheld-effect generator,
# the CLI, the JSON output and the workflow's file names.
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
