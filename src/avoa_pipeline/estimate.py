"""SOC estimation with a fitted model (issue 29): an unscented Kalman filter over the model's
states, reading a record's current and voltage; ``python -m avoa_pipeline estimate``.

The state-space form. The model is ``model.ecm``'s (its docstring has the equations): the compiled
simulator keeps its state inside, so the filter steps a second compiled function,
``ecm.COMPILED.step``, written from the same element statements (``model/loopgen.py``) with the
state exposed, one sample for all rows (the filter's sigma points): :meth:`Model.transition` steps
the state over one sample, :meth:`Model.measurement` gives the terminal voltage. State, in this
order: SOC s, RC branch 1's voltage v1, then each of the model's elements' states in registry order
(``State`` in its module: v2 with ``second_rc``, v3 with ``third_rc``, the diffusion lag δ, the
hysteresis h), then two states every model gets: the current-sensor bias b (A, added to the current
read) and the model's voltage error e (V, added to the voltage). The temperature is not a state: the
record's measured ``temperature_c`` drives the temperature laws as in ``simulate``. Open loop (no
correction, b = e = 0) the step reproduces ``FittedModel.simulate`` to 1e-9 V on every element
(``tests/unit/test_estimate.py``; not bit for bit: the filter reads a table by ``np.interp`` and
continues it past its ends). A model with the paper's load resistor (``load_ohm``: the current
follows the voltage) is refused.

The filter: filterpy 2.0's ``UnscentedKalmanFilter`` (sigma points, the unscented transform, the
update), a kept library rather than a hand-written one. filterpy calls the model once per sigma
point; ``VectorUKF`` (in :func:`_filterpy`) makes it one vectorised call per step instead (its
process sigmas in one call, its measurement sigmas computed in one call and handed to filterpy
in its order): about 1 ms a sample on the shared 2-core machine under load, the 14,102-s 25 °C
LA92 record at 1 Hz in 13.4 s (1,052× real time; the issue asks 20×; docs/real-data.md). An
EKF would need the Jacobian of every element written out and kept in step with ecm's equations;
the sigma points need only the equations. filterpy is a dependency for this module alone
(environment.txt, pyproject.toml).

The noise, from the model file alone (never tuned per record; each constant below says why).
Issue 40's rule (docs/soc-filter.md, written before its code) is the default
(``noise="expected-error"``): e's sd is the model's error on other profiles by operating point,
``model.json``'s ``expected_error`` (:class:`ErrorBins`), its correlation time that block's
``correlation_time_s``, and the white noise the logger's alone (the held-out error already holds
what the parameters' uncertainty does to the voltage) plus, beside a step of the current, what
the step moves the voltage by (a cycler's current channel may be a sample late:
:func:`_edge_neighbours`); the SOC's sd is kept at least σ / (dV/dSOC) (:func:`_hold_soc_floor`:
the model's error belongs to the operating point and is not averaged away); and a scale of e's
variance from what the filter attributes to e (:class:`Adaptation`) widens it on the record
itself. Where ``model.json`` has no ``expected_error``, or with ``noise="training-residual"``,
issue 29's rule below runs (its sd constant, its correlation from the training residual):

- **The voltage error e** (a state, not white noise): the model's training residual, whose sd is
  ``intervals.residual_sd_mv`` and whose integrated autocorrelation time is the training
  samples over ``intervals.effective_samples`` (the same two numbers the model's 95 % intervals
  are built on). A residual that keeps its sign for many minutes is not white: treated as white,
  a filter would read each sample as new evidence and grow certain of a SOC that only absorbs the
  model's bias. So e is a first-order Gauss-Markov process (the textbook treatment of coloured
  measurement noise, Bryson & Henrikson 1968) with that sd and a correlation time τc = τint/2
  samples (an AR(1)'s integrated autocorrelation time is 2τc): e_k+1 = φ·e_k + w, φ = exp(−Δt/τc),
  var w = σ²(1 − φ²). A large SOC error (hundreds of mV) is corrected within minutes; a model
  error of σ cannot be told from SOC, so the SOC's sd does not fall below about σ / dOCV/dSOC.
- **White measurement noise**: :data:`LOGGER_NOISE_V`, plus what each cell parameter's 95 %
  interval (``intervals.parameters``; sd = half-width / 1.96) moves the voltage at the current
  state (one perturbed row per parameter, summed in quadrature: a linearised propagation of the
  parameters' uncertainty, taken independent since model.json keeps no covariance).
- **Process noise**: the same propagation through :func:`transition` (how much each state's step
  moves when a parameter moves by its sd), plus the bias's random walk
  (:data:`BIAS_DRIFT_TIME_S`).
- **The start**: the guess (``--soc0``; default the library's initial-SOC rule on the record's
  opening) with sd :data:`SOC0_SD`; each RC voltage, the lag and h uniform over their reachable
  range (sd = range/√3); e at its stationary sd; b at 0 with sd :data:`BIAS_SD_OF_RANGE` of the
  record's largest |current|.

What cannot be right is said (issue 38): a SOC that leaves the model's SOC range
(:func:`soc_range`) by more than :data:`RANGE_SD` of its sd is reported (:func:`outside_range`,
a warning of the command); ``--current-bias-a`` beyond the record's currents is refused
(:func:`bias_limit_a`); a record that only rests is a valid one (its SOC is the OCV's).

Current bias: the state b (random walk) absorbs a sensor offset: a constant offset makes the
coulomb count drift by b·t/(3600·Q), which the voltage then contradicts, and the filter moves b
rather than pushing the SOC against the count at every step. ``--current-bias-a B`` adds B to
the current the filter reads (a sensor off by B A, to test this); a reference (``--reference-soc0``)
counts with the record's own current.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from .errors import DataError, UserError
from .handover import SOC_EDGES
from .model import ecm, elements, heat
from .model.ecm import IDX, N_KNOTS
from .model.elements.element import FARADAY, GAS_R
from .model.fitted import first_temperature

LOGGER_NOISE_V = 1e-3
"""White voltage noise (V): a cell tester's noise and resolution. The Panasonic records' step
noise is 0.46-0.67 mV (their sidecars' ``sign_check.noise_mv``); a 16-bit reading over 5 V
resolves 0.08 mV; 1 mV covers the loggers this package reads without claiming more."""

SOC0_SD = 0.25
"""The start guess's sd (fraction of capacity): a cold start knows little, so a guess is taken to
lie within ±0.5 of the truth at 95 % (half the SOC range either way)."""

BIAS_SD_OF_RANGE = 0.01
"""The current-sensor offset's prior sd, as a fraction of the largest |current| of the record (a
sensor's range must cover it): automotive Hall-effect current sensors are specified to an offset
of 0.5-1 % of their range."""

BIAS_DRIFT_TIME_S = 3600.0
"""The offset's random walk: in this time it may move by its prior sd (a sensor's offset follows
its temperature, which changes over an hour of driving, not over seconds)."""

SIGMA_SPREAD = 1.0
"""Sigma points at ±1 sd along each axis (Merwe's scaling, α = 1/√n, κ = 0, β = 2 for a
Gaussian prior; the unscented transform is exact to second order at any spread). Not at ±√3 sd
(a Gaussian's fourth moment, Julier & Uhlmann 2004): with the start's SOC sd of 0.25 near full
charge those points sit 0.43 past the OCV table's end, where the voltage is only the
continuation of :meth:`Model._ends` (on the 25 °C training LA92 record the first update from
the true start then moved the SOC 6 % off; docs/real-data.md has what else was tried)."""

END_SLOPE_SPAN = 0.02
"""The SOC span at each end of a measured OCV table over which the filter reads the slope it
continues past that end: 2 % of SOC, twenty steps of the table's 0.1 % grid (a slope over one
step would carry the table's rounding)."""

RANGE_SD = 2.0
"""An estimated SOC beyond the model's SOC range (:func:`soc_range`) by more than this many of
its own sd is one the cell cannot have (:func:`outside_range`): ±2 sd is the band whose coverage
the filter is scored on (``coverage_2sd``); a SOC just past an end within it is the filter's
uncertainty, not a contradiction."""

NOISE_RULES = ("expected-error", "training-residual")
"""``--noise``: the voltage error from ``expected_error`` (issue 40, the default) or from the
training residual (issue 29); docs/soc-filter.md."""
NO_EXPECTED_ERROR = "training-residual (model.json has no expected_error)"
"""``noise.rule`` when ``expected-error`` was asked of a model.json written before issue 37."""

ADAPT_WINDOW_S = 300.0
"""The adaptation's batch of innovations (docs/soc-filter.md part 3): the issue's 5-min window,
so a start's transient falls in one batch, not in the record's whole history."""
ADAPT_MIN_SAMPLES = 50
"""... and at least 50 innovations a batch: the relative sd of a mean of n independent χ²₁ is
√(2/n), 20 % at 50 (a rest logged every 60 s waits for 50 samples rather than adapting on 5)."""
ADAPT_BOUNDS = (1.0, 100.0)
"""The scale λ of e's variance: its sd between once and ten times the expected error. Once, not
less (docs/soc-filter.md's addendum; part 3 first wrote a half): the SOC's floor lets the SOC,
not e, carry a persistent error, so a small ê does not show a small model error, and the
adaptation only widens. Ten times: a record the model does not describe (``outside_range``'s
business), said by the share of time there."""

CONVERGENCE_S = 300.0
"""The issue's convergence window: errors are scored after the first 5 min."""
WITHIN = 0.02
"""The issue's "within 2 %" of SOC."""

TOP_TOL_V = 0.005
"""``--bms-events`` (docs/soc-filter.md part 5): a voltage within 5 mV of the charge's top (or of
the lower cut-off) is at it: a cycler holds its CV set point to 1-2.5 mV and logs about 1 mV; an
ohmic step moves 10-30 mV."""
CV_MIN_S = 60.0
"""A CV phase lasts at least 60 s: two samples of a CV phase logged every 60 s."""
CV_TAPER = 0.5
"""... and its current falls to at most half its start (a CC charge stopped at the top keeps its
current; a current a sample late moves a taper by one sample, not by half)."""
FULL_SD_MIN = 0.005
"""The least sd of a pseudo-measurement of the SOC (0.5 %): a CC-CV end's gap or a cut-off's
bound is never taken as known better than this."""
CUTOFF_MIN_LOAD_S = 60.0
"""The lower cut-off bounds the SOC only after 60 s of discharge: a preceding charge's
overpotential (which raises the voltage) must be gone; a shorter spike is reported, not used."""

_Z95 = 1.959963984540054  # a two-sided 95 % interval is ±1.96 sd


@dataclass(frozen=True)
class Layout:
    """Which states a model has, in order, and where each sits."""

    names: tuple[str, ...]

    def __getitem__(self, name: str) -> int:
        return self.names.index(name)

    def has(self, name: str) -> bool:
        return name in self.names

    @property
    def n(self) -> int:
        return len(self.names)


def layout_of(effects) -> Layout:
    """The SOC, RC branch 1, each of ``effects``' states in registry order (the elements'
    statements, :class:`.elements.element.State`), then the bias and the voltage error."""
    names = [st.name for e in elements.NAMES if e in effects
             for st in elements.get(e).kernel.states.values()]  # fmt: skip
    return Layout(("soc", "v1", *names, "bias", "verr"))


def state_reach() -> dict[str, object]:
    """Each state's reach (``State.reach``: the largest |value| at a current), by state name."""
    out = {"v1": lambda p, i: p["r1"] * i}  # the base's RC branch
    for e in elements.REGISTRY.values():
        out |= {st.name: st.reach for st in e.kernel.states.values()}
    return out


def _temperature_offset(dinv, rtf):
    """T − Tref (K) from what a record carries: 2RT/F gives T, 1/T − 1/Tref gives Tref."""
    tk = rtf * FARADAY / (2.0 * GAS_R)
    return tk - 1.0 / (1.0 / tk - dinv)


_NO_TABLE = np.empty(0)
_FULL = {name: k for k, name in enumerate(ecm.COMPILED.STATES)}


@dataclass(frozen=True)
class Model:
    """A fitted model as the filter steps it: its physical rows, OCV and state layout. Its
    state step and measurement are the compiled ``step`` of ``ecm.COMPILED``, written from the same
    element statements as the simulator (``model/loopgen.py``)."""

    P: np.ndarray  # (m, NP): row 0 the model's; more rows: the same model, parameters moved
    layout: Layout
    knots: ecm.Knots
    table: ecm.OcvTable | None

    extend: bool = False  # the filter's OCV continues past the table's ends (_ends)

    def rows(self, P: np.ndarray) -> Model:
        return Model(np.atleast_2d(P), self.layout, self.knots, self.table, self.extend)

    def extended(self) -> Model:
        return Model(self.P, self.layout, self.knots, self.table, True)

    def _ends(self) -> np.ndarray:
        """Past the table's ends, the OCV goes on with its slope over the last
        :data:`END_SLOPE_SPAN` of SOC at that end (the simulator holds it flat there): a state
        outside the table (a start guessed above full) then still reads a voltage that pulls it
        back, and sigma points spread across an end see the slope on both sides. Inside the
        table, nothing changes. (on, first SOC, last SOC, slope below, slope above)"""
        if self.table is None or not self.extend:
            return np.zeros(5)
        g, v = self.table.grid(), self.table.values
        w = max(round(END_SLOPE_SPAN / self.table.step), 1)
        lo_slope = (v[w] - v[0]) / (g[w] - g[0])
        hi_slope = (v[-1] - v[-1 - w]) / (g[-1] - g[-1 - w])
        return np.array([1.0, g[0], g[-1], lo_slope, hi_slope])

    def _later(self, name: str):
        """An element's physical column, or None where the library has no such parameter or
        every row has it at 0 (neutral)."""
        col = ecm.IDX.get(name)
        return None if col is None or not np.any(self.P[:, col]) else self.P[:, col]

    def _step(self, X, i_read, dt, dinv, rtf, need_v: bool, update: bool):
        """The compiled step on the rows of ``X`` (each with its parameter row, or all with row
        0): (voltage before the step, states after it)."""
        m, L = X.shape[0], self.layout
        P = self.P if self.P.shape[0] == m else np.repeat(self.P[:1], m, axis=0)
        cols = [_FULL[name] for name in L.names[:-2]]
        full = np.zeros((m, len(_FULL)))
        full[:, cols] = X[:, : L.n - 2]
        tab = self.table
        grid = _NO_TABLE if tab is None else tab.grid()
        out = np.empty(m)
        ecm.COMPILED.step(np.ascontiguousarray(P), _NO_TABLE if tab is None else tab.values,
                        0.0 if tab is None else tab.lo, 1.0 if tab is None else tab.step,
                        _NO_TABLE if tab is None else tab.dudt_shape(),
                        N_KNOTS, self.knots.lo, self.knots.step, grid, float(i_read), float(dt),
                        float(dinv), float(rtf), full, np.ascontiguousarray(X[:, L["bias"]]),
                        need_v, update, self._ends(), out)  # fmt: skip
        return out, full[:, cols]

    def transition(self, X: np.ndarray, i_read: float, dt: float, dinv: float,
                   rtf: float) -> np.ndarray:  # fmt: skip
        """The state after one sample of ``dt`` s (rows of ``X`` stepped together, each with
        its parameter row, or all with row 0)."""
        _, states = self._step(X, i_read, dt, dinv, rtf, need_v=False, update=True)
        out = X.copy()
        out[:, : self.layout.n - 2] = states
        return out

    def measurement(self, X: np.ndarray, i_read: float, dinv: float, rtf: float,
                    with_error: bool = True) -> np.ndarray:  # fmt: skip
        """Terminal voltage of each row of ``X``, plus the error state e."""
        v, _ = self._step(X, i_read, 1.0, dinv, rtf, need_v=True, update=False)
        return v + X[:, self.layout["verr"]] if with_error else v


# ----------------------------------------------------------------------------------------------
# the model file → the filter's model and noise


UNSUPPORTED = {"load": "the paper's load resistor makes the current follow the voltage"}
"""What the filter cannot step, and why. Every registered element it can: its state step and
measurement are written from the elements' statements (``model/loopgen.py``)."""


def filter_model(fitted, source: str = "model.json") -> Model:
    """The filter's form of a ``FittedModel`` (refused, one line, for what it cannot step)."""
    missing = [e for e in fitted.config.effects if e not in elements.REGISTRY]
    if missing:
        raise DataError(f"{source}: effects: estimate does not support "
                        f"{', '.join(map(repr, missing))} (its equations are not in the filter's "
                        "state-space form, avoa_pipeline.estimate)")  # fmt: skip
    if fitted.config.load_ohm is not None:
        raise DataError(f"{source}: load_ohm: estimate does not support a model with a load "
                        f"resistor ({UNSUPPORTED['load']})")  # fmt: skip
    x = fitted.x.copy()
    x[IDX["h0"]] = 0.0
    return Model(ecm.to_physical(x), layout_of(fitted.config.effects), fitted.knots,
                 fitted.config.table)  # fmt: skip


_MODES = {"rest": 0, "discharge": 1, "charge": 2}
_CURRENTS = {"low": 0, "high": 1}


@dataclass(frozen=True)
class ErrorBins:
    """``model.json``'s ``expected_error`` as the filter reads it (docs/soc-filter.md part 1):
    the voltage error's sd by operating point, a bin it does not report given its largest RMS;
    for a model over temperature, at the record's ambient (part 6)."""

    sd_v: np.ndarray  # (mode rest/discharge/charge, current low/high, SOC below/mid/above)
    median_a: float | None  # load_current_median_a: low below it, high at or above
    tau_c_s: float  # correlation_time_s: an exponential autocorrelation's 1/e lag
    lower_bound: bool  # correlation_time_lower_bound
    filled: int  # bins not reported (fewer than MIN_BIN_SAMPLES held-out samples)
    temperature: dict | None = None  # where the record's ambient lies among the groups (part 6)

    @classmethod
    def of(cls, ee: dict, ambient: tuple[float, str] | None = None) -> ErrorBins:
        """``ambient``: the record's (°C, where it came from); read where ``ee`` is split by
        test temperature (``by_temperature``)."""
        groups = ee.get("by_temperature")
        if groups and ambient is not None:
            sd, filled, at = _at_ambient(groups, *ambient)
        else:
            (sd, filled), at = _bin_table(ee), None
        med = ee.get("load_current_median_a")
        return cls(sd, None if med is None else float(med), float(ee["correlation_time_s"]),
                   bool(ee["correlation_time_lower_bound"]), filled, at)  # fmt: skip

    def points(self, i_read: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per sample, the mode (0 rest, 1 discharge, 2 charge: ``records.direction``, the one
        rest line, on the record's current scale) and the current (0 low, 1 high)."""
        from . import records

        d = records.direction(i_read, max(records.current_scale(np.abs(i_read)), 1e-6))
        mode = np.where(d > 0, 1, np.where(d < 0, 2, 0))
        if self.median_a is None:  # no load in the held-out data: every load bin is filled
            return mode, np.zeros(mode.size, dtype=int)
        return mode, (np.abs(i_read) >= self.median_a).astype(int)

    def sd(self, mode: int, current: int, soc: float) -> float:
        band = 0 if soc < SOC_EDGES[0] else (2 if soc > SOC_EDGES[1] else 1)  # handover's
        return float(self.sd_v[mode, current, band])


def _bin_table(ee: dict) -> tuple[np.ndarray, int]:
    """The (3, 2, 3) table of sds of an ``expected_error`` (or one temperature's group of it);
    a bin it does not report takes its largest RMS (part 1), and how many did."""
    lo, hi = SOC_EDGES
    socs = {f"below {lo:g}": 0, f"{lo:g}-{hi:g}": 1, f"above {hi:g}": 2}  # handover's names
    given = ee["by_operating_point"]
    # a point the held-out data barely visited: no evidence the model is better there than at
    # its worst measured one
    worst = 1e-3 * max([float(ee["rms_mv"])] + [float(b["rms_mv"]) for b in given])
    sd = np.full((3, 2, 3), np.nan)
    for b in given:
        cur = [0, 1] if b["current"] == "-" else [_CURRENTS[b["current"]]]  # a rest has one
        sd[_MODES[b["mode"]], cur, socs[b["soc"]]] = 1e-3 * float(b["rms_mv"])
    filled = int(np.isnan(sd[0, 0]).sum() + np.isnan(sd[1:]).sum())
    return np.where(np.isnan(sd), worst, sd), filled


def _at_ambient(groups: list[dict], ambient_c: float, where: str) -> tuple[np.ndarray, int, dict]:
    """Part 6: the bins at an ambient, interpolated linearly in 1/T between the two groups
    around it, the nearest group's outside their span."""
    groups = sorted(groups, key=lambda g: g["ambient_c"])
    temps = np.array([float(g["ambient_c"]) for g in groups])
    tables = [_bin_table(g) for g in groups]
    info = {"ambient_c": float(ambient_c), "from": where, "groups_c": temps.tolist()}
    if ambient_c <= temps[0] or ambient_c >= temps[-1]:
        k = 0 if ambient_c <= temps[0] else temps.size - 1
        outside = not np.isclose(ambient_c, temps[k])
        return tables[k][0], tables[k][1], info | {"between_c": [temps[k]], "outside": outside}
    k = int(np.searchsorted(temps, ambient_c))  # temps[k-1] < ambient < temps[k]
    x, x0, x1 = (1.0 / (c + 273.15) for c in (ambient_c, temps[k - 1], temps[k]))
    w = (x - x0) / (x1 - x0)
    sd = (1.0 - w) * tables[k - 1][0] + w * tables[k][0]
    filled = max(tables[k - 1][1], tables[k][1])
    return sd, filled, info | {"between_c": [temps[k - 1], temps[k]], "outside": False}


@dataclass(frozen=True)
class Noise:
    """The filter's noise, from the model file (module docstring)."""

    residual_sd_v: float  # the training residual's sd
    tau_int_samples: float  # its integrated autocorrelation time, in training samples
    perturbed: np.ndarray  # (p, NP): one row per parameter with an interval, moved by its sd
    parameters: tuple[str, ...]
    rule: str = "training-residual"  # which rule sets e (NOISE_RULES, or NO_EXPECTED_ERROR)
    bins: ErrorBins | None = None  # with the rule "expected-error"

    def summary(self) -> dict:
        out = {"rule": self.rule, "residual_sd_mv": 1e3 * self.residual_sd_v,
               "residual_correlation_samples": self.tau_int_samples,
               "logger_noise_mv": 1e3 * LOGGER_NOISE_V, "soc0_sd": SOC0_SD,
               "bias_sd_of_range": BIAS_SD_OF_RANGE, "bias_drift_time_s": BIAS_DRIFT_TIME_S,
               "parameters_propagated": list(self.parameters)}  # fmt: skip
        if self.bins is not None:
            out |= {"parameters_in_voltage": False,
                    "expected_error_correlation_time_s": self.bins.tau_c_s,
                    "expected_error_correlation_lower_bound": self.bins.lower_bound,
                    "expected_error_bins_filled": self.bins.filled}  # fmt: skip
            if self.bins.temperature is not None:
                out["temperature"] = self.bins.temperature
        return out

    def warning(self, source: str) -> str | None:
        """The one line for a model that lacks what the rule asked (docs/soc-filter.md)."""
        if self.rule != NO_EXPECTED_ERROR:
            return None
        return (f"{source}: no expected_error (diagnose writes it since issue 37): the filter's "
                "voltage error is the training residual (issue 29's rule)")  # fmt: skip


def noise_of(fitted, source: str = "model.json", rule: str = "training-residual",
             ambient: tuple[float, str] | None = None) -> Noise:  # fmt: skip
    """The noise rule's inputs from a model's ``intervals`` (refused without them) and, with
    ``rule="expected-error"``, its ``expected_error`` (issue 29's rule where it has none), at the
    record's ``ambient`` (°C, where it came from) for a model over temperature."""
    base = _residual_noise(fitted, source)
    if rule == "training-residual":
        return base
    if fitted.expected_error is None:
        return replace(base, rule=NO_EXPECTED_ERROR)
    return replace(base, rule="expected-error", bins=ErrorBins.of(fitted.expected_error, ambient))


def record_ambient(fitted, frame: pd.DataFrame,
                   ambient: tuple[float, str] | None = None) -> tuple[float, str]:  # fmt: skip
    """The record's ambient for part 6 of docs/soc-filter.md: the one given
    (``heat.ambient_if_any``), else the frame's first temperature sample, else the model's
    reference temperature."""
    if ambient is not None:
        return float(ambient[0]), str(ambient[1])
    if "temperature_c" in frame.columns and len(frame):
        return float(frame["temperature_c"].iloc[0]), "first temperature sample"
    return float(fitted.tref_k) - 273.15, "the model's reference temperature"


def colder_than_trained(bins: ErrorBins | None, source: str) -> str | None:
    """The one line for a record colder than the model's coldest test temperature by more than
    a chamber's tolerance (part 6): the error there is at least the coldest group's."""
    at = None if bins is None else bins.temperature
    if at is None or at["ambient_c"] >= at["groups_c"][0] - heat.AMBIENT_GROUP_K:
        return None
    return (f"{source}: the record's ambient {at['ambient_c']:g} °C lies below the coldest "
            f"temperature of the model's held-out error ({at['groups_c'][0]:g} °C): its "
            "voltage error there is taken as that temperature's, which the cold likely "
            "exceeds")  # fmt: skip


def _residual_noise(fitted, source: str) -> Noise:
    iv = fitted.intervals
    if not iv or "residual_sd_mv" not in iv or "effective_samples" not in iv:
        raise DataError(f"{source}: intervals: missing; estimate sets its noise from the "
                        "model's training residuals and intervals (rerun diagnose to write "
                        "them)")  # fmt: skip
    n_eff = float(iv["effective_samples"])
    given = [t.get("n_samples") for t in fitted.provenance.get("training", [])]
    # the training records' samples (their time, at the logger's rate) per effective sample;
    # without them, the fitted samples per effective sample (a shorter, so humbler, correlation)
    n = float(sum(given)) if given and all(isinstance(g, int) for g in given) else iv["samples"]
    x = fitted.x.copy()
    x[IDX["h0"]] = 0.0
    rows, names = [], []
    for rep, p in iv.get("parameters", {}).items():
        if rep not in ecm.BY_REPORT or ecm.BY_REPORT[rep] not in fitted.names:
            continue
        name = ecm.BY_REPORT[rep]
        if p.get("low95") is None or p.get("high95") is None:  # held, or no interval computed
            continue
        lo, hi = float(p["low95"]), float(p["high95"])
        with np.errstate(divide="ignore", invalid="ignore"):
            a = ecm.internal_value(rep, lo)[1] if lo > 0 or ecm.PARAMS[name].transform == "lin" \
                else np.nan  # fmt: skip
            b = ecm.internal_value(rep, hi)[1]
        sd = (b - a) / (2.0 * _Z95)
        if not np.isfinite(sd) or sd <= 0:  # a log interval reaching 0: half the upper side
            sd = (b - x[IDX[name]]) / _Z95
        if np.isfinite(sd) and sd > 0:
            xp = x.copy()
            xp[IDX[name]] += sd
            rows.append(xp)
            names.append(rep)
    P = ecm.to_physical(np.array(rows)) if rows else np.empty((0, ecm.NP))
    return Noise(1e-3 * float(iv["residual_sd_mv"]), max(n / n_eff, 1.0), P, tuple(names))


# ----------------------------------------------------------------------------------------------
# the filter


def _filterpy():
    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

    class VectorUKF(UnscentedKalmanFilter):
        """filterpy's UKF with the model called once per step on all sigma points (``fx`` takes
        and returns the (N, n) array of them) instead of once per point."""

        def compute_process_sigmas(self, dt, fx=None, **fx_args):
            sigmas = self.points_fn.sigma_points(self.x, self.P)
            self.sigmas_f = (fx or self.fx)(sigmas, dt, **fx_args)

        def update_all(self, z, h_all: np.ndarray, R):
            # filterpy asks for the measurement of each sigma point in order: hand them out
            it = iter(h_all)
            self.update(np.array([z]), R=R, hx=lambda _s: np.array([next(it)]))

    return MerweScaledSigmaPoints, VectorUKF


@dataclass(frozen=True)
class Inputs:
    """A record as the filter reads it: per sample, the current read, the step, the
    temperature's Arrhenius argument and 2RT/F."""

    t: np.ndarray
    i: np.ndarray
    v: np.ndarray
    dt: np.ndarray
    dinv: np.ndarray
    rtf: np.ndarray

    @classmethod
    def of(cls, rec: ecm.Record, bias_a: float = 0.0) -> Inputs:
        return cls(rec.t, rec.i + bias_a, rec.v, rec.dt, rec.dinv_t, rec.two_rt_f)


def open_loop(model: Model, inp: Inputs, soc0: float) -> np.ndarray:
    """The model's voltage stepped by :meth:`Model.transition` alone (no correction, bias and
    error states 0): what ``FittedModel.simulate`` gives, from the state-space form."""
    X = np.zeros((1, model.layout.n))
    X[0, model.layout["soc"]] = soc0
    v = np.empty(inp.t.size)
    for k in range(inp.t.size):
        v[k] = model.measurement(X, inp.i[k], inp.dinv[k], inp.rtf[k])[0]
        X = model.transition(X, inp.i[k], inp.dt[k], inp.dinv[k], inp.rtf[k])
    return v


def initial_state(model: Model, noise: Noise, soc0: float, i_range: float, i_scale: float,
                  verr_sd: float | None = None):  # fmt: skip
    """The start's mean and covariance (module docstring: the guess; uniform ranges; e
    stationary, at ``verr_sd``, default the training residual's; b at 0)."""
    L = model.layout
    p = dict(zip(ecm.PHYS, model.P[0], strict=True))
    x0 = np.zeros(L.n)
    x0[L["soc"]] = soc0
    sd = np.zeros(L.n)
    sd[L["soc"]] = SOC0_SD
    reach = state_reach()
    for name in L.names[1:-2]:  # uniform over ±reach
        sd[L[name]] = reach[name](p, i_scale) / np.sqrt(3.0)
    sd[L["bias"]] = BIAS_SD_OF_RANGE * i_range
    sd[L["verr"]] = noise.residual_sd_v if verr_sd is None else verr_sd
    return x0, np.diag(np.maximum(sd, 1e-9) ** 2)


class Adaptation:
    """The scale λ of e's variance from what the filter attributes to e (docs/soc-filter.md, part
    3 and its addendum): the variational-Bayes form of covariance matching (Särkkä & Nummenmaa,
    IEEE TAC 54 (2009) 596-600: a variance is the expected squared error under the posterior).
    Over a batch of at least :data:`ADAPT_WINDOW_S` and :data:`ADAPT_MIN_SAMPLES` samples,
    λ = mean (ê² + Pee) / mean σ(k)², within :data:`ADAPT_BOUNDS` (it only widens). Batches
    start after :data:`CONVERGENCE_S` (a wrong start's transient is not a model error).
    Innovation matching (Mohamed & Schwarz 1999), the rule as first written, sat at its lower
    bound on every development record: the SOC's floor puts σ² into the innovations' S."""

    def __init__(self, on: bool, t0: float):
        self.on, self.t0 = on, t0
        self.lam, self.lam_max, self.updates = 1.0, 1.0, 0
        self.samples, self.at_upper = 0, 0
        self._reset(None)

    def _reset(self, t):
        self.start, self.n, self.nu2, self.rest, self.pee = t, 0, 0.0, 0.0, 0.0

    def add(self, t: float, e: float, pee: float, var: float) -> float | None:
        """One sample's updated e, its variance and the rule's σ(k)² there; at a batch's end,
        the factor λ moved by (else None)."""
        if not self.on or t - self.t0 < CONVERGENCE_S:
            return None
        self.samples += 1
        self.at_upper += self.lam >= ADAPT_BOUNDS[1]
        if self.start is None:
            self.start = t
        self.n += 1
        self.nu2 += e * e + pee  # E[e²] given the record so far
        self.pee += var
        if self.n < ADAPT_MIN_SAMPLES or t - self.start < ADAPT_WINDOW_S:
            return None
        new = float(np.clip(self.nu2 / self.pee, *ADAPT_BOUNDS))
        factor, self.lam = new / self.lam, new
        self.lam_max = max(self.lam_max, new)
        self.updates += 1
        self._reset(None)
        return factor

    def summary(self) -> dict:
        out = {"adapt": self.on}
        if self.on:
            out |= {"method": "variational-Bayes matching of e's variance (Särkkä & Nummenmaa "
                              "2009)",
                    "window_s": ADAPT_WINDOW_S, "min_samples": ADAPT_MIN_SAMPLES,
                    "bounds": list(ADAPT_BOUNDS), "starts_after_s": CONVERGENCE_S,
                    "updates": self.updates, "final_scale": self.lam,
                    "largest_scale": self.lam_max,
                    "share_at_upper_bound": self.at_upper / max(self.samples, 1)}  # fmt: skip
        return out


@dataclass(frozen=True)
class Estimate:
    soc: np.ndarray
    soc_sd: np.ndarray
    model_v: np.ndarray
    innovation_v: np.ndarray
    bias_a: np.ndarray
    bias_sd: np.ndarray
    wall_s: float
    adaptation: dict | None = None  # Adaptation.summary()
    applied: dict | None = None  # sample → whether its pseudo-measurement ran (bms_events)


def _error_sd(noise: Noise, inp: Inputs):
    """e's sd at sample k given the SOC (the rule's σ(k)) and e's correlation time (s)."""
    bins = noise.bins
    if bins is None:  # issue 29: the training residual, its correlation from the training samples
        sd = noise.residual_sd_v
        return (lambda _k, _soc: sd), 0.5 * noise.tau_int_samples * float(np.median(inp.dt))
    mode, cur = bins.points(inp.i)
    # a held-out error already below 1/e at lag 1 is white at the training step: φ = 0 then
    return (lambda k, soc: bins.sd(mode[k], cur[k], soc)), max(bins.tau_c_s, 1e-9)


SOC_FLOOR_SPAN = 0.01
"""The SOC step over which the filter reads the voltage's slope for the SOC's floor (one point of
SOC either way: the OCV table's 0.1 % grid smoothed, the knees still seen)."""


def _hold_soc_floor(ukf, nominal: Model, i_k, dinv, rtf, var_v: float) -> None:
    """The SOC's variance kept at least var_v / (dV/dSOC)² (docs/soc-filter.md, addendum): the
    model's error at an operating point returns whenever the cell does, so it is not averaged
    away over many correlation times; never above the cold start's SOC0_SD²."""
    x = np.repeat(ukf.x[None, :], 2, axis=0)
    x[0, 0] += SOC_FLOOR_SPAN
    x[1, 0] -= SOC_FLOOR_SPAN
    v = nominal.measurement(x, i_k, dinv, rtf, with_error=False)
    slope = abs(v[0] - v[1]) / (2.0 * SOC_FLOOR_SPAN)
    floor = SOC0_SD**2 if slope * SOC0_SD <= np.sqrt(var_v) else var_v / slope**2
    p00 = ukf.P[0, 0]
    if 0.0 < p00 < floor:
        g = np.sqrt(floor / p00)
        ukf.P[0, :] *= g
        ukf.P[:, 0] *= g


def _voltage_noise(nominal: Model, pert: Model | None, x, i_k, dinv, rtf, across) -> float:
    """The white noise's variance at a sample: the logger's; the parameters' intervals moved
    through the voltage (``pert``, issue 29's rule); beside a step of the current, the largest
    square of what the model's voltage moves at the state with the current ``across`` it (the
    step may fall a sample either way, docs/soc-filter.md's addendum)."""
    r = LOGGER_NOISE_V**2
    if pert is not None:
        xb = np.repeat(x[None, :], pert.P.shape[0], axis=0)
        dv = pert.measurement(xb, i_k, dinv, rtf) - nominal.measurement(xb[:1], i_k, dinv, rtf)
        r += float(dv @ dv)
    if across:
        v_k = nominal.measurement(x[None, :], i_k, dinv, rtf)[0]
        r += max((nominal.measurement(x[None, :], i, dinv, rtf)[0] - v_k) ** 2 for i in across)
    return r


@dataclass
class _ErrorProcess:
    """e's driving noise over a step: stationary at the next sample's σ; with ``lifts`` (σ by
    operating point), where the process holds less than σ_next² (a bin of larger error) it is
    lifted to it at once, a smaller one decays through φ. Without it (issue 29's rule, σ
    constant) the arithmetic is issue 29's."""

    sd: object  # (sample, SOC) → σ
    tau_c_s: float
    lifts: bool
    var: float  # the variance the process holds now (before λ)

    def drive(self, k: int, soc: float, dt: float) -> float:
        sd_next = self.sd(k, soc)
        keep = np.exp(-2.0 * dt / self.tau_c_s)
        drive = sd_next**2 * (1.0 - keep)
        if self.lifts:
            drive += max(sd_next**2 - (keep * self.var + drive), 0.0)
            self.var = keep * self.var + drive
        return drive


def _edge_neighbours(i_read: np.ndarray) -> dict[int, list[int]]:
    """The samples beside a step of the current read, each with its neighbours across the step:
    a cycler's current channel can lag (or lead) its voltage by a sample at an edge, so such a
    sample's voltage may belong to either current."""
    out: dict[int, list[int]] = {}
    for k in np.flatnonzero(np.diff(i_read) != 0.0):
        out.setdefault(int(k), []).append(int(k) + 1)
        out.setdefault(int(k) + 1, []).append(int(k))
    return out


# ----------------------------------------------------------------------------------------------
# what a BMS knows (``--bms-events``, docs/soc-filter.md part 5)


def _directions(i: np.ndarray) -> np.ndarray:
    """Each sample's direction by the one rest line (``records.direction``); all rest for a
    record without current (the rest line has no scale there)."""
    from . import records

    return records.direction(i) if np.any(i) else np.zeros(i.size)


def _stretches(d: np.ndarray, sign: int) -> list[tuple[int, int]]:
    """(first, last) sample of each run of samples of direction ``sign`` (``records.runs_of``)."""
    from . import records

    return [(a, b - 1) for a, b in records.runs_of(d == sign)]


def cc_cv_ends(t, i, v, capacity_ah: float) -> list[dict]:
    """Every end of a CC-CV charge in a record (docs/soc-filter.md part 5): a charging stretch
    whose trailing samples lie within TOP_TOL_V of the record's charge top (its set point) for at
    least CV_MIN_S while the current falls to CV_TAPER of its start (its last sample may lie
    below: the current a sample late). Each with its sample, the cut-off current read from the
    taper's tail, the taper's time constant and the pseudo-measurement's sd."""
    d = _directions(i)
    if not np.any(d < 0):
        return []
    charging = v[d < 0]
    # the set point as logged: the median of the charging samples near the highest (the highest
    # alone sits a few logger-noise sd above it)
    top = float(np.median(charging[charging >= charging.max() - TOP_TOL_V]))
    out = []
    for a, b in _stretches(d, -1):
        at = np.flatnonzero(v[a : b + 1] >= top - TOP_TOL_V) + a
        if at.size < 2 or at[-1] < b - 1:
            continue
        first = at[-1]  # the CV phase: the trailing run of samples at the top
        while first - 1 >= a and v[first - 1] >= top - TOP_TOL_V:
            first -= 1
        end = int(at[-1])
        i0, i1 = abs(float(i[first])), abs(float(i[end]))
        span = float(t[end] - t[first])
        if span < CV_MIN_S or not 0.0 < i1 <= CV_TAPER * i0:
            continue
        tau = span / np.log(i0 / i1)
        gap = i1 * tau / (3600.0 * capacity_ah)
        out.append({"sample": end, "time_s": float(t[end]), "top_v": top,
                    "cutoff_current_a": i1, "cv_start_s": float(t[first]), "taper_s": tau,
                    "gap": gap, "sd": max(gap, FULL_SD_MIN)})  # fmt: skip
    return out


def lower_cutoffs(t, i, v) -> list[dict]:
    """Where a discharge stops at (within TOP_TOL_V of, or below) the lowest voltage of the
    record's discharges of at least CUTOFF_MIN_LOAD_S: the lower cut-off. ``used`` only after
    CUTOFF_MIN_LOAD_S of discharge (a shorter spike is reported, not used: docs/soc-filter.md
    part 5)."""
    d = _directions(i)
    # under load where the current read or the next one discharges (a channel a sample late
    # logs a spike's first sample at rest)
    d = np.where((d > 0) | (np.r_[d[1:], 0.0] > 0), 1.0, d)
    loads = _stretches(d, 1)
    sustained = [v[a : b + 1] for a, b in loads if t[b] - t[a] >= CUTOFF_MIN_LOAD_S]
    if not sustained:
        return []
    bottom = float(np.min(np.concatenate(sustained)))  # a spike's dip is not the cut-off
    out = []
    for a, b in loads:
        at = np.flatnonzero(v[a : b + 1] <= bottom + TOP_TOL_V) + a
        if at.size == 0 or at[-1] < b - 1:  # the cut-off ends the step (one sample's lag)
            continue
        k = int(at[-1])
        load_s = float(t[k] - t[a])
        out.append({"sample": k, "time_s": float(t[k]), "cutoff_v": float(v[k]),
                    "load_s": load_s, "used": load_s >= CUTOFF_MIN_LOAD_S})  # fmt: skip
    return out


def rest_soc(model: Model, volts: float, dinv: float, rtf: float) -> tuple[float, float]:
    """The SOC at which the model's voltage at rest (its states at 0) is ``volts``, and the
    sd that TOP_TOL_V gives it through the slope there (at least FULL_SD_MIN)."""
    lo, hi = (0.0, 1.0) if model.table is None else (model.table.grid()[0], model.table.grid()[-1])
    grid = np.linspace(lo, hi, 1001)
    X = np.zeros((grid.size, model.layout.n))
    X[:, 0] = grid
    rest = model.rows(model.P[:1]).measurement(X, 0.0, dinv, rtf, with_error=False)
    rest = np.maximum.accumulate(rest)  # a monotone reading of the OCV for the inverse
    s = float(np.interp(volts, rest, grid))
    slope = float(np.interp(s, grid, np.gradient(rest, grid)))
    return s, max(TOP_TOL_V / max(slope, 1e-9), FULL_SD_MIN)


def bms_pseudo(model: Model, inp: Inputs, capacity_ah: float) -> tuple[dict, dict]:
    """The pseudo-measurements by sample ((z, variance, one-sided)) and what SOC.json says of
    every event detected (docs/soc-filter.md part 5)."""
    full = cc_cv_ends(inp.t, inp.i, inp.v, capacity_ah)
    cuts = lower_cutoffs(inp.t, inp.i, inp.v)
    pseudo = {e["sample"]: (1.0, e["sd"] ** 2, False) for e in full}
    for c in cuts:
        k = c["sample"]
        c["soc_bound"], c["sd"] = rest_soc(model, c["cutoff_v"], inp.dinv[k], inp.rtf[k])
        if c["used"]:
            pseudo[k] = (c["soc_bound"], c["sd"] ** 2, True)
    return pseudo, {"cc_cv_end": full, "lower_cutoff": cuts}


def _pseudo_update(ukf, z: float, var: float, one_sided: bool) -> bool:
    """A scalar Kalman update of the SOC (H its row) by z with ``var``; one-sided (a lower
    bound), only where the estimate lies below z (Simon 2010's active set). Whether it ran."""
    if one_sided and ukf.x[0] >= z:
        return False
    s = ukf.P[0, 0] + var
    gain = ukf.P[:, 0] / s
    ukf.x = ukf.x + gain * (z - ukf.x[0])
    ukf.P = ukf.P - np.outer(gain, ukf.P[0, :])
    ukf.P = 0.5 * (ukf.P + ukf.P.T)
    return True


def run_filter(model: Model, noise: Noise, inp: Inputs, soc0: float, i_scale: float,
               source: str = "<record>", adapt: bool = True,
               pseudo: dict | None = None) -> Estimate:  # fmt: skip
    """The unscented Kalman filter over ``inp`` from the guess ``soc0`` (module docstring);
    refused (one line naming ``source``) where it breaks down. ``adapt``: what the filter
    attributes to e widens e's variance (:class:`Adaptation`); ``pseudo``: the SOC's
    pseudo-measurements by sample (:func:`bms_pseudo`)."""
    points_cls, ukf_cls = _filterpy()
    model = model.extended()
    L, n = model.layout, model.layout.n
    i_range = float(np.max(np.abs(inp.i))) if inp.i.size else 0.0
    points = points_cls(n, alpha=SIGMA_SPREAD / np.sqrt(n), beta=2.0, kappa=0.0)
    error_sd, tau_c_s = _error_sd(noise, inp)
    adaptation = Adaptation(adapt, float(inp.t[0]) if inp.t.size else 0.0)
    bias_sd = BIAS_SD_OF_RANGE * max(i_range, 1e-9)
    pert = model.rows(noise.perturbed) if noise.perturbed.size else None
    # the parameters' intervals in the voltage only where the error is the training residual:
    # a held-out error holds what they do to the voltage already (docs/soc-filter.md part 1)
    pert_v = pert if noise.bins is None else None
    nominal = model.rows(model.P[:1])
    ie, ib = L["verr"], L["bias"]

    def fx(sig, dt, i_read, dinv, rtf):
        out = nominal.transition(sig, i_read, dt, dinv, rtf)
        out[:, ie] *= np.exp(-dt / tau_c_s)
        return out

    ukf = ukf_cls(dim_x=n, dim_z=1, dt=1.0, hx=None, fx=fx, points=points)
    N = inp.t.size
    sd_e = error_sd(0, soc0) if N else noise.residual_sd_v
    process = _ErrorProcess(error_sd, tau_c_s, noise.bins is not None, sd_e**2)
    edges = _edge_neighbours(inp.i) if noise.bins is not None else {}
    ukf.x, ukf.P = initial_state(model, noise, soc0, i_range, i_scale, sd_e)
    ukf.sigmas_f = points.sigma_points(ukf.x, ukf.P)
    soc, sd, mv, inn, bias, bsd = (np.empty(N) for _ in range(6))
    applied: dict[int, bool] = {}
    started = time.perf_counter()
    for k in range(N):
        i_k, dinv, rtf, dt = inp.i[k], inp.dinv[k], inp.rtf[k], inp.dt[k]
        h_all = nominal.measurement(ukf.sigmas_f, i_k, dinv, rtf)
        r = _voltage_noise(nominal, pert_v, ukf.x, i_k, dinv, rtf,
                           [inp.i[j] for j in edges.get(k, ())])  # fmt: skip
        ukf.update_all(inp.v[k], h_all, np.array([[r]]))
        factor = adaptation.add(float(inp.t[k]), float(ukf.x[ie]), float(ukf.P[ie, ie]),
                                error_sd(k, float(ukf.x[0])) ** 2)  # fmt: skip
        if factor is not None:  # e's variance and covariances rescaled with λ at once
            g = np.sqrt(factor)
            ukf.P[ie, :] *= g
            ukf.P[:, ie] *= g
        if noise.bins is not None:
            _hold_soc_floor(ukf, nominal, i_k, dinv, rtf,
                            adaptation.lam * error_sd(k, float(ukf.x[0])) ** 2)  # fmt: skip
        if pseudo and k in pseudo:
            applied[k] = _pseudo_update(ukf, *pseudo[k])
        if not (np.all(np.isfinite(ukf.x)) and np.all(np.isfinite(ukf.P))):
            raise DataError(f"{source}: the filter's state is not finite after sample {k + 1} "
                            f"(t = {inp.t[k]:g} s): the model's voltage cannot follow this "
                            "record")  # fmt: skip
        soc[k], sd[k] = ukf.x[0], np.sqrt(max(ukf.P[0, 0], 0.0))
        mv[k], inn[k], bias[k] = inp.v[k] - ukf.y[0], ukf.y[0], ukf.x[ib]
        bsd[k] = np.sqrt(max(ukf.P[ib, ib], 0.0))
        q = np.zeros((n, n))
        if pert is not None:  # ... and through the state's step
            xb = np.repeat(ukf.x[None, :], pert.P.shape[0], axis=0)
            d = pert.transition(xb, i_k, dt, dinv, rtf) - nominal.transition(xb[:1], i_k, dt,
                                                                             dinv, rtf)  # fmt: skip
            q += d.T @ d
        q[ib, ib] += bias_sd**2 * dt / BIAS_DRIFT_TIME_S
        q[ie, ie] += adaptation.lam * process.drive(min(k + 1, N - 1), float(ukf.x[0]), dt)
        ukf.Q = q
        try:
            ukf.predict(dt=dt, i_read=i_k, dinv=dinv, rtf=rtf)
        except np.linalg.LinAlgError:  # scipy's is numpy's
            raise DataError(f"{source}: the filter's covariance is no longer positive definite "
                            f"at sample {k + 1} (t = {inp.t[k]:g} s): the model's voltage "
                            "cannot follow this record") from None  # fmt: skip
        ukf.P = 0.5 * (ukf.P + ukf.P.T)  # rounding must not cost the Cholesky factor its symmetry
    return Estimate(soc, sd, mv, inn, bias, bsd, time.perf_counter() - started,
                    adaptation.summary(), applied)  # fmt: skip


# ----------------------------------------------------------------------------------------------
# a record → the estimate, its reference and its summary


def reference_soc(rec: ecm.Record, model: Model, soc0: float) -> np.ndarray:
    """Coulomb counting with the record's own current from ``soc0`` against the model's
    capacity (at the record's temperature where the model's capacity follows it; the charge
    counted with the model's coulombic efficiency, zero-order hold as the simulator)."""
    P = model.P[0]
    ie = np.where(rec.i > 0.0, rec.i, P[ecm.ETA] * rec.i)
    kq = model.rows(model.P[:1])._later("kq")  # a capacity that follows the temperature
    qf = 1.0 if kq is None else 1.0 + kq * _temperature_offset(rec.dinv_t, rec.two_rt_f)
    dq = (ie / (3600.0 * P[ecm.Q] * qf))[:-1] * rec.dt[:-1]
    return soc0 - np.concatenate([[0.0], np.cumsum(dq)])


COUNTED_WITH = "the record's current, the model's capacity"  # what a reference counts with


def full_reference(rec: ecm.Record, model: Model) -> tuple[np.ndarray, list[dict]]:
    """The reference counted from SOC = 1 at every end of a CC-CV charge (:func:`cc_cv_ends`):
    coulomb counting as :func:`reference_soc` (the record's own current, the model's capacity)
    from each end to the next, and back from the first to the record's start. A record without
    one is refused."""
    ends = cc_cv_ends(rec.t, rec.i, rec.v, float(model.P[0, ecm.Q]))
    if not ends:
        raise UserError(f"{rec.source}: no end of a CC-CV charge (the top voltage held while "
                        "the current tapers), so no reference from full charge")  # fmt: skip
    counted = reference_soc(rec, model, 0.0)  # the SOC moved since the start
    ref = np.empty(rec.n)
    marks = [e["sample"] for e in ends]
    for j, k in enumerate(marks):
        a = 0 if j == 0 else k
        b = marks[j + 1] if j + 1 < len(marks) else rec.n
        ref[a:b] = 1.0 + counted[a:b] - counted[k]
    return ref, ends


def _events_summary(events: dict, applied: dict) -> dict:
    """SOC.json's ``bms_events``: each event detected, when, and whether it moved the SOC."""
    out = {"rule": "docs/soc-filter.md part 5", "top_tol_v": TOP_TOL_V}
    for name, found in events.items():
        out[name] = [{**e, "applied": bool(applied.get(e["sample"], False))} for e in found]
    return out


def score(t, soc, soc_sd, ref, window_s: float = CONVERGENCE_S) -> dict:
    """The issue's numbers for one run (docs/real-data.md, "SOC estimation (issue 29)")."""
    err = soc - ref
    late = (t - t[0]) >= window_s
    e = err[late] if late.any() else err
    out_at = np.flatnonzero(np.abs(err) > WITHIN)
    if out_at.size == 0:
        t_within = 0.0
    elif out_at[-1] == err.size - 1:
        t_within = None  # never stays within
    else:
        t_within = float(t[out_at[-1] + 1] - t[0])
    return {
        "rmse_after_window": float(np.sqrt(np.mean(e**2))),
        "mae_after_window": float(np.mean(np.abs(e))),
        "max_error_after_window": float(np.max(np.abs(e))),
        "max_error": float(np.max(np.abs(err))),
        "time_within_2pct_s": t_within,
        "coverage_2sd": float(np.mean(np.abs(e) <= 2.0 * (soc_sd[late] if late.any() else soc_sd))),
        "error_at_end": float(err[-1]),  # issue 40 part 4: where a BMS leaves the cell
    }


@dataclass(frozen=True)
class Result:
    frame: pd.DataFrame  # one row per sample: time_s, soc, soc_sd, model_v, innovation_v[, ...]
    summary: dict
    warnings: tuple[str, ...] = ()  # one line each (the command prints them)


def estimate_record(fitted, rec_frame: pd.DataFrame, soc0: float | None = None,
                    bias_a: float = 0.0, reference_soc0: float | None = None,
                    source: str = "model.json", noise: str = "expected-error",
                    adapt: bool = True, bms_events: bool = False,
                    reference_full: bool = False,
                    ambient: tuple[float, str] | None = None) -> Result:  # fmt: skip
    """The filter on one record of the cell (``soc0``: the start's guess, default the library's
    rule on the record's opening; ``bias_a``: added to the current the filter reads;
    ``reference_soc0``: the known start, for the coulomb-counted reference and the errors;
    ``noise``: which rule sets the voltage error, :data:`NOISE_RULES`; ``adapt``: the
    innovation-based scale of it, docs/soc-filter.md; ``bms_events``: the ends of CC-CV charges
    and the lower cut-off as pseudo-measurements, part 5; ``reference_full``: the reference
    counted from SOC = 1 at every CC-CV end; ``ambient``: the record's ambient (°C, where it
    came from: ``heat.ambient_if_any``), for a model over temperature, part 6, default
    :func:`record_ambient`'s). A model without
    ``expected_error`` runs the training-residual rule and says so (``Result.warnings``,
    ``noise.rule``). A model of per-temperature sets runs ``FittedModel.at_ambient`` of
    ``ambient``, else of the record's first temperature sample (refused without one)."""
    if noise not in NOISE_RULES:
        raise UserError(f"noise must be one of {', '.join(NOISE_RULES)}, got {noise!r}")
    if reference_full and reference_soc0 is not None:
        raise UserError("reference_soc0 and reference_full are two references: give one")
    if fitted.by_temperature is not None:  # per-temperature sets: those at the record's ambient
        if ambient is None:
            ambient = (first_temperature(fitted, rec_frame, source), "first temperature sample")
        fitted = fitted.at_ambient(ambient[0])
    model = filter_model(fitted, source)
    rule = noise_of(fitted, source, noise, record_ambient(fitted, rec_frame, ambient))
    rec = fitted.record(rec_frame)
    guess = fitted.initial_soc(rec) if soc0 is None else float(soc0)
    i_scale = fitted.current_scale_a or float(np.max(np.abs(rec.i)))
    inp = Inputs.of(rec, bias_a)
    pseudo, events = bms_pseudo(model, inp, float(model.P[0, ecm.Q])) if bms_events else ({}, None)
    est = run_filter(model, rule, inp, guess, i_scale, rec.source, bool(adapt), pseudo)
    frame = pd.DataFrame({"time_s": rec.t, "soc": est.soc, "soc_sd": est.soc_sd,
                          "model_v": est.model_v, "innovation_v": est.innovation_v})  # fmt: skip
    duration = float(rec.t[-1] - rec.t[0]) if rec.n > 1 else 0.0
    summary = {
        "samples": int(rec.n), "duration_s": duration, "soc0_guess": guess,
        "current_bias_a": float(bias_a), "capacity_ah": float(model.P[0, ecm.Q]),
        "states": list(model.layout.names), "noise": rule.summary() | est.adaptation,
        "wall_s": est.wall_s, "times_real_time": duration / max(est.wall_s, 1e-9),
        "final_soc": float(est.soc[-1]), "final_soc_sd": float(est.soc_sd[-1]),
        "final_bias_a": float(est.bias_a[-1]), "final_bias_sd_a": float(est.bias_sd[-1]),
        "innovation_rms_mv": float(1e3 * np.sqrt(np.mean(est.innovation_v**2))),
        "rest_only": bool(not np.any(rec.i)),  # the SOC is then the OCV's
        "soc_range": list(soc_range(fitted)),
        "outside_range": outside_range(fitted, frame),
    }  # fmt: skip
    if events is not None:
        summary["bms_events"] = _events_summary(events, est.applied or {})
    if reference_full:
        ref, ends = full_reference(rec, model)
        summary["reference"] = {"kind": "full", "cc_cv_end_s": [e["time_s"] for e in ends],
                                "counted_with": COUNTED_WITH}  # fmt: skip
    elif reference_soc0 is not None:
        ref = reference_soc(rec, model, float(reference_soc0))  # SOC.json as before part 5
    if reference_full or reference_soc0 is not None:
        frame["soc_reference"] = ref
        frame["soc_error"] = est.soc - ref
        # plain coulomb counting from the same guess with the same (biased) current
        counted = reference_soc(replace_current(rec, rec.i + bias_a), model, guess)
        if reference_soc0 is not None:
            summary["reference_soc0"] = float(reference_soc0)
        summary["filter"] = score(rec.t, est.soc, est.soc_sd, ref)
        summary["coulomb_counting"] = score(rec.t, counted, np.zeros(rec.n), ref)
        summary["coulomb_counting"].pop("coverage_2sd")
    said = (rule.warning(source), colder_than_trained(rule.bins, source))
    return Result(frame, summary, tuple(w for w in said if w is not None))


def soc_range(fitted) -> tuple[float, float]:
    """The SOC over which a model's OCV is known: its table's span, or 0-1 for the rational
    curve (its SOC is the fraction of the fitted capacity)."""
    table = fitted.config.table
    if table is None:
        return 0.0, 1.0
    grid = table.grid()
    return float(grid[0]), float(grid[-1])


def outside_range(fitted, frame: pd.DataFrame) -> dict | None:
    """Where the estimate leaves the model's SOC range (:func:`soc_range`) by more than
    :data:`RANGE_SD` of its own sd, after the first :data:`CONVERGENCE_S` (a wrong start's
    transient; the whole record if it is shorter): its farthest sample (time, SOC, sd, the
    range), or None. A record whose voltage lies outside the model's OCV (in issue 38's probe,
    0.5 V below it gave a final SOC of −0.86 ± 0.0006) ends there: no SOC of the cell."""
    lo, hi = soc_range(fitted)
    t, soc, sd = (frame[c].to_numpy() for c in ("time_s", "soc", "soc_sd"))
    late = (t - t[0]) >= CONVERGENCE_S
    idx = np.flatnonzero(late) if late.any() else np.arange(t.size)
    excess = np.maximum(lo - soc[idx], soc[idx] - hi) - RANGE_SD * sd[idx]
    k = int(idx[np.argmax(excess)])
    if excess.max() <= 0:
        return None
    return {"time_s": float(t[k]), "soc": float(soc[k]), "soc_sd": float(sd[k]),
            "range": [lo, hi], "sd_beyond": RANGE_SD}  # fmt: skip


def bias_limit_a(fitted, current_a: np.ndarray) -> float:
    """The largest current-sensor offset (A) a run may add (``--current-bias-a``): the largest
    |current| of the record, since a sensor's range covers what it reads and its offset is a
    fraction of that range (:data:`BIAS_SD_OF_RANGE`); on a record that only rests, the current
    the model was trained at (``current_scale_a``), else 1C of its capacity. 1e6 A on a 2 A
    record ran without a word before, its innovations 599 V RMS (issue 38's probe)."""
    peak = float(np.max(np.abs(current_a))) if np.size(current_a) else 0.0
    if peak > 0:
        return peak
    return fitted.current_scale_a or float(10.0 ** fitted.x[IDX["lq"]])


def replace_current(rec: ecm.Record, i: np.ndarray) -> ecm.Record:
    return replace(rec, i=np.ascontiguousarray(i, dtype=float))
