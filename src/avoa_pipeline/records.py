"""Measured records of one cell, and every check of one, each defined once.

A *record* is one cell's time series in the canonical columns: ``time_s`` (s, strictly
increasing), ``current_a`` (A, positive = discharge; row k's value is the current over
[t_k, t_k+1), the zero-order hold of the model library), ``voltage_v`` (V, the terminal voltage
at t_k) and optionally ``temperature_c`` (°C). A record file is a CSV in these columns with a
JSON sidecar of the same stem; this module owns them: :func:`write` (the importers, the synthetic
data, ``convert``) and :func:`read` (the input layer, the paper problem, the real-data
experiments, the gap check) go through the same checks. It is the bottom of the package for
records: it imports no model code, and the model library takes its rest line from here.

What is defined here, once:

- :func:`read`, :func:`write`, :data:`SIDECAR_KEYS` (an imported record's sidecar) and
  :func:`check_source` (a source file against its configured sha256);
- :data:`COLUMNS`, :func:`validate` (columns present, numbers, finite, time strictly increasing);
- :func:`current_scale` (the 99th-percentile |I|) and the fractions of it that make a rest
  (:data:`REST_FRACTION`, :func:`at_rest`) and a current step (:data:`STEP_FRACTION`);
- :func:`check_scale`: the units of time, current and voltage, and a capacity against a record
  (:func:`check_capacity`), each with the physical reason beside its limit;
- :func:`sign_evidence`: the current's sign read from the voltage, on all the evidence a record
  holds, with "cannot tell" where it is weak (docs/inputs.md, "The sign check").

Why hand-written: the checks are physics of a cell (how its voltage answers a current step),
which no record library states; the column conventions follow PyProBE's and pandas'.
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import DataError, UserError
from .io import READ_NOTES, atomic_paths, read_csv, read_json, read_sidecar, sha256, sidecar_of

COLUMNS = ("time_s", "current_a", "voltage_v", "temperature_c")
REQUIRED = COLUMNS[:3]

SIDECAR_KEYS = (
    "cell",
    "nominal_capacity_ah",
    "ambient_temperature_c",
    "test_type",
    "source_file",
    "source_sha256",
    "citation",
    "licence",
)
"""What an imported record's sidecar says, so that a reader can use the record without opening
its source: identity, conditions, provenance."""

REST_FRACTION = 0.02
"""At rest: |I| at most this fraction of the record's 99th-percentile |I| (a logger's offset and a
cycler's trickle are far below it; any load pulse is far above)."""
STEP_FRACTION = 0.1
"""A current step: a change of |ΔI| above this fraction of the 99th-percentile |I| (the pulse
edges and load changes of a test, not the ripple of a controlled current)."""

AMBIGUOUS_CURRENT_A = 30.0
"""Without a capacity, a 99th-percentile |I| above this gets a warning, not a refusal. Cells of up
to about 5 Ah (cylindrical, pouch, coin) are tested below 6 C, so below 30 A; a larger current is
a large-format cell (a 280 Ah LFP prismatic runs its drive cycles at 224 A) or milliamperes of a
small one (50 mA pulses of a 0.1 Ah cell written as 50). The records cannot tell the two apart:
a current k times too large makes every fitted resistance k times smaller and the capacity k
times larger, and the voltage the model predicts is the same. Only a capacity decides it
(MAX_C_RATE, MIN_C_RATE), so the warning names what is assumed and asks for it."""
MAX_C_RATE = 50.0
"""With a known capacity, a 99th-percentile current above 50 C is taken for milliamperes (no
lithium-ion cell is tested above that)."""
MIN_C_RATE = 0.01
"""No cell test runs its largest currents below C/100 (a slow OCV test runs at C/20-C/50): a cell
therefore holds at most 1/MIN_C_RATE = 100 hours of a record's 99th-percentile current. A record
that moves more charge than that in one stretch has its time in milliseconds; a capacity larger
than that is in mAh."""
CAPACITY_MARGIN = 1.1
"""A record never moves more charge between its fullest and its emptiest instant than the cell
holds; 10 % covers the counting drift of a cycler over a test and a capacity stated at another
age or temperature."""
VOLTAGE_RANGE_V = (0.5, 6.0)
"""Cell voltages outside this are taken for a wrong unit (mV) or a pack."""
MIN_TIME_STEP_S = 1e-3
"""Cyclers and BMS loggers sample at 1 kHz at most: a median step below 1 ms means the time is
not in seconds (1-s logging written in hours gives 0.28 ms)."""
FAST_TIME_STEP_S = 0.05
"""A median step below 50 ms (above 20 Hz) gets a warning: cyclers log at 10 Hz at most outside
short pulse tests, and 1-s logging written in minutes gives 16.7 ms. Without a capacity the
records cannot tell minutes from a fast logger (a time 60 times too short makes the capacity and
every time constant 60 times smaller, and the voltage the same); with one, the rests can
(OCV_SLOPE_MAX)."""
TEMPERATURE_RANGE_C = (-60.0, 150.0)
"""Cell temperatures in °C: lithium-ion cells are tested from -40 °C (chamber limits reach -60)
to about 85 °C, and a cell above 150 °C is in thermal runaway, which no model here describes.
Kelvin (233-423 for the same range) lies above it: that is the unit slip this catches."""
MAX_GAP_S = 3600.0
GAP_STEPS = 100
"""A logging gap longer than an hour, and than 100 of the record's median steps, hides what the
cell did (a charge not exported, a test paused): charge is counted within the stretches between
such gaps only. (The second condition keeps a record whose time is in ms from being all gaps.)
A record whose row before such a gap carries a current (above the rest line) is refused: the
zero-order hold would have the model draw that current through the whole gap (2 A over two
hours is 4 Ah, more than an 18650 holds), so every fitted parameter would answer a charge that
never flowed."""

OCV_SLOPE_MAX = 5.0
"""The steepest mean slope of a lithium-ion OCV between two rests, in V per unit SOC (the ends of
the range; 0.5-1.5 in the middle, 0.01 on an LFP plateau). Rested voltages that change faster with
the charge counted between them mean a capacity so small that the records' current would exceed
MAX_C_RATE: the time is not in seconds."""

LOAD_SPAN_S = 60.0
"""Sign check: the voltage change across a current step is taken over the two logging intervals
around it; where one of them is under load, it may last at most 60 s. Over a load interval the OCV
drifts by (dOCV/dSOC)·I·Δt/(3600·Q), and with dOCV/dSOC ≤ 1.5 V and R0·Q ≥ 0.07 Ω·Ah for
lithium-ion cells the drift stays below a third of the ohmic step R0·ΔI for Δt ≤ 60 s. Rest
intervals may be any length: relaxation moves the voltage the same way as the step."""
SIGN_CLIP = 3.0
"""Sign check: each item's voltage change counts in units of the voltage noise, clipped at ±3: a
change beyond three noise units is a response, not noise, and no single row (a glitch, a row
logged late) weighs more than three."""
SIGN_Z = 3.29
"""Sign check: a sign is declared when the evidence's z is beyond ±3.29, the two-sided 0.1 %
point of a normal: chance alone would give so one-sided a pattern in one record of a thousand."""
SIGN_LATE_Z = 3.48
"""Sign check, second look: a record that cannot tell is read again with its current a row
earlier (a cycler whose current channel is logged a sample late at each edge: the voltage has
answered a step one row before the logged current shows it, so the first look's window misses
the jump). Its sign is declared beyond ±3.48, the two-sided 0.05 % point: for a normal z the two
looks together declare a sign by chance in at most 0.15 % of records (Bonferroni: 0.1 % +
0.05 %). Measured on 40,000 records whose voltage is noise alone (40 steps of 10 s each): the
first look 0.12 %, both 0.19 % (the robust noise estimate widens z's tails a little)."""
VOLTAGE_RESOLUTION_V = 1e-4
"""The floor of the noise estimate: one step of a lab cycler's voltage channel (0.1 mV)."""

SIGNS = ("discharge-positive", "charge-positive")
CANNOT_TELL = "cannot tell"


def check_voltage(v: np.ndarray, source: str, column: str) -> None:
    """A one-line DataError naming ``column`` unless every voltage lies in VOLTAGE_RANGE_V."""
    lo, hi = VOLTAGE_RANGE_V
    if v.min() < lo or v.max() > hi:
        raise DataError(f"{source}: column {column!r}: values {v.min():g}..{v.max():g} outside "
                        f"{lo:g}..{hi:g} V of one cell (mV given?)")  # fmt: skip


# ----------------------------------------------------------------------------------------------
# columns


def validate(
    frame: pd.DataFrame,
    source: str,
    *,
    first_row: int = 2,
    min_samples: int = 2,
    required: tuple[str, ...] = REQUIRED,
) -> pd.DataFrame:
    """The record as float columns (:data:`COLUMNS` order, optional ones where present): every
    ``required`` column present, numbers, finite, at least ``min_samples`` rows, time strictly
    increasing. ``first_row`` numbers the frame's first sample in messages (2: a CSV line behind
    its header). One-line DataError naming the source, column and row."""
    if not isinstance(frame, pd.DataFrame):
        raise DataError(f"{source}: not a table ({type(frame).__name__})")
    for col in required:
        if col not in frame.columns:
            raise DataError(f"{source}: missing column {col!r} (need {', '.join(required)})")
    if len(frame) < min_samples:
        raise DataError(f"{source}: {len(frame)} samples; need at least {min_samples}")
    out = {}
    for col in (c for c in COLUMNS if c in frame.columns):
        raw = frame[col]
        values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
        not_number = np.isnan(values) & raw.notna().to_numpy()
        if not_number.any():
            i = int(np.flatnonzero(not_number)[0])
            raise DataError(
                f"{source}: column {col!r} row {i + first_row}: not a number ({raw.iloc[i]!r})"
            )
        if np.isnan(values).any():
            i = int(np.flatnonzero(np.isnan(values))[0])
            raise DataError(f"{source}: column {col!r} row {i + first_row}: missing value (NaN)")
        if not np.isfinite(values).all():
            i = int(np.flatnonzero(~np.isfinite(values))[0])
            raise DataError(f"{source}: column {col!r} row {i + first_row}: not finite")
        out[col] = values
    dt = np.diff(out["time_s"])
    if (dt == 0).any():
        i = int(np.flatnonzero(dt == 0)[0]) + 1
        raise DataError(f"{source}: column 'time_s' row {i + first_row}: duplicate time")
    if (dt < 0).any():
        i = int(np.flatnonzero(dt < 0)[0]) + 1
        raise DataError(f"{source}: column 'time_s' row {i + first_row}: time goes backwards")
    return pd.DataFrame(out)


# ----------------------------------------------------------------------------------------------
# current scale, rests, charge


def current_scale(current) -> float:
    """The record's current scale: its 99th-percentile |I| (A). Rest and step lines are fractions
    of it; the largest 1 % of samples (a spike, a short pulse) do not set it."""
    a = np.abs(np.asarray(current, dtype=float))
    return float(np.quantile(a, 0.99)) if a.size else 0.0


def only_rests(current) -> bool:
    """Whether no current flows at all (every 99th-percentile |I| is 0): no sign to tell."""
    return current_scale(current) <= 0


def at_rest(current, scale: float | None = None) -> np.ndarray:
    """Per sample: |I| at most REST_FRACTION of the current scale (:func:`current_scale` of
    ``current`` unless given: a caller passes the whole record's, or floors it away from 0)."""
    a = np.abs(np.asarray(current, dtype=float))
    return a <= REST_FRACTION * (current_scale(a) if scale is None else scale)


def direction(current, scale: float | None = None) -> np.ndarray:
    """Per sample: +1 discharging, −1 charging, 0 at rest (:func:`at_rest`, the one rest line)."""
    i = np.asarray(current, dtype=float)
    return np.where(at_rest(i, scale), 0.0, np.sign(i))


def charge_swing_ah(time_s, current_a) -> float:
    """The largest charge (Ah) the record moves between its fullest and its emptiest instant,
    within stretches that no logging gap (MAX_GAP_S, GAP_STEPS) interrupts."""
    t = np.asarray(time_s, dtype=float)
    i = np.asarray(current_a, dtype=float)
    dt = np.diff(t)
    swing = 0.0
    gap = max(MAX_GAP_S, GAP_STEPS * float(np.median(dt))) if dt.size else MAX_GAP_S
    cuts = np.r_[0, np.flatnonzero(dt > gap) + 1, t.size]
    for a, b in itertools.pairwise(cuts):
        if b - a < 2:
            continue
        q = np.r_[0.0, np.cumsum(i[a : b - 1] * dt[a : b - 1])] / 3600.0
        swing = max(swing, float(np.ptp(q)))
    return swing


# ----------------------------------------------------------------------------------------------
# units and scale


def check_scale(
    frame: pd.DataFrame,
    source: str,
    capacity_ah: float | None = None,
    *,
    names: dict[str, str] | None = None,
    rest_ok: bool = False,
) -> tuple[str, ...]:
    """One cell's record in seconds, amperes, volts and °C: DataError naming the column (``names``
    maps a canonical column to the raw export's own, for messages about a raw file); returns the
    warnings where the record cannot tell a unit (what was assumed and what would show it).

    - time: a median step of at least MIN_TIME_STEP_S (a warning below FAST_TIME_STEP_S), no
      stretch moving more charge than the cell can hold (CAPACITY_MARGIN × a known capacity,
      else 1/MIN_C_RATE hours of the record's 99th-percentile current): milliseconds and hours
      are caught; with a known capacity, minutes too (the rests, OCV_SLOPE_MAX); no logging gap
      (MAX_GAP_S) under load;
    - current: a 99th-percentile |I| above zero (``rest_ok``: a record that only rests passes,
      for ``estimate``: its SOC is the OCV's) and, with a known capacity, between MIN_C_RATE and
      MAX_C_RATE; without one, above AMBIGUOUS_CURRENT_A a warning;
    - voltage: within VOLTAGE_RANGE_V; temperature within TEMPERATURE_RANGE_C.
    """
    col = {c: c for c in COLUMNS} | (names or {})
    t = frame["time_s"].to_numpy(dtype=float)
    i = frame["current_a"].to_numpy(dtype=float)
    v = frame["voltage_v"].to_numpy(dtype=float)
    notes = []
    scale = current_scale(i)
    if capacity_ah is not None and scale > MAX_C_RATE * capacity_ah:
        raise DataError(
            f"{source}: column {col['current_a']!r}: 99th-percentile |I| {scale:g} A "
            f"is over {MAX_C_RATE:g} C for {capacity_ah:g} Ah; looks like mA "
            "(need A)"
        )
    if scale <= 0 and not rest_ok:
        raise DataError(
            f"{source}: column {col['current_a']!r}: no current flows; nothing to identify"
        )
    if capacity_ah is None and scale > AMBIGUOUS_CURRENT_A:
        notes.append(
            f"{source}: column {col['current_a']!r}: 99th-percentile |I| {scale:.4g} taken as "
            f"amperes (a large-format cell); if it is mA, every fitted resistance is 1000 times "
            "too small and the capacity 1000 times too large: give the capacity to check"
        )
    check_voltage(v, source, col["voltage_v"])
    if "temperature_c" in frame.columns:
        _check_temperature(frame["temperature_c"].to_numpy(dtype=float), source,
                           col["temperature_c"])  # fmt: skip
    step = _check_steps(t, i, scale, source, col)
    decided = _check_rest_slope(t, i, v, scale, source, col["time_s"], capacity_ah)
    if step < FAST_TIME_STEP_S and not (decided and capacity_ah):
        notes.append(
            f"{source}: column {col['time_s']!r}: median step {step:.3g} s ({1 / step:.3g} Hz) "
            "taken as seconds; if the time is in minutes, the capacity and every time constant "
            "come out 60 times too small (rests between loads, with the capacity given, "
            "would show it)"
        )
    swing = charge_swing_ah(t, i)
    limit = CAPACITY_MARGIN * capacity_ah if capacity_ah is not None else scale / MIN_C_RATE
    if swing > limit:
        why = (
            f"{CAPACITY_MARGIN:g} × the capacity {capacity_ah:g} Ah"
            if capacity_ah is not None
            else f"{1 / MIN_C_RATE:g} h of its 99th-percentile current {scale:.3g} A"
        )
        raise DataError(
            f"{source}: column {col['time_s']!r}: the record moves {swing:.4g} Ah in "
            f"one stretch, more than {why}; is the time in ms (need s)?"
        )
    return tuple(notes)


def _check_temperature(temp, source: str, column: str) -> None:
    lo, hi = TEMPERATURE_RANGE_C
    if temp.min() >= lo and temp.max() <= hi:
        return
    kelvin = temp.min() >= lo + 273.15 and temp.max() <= hi + 273.15
    hint = "looks like kelvin (need °C)" if kelvin else f"outside {lo:g}..{hi:g} °C of a cell"
    raise DataError(f"{source}: column {column!r}: values {temp.min():g}..{temp.max():g}; {hint}")


def _check_steps(t, i, scale: float, source: str, col: dict) -> float:
    """The median time step (inf for one sample), at least MIN_TIME_STEP_S, and no logging gap
    (MAX_GAP_S and GAP_STEPS) after a row that carries a current."""
    if t.size < 2:
        return np.inf
    dt = np.diff(t)
    step = float(np.median(dt))
    if step < MIN_TIME_STEP_S:
        raise DataError(
            f"{source}: column {col['time_s']!r}: median step {step:.3g} s, "
            f"below {MIN_TIME_STEP_S:g} s; is the time in hours or minutes (need s)?"
        )
    gap = max(MAX_GAP_S, GAP_STEPS * step)
    under_load = (dt > gap) & ~at_rest(i[:-1], scale)
    if under_load.any():
        k = int(np.flatnonzero(under_load)[0])
        raise DataError(
            f"{source}: column {col['time_s']!r} row {k + 2}: a {dt[k]:.0f}-s logging gap after "
            f"a row at {i[k]:.4g} A; the current over it is unknown (the model would draw "
            f"{abs(i[k]) * dt[k] / 3600:.3g} Ah there): split the record at the gap"
        )
    return step


def _check_rest_slope(
    t, i, v, scale: float, source: str, column: str, capacity_ah: float | None = None
) -> bool:
    """The time unit from the rests: between consecutive rests (two intervals or more) that the
    current moved at least 1 % of the record's swing apart, the rested voltage changes by ΔV over
    the counted charge Δq; their median |ΔV/Δq| (V/Ah) times the capacity is the OCV's slope, at
    most OCV_SLOPE_MAX: with a known capacity that is the check (a time in minutes makes it 60
    times steeper), without one the capacity is at least slope/OCV_SLOPE_MAX and the current's
    C-rate at most MAX_C_RATE. Needs three such pairs (a GITT or HPPC test has dozens): returns
    whether it had them."""
    if t.size < 4:
        return False
    dt = np.diff(t)
    q = np.r_[0.0, np.cumsum(i[:-1] * dt)] / 3600.0
    ends = [b for a, b in runs_of(at_rest(i[:-1], scale)) if b - a >= 2]
    if len(ends) < 4:
        return False
    qe, ve = q[np.array(ends) - 1], v[np.array(ends) - 1]
    dq, dv = np.diff(qe), np.diff(ve)
    moved = np.abs(dq) >= 0.01 * max(float(np.ptp(q)), 1e-12)
    if moved.sum() < 3:
        return False
    slope = float(np.median(np.abs(dv[moved] / dq[moved])))
    if capacity_ah is not None and slope * capacity_ah > OCV_SLOPE_MAX:
        raise DataError(
            f"{source}: column {column!r}: the rested voltage changes {slope:.3g} V per Ah "
            f"counted, {slope * capacity_ah:.3g} V per unit SOC of {capacity_ah:g} Ah (an OCV "
            f"changes {OCV_SLOPE_MAX:g} at most); is the time in minutes or hours (need s)?"
        )
    if scale * slope / OCV_SLOPE_MAX > MAX_C_RATE:
        raise DataError(
            f"{source}: column {column!r}: the rested voltage changes {slope:.3g} V per Ah "
            f"counted, which makes the current over {MAX_C_RATE:g} C for any cell; is the time "
            "in hours or minutes (need s)?"
        )
    return True


def check_capacity(capacity_ah: float, swing_ah: float, scale_a: float, what: str) -> None:
    """A capacity (``what`` names where it came from, e.g. ``--capacity-ah``) against the records
    of the cell: positive; between their 99th-percentile current ÷ MAX_C_RATE and ÷ MIN_C_RATE
    (a unit slip is a factor of 1000); not below the charge they move (÷ CAPACITY_MARGIN).
    UserError naming it."""
    if not (np.isfinite(capacity_ah) and capacity_ah > 0):
        raise UserError(f"{what} must be a positive number of Ah, got {capacity_ah}")
    if scale_a > MAX_C_RATE * capacity_ah:
        raise UserError(
            f"{what} {capacity_ah:g} Ah makes the records' 99th-percentile current "
            f"{scale_a:.3g} A over {MAX_C_RATE:g} C; is the current in mA (need A)?"
        )
    if scale_a < MIN_C_RATE * capacity_ah:
        raise UserError(
            f"{what} {capacity_ah:g} Ah makes the records' 99th-percentile current "
            f"{scale_a:.3g} A slower than C/{1 / MIN_C_RATE:g}; is the capacity in mAh "
            "(need Ah)?"
        )
    if swing_ah > CAPACITY_MARGIN * capacity_ah:
        raise UserError(
            f"{what} {capacity_ah:g} Ah is below the {swing_ah:.4g} Ah the records "
            "move between their fullest and emptiest instant"
        )


# ----------------------------------------------------------------------------------------------
# the sign


@dataclass(frozen=True)
class SignEvidence:
    """What a record's voltage says of its current's sign.

    ``verdict`` is for the current as given: ``discharge-positive`` (the pipeline's sign),
    ``charge-positive`` or ``cannot tell``. ``z`` > 0 leans to discharge-positive.
    """

    verdict: str
    z: float
    steps: int  # current changes between neighbouring intervals that carry evidence
    events: int  # rest → load and load → rest transitions
    agreeing: float | None  # share of the decisive items (beyond SIGN_CLIP) that say discharge
    resistance_ohm: float | None  # least-squares −ΔV/ΔI over the steps (apparent, for reports)
    noise_v: float
    current_lag_samples: int = 0  # 1: told with the current read a row earlier (SIGN_LATE_Z)

    @property
    def contradicts(self) -> bool:
        return self.verdict == SIGNS[1]

    @classmethod
    def from_dict(cls, d: dict) -> SignEvidence:
        """The evidence of :meth:`as_dict` (a converted export's sidecar)."""
        return cls(d["verdict"], d["z"], d["steps"], d["events"], d["agreeing_share"],
                   d["step_resistance_ohm"], 1e-3 * d["noise_mv"],
                   d.get("current_lag_samples", 0))  # fmt: skip

    def as_dict(self) -> dict:
        """The evidence for a sidecar; ``current_lag_samples`` only where the second look told
        the sign (absent: 0, as every sidecar written before it)."""
        out = {
            "verdict": self.verdict,
            "z": self.z,
            "steps": self.steps,
            "events": self.events,
            "agreeing_share": self.agreeing,
            "step_resistance_ohm": self.resistance_ohm,
            "noise_mv": 1e3 * self.noise_v,
        }
        if self.current_lag_samples:
            out["current_lag_samples"] = self.current_lag_samples
        return out

    def describe(self) -> str:
        """One clause for messages: the evidence in numbers."""
        share = "" if self.agreeing is None else f", {self.agreeing:.0%} of the clear ones"
        late = ", with the current read a row earlier" if self.current_lag_samples else ""
        return (
            f"z {self.z:+.1f} over {self.steps} current steps and {self.events} rest/load "
            f"transitions{share} saying discharge-positive{late}"
        )


def runs_of(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) of every run of True."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def sign_evidence(time_s, current_a, voltage_v) -> SignEvidence:
    """The current's sign from the voltage's answer to it, on all the evidence of the record.

    With discharge positive the terminal voltage falls when the current rises: the ohmic drop,
    the polarisation and (under load) the falling OCV all push it the same way. Two kinds of item,
    each a voltage change e counted positive when it says discharge-positive:

    - *steps*: every change of the interval current between neighbouring rows of at least
      REST_FRACTION of the scale (ramped and filtered edges count row by row), with the voltage
      change over the two intervals around the row, V[k+1] − V[k−1]: whether a row's voltage was
      measured under its own interval's current (bin means) or under the previous one (a step's
      last row, a late-logged rest whose row carries the interval's mean current), the window
      holds the whole answer. Load intervals in it may last at most LOAD_SPAN_S (OCV drift).
    - *events*: each transition between a rest (two intervals or more) and a load run that no
      step item covers (its load interval longer than LOAD_SPAN_S: a slow test logged coarsely):
      the rested voltage against the voltage at the run's far end, whatever the logging
      interval (the OCV drift under load and the relaxation at rest point the same way as the
      step). One transition is one item: a step and an event of it would share a sample.

    Each item counts e / (σ√2) clipped at ±SIGN_CLIP, σ the logger's voltage noise (robust, from
    steady intervals; at least VOLTAGE_RESOLUTION_V); z = their sum / √(number of items), about
    standard normal if the voltage did not answer the current. Beyond ±SIGN_Z the verdict is
    that sign.

    Otherwise a second look: the same evidence with the current read a row earlier (row k's
    current is row k+1's), as a cycler whose current channel is a sample late logs it. There a
    step's jump lies between V[k−2] and V[k−1] of the row k the logged current changes at, and
    the first look's window sees only what follows it: on a flat OCV (LFP under a drive) nothing
    else tells. Beyond ±SIGN_LATE_Z (stricter: two looks) the verdict is that sign, with
    ``current_lag_samples`` 1; else ``cannot tell`` with the first look's evidence. A record the
    first look decides is untouched by the second.
    """
    t = np.asarray(time_s, dtype=float)
    i = np.asarray(current_a, dtype=float)
    v = np.asarray(voltage_v, dtype=float)
    first = _sign_look(t, i, v, SIGN_Z)
    if first.verdict != CANNOT_TELL or i.size < 2:
        return first
    late = _sign_look(t, np.r_[i[1:], i[-1:]], v, SIGN_LATE_Z)
    return first if late.verdict == CANNOT_TELL else replace(late, current_lag_samples=1)


def _sign_look(t: np.ndarray, i: np.ndarray, v: np.ndarray, z_line: float) -> SignEvidence:
    """One look of :func:`sign_evidence` at the current as given, its verdict beyond ±z_line."""
    n = t.size
    ii = i[:-1]  # interval currents
    scale = current_scale(ii)
    if n < 3 or scale <= 0:
        return SignEvidence(CANNOT_TELL, 0.0, 0, 0, None, None, VOLTAGE_RESOLUTION_V)
    dt = np.diff(t)
    line = REST_FRACTION * scale
    rest = at_rest(ii, scale)
    # the voltage noise: differences over steady intervals (the current as in the previous one)
    dv = np.diff(v)
    steady = np.r_[False, np.abs(np.diff(ii)) <= line]
    pool = dv[steady] if steady.sum() >= 10 else dv
    mad = float(np.median(np.abs(pool - np.median(pool)))) if pool.size else 0.0
    sigma = float(max(1.4826 * mad / np.sqrt(2.0), VOLTAGE_RESOLUTION_V))
    unit = sigma * np.sqrt(2.0)

    # steps: row k between intervals k−1 and k (k = 1..n−2), window V[k+1] − V[k−1]
    k = np.arange(1, n - 1)
    d = ii[k] - ii[k - 1]
    short = lambda j: rest[j] | (dt[j] <= LOAD_SPAN_S)  # noqa: E731
    sel = (np.abs(d) >= line) & short(k - 1) & short(k)
    window = v[k + 1] - v[k - 1]
    e_steps = -window[sel] * np.sign(d[sel])
    resistance = None
    if sel.any():
        resistance = float(-np.sum(window[sel] * d[sel]) / np.sum(d[sel] ** 2))

    # events: rest (≥ 2 intervals) ↔ load run (≥ 2 intervals of one sign), where no step item
    # stands at the transition's row already (the two would share a voltage sample)
    stepped = set(k[sel].tolist())
    e_events = []
    rest_runs = [(a, b) for a, b in runs_of(rest) if b - a >= 2]
    rest_end = {b: a for a, b in rest_runs}  # a rest ending where a run starts
    rest_start = {a: b for a, b in rest_runs}
    for sgn in (1.0, -1.0):
        for a, b in runs_of(~rest & (np.sign(ii) == sgn)):
            if b - a < 2:
                continue
            v_load = v[b - 1]  # under load: intervals b−2 and b−1 both carry the run's current
            if a in rest_end and a not in stepped:  # V[a−1]: intervals a−2, a−1 both rest
                e_events.append(-(v_load - v[a - 1]) * sgn)
            if b in rest_start and b not in stepped:  # the rest's last voltage: most relaxed
                e_events.append((v[rest_start[b] - 1] - v_load) * sgn)
    e = np.concatenate([e_steps, np.asarray(e_events, dtype=float)])
    if e.size == 0:
        return SignEvidence(CANNOT_TELL, 0.0, 0, 0, None, resistance, sigma)
    score = np.clip(e / unit, -SIGN_CLIP, SIGN_CLIP)
    z = float(score.sum() / np.sqrt(e.size))
    clear = np.abs(score) >= SIGN_CLIP
    agreeing = float(np.mean(score[clear] > 0)) if clear.any() else None
    verdict = SIGNS[0] if z >= z_line else SIGNS[1] if z <= -z_line else CANNOT_TELL
    return SignEvidence(verdict, z, int(e_steps.size), len(e_events), agreeing, resistance, sigma)


def frame_sign(frame: pd.DataFrame) -> SignEvidence:
    """:func:`sign_evidence` of a canonical frame."""
    return sign_evidence(frame["time_s"], frame["current_a"], frame["voltage_v"])


def sign_contradiction(source: str, where: str, declared: str, ev: SignEvidence) -> str:
    """The message for a record whose voltage says its current is not ``declared`` (``where``:
    the current's place in the file, e.g. ``column 'current_a'``)."""
    return (
        f"{source}: {where}: sign contradicts the voltage response (it rises with "
        f"the current read as {declared}: {ev.describe()})"
    )


def require_sign(
    time_s, current_a, voltage_v, source: str, where: str, declared: str = SIGNS[0]
) -> SignEvidence:
    """:func:`sign_evidence` of a current already turned into the pipeline's sign, for a reader
    that knows its source's convention (``declared``, named in the message): DataError if the
    voltage contradicts it; a record that cannot tell passes (its evidence says so)."""
    ev = sign_evidence(time_s, current_a, voltage_v)
    if ev.contradicts:
        raise DataError(sign_contradiction(source, where, declared, ev))
    return ev


# ----------------------------------------------------------------------------------------------
# a checked record


@dataclass(frozen=True)
class Checked:
    """A record that passed the checks: its canonical frame (discharge positive), its name, the
    sign evidence, and what is odd about it (warnings for the user and the JSON). ``origin``
    says how it was read (a canonical CSV, a converted export with its sidecar, a frame);
    ``meta`` is its sidecar's content where :func:`read` read one."""

    frame: pd.DataFrame
    source: str
    sign: SignEvidence
    warnings: tuple[str, ...] = ()
    origin: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.frame)


def check(
    frame: pd.DataFrame,
    source: str,
    *,
    capacity_ah: float | None = None,
    first_row: int = 2,
    origin: dict | None = None,
    required: tuple[str, ...] = REQUIRED,
    min_samples: int = 2,
    current_sign: str = SIGNS[0],
    judge_sign: bool = True,
    meta: dict | None = None,
    rest_ok: bool = False,
) -> Checked:
    """The one check of a frame: :func:`validate`, the current negated if ``current_sign`` is
    charge-positive, :func:`check_scale` and :func:`sign_evidence`; a contradicted sign is a
    DataError, a sign the record cannot tell a warning, unless ``judge_sign`` is False (the input
    layer judges a command's files together). ``meta``: its sidecar's content; ``rest_ok``: a
    record that only rests passes (:func:`check_scale`), with no word on its sign."""
    clean = validate(frame, source, first_row=first_row, min_samples=min_samples,
                     required=required)  # fmt: skip
    if current_sign == SIGNS[1]:
        clean = clean.assign(current_a=-clean["current_a"])
    notes = check_scale(clean, source, capacity_ah, rest_ok=rest_ok)
    clean.attrs["source"] = source  # what the model library names in its messages
    ev = frame_sign(clean)
    if judge_sign and ev.contradicts:
        raise DataError(sign_contradiction(source, "column 'current_a'", current_sign, ev))
    if judge_sign and ev.verdict == CANNOT_TELL and not only_rests(clean["current_a"]):
        notes = (*notes, sign_unclear(source, "column 'current_a'", ev))
    return Checked(clean, source, ev, notes, dict(origin or {"read_as": "frame"}), meta or {})


def converted(frame: pd.DataFrame, source: str, info: dict, origin: dict) -> Checked:
    """A raw export's record as ``importers.cycler.convert`` made and checked it: its sign
    read from the current channel (``info``, the conversion's sidecar), its warnings the
    conversion's."""
    ev = SignEvidence.from_dict(info["sign"]["voltage_check"])
    return Checked(frame, source, ev, tuple(info["warnings"]), origin)


def sign_unclear(source: str, where: str, ev: SignEvidence) -> str:
    return (
        f"{source}: {where}: the voltage does not tell the current's sign "
        f"({ev.describe()}); the declared sign is taken as it is"
    )


# ----------------------------------------------------------------------------------------------
# record files: a CSV and its JSON sidecar


def check_source(path: str | Path, sha256_expected: str, *, key: str | None = None) -> Path:
    """``path`` if it exists and its sha256 is the configured one (an importer's source).

    ``key`` is the file's name in the config's ``real.sources`` (its path relative to the data
    root); it defaults to ``path`` and only shapes the message.
    """
    path = Path(path)
    key = str(path) if key is None else key
    if not path.is_file():
        raise DataError(f"{path}: missing (config real.sources[{key!r}])")
    got = sha256(path)
    if got != str(sha256_expected).strip().lower():
        raise DataError(
            f"{path}: sha256 {got} does not match config real.sources[{key!r}] "
            f"({sha256_expected}); the file changed or is another version"
        )
    return path


def _sidecar_text(sidecar: dict, source: str, keys: tuple[str, ...]) -> str:
    if not isinstance(sidecar, dict):
        raise DataError(f"{source}: sidecar is not a mapping ({type(sidecar).__name__})")
    for key in keys:
        if key not in sidecar:
            raise DataError(f"{source}: sidecar field {key!r} missing")
    try:
        return json.dumps(sidecar, indent=1, allow_nan=False) + "\n"
    except (TypeError, ValueError) as exc:
        raise DataError(f"{source}: sidecar not JSON-able ({exc})") from None


def write(
    frame: pd.DataFrame,
    sidecar: dict,
    out_csv: str | Path,
    *,
    keys: tuple[str, ...] = SIDECAR_KEYS,
    required: tuple[str, ...] = COLUMNS,
    float_format: str | None = None,
    digest: str | None = None,
) -> Path:
    """A record file: the frame :func:`validate`-d (``required`` columns) as ``out_csv`` and
    ``sidecar`` (holding ``keys``) beside it (:func:`~avoa_pipeline.io.sidecar_of`), both or
    neither (``io.atomic_paths``); everything is checked before anything is written. ``digest``
    names a sidecar field that gets the written CSV's sha256 (:func:`read` then refuses a CSV
    changed since). Returns the sidecar's path."""
    out_csv = Path(out_csv)
    source = str(sidecar.get("source_file", out_csv)) if isinstance(sidecar, dict) else str(out_csv)
    clean = validate(frame, source, first_row=0, required=required)
    text = _sidecar_text(sidecar, source, keys)
    side = sidecar_of(out_csv)
    with atomic_paths(out_csv, side) as (tmp_csv, tmp_side):
        clean.to_csv(tmp_csv, index=False, float_format=float_format)
        if digest:
            text = _sidecar_text({**sidecar, digest: sha256(tmp_csv)}, source, keys)
        tmp_side.write_text(text)
    return side


def read(
    path: str | Path,
    *,
    keys: tuple[str, ...] | None = SIDECAR_KEYS,
    required: tuple[str, ...] = COLUMNS,
    capacity_ah: float | Callable[[dict], float] | None = None,
    **check_as,
) -> Checked:
    """The record file at ``path`` through :func:`check` (``check_as``: its ``current_sign``,
    ``min_samples``, ``judge_sign``), its sidecar in ``meta``. ``keys``: what the sidecar must
    hold (an imported record's by default, where it must exist); ``()``: a sidecar is optional;
    None: it is not read. A sidecar's ``csv_sha256`` (:func:`write`'s ``digest``) must be the
    CSV's. ``capacity_ah`` may be a function of the sidecar."""
    path = Path(path)
    meta, side = {}, sidecar_of(path)
    if keys:
        meta = read_json(side, f"sidecar of {path.name}")
        _sidecar_text(meta, str(side), keys)
    elif keys is not None:
        meta = read_sidecar(path)
    digest = meta.get("csv_sha256")
    if digest is not None and digest != sha256(path):
        raise DataError(
            f"{side}: field 'csv_sha256': does not match {path} (the CSV changed after the "
            "sidecar was written: regenerate it, or remove the sidecar to use the CSV alone)"
        )
    cap = capacity_ah(meta) if callable(capacity_ah) else capacity_ah
    origin = {"read_as": "canonical CSV", "current_sign": check_as.get("current_sign", SIGNS[0])}
    if side.is_file():
        origin["sidecar"] = str(side)
    raw = read_csv(path)
    checked = check(raw, str(path), capacity_ah=cap, origin=origin, meta=meta,
                    required=required, **check_as)  # fmt: skip
    read_notes = raw.attrs.get(READ_NOTES, ())  # a partial last row dropped (io.read_csv)
    return replace(checked, warnings=(*read_notes, *checked.warnings)) if read_notes else checked
