"""A fitted model exported to files, checked and written all or none: PyBaMM's parameter
module (``interop.pybamm``), or a BMS lookup table with its sidecar (``interop.table``).
``export`` calls these and prints what they return; ``out`` and the other paths are as the user
gave them (the messages name them so)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..errors import UserError


@dataclass(frozen=True)
class TableFiles:
    model: object  # the FittedModel
    csv: Path
    sidecar: Path
    side: dict  # the sidecar's content: the grid, the columns, the interpolation error


def write_table(model_path, out, soc_grid: str | None = None,
                temperatures: str | None = None) -> TableFiles:  # fmt: skip
    """The table (``out``, a .csv) and its sidecar, on the SOC grid and temperatures given as
    comma-separated text (``--soc-grid``, ``--temperatures``; None: the table's defaults)."""
    import json

    from .. import records
    from ..io import atomic_paths, check_output, sidecar_of
    from ..model_inputs import read_model_and_record
    from . import table

    csv = Path(out)
    if csv.suffix != ".csv":
        raise UserError(f"--out {out}: the table is a CSV; end it .csv")
    check_output(csv, inputs=[model_path])
    check_output(sidecar_of(csv), inputs=[model_path], what="--out's sidecar")
    soc = temps = None
    if soc_grid is not None:
        soc = table.parse_grid(soc_grid, "--soc-grid", table.SOC_RANGE, "")
    if temperatures is not None:
        temps = table.parse_grid(temperatures, "--temperatures",
                                 records.TEMPERATURE_RANGE_C, "°C")  # fmt: skip
    model, _ = read_model_and_record(model_path, None)
    model.check_cell(None, None, model_path)  # what simulate and export --to pybamm refuse
    frame, side = table.export_table(model, model_path, soc, temps)
    with atomic_paths(csv, sidecar_of(csv)) as (tmp, tmp_side):
        frame.to_csv(tmp, index=False, float_format="%.10g")
        tmp_side.write_text(json.dumps(side, indent=1, ensure_ascii=False) + "\n")
    return TableFiles(model, csv, sidecar_of(csv), side)


@dataclass(frozen=True)
class PybammFiles:
    model: object  # the FittedModel as read
    export: object  # interop.pybamm's export: the module's text, the model exported, the cost
    options: dict  # the module's PyBaMM model options
    check: dict | None  # PyBaMM on the record against our simulator, where a record was given
    ambient: float | None  # the record's ambient where the thermal state was compared
    module: Path
    cost: Path  # what dropping elements costs on the record (written only with a cost)


def write_pybamm(model_path, out, *, record=None, soc0=None, drop_unsupported=False,
                 predict_temperature=False, cycler=None,
                 current_sign=None) -> PybammFiles:  # fmt: skip
    """The PyBaMM parameter module (``out``, a .py), loaded by PyBaMM before it is written; on a
    ``record``, PyBaMM runs it there against our simulator first; with ``drop_unsupported``, the
    elements PyBaMM's Thevenin model lacks are dropped and what that costs on the record is
    written beside it (``out`` with .dropped.csv)."""
    import contextlib

    from ..ambient import export_ambient
    from ..io import atomic_path, check_output
    from ..model_inputs import read_model_and_record
    from . import pybamm as to_pybamm

    module = Path(out)
    if module.suffix != ".py":
        raise UserError(f"--out {out}: the PyBaMM parameters are a Python module; end it .py")
    cost_path = module.with_suffix(".dropped.csv")
    check_output(module, inputs=[model_path, record])
    check_output(cost_path, inputs=[model_path, record], what="--out's cost file")
    model, rec = read_model_and_record(model_path, record, soc0=soc0, cycler=cycler,
                                       current_sign=current_sign, predicts=True)  # fmt: skip
    to_pybamm.check_one_set(model, model_path)
    ambient = export_ambient(model, rec, model_name=model_path, record_name=record,
                             predict=predict_temperature)  # fmt: skip
    to_pybamm.check_exportable(model, model_path, drop_unsupported)
    frame = None if rec is None else rec.frame
    to_pybamm.require_pybamm()
    ex = to_pybamm.export(model, model_path, soc0, frame, record, drop_unsupported, module.name)
    loaded = to_pybamm.load_source(ex.text)
    options, _ = to_pybamm.build(loaded)  # it loads before it is written
    # on a record, PyBaMM runs the module before it is written: its voltage against ours
    check = None
    if ambient is not None:  # the thermal state, from the record's ambient, against heat.py's
        check = to_pybamm.thermal_agreement(loaded, ex.model, frame, ex.initial_soc, ambient)
    elif frame is not None:
        check = to_pybamm.agreement(loaded, ex.model, frame, ex.initial_soc)
    with (
        atomic_path(module) as tmp,
        atomic_path(cost_path) if ex.cost is not None else contextlib.nullcontext() as cost_tmp,
    ):
        tmp.write_text(ex.text)
        if ex.cost is not None:
            ex.cost.to_csv(cost_tmp, index=False)
    return PybammFiles(model, ex, options, check, ambient, module, cost_path)
