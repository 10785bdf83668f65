"""A fitted model of one cell: its configuration, parameters, OCV table and bounds; saved as
``model.json``, loaded with checks, and run on any record of the cell.

The initial SOC of a record comes from the library's one rule (``ecm.soc0_from_voltage``: the
OCV at the first sample, corrected for the ohmic drop; hysteresis state 0), or is given.

A ``model.json`` is hand-editable, so loading it trusts nothing: one JSON Schema, a data file
(``schemas/model.schema.yaml``) whose ranges that the library owns are filled in from its own
tables (``ecm.PARAMS``, ``ecm.LIMITS``, ``ecm.EFFECTS``; :func:`model_schema`), checks every
field the writer writes for presence, JSON type (a boolean is not a number), finiteness, shape
and range before any number is used; what a schema cannot say (bounds in
order, a table that rises, values written for readers equal to what the parameters give)
follows in :meth:`FittedModel.from_json`. Every refusal is one line naming the file and the
field. Whether the parameters describe a cell *together* is judged by the voltage they predict
(:meth:`FittedModel.predict`), the one check ``simulate`` and ``export`` share.

A model carries the 95 % intervals of its fit (``model/intervals.py``; ``fit_model`` and the
diagnosis compute them): read back with every consistency a file can be held to (each value is
its parameter's, each flag what the bounds and the interval say), and their flags are warning
lines wherever the model is used. A model.json written before them (no ``intervals``) loads.

A model may carry a ``heat`` block (``model/heat.py``: the lumped thermal state that predicts
the cell temperature from the ambient; ``diagnose`` writes it where its training records allow):
checked like the rest (the schema's ``heat``, :func:`_check_heat`); a model.json without it
loads, and then predicts no temperature.

A model may carry an ``expected_error`` block (the error to expect on profiles unlike its
training records, from its held-out training data: ``avoa_pipeline.handover``,
docs/handover-rule.md): checked by the schema (its ``expected_error``), read for
``simulate`` to print; a model.json without it loads.

A model may hold one parameter set per test temperature (``by_temperature``: each an ordinary
model, coldest first; docs/temperature-rule.md parts 3-4, :meth:`FittedModel.per_temperature`):
the top level is one of them (what a reader that knows nothing of the sets runs), and
:meth:`FittedModel.at_ambient` gives the ordinary model at a record's ambient, interpolated in
1/T between the sets around it. Each set is read back with the same checks as the top level.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import itertools
import json
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import jsonschema
import numpy as np
import pandas as pd
import yaml

from .. import __version__
from ..errors import DataError
from ..records import VOLTAGE_RANGE_V, current_scale
from . import ecm, elements
from . import heat as heat_mod
from . import ocv as ocv_mod
from .ecm import IDX, Config, Knots, Record
from .intervals import CORR_LIMIT, LEVEL

FORMAT = "avoa-pipeline-model"
FORMAT_VERSION = 1

PROBE_C_RATE = 1.0
"""Without a record of the cell, ``export`` judges a model by its voltage under a discharge and a
charge across the SOC it was fitted on (:func:`probe_record`), at the current its training
records ran at (``current_scale_a``: their 99th-percentile |I|, ``records.current_scale``).
Not at 1C of the fitted capacity: a diagnosis of a short drive cycle without ``--capacity-ah``
fits 19.7 Ah for the 2.9 Ah Panasonic cell (-10 °C UDDS), and its sound model fails at 19.7 A.
Only a model.json without ``current_scale_a`` (written before it existed, or with it removed)
is probed at 1C of its capacity: every lithium-ion cell carries 1C, so a model whose voltage
leaves one cell's range there (R0 = 1.9 Ω in a 2.6 Ah cell: a 4.9 V drop) describes no cell.
A record given to ``export --record`` is judged instead, as ``simulate`` judges it."""
PROBE_SAMPLES = 200
"""Samples per leg of the probe: the simulator is exact for any step (zero-order hold), so these
only set where the voltage is looked at."""


@dataclass
class FittedModel:
    config: Config
    x: np.ndarray  # internal vector of the cell (per-record entries: those of the first record)
    knots: Knots
    tref_k: float
    bounds: dict[str, tuple[float, float]]  # internal names → the fit's bounds
    provenance: dict = field(default_factory=dict)
    current_scale_a: float | None = None  # the training's current (training_current_scale)
    intervals: dict | None = None  # model/intervals.py's report of the fit (read, not used)
    heat: heat_mod.Heat | None = None  # the lumped thermal state (model/heat.py), if fitted
    expected_error: dict | None = None  # the error to expect on other profiles (handover.py)
    by_temperature: list[tuple[float, FittedModel]] | None = None
    # (ambient °C, that test temperature's model), coldest first; None for an ordinary model

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(n for n in self.config.names() if not ecm.PARAMS[n].per_record)

    def parameters(self) -> dict[str, float]:
        """Report-named physical values of the cell's parameters (initial states left out)."""
        out = ecm.report(self.x, self.names)
        p = ecm.physical(self.x, self.knots)
        for e in elements.REGISTRY.values():  # vector elements' knot values, registry order
            if e.name in self.config.effects and e.vector is not None:
                out.update(e.vector.report(p))
        return out

    def record(self, frame: pd.DataFrame) -> Record:
        return Record.from_frame(frame, tref_k=self.tref_k)

    def initial_soc(self, rec: Record) -> float:
        x = self.x.copy()
        x[IDX["h0"]] = 0.0
        return ecm.soc0_from_voltage(ecm.to_physical(x)[0], rec, self.knots, self.config.table,
                                     self.config.load_ohm)  # fmt: skip

    def simulate(self, frame: pd.DataFrame, soc0: float | None = None, traces: bool = False):
        """Model voltage for ``frame`` (a record of the same cell); with ``traces`` also the
        (5, n) state traces (SOC, h, RC voltage, thermal factor, current). A model of
        per-temperature sets runs :meth:`at_ambient` of the record's first ``temperature_c``
        sample (a caller that knows the ambient better calls :meth:`at_ambient` first)."""
        if self.by_temperature is not None:
            return self.at_ambient(first_temperature(self, frame)).simulate(frame, soc0, traces)
        rec = self.record(frame)
        x = self.x.copy()
        x[IDX["h0"]] = 0.0
        x[IDX["soc0"]] = self.initial_soc(rec) if soc0 is None else float(soc0)
        res = ecm.simulate_rows(rec, x, self.knots, self.config.table, self.config.load_ohm,
                                traces=traces)  # fmt: skip
        return (res[0][:, 0], res[1]) if traces else res[:, 0]

    def predict(self, frame: pd.DataFrame, soc0: float | None = None,
                source: str = "model.json", on: str = "") -> np.ndarray:  # fmt: skip
        """:meth:`simulate`, refused (DataError naming ``source``) where the model's voltage
        leaves one cell's range (``records.VOLTAGE_RANGE_V``) or is not finite: parameters
        that pass every bound one by one may still not describe a cell together. The one
        refusal ``simulate`` and ``export`` share (:meth:`check_cell`); ``on`` says what ran."""
        # an extreme model may overflow on the way; its voltage is judged right below, and a
        # numpy warning printed before the one-line refusal would only hide it
        with np.errstate(all="ignore"):
            v = self.simulate(frame, soc0=soc0)
        lo, hi = VOLTAGE_RANGE_V
        where = f" {on}" if on else ""
        bad = int(np.count_nonzero(~np.isfinite(v)))
        if bad:
            raise DataError(f"{source}: the model predicts no finite voltage at {bad} of {v.size}"
                            f" samples{where}: its parameters do not describe a cell")  # fmt: skip
        if v.min() < lo or v.max() > hi:
            raise DataError(f"{source}: the model predicts {v.min():.4g}..{v.max():.4g} V{where},"
                            f" outside one cell's {lo:g}..{hi:g} V: its parameters do not "
                            "describe a cell")  # fmt: skip
        return v

    def at_bounds(self) -> list[dict]:
        """The cell's parameters pressed against a bound of their fit: within
        ``fitting.AT_BOUND`` of the searched range (internal coordinates) from either end."""
        from . import fitting

        flags, values = [], self.parameters()
        for n in self.names:
            lo, hi = self.bounds[n]
            x = float(self.x[IDX[n]])
            if hi > lo and fitting.at_bound(x, lo, hi):  # a fixed value (lo = hi) is no bound hit
                rep = ecm.PARAMS[n].report
                flags.append({"parameter": rep, "value": values[rep],
                              "bound": "lower" if x - lo <= hi - x else "upper",
                              "bounds": self.physical_bounds(n)})  # fmt: skip
        return flags

    def check_cell(self, frame: pd.DataFrame | None = None, soc0: float | None = None,
                   source: str = "model.json") -> None:  # fmt: skip
        """What ``export`` refuses, by ``simulate``'s own check (:meth:`predict`): on the
        record given (from ``soc0``, else by the library's rule, as ``simulate`` starts it);
        without one, on :func:`probe_record` (of every set of a model of per-temperature sets,
        each named by its place and ambient)."""
        if frame is None and self.by_temperature is not None:
            for j, (ambient, m) in enumerate(self.by_temperature):
                m.check_cell(None, None, f"{source} (by_temperature[{j}], {ambient:g} °C)")
            return
        if frame is not None:
            self.predict(frame, soc0=soc0, source=source)
            return
        probe, start, what = probe_record(self)
        grid = self.knots.grid()
        self.predict(probe, soc0=start, source=source,
                     on=f"{what} ({max(grid[0], 0.0):.3g}-{grid[-1]:.3g}; --record checks a "
                     "record of the cell instead)")  # fmt: skip

    # ------------------------------------------------------------------------------------------
    # per-temperature parameter sets (docs/temperature-rule.md parts 3-4)

    @classmethod
    def per_temperature(cls, sets: list[tuple[float, FittedModel]],
                        provenance: dict | None = None) -> FittedModel:  # fmt: skip
        """One model of several test temperatures' own models (each an ordinary FittedModel,
        possibly with different elements). Each set widened to the union of the sets'
        elements (a missing element at its neutral value, its bounds the library's limits for
        it), in ecm.EFFECTS order; the top level (what a reader that knows nothing of the sets
        sees, and what validates like any model.json) is the set whose ambient is nearest the
        sets' tref_k (25 °C usually; :func:`top_set`); by_temperature holds all sets, coldest
        first. ``provenance``: the top level's (default the top set's own)."""
        sets = sorted(((float(a), m) for a, m in sets), key=lambda s: s[0])
        if len(sets) < 2:
            raise ValueError(f"per-temperature sets: {len(sets)} given, need at least 2")
        for (a, _), (b, _) in itertools.pairwise(sets):
            if not b > a:
                raise ValueError(f"per-temperature sets: two at {a:g} °C (one per ambient)")
        for a, m in sets:
            if m.by_temperature is not None:
                raise ValueError(f"per-temperature sets: the set at {a:g} °C holds sets itself")
            heat_mod.check_ambient(a, f"per-temperature sets: ambient {a!r}")
        effects = tuple(e for e in ecm.EFFECTS if any(e in m.config.effects for _, m in sets))
        widened = [(a, widened_to(m, effects)) for a, m in sets]
        top = widened[top_set(widened)][1]
        return dataclasses.replace(
            top,
            provenance=dict(top.provenance if provenance is None else provenance),
            by_temperature=widened,
        )

    def at_ambient(self, ambient_c: float) -> FittedModel:
        """The ordinary model at ``ambient_c``: for a by_temperature model, the two sets around
        it interpolated linearly in 1/T (each parameter's physical value; absolute
        temperature), where both sets share what their parameters mean (:func:`interpolable`:
        elements, OCV kind and table, load; the knots where an element lives on them, the
        reference temperature where a law reads it); else (and outside the sets' span) the
        nearest set in 1/T. At a set's own ambient, that set (its voltage exactly). An ordinary
        model returns itself. :meth:`ambient_note` says which it was."""
        return self._at_ambient(ambient_c)[0]

    def ambient_note(self, ambient_c: float) -> str:
        """What :meth:`at_ambient` does at ``ambient_c``, in words (for a command's line)."""
        return self._at_ambient(ambient_c)[1]

    def _at_ambient(self, ambient_c: float) -> tuple[FittedModel, str]:
        sets = self.by_temperature
        if sets is None:
            return self, "an ordinary model (one parameter set)"
        ambient_c = float(ambient_c)
        temps = [a for a, _ in sets]
        for j, a in enumerate(temps):
            if a == ambient_c:
                return self._run_set(j), f"the set at {a:g} °C (by_temperature[{j}])"
        inv = 1.0 / (ambient_c + heat_mod.KELVIN)
        invs = [1.0 / (a + heat_mod.KELVIN) for a in temps]
        span = f"{temps[0]:g}..{temps[-1]:g} °C"
        if ambient_c < temps[0] or ambient_c > temps[-1]:
            j = 0 if ambient_c < temps[0] else len(sets) - 1
            return self._run_set(j), (f"the nearest set, {temps[j]:g} °C (by_temperature[{j}]; "
                                      f"{ambient_c:g} °C lies outside the sets' "
                                      f"{span})")  # fmt: skip
        k = int(np.searchsorted(temps, ambient_c))  # temps[k - 1] < ambient < temps[k]
        near = k - 1 if abs(inv - invs[k - 1]) <= abs(inv - invs[k]) else k
        (a0, m0), (a1, m1) = sets[k - 1], sets[k]
        why = interpolable(m0, m1)
        if why:
            return self._run_set(near), (f"the nearest set in 1/T, {temps[near]:g} °C "
                                         f"(by_temperature[{near}]; the sets at {a0:g} and "
                                         f"{a1:g} °C differ in {why})")  # fmt: skip
        w = (inv - invs[k - 1]) / (invs[k] - invs[k - 1])
        run = self._run_set(near)
        x = run.x.copy()
        for n in m0.names:
            rep = ecm.PARAMS[n].report
            v0, v1 = ecm.report(m0.x, [n])[rep], ecm.report(m1.x, [n])[rep]
            x[IDX[n]] = x[IDX[n]] if v0 == v1 else ecm.internal_value(rep, v0 + w * (v1 - v0))[1]
        bounds = {n: (min(m0.bounds[n][0], m1.bounds[n][0]), max(m0.bounds[n][1], m1.bounds[n][1]))
                  for n in m0.names}  # fmt: skip
        out = dataclasses.replace(run, x=x, bounds=bounds)
        out.intervals = interpolated_intervals(m0, m1, w, out, run.intervals)
        return out, (f"interpolated linearly in 1/T between the sets at {a0:g} and {a1:g} °C "
                     f"(by_temperature[{k - 1}] and [{k}])")  # fmt: skip

    def _run_set(self, j: int) -> FittedModel:
        """Set ``j`` as it runs: its own heat block and expected error, or the top level's where
        it has none (the voltage is the set's exactly)."""
        m = self.by_temperature[j][1]
        return dataclasses.replace(
            m,
            heat=self.heat if m.heat is None else m.heat,
            expected_error=self.expected_error if m.expected_error is None else m.expected_error,
        )

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
            "bounds": {ecm.PARAMS[n].report: self.physical_bounds(n) for n in self.names},
            "knots": {"lo": self.knots.lo, "step": self.knots.step},
            "tref_k": self.tref_k,
            "ocv_table": None if self.config.table is None else ocv_mod.to_json(self.config.table),
            "capacity_ah": float(10.0 ** self.x[IDX["lq"]]),
            "current_scale_a": self.current_scale_a,
            "intervals": self.intervals,
            "provenance": self.provenance,
            **({} if self.heat is None else {"heat": self.heat.to_json()}),
            **({} if self.expected_error is None else {"expected_error": self.expected_error}),
            **({} if self.by_temperature is None else {"by_temperature": [
                {"ambient_c": float(a), "model": _without_sets(m.to_json())}
                for a, m in self.by_temperature]}),
        }  # fmt: skip

    def physical_bounds(self, name: str) -> list[float]:
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
    def from_json(cls, d, source: str = "model.json") -> FittedModel:
        """A saved model, checked before any of it is used (module docstring): its format and
        version, its configuration, then :func:`model_schema` and what a schema cannot say.
        Every refusal is one DataError naming ``source`` and the field."""
        if not isinstance(d, dict):
            raise DataError(f"{source}: field '(top level)': {_kind(d)}, not an object (an "
                            f"{FORMAT} file)")  # fmt: skip
        if d.get("format") != FORMAT:
            raise DataError(f"{source}: field 'format': not an {FORMAT} file")
        version = d.get("format_version")
        if type(version) is not int or version != FORMAT_VERSION:  # true == 1 in Python
            raise DataError(f"{source}: field 'format_version': {json.dumps(version)}; this "
                            f"version ({__version__}) reads version {FORMAT_VERSION}")  # fmt: skip
        _validate(d, _library_schema()["$defs"]["envelope"], source)
        # the configuration first (with a stand-in table: the table is checked by the schema)
        try:
            stand_in = _STAND_IN_TABLE if d["ocv"] == "table" else None
            config = Config(tuple(d["effects"]), stand_in)
        except ValueError as exc:
            raise DataError(f"{source}: field 'effects': {exc}") from None
        _validate(d, model_schema(config), source)
        table = None if stand_in is None else _table(d["ocv_table"], source)
        try:
            config = Config(config.effects, table, d["load_ohm"])
        except ValueError as exc:
            raise DataError(f"{source}: field 'load_ohm': {exc}") from None
        params, bounds_rep = d["parameters"], d["bounds"]
        x = ecm.NEUTRAL.copy()
        bounds = {}
        for n in config.names():
            p = ecm.PARAMS[n]
            if p.per_record:
                continue
            rep = p.report
            value, (lo, hi) = float(params[rep]), map(float, bounds_rep[rep])
            if lo > hi:
                raise DataError(f"{source}: field 'bounds.{rep}': lower {lo:g} above upper "
                                f"{hi:g}")  # fmt: skip
            tol = 1e-9 * max(1.0, abs(hi - lo))
            if not lo - tol <= value <= hi + tol:
                raise DataError(f"{source}: field 'parameters.{rep}': {value:g} outside the "
                                f"bounds it was fitted in [{lo:g}, {hi:g}]")  # fmt: skip
            x[IDX[n]] = ecm.internal_value(rep, value)[1]
            bounds[n] = tuple(sorted((ecm.internal_value(rep, lo)[1],
                                      ecm.internal_value(rep, hi)[1])))  # fmt: skip
        knots = Knots(float(d["knots"]["lo"]), float(d["knots"]["step"]))
        top = _library_schema()["properties"]["knots"]["properties"]["lo"]["maximum"]
        if knots.grid()[-1] > top:
            raise DataError(f"{source}: field 'knots.step': the knots reach SOC "
                            f"{knots.grid()[-1]:.6g}, beyond {top:g}")  # fmt: skip
        model = cls(config, x, knots, float(d["tref_k"]), bounds, d["provenance"],
                    d.get("current_scale_a"), d.get("intervals"),
                    expected_error=d.get("expected_error"))  # fmt: skip
        written = {**{k: params[k] for k in _derived_keys(config)},
                   "capacity_ah": d["capacity_ah"]}  # fmt: skip
        derived = {**model.parameters(), "capacity_ah": float(10.0 ** x[IDX["lq"]])}
        for key, value in written.items():
            want = derived[key]
            if not math.isclose(value, want, rel_tol=DERIVED_RTOL, abs_tol=DERIVED_RTOL):
                field_name = key if key == "capacity_ah" else f"parameters.{key}"
                raise DataError(f"{source}: field '{field_name}': {value:.10g}, but the "
                                f"parameters give {want:.10g} (written for readers, never read:"
                                " edit the parameters instead)")  # fmt: skip
        _check_intervals(model, params, source)
        if d.get("heat") is not None:
            _check_heat(d["heat"], source)
            model.heat = heat_mod.Heat.from_json(d["heat"])
        if d.get("by_temperature") is not None:
            model.by_temperature = _read_sets(d, model, source)
        return model

    @classmethod
    def load(cls, path) -> FittedModel:
        """:meth:`from_json` of the file at ``path``; a folder, an unreadable file or text that
        is not JSON is a one-line DataError too."""
        from ..io import read_json

        if Path(path).is_dir():
            raise DataError(f"{path}: a folder, not a model.json file")
        try:
            d = read_json(path)
        except OSError as exc:
            raise DataError(f"{path}: cannot be read ({exc.strerror or exc})") from None
        except (ValueError, RecursionError) as exc:  # e.g. an integer of over 4,300 digits
            raise DataError(f"{path}: not readable JSON ({str(exc)[:80]})") from None
        return cls.from_json(d, str(path))


# ----------------------------------------------------------------------------------------------
# model.json: what a file must hold (schemas/model.schema.yaml, the library's numbers filled in)

SCHEMA_PATH = Path(str(resources.files("avoa_pipeline") / "schemas" / "model.schema.yaml"))
DERIVED_RTOL = 1e-9
"""Values model.json writes for readers (the knots, the OCV correction and resistance factors at
them, the capacity beside the parameters, the table's SOC grid) are computed from the parameters;
an edited one would be ignored on loading, so it must equal the recomputed value (to 1e-9
relative: what a JSON round trip of the same arithmetic leaves)."""
LIMIT_RTOL = 1e-9
"""A value at a limit of ``ecm.LIMITS`` may lie this far (relative) beyond it: the physical value
is written from its internal coordinate (10**log10(x) is not always x to the last bit)."""

_TYPE_WORDS = {"number": "a number", "integer": "an integer", "string": "a string",
               "array": "a list", "object": "an object", "null": "null",
               "boolean": "true or false"}  # fmt: skip


def _kind(value) -> str:
    """A JSON value's type as the user wrote it (true/false is a boolean, not a number)."""
    if isinstance(value, bool):
        return f"a boolean ({str(value).lower()})"
    if value is None:
        return "null"
    if isinstance(value, str):
        return f"a string ({value[:40]!r})"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    if isinstance(value, dict):
        return "an object"
    return f"the number {_show(value)}"


def _show(value) -> str:
    """A number as JSON spells it (NaN, Infinity), or the words for one no float holds."""
    try:
        x = float(value)
    except OverflowError:
        return "an integer beyond a float's range"
    if math.isnan(x):
        return "NaN"
    if math.isinf(x):
        return "-Infinity" if x < 0 else "Infinity"
    return f"{x:.6g}"


def _is_finite(value) -> bool:
    """JSON parses NaN and ±Infinity (and 1e400 as inf) as numbers, and an integer of any
    length, which no float holds; none is a parameter."""
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


def _finite(validator, wanted, instance, schema):
    """The schema keyword ``finite`` (:func:`_is_finite`)."""
    if wanted and validator.is_type(instance, "number") and not _is_finite(instance):
        yield jsonschema.ValidationError(f"{_show(instance)}, not a finite number")


def _entries(validator, item_schema, instance, schema):
    """The schema keyword ``entries``: ``items`` for a long list of numbers (an OCV table's
    1,001), judged at the first entry that fails, so a table costs microseconds, not a schema
    walk per entry."""
    if not validator.is_type(instance, "array"):
        return
    lo, hi = item_schema.get("minimum", -math.inf), item_schema.get("maximum", math.inf)
    for j, value in enumerate(instance):
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if not (number and _is_finite(value) and lo <= value <= hi):
            yield from validator.descend(value, item_schema, path=j)
            return


_Validator = jsonschema.validators.extend(
    jsonschema.Draft202012Validator, {"finite": _finite, "entries": _entries}
)


@functools.cache
def _library_schema() -> dict:
    """The schema file with the numbers it leaves to their owners filled in (its description):
    those of no configuration. Cached: the file is read once."""
    s = yaml.safe_load(SCHEMA_PATH.read_text())
    top, d = s["properties"], s["$defs"]
    lo, hi = VOLTAGE_RANGE_V
    qlo, qhi = ecm.LIMITS["lq"]
    top["load_ohm"]["minimum"] = hi / top["current_scale_a"]["maximum"]
    top["capacity_ah"].update(minimum=qlo, maximum=qhi)
    d["envelope"]["properties"]["effects"]["items"]["enum"] = list(ecm.EFFECTS)
    table = d["ocv_table"]["properties"]
    table["soc_lo"]["maximum"] = 1.0 - ocv_mod.MIN_TABLE_SPAN
    table["ocv_v"]["entries"].update(minimum=lo, maximum=hi)
    table["capacity_ah"].update(minimum=qlo, maximum=qhi)
    table["capacity_sd_ah"]["maximum"] = qhi
    iv = d["intervals"]["properties"]
    iv["level"]["const"] = LEVEL
    iv["residual_sd_mv"]["maximum"] = 1e3 * (hi - lo)
    below, above = iv["correlated_pairs"]["items"]["properties"]["correlation"]["anyOf"]
    below["maximum"], above["minimum"] = -CORR_LIMIT, CORR_LIMIT
    heat = d["heat"]["properties"]
    lo_c, hi_c = heat_mod.AMBIENT_RANGE_C
    heat["records"]["items"]["properties"]["ambient_c"].update(minimum=lo_c, maximum=hi_c)
    d["kelvin"]["maximum"] = heat["fixed_point"]["properties"]["tolerance_k"]["maximum"] = (
        hi_c - lo_c
    )
    for key, limits in _HEAT_LIMITS.items():
        value = _within(d["parameter"], limits, f"the library's range of heat.{key}")
        heat["parameters"]["properties"][key] = value
        heat["bounds"]["properties"][key] = _pair(value)
        heat["intervals"]["properties"][key] = {"$ref": "#/$defs/heat_entry"}
    heat["parameters"]["required"] = heat["bounds"]["required"] = list(_HEAT_LIMITS)
    sets = d["by_temperature"]["items"]["properties"]
    sets["ambient_c"].update(minimum=lo_c, maximum=hi_c)
    heat["intervals"]["required"] = [k for k in _HEAT_LIMITS if k != "dudt_v_per_k"]
    return s


def _within(number: dict, limits, why: str | None = None) -> dict:
    """``number`` (a schema) between the library's ``limits``, widened by :data:`LIMIT_RTOL`."""
    lo, hi = limits
    out = {**number, "minimum": lo - LIMIT_RTOL * abs(lo), "maximum": hi + LIMIT_RTOL * abs(hi)}
    return out if why is None else {**out, "description": why}


def _pair(items: dict) -> dict:
    """A fit's bounds: two values."""
    return {"type": "array", "items": items, "minItems": 2, "maxItems": 2}


def model_schema(config: Config) -> dict:
    """The JSON Schema of a model.json of ``config``: the schema file, with its parameters'
    names and ranges (``ecm.LIMITS``, each bound in its transform's domain), the values written
    for readers, the OCV kind and table, and the interval entries of this configuration. Built
    once per configuration (shared: not to be edited)."""
    return _schema_of(config.effects, config.table is not None)


@functools.cache
def _schema_of(effects: tuple[str, ...], table: bool) -> dict:
    config = Config(effects, _STAND_IN_TABLE if table else None)
    s = copy.deepcopy(_library_schema())
    top, d = s["properties"], s["$defs"]
    top["ocv"]["const"] = config.ocv_kind
    if config.table is not None:
        top["ocv_table"] = {"$ref": "#/$defs/ocv_table"}
    names = [n for n in config.names() if not ecm.PARAMS[n].per_record]
    reports = [ecm.PARAMS[n].report for n in names]
    params, bounds = top["parameters"]["properties"], top["bounds"]["properties"]
    for n, rep in zip(names, reports, strict=True):
        params[rep] = _within(d["parameter"], ecm.LIMITS[n])
        bounds[rep] = _pair(d["bound"][ecm.PARAMS[n].transform])
    params.update(dict.fromkeys(_derived_keys(config), d["written"]))
    top["parameters"]["required"], top["bounds"]["required"] = list(params), reports
    entries = d["intervals"]["properties"]["parameters"]
    entries["properties"] = {r: {"$ref": "#/$defs/interval_entry"} for r in reports}
    entries["required"] = reports
    pair = d["intervals"]["properties"]["correlated_pairs"]["items"]["properties"]
    pair["a"]["enum"] = pair["b"]["enum"] = reports
    return _inlined(s, d)


def _inlined(node, defs: dict):
    """``node`` with each ``$ref`` replaced by the definition it names: jsonschema resolves a
    reference on every validation (a thermal model.json: 5.9 ms with them, 4.8 ms inlined)."""
    if isinstance(node, dict):
        if "$ref" in node:
            return _inlined(defs[node["$ref"].removeprefix("#/$defs/")], defs)
        return {k: _inlined(v, defs) for k, v in node.items()}
    if isinstance(node, list):
        return [_inlined(v, defs) for v in node]
    return node


def _check_intervals(model: FittedModel, params: dict, source: str) -> None:
    """What the schema cannot say of a model.json's intervals (written for readers; only their
    flags are used, as warnings): each entry's value is the parameter's, its flags are what the
    model's bounds say (``at_bound`` by ``fitting.at_bound``, ``held`` for a fixed parameter,
    ``identified`` by ``intervals.identified``), its ends are numbers around the value exactly
    where it has an interval, and ``flags`` are the entries' own (``intervals.flags``)."""
    from . import fitting, intervals

    iv = model.intervals
    if iv is None:
        return
    where = f"{source}: field 'intervals"
    if iv["effective_samples"] > iv["samples"]:
        raise DataError(f"{where}.effective_samples': {iv['effective_samples']:.6g}, more than "
                        f"the {iv['samples']} samples")  # fmt: skip
    for rep, e in iv["parameters"].items():
        n = ecm.BY_REPORT[rep]
        lo, hi = model.bounds[n]
        x = float(model.x[IDX[n]])
        at = f"{where}.parameters.{rep}"
        if not math.isclose(e["value"], params[rep], rel_tol=DERIVED_RTOL, abs_tol=DERIVED_RTOL):
            raise DataError(f"{at}.value': {e['value']:.10g}, but the parameter is "
                            f"{params[rep]:.10g} (the intervals are the fit's: remove "
                            "'intervals' to edit the parameters by hand)")  # fmt: skip
        held = bool(hi <= lo)
        if e["held"] != held:
            raise DataError(f"{at}.held': {json.dumps(e['held'])}, but the bounds "
                            f"{'fix' if held else 'do not fix'} it")  # fmt: skip
        bound = not held and bool(fitting.at_bound(x, lo, hi))
        if e["at_bound"] != bound:
            raise DataError(f"{at}.at_bound': {json.dumps(e['at_bound'])}, but the value "
                            f"{'is' if bound else 'is not'} at a bound of the fit")  # fmt: skip
        has = not (held or bound)
        _check_ends(e, at, *model.physical_bounds(n), has=has)
        if not has:
            if e["identified"]:
                raise DataError(f"{at}.identified': true, but the parameter has no interval")
            continue
        width = abs(np.diff([ecm.internal_value(rep, e[k])[1] for k in ("low95", "high95")])[0])
        if e["identified"] != intervals.identified(width, lo, hi):
            raise DataError(f"{at}.identified': {json.dumps(e['identified'])}, but its interval "
                            f"spans {width / (hi - lo):.3g} of its range (identified at most "
                            f"{intervals.UNIDENTIFIED_SHARE:g})")  # fmt: skip
    own = intervals.flags(iv["parameters"], iv["correlated_pairs"])
    if iv["flags"] != own:
        wrong = [j for j, (a, b) in enumerate(zip(iv["flags"], own, strict=False)) if a != b]
        at = f"{where}.flags[{wrong[0]}]'" if wrong else f"{where}.flags'"
        raise DataError(
            f"{at}: not the entries' own flags ({len(own)}: "
            f"{'; '.join(own) or 'none'}: what the entries and pairs say)"
        )


_HEAT_LIMITS = {"c_th_j_per_k": heat_mod.C_TH_LIMITS_J_PER_K,
                "ha_w_per_k": heat_mod.HA_LIMITS_W_PER_K,
                "dudt_v_per_k": heat_mod.DUDT_LIMITS_V_PER_K}  # fmt: skip


def _check_heat(h: dict, source: str) -> None:
    """What the schema cannot say of a heat block: its bounds the library's (the fit searched
    them; written for readers), each parameter inside them; dU/dT 0 unless the entropic term was
    admitted, and an interval entry for it exactly then; each interval entry's value the
    parameter's (the candidate's inside its bounds, and dU/dT itself where admitted), its
    ``at_bound`` what the bounds say, its ends around the value and inside the bounds."""
    where = f"{source}: field 'heat"
    params, bounds = h["parameters"], h["bounds"]
    for key in params:
        lo, hi = _HEAT_LIMITS[key]
        if list(bounds[key]) != [lo, hi]:
            raise DataError(f"{where}.bounds.{key}': {json.dumps(bounds[key])}, but the fit "
                            f"searched the library's range [{lo:g}, {hi:g}] (written for "
                            "readers, never read)")  # fmt: skip
    entry = "field 'heat.intervals.dudt_v_per_k'"
    if h["entropic"] != ("dudt_v_per_k" in h["intervals"]):
        raise DataError(f"{where}.entropic': {json.dumps(h['entropic'])}, but {entry} is "
                        f"{'missing' if h['entropic'] else 'there'} (an entry exactly where "
                        "dU/dT was admitted)")  # fmt: skip
    if not h["entropic"] and params["dudt_v_per_k"] != 0.0:
        raise DataError(f"{where}.parameters.dudt_v_per_k': {params['dudt_v_per_k']:g}, but "
                        "entropic is false (dU/dT not admitted: 0)")  # fmt: skip
    cand = h["entropic_candidate"]
    want = {**params, "entropic_candidate": cand["value"]}
    if h["entropic"]:
        want["entropic_candidate"] = params["dudt_v_per_k"]
    entries = {**h["intervals"], "entropic_candidate": cand}
    for key, e in entries.items():
        at = (f"{where}.intervals.{key}" if key != "entropic_candidate"
              else f"{where}.entropic_candidate")  # fmt: skip
        lo, hi = _HEAT_LIMITS.get(key, DUDT_LIMITS)
        if not math.isclose(e["value"], want[key], rel_tol=DERIVED_RTOL, abs_tol=1e-15):
            raise DataError(f"{at}.value': {e['value']:.10g}, but the parameter is "
                            f"{want[key]:.10g}")  # fmt: skip
        if not lo <= e["value"] <= hi:
            raise DataError(f"{at}.value': {e['value']:.6g} outside the bounds it was fitted in "
                            f"[{lo:g}, {hi:g}]")  # fmt: skip
        _check_at_bound(e, (lo, hi), key, at)
        _check_ends(e, at, lo, hi)


DUDT_LIMITS = heat_mod.DUDT_LIMITS_V_PER_K


def _check_at_bound(e: dict, bounds, key: str, at: str) -> None:
    """``at_bound`` is what ``fitting.at_bound`` says of the value in the fit's coordinates
    (log10 for C_th and hA, the value for dU/dT)."""
    from . import fitting

    f = math.log10 if key in ("c_th_j_per_k", "ha_w_per_k") else (lambda v: v)
    bound = bool(fitting.at_bound(f(e["value"]), f(bounds[0]), f(bounds[1])))
    if e["at_bound"] != bound:
        raise DataError(f"{at}.at_bound': {json.dumps(e['at_bound'])}, but the value "
                        f"{'is' if bound else 'is not'} at a bound of the fit")  # fmt: skip


def _check_ends(e: dict, at: str, lo: float, hi: float, has: bool | None = None) -> None:
    """An interval entry's ends: both numbers or both null (null exactly where it ``has`` no
    interval: by default at a bound), the low end at most the value, the high end at least it,
    both inside the bounds [lo, hi]. The one check of the fit's intervals and the heat block's."""
    has = not e["at_bound"] if has is None else has
    for key in ("low95", "high95"):
        if (e[key] is None) == has:
            raise DataError(f"{at}.{key}': {json.dumps(e[key])}, but the parameter "
                            f"{'has' if has else 'has no'} interval")  # fmt: skip
    if not has:
        return
    tol = DERIVED_RTOL * max(1.0, abs(e["value"]))
    ptol = LIMIT_RTOL * max(abs(lo), abs(hi))
    for key, ok in (("low95", e["low95"] <= e["value"] + tol),
                    ("high95", e["high95"] >= e["value"] - tol)):  # fmt: skip
        if not ok:
            raise DataError(f"{at}.{key}': {e[key]:.6g}, on the wrong side of the value "
                            f"{e['value']:.6g}")  # fmt: skip
        if not lo - ptol <= e[key] <= hi + ptol:
            raise DataError(f"{at}.{key}': {e[key]:.6g}, outside the bounds it was fitted in "
                            f"[{lo:g}, {hi:g}]")  # fmt: skip


def _derived_keys(config: Config) -> list[str]:
    """The names of the values written for readers (:meth:`FittedModel.parameters` beyond the
    parameters themselves): those of a model of ``config`` at neutral values."""
    names = {ecm.PARAMS[n].report for n in config.names()}
    probe = FittedModel(config, ecm.NEUTRAL.copy(), Knots(0.0, 0.2), ecm.T_DEFAULT_K, {})
    return [k for k in probe.parameters() if k not in names]


def _field(path) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


def _refusal(err: jsonschema.ValidationError) -> tuple[str, str]:
    """(field, what) of a schema error, in the user's words (JSON's types, not Python's)."""
    path, value, s, v = list(err.absolute_path), err.instance, err.schema, err.validator
    if v == "required":
        missing = next(k for k in s["required"] if k not in value)
        return _field([*path, missing]), "missing"
    if v == "additionalProperties":
        extra = next(k for k in value if k not in s["properties"])
        return _field([*path, extra]), "not a field of this model.json's configuration"
    field = _field(path) or "(top level)"
    if v == "type":
        wanted = s["type"] if isinstance(s["type"], list) else [s["type"]]
        return field, f"{_kind(value)}, not {' or '.join(_TYPE_WORDS[t] for t in wanted)}"
    if v in ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"):
        lo = s.get("minimum", s.get("exclusiveMinimum"))
        hi = s.get("maximum", s.get("exclusiveMaximum"))
        left = "(" if "exclusiveMinimum" in s else "["
        right = ")" if "exclusiveMaximum" in s else "]"
        ends = (
            _show(lo) if lo is not None else "-Infinity",
            _show(hi) if hi is not None else "Infinity",
        )
        span = f"{left}{ends[0]}, {ends[1]}{right}"
        why = s.get("description") or "the allowed range"
        return field, f"{_show(value)} outside {why} {span}"
    if v == "enum" and path and path[0] == "effects":
        return field, f"unknown element {value!r}; choose from {', '.join(ecm.EFFECTS)}"
    if v in ("enum", "const"):
        allowed = s["enum"] if v == "enum" else [s["const"]]
        return field, f"{value!r}, not {' or '.join(map(repr, allowed))}"
    if v in ("minItems", "maxItems"):
        return field, f"a list of {len(value)}, need " + (
            f"{s['minItems']}"
            if s.get("minItems") == s.get("maxItems")
            else f"at least {s['minItems']}"
        )
    if v == "uniqueItems":
        return field, "an entry twice"
    return field, err.message


_STAND_IN_TABLE = ecm.OcvTable(0.0, 1.0, np.array([3.0, 4.0]))
"""Tells :class:`Config` that the OCV is a table while the file's own table awaits its checks."""


def _table(d: dict, source: str) -> ecm.OcvTable:
    """The OCV table of a model.json that passed the schema, with what a schema cannot say: it
    rises strictly (the initial-SOC rule inverts it), its grid stays within SOC 0-1 and spans
    at least ``ocv.MIN_TABLE_SPAN`` (as a table read from a file must), and ``soc`` is that
    grid."""
    v = np.asarray(d["ocv_v"], dtype=float)
    k = np.flatnonzero(np.diff(v) <= 0.0)
    if k.size:
        j = int(k[0]) + 1
        raise DataError(f"{source}: field 'ocv_table.ocv_v[{j}]': {v[j]:.6g} V, not above the "
                        f"entry before ({v[j - 1]:.6g} V); the initial-SOC rule inverts the "
                        "table, so it must rise strictly")  # fmt: skip
    lo, step = float(d["soc_lo"]), float(d["soc_step"])
    span = step * (v.size - 1)
    if lo + span > 1.0 + DERIVED_RTOL or span < ocv_mod.MIN_TABLE_SPAN - DERIVED_RTOL:
        raise DataError(
            f"{source}: field 'ocv_table.soc_step': the table covers SOC "
            f"{lo:.6g}-{lo + span:.6g} (soc_lo + soc_step × (entries − 1)); an OCV "
            f"table lies within 0-1 and spans at least {ocv_mod.MIN_TABLE_SPAN:g}"
        )
    if len(d["soc"]) != v.size:
        raise DataError(f"{source}: field 'ocv_table.soc': a list of {len(d['soc'])}, need "
                        f"{v.size} (one per ocv_v entry)")  # fmt: skip
    profile = d.get("dudt_v_per_k")
    if profile is not None and len(profile) != v.size:
        raise DataError(f"{source}: field 'ocv_table.dudt_v_per_k': a list of {len(profile)}, "
                        f"need {v.size} (∂U/∂T at each ocv_v entry)")  # fmt: skip
    grid = lo + step * np.arange(v.size)
    for j, (got, want) in enumerate(zip(d["soc"], grid, strict=True)):
        if not math.isclose(got, want, rel_tol=DERIVED_RTOL, abs_tol=DERIVED_RTOL):
            raise DataError(
                f"{source}: field 'ocv_table.soc[{j}]': {got:.10g}, but soc_lo and "
                f"soc_step give {want:.10g} (written for readers, never read)"
            )
    return ocv_mod.from_json(d)


# ----------------------------------------------------------------------------------------------
# per-temperature parameter sets (``by_temperature``)


def first_temperature(model: FittedModel, frame: pd.DataFrame, source: str = "model.json") -> float:
    """The ambient a model of per-temperature sets runs ``frame`` at without being told one: its
    first ``temperature_c`` sample; a one-line DataError naming ``source`` where it has none."""
    if "temperature_c" not in frame.columns or not len(frame):
        temps = ", ".join(f"{a:g}" for a, _ in model.by_temperature)
        raise DataError(f"{source}: field 'by_temperature': the model holds per-temperature "
                        f"parameter sets ({temps} °C); the record needs temperature_c or an "
                        "ambient to choose among them")  # fmt: skip
    return float(frame["temperature_c"].iloc[0])


def widened_to(model: FittedModel, effects: tuple[str, ...]) -> FittedModel:
    """``model`` with the elements of ``effects`` it lacks added at their neutral values (so
    its voltage is unchanged), their bounds the library's limits (``fitting.internal_limits``)
    and, where it has intervals, their entries as those bounds say (an element no fit moved:
    at a bound, or an interval of the whole range, not identified)."""
    from . import fitting, intervals

    missing = tuple(e for e in effects if e not in model.config.effects)
    if not missing and model.config.effects == effects:
        return model
    config = Config(effects, model.config.table, model.config.load_ohm)
    x = fitting.neutralise(model.x[None, :], missing)[0]
    added = [n for e in missing for n in ecm.element_params(e) if not ecm.PARAMS[n].per_record]
    bounds = {**model.bounds, **{n: fitting.internal_limits(n) for n in added}}
    bounds = {n: bounds[n] for n in config.names() if not ecm.PARAMS[n].per_record}
    out = dataclasses.replace(model, config=config, x=x, bounds=bounds)
    iv = model.intervals
    if iv is not None:
        entries = dict(iv["parameters"])
        values = out.parameters()
        for n in added:
            lo, hi = bounds[n]
            rep = ecm.PARAMS[n].report
            at = bool(fitting.at_bound(x[IDX[n]], lo, hi))
            ends = (None, None) if at else tuple(out.physical_bounds(n))
            entries[rep] = {"value": values[rep], "low95": ends[0], "high95": ends[1],
                            "at_bound": at, "identified": False if at else
                            intervals.identified(hi - lo, lo, hi), "held": False}  # fmt: skip
        entries = {ecm.PARAMS[n].report: entries[ecm.PARAMS[n].report] for n in out.names}
        out.intervals = {**iv, "parameters": entries,
                         "flags": intervals.flags(entries, iv["correlated_pairs"])}  # fmt: skip
    return out


def interpolated_intervals(m0: FittedModel, m1: FittedModel, w: float, out: FittedModel,
                           near: dict | None) -> dict | None:  # fmt: skip
    """The intervals of ``out``, the sets ``m0`` and ``m1`` interpolated with weight ``w`` (in
    1/T): each end interpolated as its value is (so it still brackets the value; ``estimate``
    reads the widths), the flags what ``out``'s bounds say (``_check_intervals``'s rules, so a
    saved interpolated model loads), and the rest (training residual, samples, correlated
    pairs) the nearer set's ``near``. None where either set has none."""
    from . import fitting, intervals

    if near is None or m0.intervals is None or m1.intervals is None:
        return None
    entries, values = {}, out.parameters()
    for n in out.names:
        rep = ecm.PARAMS[n].report
        e0, e1 = m0.intervals["parameters"][rep], m1.intervals["parameters"][rep]
        lo, hi = out.bounds[n]
        held = bool(hi <= lo)
        at = not held and bool(fitting.at_bound(out.x[IDX[n]], lo, hi))
        entry = {"value": values[rep], "low95": None, "high95": None, "at_bound": at,
                 "identified": False, "held": held}  # fmt: skip
        if not (held or at):
            if None in (e0["low95"], e1["low95"]):  # a set without one: nothing excluded
                ends = out.physical_bounds(n)
            else:
                ends = [e0[k] + w * (e1[k] - e0[k]) for k in ("low95", "high95")]
                ends = [min(ends[0], values[rep]), max(ends[1], values[rep])]
            width = abs(ecm.internal_value(rep, ends[1])[1] - ecm.internal_value(rep, ends[0])[1])
            entry |= {"low95": ends[0], "high95": ends[1],
                      "identified": intervals.identified(width, lo, hi)}  # fmt: skip
        entries[rep] = entry
    pairs = near["correlated_pairs"]
    return {**near, "method": f"interpolated in 1/T between two sets' intervals; {near['method']}",
            "parameters": entries, "flags": intervals.flags(entries, pairs)}  # fmt: skip


def top_set(sets: list[tuple[float, FittedModel]]) -> int:
    """Which set is a model's top level: the one whose ambient is nearest (in 1/T; the colder
    of two as near) the sets' reference temperature where they share one, else 25 °C
    (``ecm.T_DEFAULT_K``: where a record without a temperature runs, so what a reader that
    knows nothing of the sets should see)."""
    trefs = {m.tref_k for _, m in sets}
    ref = trefs.pop() if len(trefs) == 1 else ecm.T_DEFAULT_K
    dist = [abs(1.0 / (a + heat_mod.KELVIN) - 1.0 / ref) for a, _ in sets]
    return int(np.argmin(dist))


def interpolable(a: FittedModel, b: FittedModel) -> str:
    """What keeps two sets' parameters from being interpolated ('' where nothing does): they
    mean the same only on the same elements, OCV (kind and table) and load; on the same knots
    where an element's values live on them (ocv_shape, r0_soc, r1_soc); on the same reference
    temperature where a law reads 1/T − 1/Tref or T − Tref (``Element.needs_temperature``).
    Elsewhere the knots and Tref change no voltage, so sets fitted apart (each its own records'
    knots and mean temperature) still interpolate."""
    ca, cb = a.config, b.config
    if ca.effects != cb.effects:
        return "their elements"
    if ca.load_ohm != cb.load_ohm:
        return "their load"
    ta, tb = ca.table, cb.table
    same_table = (ta is None and tb is None) or (
        ta is not None and tb is not None and ta.lo == tb.lo and ta.step == tb.step
        and np.array_equal(ta.values, tb.values)
        and np.array_equal(ta.dudt_shape(), tb.dudt_shape())
    )  # fmt: skip
    if not same_table:
        return "their OCV"
    if any(elements.get(e).vector is not None for e in ca.effects) and a.knots != b.knots:
        return "their SOC knots"
    if any(elements.get(e).needs_temperature for e in ca.effects) and a.tref_k != b.tref_k:
        return "their reference temperature"
    return ""


def _without_sets(d: dict) -> dict:
    return {k: v for k, v in d.items() if k != "by_temperature"}


_VOLTAGE_FIELDS = ("ocv", "effects", "load_ohm", "parameters", "bounds", "knots", "tref_k",
                   "ocv_table", "capacity_ah")  # fmt: skip
"""The fields of a model.json that decide its voltage: the top level of per-temperature sets
equals its top set's in each."""


def _read_sets(d: dict, top: FittedModel, source: str) -> list[tuple[float, FittedModel]]:
    """A model.json's ``by_temperature`` after the schema (at least 2 entries, each an ambient
    in ``heat.AMBIENT_RANGE_C`` and an object): ambients strictly increasing, each set a valid
    model.json of its own (every check of the top level, its refusal naming the set's place)
    holding no sets, all with the top level's elements, and the top level the set
    :func:`top_set` names in every field that decides the voltage."""
    sets = []
    for j, entry in enumerate(d["by_temperature"]):
        at = f"by_temperature[{j}]"
        a = float(entry["ambient_c"])
        if sets and not a > sets[-1][0]:
            raise DataError(f"{source}: field '{at}.ambient_c': {a:g} °C, not above the set "
                            f"before ({sets[-1][0]:g} °C): the sets run coldest first, one per "
                            "test temperature")  # fmt: skip
        sd = entry["model"]
        if isinstance(sd, dict) and sd.get("by_temperature") is not None:
            raise DataError(f"{source}: field '{at}.model.by_temperature': a set holds no sets")
        try:
            m = FittedModel.from_json(sd, source)
        except DataError as exc:
            text, head = str(exc), f"{source}: field '"
            if text.startswith(head):
                text = f"{head}{at}.model.{text.removeprefix(head)}"
            else:
                text = f"{source}: field '{at}.model': {text.removeprefix(f'{source}: ')}"
            raise DataError(text) from None
        if m.config.effects != top.config.effects:
            raise DataError(f"{source}: field '{at}.model.effects': {list(m.config.effects)}, "
                            f"but the top level's are {list(top.config.effects)} (every set "
                            "holds the union of the sets' elements, a missing one "
                            "neutral)")  # fmt: skip
        sets.append((a, m))
    k = top_set(sets)
    want = d["by_temperature"][k]["model"]
    for key in _VOLTAGE_FIELDS:
        if d[key] != want[key]:
            raise DataError(f"{source}: field '{key}': not by_temperature[{k}]'s ({sets[k][0]:g} "
                            "°C, the set nearest the sets' reference temperature): the top "
                            "level is that set, what a reader that knows nothing of the sets "
                            "runs")  # fmt: skip
    return sets


def training_current_scale(recs) -> float:
    """The current a model was fitted at: the largest of its training records' current scales
    (99th-percentile |I|, ``records.current_scale``)."""
    return max(current_scale(r.i) for r in recs)


def probe_record(model: FittedModel) -> tuple[pd.DataFrame, float, str]:
    """(record, initial SOC, what it is) on which ``export`` judges a model without a record of
    the cell: from the top of the SOC range the model was fitted on (its knots) a discharge to
    the bottom, a rest and a charge back, at the model's training current (else at
    :data:`PROBE_C_RATE` of its capacity) and its reference temperature."""
    grid = model.knots.grid()
    lo, hi = max(float(grid[0]), 0.0), float(grid[-1])
    q = float(10.0 ** model.x[IDX["lq"]])
    if model.current_scale_a is not None:
        amps, what = model.current_scale_a, f"its training current ({model.current_scale_a:.3g} A)"
    else:
        amps, what = PROBE_C_RATE * q, f"{PROBE_C_RATE:g}C (model.json has no current_scale_a)"
    dt = max(hi - lo, 1e-3) * q * 3600.0 / amps / PROBE_SAMPLES  # a leg crosses the range
    rest = np.zeros(PROBE_SAMPLES // 10)
    cur = np.concatenate([rest, np.full(PROBE_SAMPLES, amps), rest,
                          np.full(PROBE_SAMPLES, -amps), rest])  # fmt: skip
    frame = pd.DataFrame({
        "time_s": dt * np.arange(cur.size),
        "current_a": cur,
        "voltage_v": np.zeros(cur.size),  # not measured: the probe's initial SOC is given
        "temperature_c": np.full(cur.size, model.tref_k - 273.15),
    })  # fmt: skip
    return frame, hi, f"under a discharge and charge at {what} across the SOC it was fitted on"


def _validate(d, schema: dict, source: str) -> None:
    err = jsonschema.exceptions.best_match(_Validator(schema).iter_errors(d))
    if err is not None:
        field, what = _refusal(err)
        raise DataError(f"{source}: field '{field}': {what}")


def fit_model(frames, config: Config, capacity_ah: float | None = None,
              soc0: float | None = None, provenance: dict | None = None):  # fmt: skip
    """Fit ``config`` to one or several records of one cell: the base by multi-start least
    squares, then the configuration's elements one at a time, each started from the previous
    fit (as the diagnosis's ladder adds them); every fit checked (``fitting.check_fit``, reported
    in ``Fit.checks``), and an element whose fit ends above the fit without it fitted again from
    that one with the element neutral (a nested model cannot fit worse; the selection's
    ``try_effects`` keeps the reference's optimum so). Shared cell parameters, each record
    started by the library's rule (``fitting.structure``) and counting alike; one reference
    temperature (the mean over all records). The training RMSE is the records-alike one (the
    root of the mean over records of each record's mean squared error). The model carries its
    parameters' intervals (``model/intervals.py``). Returns a ``fitting.Fit``."""
    from . import fitting, intervals

    frames = [frames] if isinstance(frames, pd.DataFrame) else list(frames)
    recs = [Record.from_frame(f, tref_k=reference_temperature(frames)) for f in frames]
    base_cfg = Config((), config.table, config.load_ohm)
    fix_q, fix_s = capacity_ah is not None, soc0 is not None
    st = fitting.structure(recs, base_cfg, None, fix_q, fix_s)
    res = fitting.best_of(recs, st, fitting.base_starts(recs, base_cfg, capacity_ah, soc0))
    knots = fitting.knots_for(recs, res.X)
    nfev, X, now, checks = res.nfev, res.X, base_cfg, res.checks
    for e in config.effects:
        now = now.with_effect(e)
        st = fitting.structure(recs, now, knots, fix_q, fix_s)
        ref, res = res, fitting.best_of(recs, st, fitting.effect_starts(recs, X, e, config.table))
        if res.cost_fit > ref.cost_fit:  # a nested model cannot fit worse (as the selection's
            # try_effects): fit again from the reference's optimum with the element neutral
            nfev += res.nfev
            res = fitting.best_of(recs, st, [fitting.neutralise(X, (e,))])
        nfev, X, checks = nfev + res.nfev, res.X, checks + res.checks
    st = fitting.structure(recs, config, knots, fix_q, fix_s)
    X = fitting.complete(st, recs, X)
    mse = [float(np.mean((ecm.simulate_rows(rec, X[r], knots, config.table,
                                            config.load_ohm)[:, 0] - rec.v) ** 2))
           for r, rec in enumerate(recs)]  # fmt: skip
    model = model_of(recs, config, X, knots, fix_q, provenance)
    model.intervals = intervals.of_fit(recs, st, X).report()
    return fitting.Fit(X, res.cost_fit, nfev, model, 1e3 * float(np.sqrt(np.mean(mse))), checks)


def model_of(recs, config: Config, X: np.ndarray, knots: Knots, fix_capacity: bool,
             provenance: dict | None = None, pinned=()) -> FittedModel:  # fmt: skip
    """The fitted model of ``config`` fitted as rows ``X`` to ``recs``: the cell's parameters
    (the first row's), the bounds the fit searched (``fitting.bounds_for``; a given capacity
    held at its value), the records' reference temperature and current scale."""
    from . import fitting

    b = fitting.bounds_for(recs, config.table)
    bounds = {n: b[n] for n in config.names() if not ecm.PARAMS[n].per_record}
    if fix_capacity:
        bounds["lq"] = (X[0, IDX["lq"]],) * 2
    for n in pinned:  # held at its neutral value by the fit (``fitting.Structure.pinned``)
        bounds[n] = (X[0, IDX[n]],) * 2
    return FittedModel(config, X[0].copy(), knots, recs[0].tref_k, bounds, provenance or {},
                       training_current_scale(recs))  # fmt: skip


def reference_temperature(frames) -> float | None:
    """One reference temperature (K) for records fitted together (the thermal and
    Butler–Volmer parameters are shared): the mean of every measured sample; None without a
    temperature column (each record then takes its own, ``Record.from_frame``)."""
    temps = [f["temperature_c"].to_numpy() for f in frames if "temperature_c" in f.columns]
    return float(np.mean(np.concatenate(temps))) + 273.15 if temps else None


def prediction_errors(model_v, measured_v, inside: np.ndarray | None = None) -> dict:
    """RMSE and largest |error| (mV) of a model's voltage against a record's; infinite where
    the model gave a non-finite value. With ``inside`` (a mask), also the RMSE over it and its
    share of the samples (a diagnosis's validation: inside the SOC range it trained on)."""
    e = np.asarray(model_v, dtype=float) - np.asarray(measured_v, dtype=float)
    if not np.all(np.isfinite(e)):
        out = {"rmse_mv": float("inf"), "max_err_mv": float("inf")}
    else:
        out = {"rmse_mv": 1e3 * float(np.sqrt(np.mean(e**2))),
               "max_err_mv": 1e3 * float(np.max(np.abs(e)))}  # fmt: skip
    if inside is not None:
        out["rmse_in_training_soc_mv"] = (1e3 * float(np.sqrt(np.mean(e[inside] ** 2)))
                                          if inside.any() else None)  # fmt: skip
        out["share_in_training_soc"] = float(np.mean(inside))
    return out
