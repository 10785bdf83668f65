"""What a command that runs a fitted model reads: the model (``FittedModel.load``, its one
refusal) and the record it runs on, checked together (``simulate``, ``export``, ``estimate``)."""

from __future__ import annotations

from .errors import UserError


def read_model_and_record(model_path, data, *, soc0=None, cycler=None, current_sign=None,
                          predicts: bool = False, rest_ok: bool = False):  # fmt: skip
    """(model, ``records.Checked`` or None where ``data`` is None): ``soc0`` in [0, 1]; the
    record's units against the model's capacity; a temperature for a model whose law reads one
    (unless the caller ``predicts`` one: ``ambient.cell_temperature``); ``rest_ok``: a record
    that only rests is read (``estimate``)."""
    import numpy as np

    from . import inputs
    from .model.fitted import FittedModel

    if soc0 is not None and not (np.isfinite(soc0) and 0.0 <= soc0 <= 1.0):
        raise UserError(f"--soc0 must lie in [0, 1], got {soc0}")
    model = FittedModel.load(model_path)
    if data is None:
        return model, None
    rec = inputs.read_record(data, cycler=cycler, current_sign=current_sign,
                             rest_ok=rest_ok)  # fmt: skip
    from .ambient import needs_temperature

    check_units(model, rec, rest_ok)
    needs_t = needs_temperature(model)
    if needs_t and "temperature_c" not in rec.frame.columns and not predicts:
        raise UserError(f"{data}: missing column 'temperature_c' (the model has "
                        f"{', '.join(needs_t)})")  # fmt: skip
    return model, rec


def check_units(model, rec, rest_ok: bool = False) -> None:
    """A checked record's units against a fitted model's capacity (``records.check_scale``): the
    capacity tells the units the record alone cannot (minutes, mA)."""
    from . import records
    from .model.ecm import IDX

    records.check_scale(rec.frame, rec.source, float(10.0 ** model.x[IDX["lq"]]),
                        rest_ok=rest_ok)  # fmt: skip


def prediction_frame(frame, model_v, temp_c, temperature_source):
    """What ``simulate`` writes (and ``api.Model.simulate`` returns): time_s, voltage_v,
    model_v, error_mv, the cell temperature the model ran on and where it came from (and the
    record's measured temperature_c where it has one)."""
    import numpy as np
    import pandas as pd

    out = pd.DataFrame({
        "time_s": frame["time_s"], "voltage_v": frame["voltage_v"], "model_v": model_v,
        "error_mv": 1e3 * (model_v - frame["voltage_v"].to_numpy()),
        "temperature_c_model": np.nan if temp_c is None else temp_c,
        "temperature_source": temperature_source,
    })  # fmt: skip
    if "temperature_c" in frame.columns:
        out["temperature_c"] = frame["temperature_c"]
    return out
