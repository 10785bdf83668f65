"""The cell temperature a fitted model runs a record on: the record's measured one, or one
predicted from the ambient by the model's heat block (``model/heat.py``), and the ambient that
prediction starts from. ``simulate`` and ``export --to pybamm --record`` decide by these rules;
each refusal is one line naming what is missing. A model whose voltage needs no temperature may
still hold a heat block (docs/temperature-rule.md part 6): it predicts the cell temperature where
an ambient is at hand, and the voltage runs as without it.

``model_name`` and ``data_name`` are the paths as the user gave them (the messages name them)."""

from __future__ import annotations

from .errors import UserError


def needs_temperature(model) -> list[str]:
    """The model's elements whose law reads the cell temperature, sorted."""
    from .model import elements

    return sorted(e for e in model.config.effects if elements.get(e).needs_temperature)


def record_ambient(data_name, rec, ambient_c: float | None) -> tuple[float, str]:
    """(ambient °C, where from) for a prediction: ``ambient_c`` (``--ambient-c``), else the CSV's
    sidecar's ``ambient_temperature_c``; else a one-line refusal naming the missing field."""
    from .io import sidecar_of
    from .model import heat

    if ambient_c is not None:
        lo, hi = heat.AMBIENT_RANGE_C
        if not lo <= ambient_c <= hi:  # NaN fails too
            raise UserError(f"--ambient-c must lie in {lo:g}..{hi:g} °C, got {ambient_c}")
        return float(ambient_c), "--ambient-c"
    meta = _sidecar(data_name, rec)
    side = sidecar_of(data_name)
    if "ambient_temperature_c" not in meta:
        what = f"{side}: field 'ambient_temperature_c': missing" if meta else f"no sidecar {side}"
        raise UserError(f"{data_name}: no ambient to predict the cell temperature from ({what}); "
                        "give --ambient-c")  # fmt: skip
    where = f"{side}: field 'ambient_temperature_c'"
    return heat.check_ambient(meta["ambient_temperature_c"], where), "the sidecar"


def model_at_ambient(model, rec, *, model_name, data_name, ambient_c: float | None = None):
    """(the ordinary model to run ``rec`` with, the line that says so or None): for a model of
    per-temperature sets (``FittedModel.by_temperature``), its parameters at the record's
    ambient (``FittedModel.at_ambient``): ``ambient_c`` (``--ambient-c``), else the CSV's
    sidecar's ``ambient_temperature_c``, else its first temperature sample (``heat.ambient_of``);
    refused in one line where the record has none. An ordinary model is run as it is."""
    from .model import heat

    if model.by_temperature is None:
        return model, None
    if ambient_c is not None:
        ambient, where = record_ambient(data_name, rec, ambient_c)
    elif ("temperature_c" in rec.frame.columns
          or "ambient_temperature_c" in _sidecar(data_name, rec)):  # fmt: skip
        ambient, where = heat.ambient_of(rec)
    else:
        temps = ", ".join(f"{a:g}" for a, _ in model.by_temperature)
        raise UserError(f"{model_name}: field 'by_temperature': the model holds per-temperature "
                        f"parameter sets ({temps} °C), and {data_name} has no temperature_c and "
                        "no sidecar ambient_temperature_c to choose among them; give "
                        "--ambient-c")  # fmt: skip
    line = (f"{model_name}: parameters at ambient {ambient:g} °C ({where}): "
            f"{model.ambient_note(ambient)}")  # fmt: skip
    return model.at_ambient(ambient), line


def heat_ambient(model, rec, ambient_c: float | None, predict: bool = False) -> float | None:
    """The ambient the heat block is to predict the cell temperature from (``cell_temperature``'s
    ``ambient_c``): ``ambient_c``, except for a model of per-temperature sets on a record that
    measured its temperature and is not asked to predict it: the ambient then chose the set
    (:func:`model_at_ambient`), and the measured temperature runs. ``model``: as read, before
    :func:`model_at_ambient`."""
    measured = "temperature_c" in rec.frame.columns and not predict
    return None if model.by_temperature is not None and measured else ambient_c


def _sidecar(data_name, rec) -> dict:
    """The record's sidecar ({} where it was not read from a canonical CSV or has none)."""
    from .io import read_sidecar

    return read_sidecar(data_name) if rec.origin.get("read_as") == "canonical CSV" else {}


def unused_ambient(ambient_c: float | None, model_name, pred) -> list[str]:
    """An ambient given where nothing predicted a temperature from it (the model has no
    temperature law, so the record's run needs none, and no heat block to predict one): one
    warning line, as the option changed nothing (a record with temperature_c is refused in
    :func:`cell_temperature`)."""
    if ambient_c is None or pred is not None:
        return []
    return [f"--ambient-c {ambient_c:g}: ignored: {model_name} has no temperature law and no "
            "heat block, so no cell temperature is predicted from the ambient"]  # fmt: skip


def cell_temperature(model, rec, *, model_name, data_name, ambient_c=None, predict=False,
                     soc0=None):  # fmt: skip
    """``simulate``'s cell temperature: (°C per sample or None, what it is, the prediction or
    None). The record's measured ``temperature_c`` where it has one; predicted from the ambient
    by the model's heat block where it has none and the model needs one, or with ``predict``
    (``--predict-temperature``); refused where neither is possible. A model that needs none but
    holds a heat block predicts it where an ambient is at hand (``ambient_c`` or the sidecar's),
    its voltage unchanged (docs/temperature-rule.md part 6); else it runs without one."""
    from .model import heat
    from .model.ecm import T_DEFAULT_K

    has_t = "temperature_c" in rec.frame.columns
    needs_t = needs_temperature(model)
    if has_t and not predict:
        if ambient_c is not None:
            raise UserError(
                "--ambient-c: the record has temperature_c, which simulate uses; add "
                "--predict-temperature to predict from the ambient instead"
            )
        return rec.frame["temperature_c"].to_numpy(), "measured (the record's temperature_c)", None
    if not predict and not needs_t:  # the voltage needs none: predicted only where it can be
        default = f"the model has no temperature law: {T_DEFAULT_K - heat.KELVIN:g} °C in its 2RT/F"
        if model.heat is None:
            return None, f"none (no temperature_c; {default})", None
        if ambient_c is None and "ambient_temperature_c" not in _sidecar(data_name, rec):
            return None, f"none (no temperature_c, no ambient for the heat block; {default})", None
    if model.heat is None:
        why = (
            "--predict-temperature"
            if predict
            else f"{data_name} has no temperature_c and the model has {', '.join(needs_t)}"
        )
        raise UserError(f"{model_name}: field 'heat': missing ({why}; diagnose writes it when "
                        "its training records have a moving measured temperature)")  # fmt: skip
    ambient, where = record_ambient(data_name, rec, ambient_c)
    pred = heat.predict(model, model.heat, rec.frame, ambient, soc0=soc0)
    what = (f"predicted from ambient {ambient:g} °C ({where}) by {model_name}'s heat block, "
            f"{pred.passes} fixed-point passes")  # fmt: skip
    if not heat.temperature_readers(model):
        what += f" ({heat.VOLTAGE_BLIND})"
    return pred.temp_k - heat.KELVIN, what, pred


def export_ambient(model, rec, *, model_name, record_name, predict=False) -> float | None:
    """``export --to pybamm --record``'s temperature mode: the record's ambient (°C,
    ``heat.ambient_of``) where the module's thermal state is compared (``predict``, or a record
    without temperature_c and a model with a heat block; for a model that needs no temperature,
    only where the record's sidecar gives the ambient, as in :func:`cell_temperature`), else
    None (the measured temperature, as ``simulate`` uses it); refused where a model needs a
    temperature and neither is possible."""
    from .model import heat

    if predict and rec is None:
        raise UserError("--predict-temperature needs --record (where the comparison runs)")
    if rec is None:
        return None
    has_t = "temperature_c" in rec.frame.columns
    if has_t and not predict:
        return None
    if model.heat is None:
        needs_t = needs_temperature(model)
        if not predict and not needs_t:
            return None
        why = (
            "--predict-temperature"
            if predict
            else (f"{record_name} has no temperature_c and the model has {', '.join(needs_t)}")
        )
        raise UserError(f"{model_name}: field 'heat': missing ({why})")
    no_ambient = "ambient_temperature_c" not in _sidecar(record_name, rec)
    if not predict and not needs_temperature(model) and no_ambient:  # the voltage needs none
        return None
    return heat.ambient_of(rec)[0]
