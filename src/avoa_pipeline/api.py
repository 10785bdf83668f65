"""The Python API (issue 39): what the commands do, returning frames and objects instead of
writing files, for a notebook (docs/api.md).

    from avoa_pipeline import diagnose, load_model, read_record

``read_record`` is the input layer's (``inputs.read_record``: a canonical CSV, or a cycler's
export, checked once); ``diagnose`` is the one diagnose pipeline (``diagnosis.diagnose``);
``load_model`` wraps a model.json (``model.fitted.FittedModel.load``, its one refusal) in a
:class:`Model` that simulates, estimates and exports as ``simulate``, ``estimate`` and
``export`` do. The wrapper lives here, above ``estimate.py`` and ``interop/``, not on
``FittedModel``: ``model/`` is a lower layer than both. Every refusal is the commands' one-line
DataError or UserError.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from .names import CURRENT_SIGNS


def read_record(path, *, cycler: str | None = None, current_sign: str = CURRENT_SIGNS[0],
                rest_ok: bool = False):  # fmt: skip
    """One checked record (``records.Checked``: ``.frame``, ``.source``, ``.warnings``) of a
    canonical CSV or, with ``cycler``, of that cycler's raw export; ``rest_ok``: a record that
    only rests passes (``estimate`` reads one)."""
    from . import inputs

    return inputs.read_record(str(path), cycler=cycler, current_sign=current_sign,
                              rest_ok=rest_ok)  # fmt: skip


def load_model(path) -> Model:
    """The model in a model.json (``FittedModel.load``: checked before any of it is used)."""
    from .model.fitted import FittedModel

    return Model(FittedModel.load(path), str(path))


@dataclass
class Model:
    """A fitted model (``fitted``: the ``FittedModel``; ``source``: its file, named in
    messages) with the commands' uses of it."""

    fitted: object  # model.fitted.FittedModel
    source: str = "model.json"

    def record(self, record, rest_ok: bool = False):
        """A record of this model's cell, checked: a path (:func:`read_record`), a
        ``records.Checked`` or a frame (``records.check``, named by ``attrs["source"]``), then
        its units against the model's capacity (``records.check_scale``: minutes, mA)."""
        import pandas as pd

        from . import records
        from .model_inputs import check_units

        if isinstance(record, str | Path):
            rec = read_record(record, rest_ok=rest_ok)
        elif isinstance(record, pd.DataFrame):
            name = str(record.attrs.get("source") or "frame")
            rec = records.check(record, name, rest_ok=rest_ok)
        elif isinstance(record, records.Checked):
            rec = record
        else:
            raise TypeError(f"a record is a path, a records.Checked or a DataFrame, not "
                            f"{type(record)!r}")  # fmt: skip
        check_units(self.fitted, rec, rest_ok)
        return rec

    def simulate(self, record, soc0: float | None = None, ambient_c: float | None = None):
        """The model's voltage on a record, as ``simulate`` writes it: a frame of ``time_s``,
        ``voltage_v``, ``model_v``, ``error_mv``, ``temperature_c_model``,
        ``temperature_source`` (and the record's ``temperature_c``). The cell temperature is the
        command's rule (``ambient.cell_temperature``): the record's where it has one; predicted
        by the model's heat block from ``ambient_c`` where given (as ``--ambient-c
        --predict-temperature``), else, where the model needs a temperature the record lacks,
        from the record's sidecar's ambient. A model of per-temperature sets
        (``by_temperature``) runs its parameters at the record's ambient
        (``ambient.model_at_ambient``: ``ambient_c``, else the sidecar's, else the first
        temperature sample); on a record with ``temperature_c``, ``ambient_c`` then chooses the
        parameters and the measured temperature still runs, as in ``simulate``."""
        import numpy as np

        from .ambient import cell_temperature, heat_ambient, model_at_ambient
        from .errors import UserError
        from .model_inputs import prediction_frame

        if soc0 is not None and not (np.isfinite(soc0) and 0.0 <= soc0 <= 1.0):
            raise UserError(f"soc0 must lie in [0, 1], got {soc0}")
        rec = self.record(record)
        fitted, _ = model_at_ambient(self.fitted, rec, model_name=self.source,
                                     data_name=rec.source, ambient_c=ambient_c)  # fmt: skip
        ambient_c = heat_ambient(self.fitted, rec, ambient_c)  # the API predicts iff ambient_c
        temp_c, where, _ = cell_temperature(
            fitted, rec, model_name=self.source, data_name=rec.source, ambient_c=ambient_c,
            predict=ambient_c is not None, soc0=soc0)  # fmt: skip
        run = rec.frame if temp_c is None else rec.frame.assign(temperature_c=temp_c)
        v = fitted.predict(run, soc0=soc0, source=self.source)
        return prediction_frame(rec.frame, v, temp_c, where)

    def estimate(self, record, soc0: float | None = None, bias_a: float = 0.0,
                 reference_soc0: float | None = None, noise: str = "expected-error",
                 adapt: bool = True, bms_events: bool = False,
                 reference_full: bool = False):  # fmt: skip
        """The SOC filter on a record (``estimate.estimate_record``): its ``Result``, with
        ``.frame`` (time_s, soc, soc_sd, model_v, innovation_v, ...) and ``.summary`` (what
        ``estimate`` writes beside its CSV). ``soc0``: the start's guess (default: the library's
        rule on the record's opening); ``bias_a``: added to the current the filter reads;
        ``reference_soc0``: the known start, for the errors; ``noise``: "expected-error" (the
        model's error on other profiles; a model without it runs the other rule, said in
        ``.warnings`` and ``.summary["noise"]["rule"]``) or "training-residual"; ``adapt``:
        widen the error from what the filter attributes to it (docs/soc-filter.md);
        ``bms_events``: the ends of CC-CV charges and the lower cut-off as pseudo-measurements
        (``.summary["bms_events"]``); ``reference_full``: the reference counted from SOC = 1 at
        every CC-CV end (docs/soc-filter.md part 5). A record that only rests is read. A model
        of per-temperature sets runs its parameters at the record's ambient (the sidecar's, else
        its first temperature sample; ``ambient.model_at_ambient``)."""
        from . import estimate
        from .ambient import model_at_ambient
        from .errors import UserError
        from .model import heat

        rec = self.record(record, rest_ok=True)
        fitted, _ = model_at_ambient(self.fitted, rec, model_name=self.source,
                                     data_name=rec.source)  # fmt: skip
        limit = estimate.bias_limit_a(fitted, rec.frame["current_a"].to_numpy())
        if not abs(bias_a) <= limit:  # NaN fails too
            raise UserError(f"bias_a {bias_a:g} A: beyond the currents of {rec.source} (|I| at "
                            f"most {limit:.4g} A)")  # fmt: skip
        return estimate.estimate_record(fitted, rec.frame, soc0, bias_a, reference_soc0,
                                        source=self.source, noise=noise, adapt=adapt,
                                        bms_events=bms_events,
                                        reference_full=reference_full,
                                        ambient=heat.ambient_if_any(rec))  # fmt: skip

    def export(self, to: str = "pybamm", *, record=None, soc0: float | None = None,
               drop_unsupported: bool = False, soc=None, temperature_c=None,
               file_name: str = "cell.py"):  # fmt: skip
        """``to="pybamm"``: the PyBaMM parameter module's source (``interop.pybamm.export``;
        ``interop.pybamm.load_source`` loads it), its initial SOC from ``record`` unless
        ``soc0``; ``to="table"``: the BMS lookup table (``interop.table.export_table``) as a
        frame, its sidecar in ``.attrs["sidecar"]``, on the grids ``soc`` and
        ``temperature_c`` (defaults: the export's)."""
        from .errors import UserError

        if to == "table":
            from .interop import table

            if record is not None or soc0 is not None or drop_unsupported:
                raise UserError("record, soc0 and drop_unsupported apply to to='pybamm'")
            self.fitted.check_cell(None, None, self.source)  # what simulate refuses
            frame, side = table.export_table(self.fitted, self.source, soc, temperature_c)
            frame.attrs["sidecar"] = side
            return frame
        if to != "pybamm":
            raise UserError(f"to must be 'pybamm' or 'table', got {to!r}")
        if soc is not None or temperature_c is not None:
            raise UserError("soc and temperature_c apply to to='table'")
        from .interop import pybamm as to_pybamm

        rec = None if record is None else self.record(record)
        to_pybamm.check_exportable(self.fitted, self.source, drop_unsupported)
        to_pybamm.require_pybamm()
        frame, name = (None, None) if rec is None else (rec.frame, rec.source)
        ex = to_pybamm.export(self.fitted, self.source, soc0, frame, name, drop_unsupported,
                              file_name)  # fmt: skip
        return ex.text
