"""A fitted model of one cell: its configuration, parameters, OCV table and bounds; saved as
``model.json``, loaded with checks, and run on any record of the cell.

The initial SOC of a record comes from the library's one rule (``ecm.soc0_from_voltage``: the
OCV at the first sample, corrected for the ohmic drop; hysteresis state 0), or is given.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .. import __version__
from ..errors import DataError
from ..records import VOLTAGE_RANGE_V
from . import ecm
from . import ocv as ocv_mod
from .ecm import IDX, Config, Knots, Record

FORMAT = "avoa-pipeline-model"
FORMAT_VERSION = 1


AT_BOUND = 1e-4
"""A fitted parameter within 1e-4 of its searched range (in the optimizer's internal coordinates)
of a bound is pressed against it: the bound stopped the fit, not the data, so the value is not a
finding (the records would have taken it further). Bounded least squares stops within about
1e-8 of the range from an active bound; 1e-4 leaves room for that and still lies below the values
records set (0.2 mΩ of a 0-2 Ω range, 0.06 % of a time constant over 5 decades)."""


@dataclass
class FittedModel:
    config: Config
    x: np.ndarray  # internal vector of the cell (per-record entries: those of the first record)
    knots: Knots
    tref_k: float
    bounds: dict[str, tuple[float, float]]  # internal names → the fit's bounds
    provenance: dict = field(default_factory=dict)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(n for n in self.config.names() if not ecm.PARAMS[n].per_record)

    def parameters(self) -> dict[str, float]:
        """Report-named physical values of the cell's parameters (initial states left out)."""
        out = ecm.report(self.x, self.names)
        P = ecm.to_physical(self.x)[0]
        grid = self.knots.grid()
        if "ocv_shape" in self.config.effects:
            d = P[ecm.D0 : ecm.D0 + ecm.N_KNOTS]
            for j, s in enumerate(grid):
                out[f"ocv_knot{j}_soc"] = float(s)
                out[f"ocv_d{j}_v"] = float(d[j])
        for element, col, key in (("r0_soc", ecm.L0, "r0"), ("r1_soc", ecm.L1, "r1")):
            if element in self.config.effects:
                factors = np.exp(P[col : col + ecm.N_KNOTS])
                for j, s in enumerate(grid):
                    out[f"{key}_knot{j}_soc"] = float(s)
                    out[f"{key}_knot{j}_factor"] = float(factors[j])
        return out

    def record(self, frame: pd.DataFrame) -> Record:
        return Record.from_frame(frame, tref_k=self.tref_k)

    def initial_soc(self, rec: Record) -> float:
        x = self.x.copy()
        x[IDX["h0"]] = 0.0
        return ecm.soc0_from_voltage(ecm.to_physical(x)[0], rec, self.knots, self.config.table)

    def simulate(self, frame: pd.DataFrame, soc0: float | None = None, traces: bool = False):
        """Model voltage for ``frame`` (a record of the same cell); with ``traces`` also the
        (5, n) state traces (SOC, h, RC voltage, thermal factor, current)."""
        rec = self.record(frame)
        x = self.x.copy()
        x[IDX["h0"]] = 0.0
        x[IDX["soc0"]] = self.initial_soc(rec) if soc0 is None else float(soc0)
        res = ecm.simulate_rows(rec, x, self.knots, self.config.table, self.config.load_ohm,
                                traces=traces)  # fmt: skip
        return (res[0][:, 0], res[1]) if traces else res[:, 0]

    def predict(self, frame: pd.DataFrame, soc0: float | None = None,
                source: str = "model.json") -> np.ndarray:  # fmt: skip
        """:meth:`simulate`, refused (DataError naming ``source``) where the model's voltage
        leaves one cell's range (``records.VOLTAGE_RANGE_V``): parameters that pass every bound
        one by one may still not describe a cell together."""
        v = self.simulate(frame, soc0=soc0)
        lo, hi = VOLTAGE_RANGE_V
        if not (np.all(np.isfinite(v)) and v.min() >= lo and v.max() <= hi):
            raise DataError(f"{source}: the model predicts {np.nanmin(v):.4g}..{np.nanmax(v):.4g}"
                            f" V, outside one cell's {lo:g}..{hi:g} V: its parameters do not "
                            "describe a cell")  # fmt: skip
        return v

    def at_bounds(self) -> list[dict]:
        """The cell's parameters pressed against a bound of their fit: within AT_BOUND of the
        searched range (internal coordinates, the optimizer's own) from either end."""
        flags = []
        for n in self.names:
            lo, hi = self.bounds[n]
            span = hi - lo
            if not span > 0:
                continue
            x = float(self.x[IDX[n]])
            near = {"lower": x - lo, "upper": hi - x}
            side = min(near, key=near.get)
            if near[side] <= AT_BOUND * span:
                rep = ecm.PARAMS[n].report
                value = self.parameters()[rep]
                plo, phi = self._physical_bounds(n)
                flags.append({"parameter": rep, "value": value, "bound": side,
                              "bounds": [plo, phi]})  # fmt: skip
        return flags

    # ------------------------------------------------------------------------------------------

    def to_json(self) -> dict:
        return {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "package_version": __version__,
            "ocv": self.config.ocv_kind,
            "effects": list(self.config.effects),
            "load_ohm": self.config.load_ohm,
            "parameters": self.parameters(),
            "bounds": {ecm.PARAMS[n].report: self._physical_bounds(n) for n in self.names},
            "knots": {"lo": self.knots.lo, "step": self.knots.step},
            "tref_k": self.tref_k,
            "ocv_table": None if self.config.table is None else ocv_mod.to_json(self.config.table),
            "capacity_ah": float(10.0 ** self.x[IDX["lq"]]),
            "provenance": self.provenance,
        }

    def _physical_bounds(self, name: str) -> list[float]:
        lo, hi = self.bounds[name]
        t = ecm.PARAMS[name].transform
        if t == "log10":
            return [10.0**lo, 10.0**hi]
        if t == "log10_1m":
            return sorted([1.0 - 10.0**lo, 1.0 - 10.0**hi])
        return [lo, hi]

    def save(self, path) -> None:
        from ..io import atomic_path

        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(self.to_json(), indent=1, allow_nan=False) + "\n")

    @classmethod
    def from_json(cls, d: dict, source: str = "model.json") -> FittedModel:
        """A saved model, checked: its format and version, known elements, every parameter of
        the configuration present, finite and inside the bounds it was fitted in."""
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise DataError(f"{source}: field 'format': not an {FORMAT} file")
        if d.get("format_version") != FORMAT_VERSION:
            raise DataError(f"{source}: field 'format_version': {d.get('format_version')!r}; this "
                            f"version ({__version__}) reads version {FORMAT_VERSION}")  # fmt: skip
        try:
            table = ocv_mod.from_json(d["ocv_table"]) if d.get("ocv") == "table" else None
            config = Config(tuple(d["effects"]), table, d.get("load_ohm"))
        except (KeyError, TypeError, ValueError) as exc:
            raise DataError(f"{source}: field 'effects'/'ocv': {exc}") from None
        params, bounds_rep = d.get("parameters") or {}, d.get("bounds") or {}
        x = ecm.NEUTRAL.copy()
        bounds = {}
        for n in config.names():
            p = ecm.PARAMS[n]
            if p.per_record:
                continue
            rep = p.report
            if rep not in params or rep not in bounds_rep:
                raise DataError(f"{source}: field 'parameters.{rep}': missing")
            value = params[rep]
            lo, hi = bounds_rep[rep]
            if not (isinstance(value, int | float) and np.isfinite(value)):
                raise DataError(f"{source}: field 'parameters.{rep}': not a finite number")
            tol = 1e-9 * max(1.0, abs(hi - lo))
            if not lo - tol <= value <= hi + tol:
                raise DataError(f"{source}: field 'parameters.{rep}': {value:g} outside the "
                                f"bounds it was fitted in [{lo:g}, {hi:g}]")  # fmt: skip
            plo, phi = ecm.LIMITS[n]
            if not plo - 1e-9 * abs(plo) <= value <= phi + 1e-9 * abs(phi):
                raise DataError(f"{source}: field 'parameters.{rep}': {value:g} outside the "
                                f"library's physical range [{plo:g}, {phi:g}]")  # fmt: skip
            x[IDX[n]] = ecm.internal_value(rep, value)[1]
            bounds[n] = tuple(sorted((ecm.internal_value(rep, lo)[1],
                                      ecm.internal_value(rep, hi)[1])))  # fmt: skip
        knots = Knots(float(d["knots"]["lo"]), float(d["knots"]["step"]))
        return cls(config, x, knots, float(d["tref_k"]), bounds, d.get("provenance") or {})

    @classmethod
    def load(cls, path) -> FittedModel:
        from ..io import read_json

        return cls.from_json(read_json(path), str(path))


@dataclass
class Fit:
    """A configuration fitted to records: the model, each record's rows, the training RMSE."""

    model: FittedModel
    X: np.ndarray  # per-record internal rows (each record's initial state, by the rule, its own)
    train_rmse_mv: float
    nfev: int


def fit_model(frames, config: Config, capacity_ah: float | None = None,
              soc0: float | None = None, provenance: dict | None = None) -> Fit:  # fmt: skip
    """Fit ``config`` to one or several records of one cell: the base by multi-start least
    squares, then the configuration's elements one at a time, each started from the previous
    fit (as the diagnosis's ladder adds them). Shared cell parameters, each record started by
    the library's rule (``fitting.structure``) and counting alike; one reference temperature
    (the mean over all records). The training RMSE is the records-alike one (the root of the
    mean over records of each record's mean squared error)."""
    from . import fitting

    frames = [frames] if isinstance(frames, pd.DataFrame) else list(frames)
    temps = [f["temperature_c"].to_numpy() for f in frames if "temperature_c" in f.columns]
    tref = float(np.mean(np.concatenate(temps))) + 273.15 if temps else None
    recs = [Record.from_frame(f, tref_k=tref) for f in frames]
    base_cfg = Config((), config.table, config.load_ohm)
    fix_q, fix_s = capacity_ah is not None, soc0 is not None
    st = fitting.structure(recs, base_cfg, None, fix_q, fix_s)
    res = fitting.best_of(recs, st, fitting.base_starts(recs, base_cfg, capacity_ah, soc0))
    knots = fitting.knots_for(recs, res.X)
    nfev, X, now = res.nfev, res.X, base_cfg
    for e in config.effects:
        now = now.with_effect(e)
        st = fitting.structure(recs, now, knots, fix_q, fix_s)
        res = fitting.best_of(recs, st, fitting.effect_starts(recs, X, e))
        nfev, X = nfev + res.nfev, res.X
    st = fitting.structure(recs, config, knots, fix_q, fix_s)
    X = fitting.complete(st, recs, X)
    b = fitting.bounds_for(recs)
    bounds = {n: b[n] for n in config.names() if not ecm.PARAMS[n].per_record}
    if fix_q:
        bounds["lq"] = (X[0, IDX["lq"]],) * 2
    mse = [float(np.mean((ecm.simulate_rows(rec, X[r], knots, config.table,
                                            config.load_ohm)[:, 0] - rec.v) ** 2))
           for r, rec in enumerate(recs)]  # fmt: skip
    model = FittedModel(config, X[0].copy(), knots, recs[0].tref_k, bounds, provenance or {})
    return Fit(model, X, 1e3 * float(np.sqrt(np.mean(mse))), nfev)
