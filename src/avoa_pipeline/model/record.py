"""The inputs a simulation needs, prepared once per record (:class:`Record`), and what starts a
record (:func:`opening`, :func:`load_window`). ``ecm`` re-exports every name here."""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import pandas as pd

from ..records import at_rest, current_scale
from .elements.element import FARADAY, GAS_R

T_DEFAULT_K = 298.15

THERMAL_MIN_RANGE_C = 2.0
"""The thermal element needs the measured temperature to move at least this much (°C): with
less, an Arrhenius factor is a constant that R0 and R1 already absorb."""

OPENING_WINDOW_S = 60.0
"""The initial state is read from 60 s of a record's opening: the last 60 s of its opening rest
(at 1 Hz sixty samples, so the logger's noise enters √60 times less than through one sample, and
the end of the rest is its most relaxed part; docs/gap-diagnosis.md, "Selection judged like
prediction"), or the first 60 s of a record that starts under load (issue 37: the model is
simulated over them, :func:`soc0_rows`; one sample left the initial SOC, and with it the offset
and capacity that trade along it, at the mercy of one sample's noise)."""

MIN_OPENING_SAMPLES = 25
"""The opening window holds at least this many samples (the last ones of the opening rest, or the
first under load), however long they last. Why: a cycler logs a rest every 30-300 s, so 60 s of
it may be one or two samples, and the initial state then carries one sample's noise through the
whole record as a constant offset (issue 37's fit-back cases: the true model, started by the rule
on rests logged every 60 s, scored 1.39-1.42 × the noise). With n samples the rule adds σ²/n to
the squared error, so the RMSE ÷ noise of a model that is otherwise exact is √(1 + 1/n);
n ≥ 25 keeps it within 1.02 (the fit-back goal). At a 1 Hz log the 60 s already hold 60."""


def opening(t: np.ndarray, i: np.ndarray, v: np.ndarray) -> tuple[float, float, int]:
    """(voltage, current, samples) that start a record: their means over the last
    OPENING_WINDOW_S of the opening rest (the leading samples ``records.at_rest``), or, if the
    record starts under load, over its first OPENING_WINDOW_S (each at least MIN_OPENING_SAMPLES
    samples where the record has them; the rule
    then simulates the model over those samples, :func:`load_window`)."""
    moving = np.flatnonzero(~at_rest(i, max(current_scale(i), 1e-6)))
    end = int(moving[0]) if moving.size else i.size
    if end == 0:
        w = load_window(t, i)
        return float(np.mean(v[:w])), float(np.mean(i[:w])), w
    first = int(np.searchsorted(t[:end], t[end - 1] - OPENING_WINDOW_S, side="left"))
    first = max(0, min(first, end - MIN_OPENING_SAMPLES))
    return float(np.mean(v[first:end])), float(np.mean(i[first:end])), end - first


def load_window(t: np.ndarray, i: np.ndarray) -> int:
    """Samples of the opening window of a record that starts under load (the first
    OPENING_WINDOW_S, at least MIN_OPENING_SAMPLES where there are), or 0 if it starts at rest
    (``records.at_rest``)."""
    if i.size == 0 or at_rest(float(i[0]), max(current_scale(i), 1e-6)):
        return 0
    w = int(np.searchsorted(t, t[0] + OPENING_WINDOW_S, side="left"))
    return min(max(w, MIN_OPENING_SAMPLES), i.size)


def _constant(a: np.ndarray) -> bool:
    """Every element of float array ``a`` is its first, bit for bit (an empty array too)."""
    bits = a.view(np.uint64)  # bits, not values: −0.0 and 0.0 differ, NaN equals itself
    return a.size == 0 or bool(np.all(bits == bits[0]))


@dataclass(frozen=True)
class Record:
    """The inputs a simulation needs, prepared once per record."""

    t: np.ndarray
    i: np.ndarray
    v: np.ndarray
    temp_c: np.ndarray | None
    dt: np.ndarray  # dt[k] = t[k+1] − t[k]; the last is the median step (never used by V)
    uniform: bool
    tref_k: float
    dinv_t: np.ndarray
    two_rt_f: np.ndarray
    source: str = "<data>"
    v_open: float = np.nan  # what starts the record (:func:`opening`)
    i_open: float = 0.0
    n_load_open: int = 0  # starts under load: samples of its opening window (:func:`load_window`)

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def temperature_varies(self) -> bool:
        return self.temp_c is not None and float(np.ptp(self.temp_c)) >= THERMAL_MIN_RANGE_C

    @classmethod
    def from_frame(cls, frame: pd.DataFrame, tref_k: float | None = None, source=None) -> Record:
        t = np.ascontiguousarray(frame["time_s"].to_numpy(dtype=float))
        i = np.ascontiguousarray(frame["current_a"].to_numpy(dtype=float))
        v = np.ascontiguousarray(frame["voltage_v"].to_numpy(dtype=float))
        temp = None
        if "temperature_c" in frame.columns:
            temp = np.ascontiguousarray(frame["temperature_c"].to_numpy(dtype=float))
        d = np.diff(t)
        step = float(np.median(d)) if d.size else 1.0
        dt = np.append(d, step)
        uniform = bool(np.all(np.abs(d - step) <= 1e-9 * max(step, 1.0)))
        if uniform:
            dt = np.full(t.size, step)
        tk = np.full(t.size, T_DEFAULT_K) if temp is None else temp + 273.15
        if tref_k is None:
            tref_k = float(np.mean(tk))
        v_open, i_open, _ = opening(t, i, v)
        return cls(
            t=t, i=i, v=v, temp_c=temp, dt=np.ascontiguousarray(dt), uniform=uniform,
            tref_k=float(tref_k), dinv_t=np.ascontiguousarray(1.0 / tk - 1.0 / tref_k),
            two_rt_f=np.ascontiguousarray(2.0 * GAS_R * tk / FARADAY),
            source=str(source if source is not None else frame.attrs.get("source", "<data>")),
            v_open=v_open, i_open=i_open, n_load_open=load_window(t, i),
        )  # fmt: skip

    @classmethod
    def join(cls, recs: list[Record]) -> Record:
        """One record of several, end to end (time made continuous, the next record a median
        step after the last sample), for what reads the residual against current, time and
        temperature (the diagnosis's localization and signatures)."""
        if len(recs) == 1:
            return recs[0]
        t, start = [], 0.0
        for r in recs:
            t.append(r.t - r.t[0] + start)
            start = t[-1][-1] + float(np.median(r.dt))
        temps = None
        if all(r.temp_c is not None for r in recs):
            temps = np.concatenate([r.temp_c for r in recs])
        joined = {k: np.concatenate([getattr(r, k) for r in recs])
                  for k in ("i", "v", "dt", "dinv_t", "two_rt_f")}  # fmt: skip
        return cls(t=np.concatenate(t), temp_c=temps, uniform=False, tref_k=recs[0].tref_k,
                   source="+".join(r.source for r in recs), **joined)  # fmt: skip

    @cached_property
    def rest_held(self) -> tuple[np.ndarray, np.ndarray]:
        """``dinv_t`` and ``two_rt_f`` with each run of zero current given its first sample's
        values (what :func:`simulate_physical` passes the simulator where no current flows
        at rest).

        Why: at zero current the temperature acts on nothing the simulator computes (its
        factors multiply the current: R0's and the RC resistances' Arrhenius factors, the
        Butler–Volmer term's RT/F and exchange current; every state increment is then 0 and
        the voltage is the OCV side, whatever the temperature), but a measured temperature
        that flickers by a hundredth of a kelvin breaks the simulator's held-current shortcut
        (the generated loop, ``model/loopgen.py``: a thermal model's hold needs the same
        temperature) at every sample. The Panasonic HPPC records rest 93 % of their ~90,000
        samples, and the thermocouple moves at 94 % of them. Held this way, a rest is one hold,
        and every voltage is the same bit for bit (``tests/unit/test_long_records.py``).

        Where both are one value throughout (a record without a measured temperature), holding
        changes nothing: the arrays themselves are returned, not 16 bytes a sample more (issue
        42: a long record's memory)."""
        if _constant(self.dinv_t) and _constant(self.two_rt_f):
            return self.dinv_t, self.two_rt_f
        # per sample, the index of the last sample that is not inside a rest's tail
        src = np.where(self.rest_tail(), 0, np.arange(self.n))
        np.maximum.accumulate(src, out=src)
        return (np.ascontiguousarray(self.dinv_t[src]),
                np.ascontiguousarray(self.two_rt_f[src]))  # fmt: skip

    def rest_tail(self, end: int | None = None) -> np.ndarray:
        """Per sample (of the first ``end``), whether it lies inside a run of zero current after
        the run's first sample: what :attr:`rest_held` holds at the run's first values and a
        thinned simulation merges into the run's first step (``ecm._rests_merged``)."""
        zero = self.i[:end] == 0.0
        tail = np.zeros_like(zero)
        tail[1:] = zero[1:] & zero[:-1]
        return tail

    @cached_property
    def opening_record(self) -> Record:
        """The record's first ``n_load_open`` samples (what :func:`soc0_rows` simulates for a
        record that starts under load)."""
        k = max(self.n_load_open, 1)
        cut = {f: getattr(self, f)[:k] for f in ("t", "i", "v", "dt", "dinv_t", "two_rt_f")}
        temp = None if self.temp_c is None else self.temp_c[:k]
        return replace(self, temp_c=temp, uniform=self.uniform, n_load_open=0, **cut)

    def charge_ah(self) -> np.ndarray:
        """Charge removed since the start (Ah) at each sample (discharge positive)."""
        return np.concatenate([[0.0], np.cumsum(self.i[:-1] * self.dt[:-1])]) / 3600.0

    def imax(self) -> float:
        return max(current_scale(self.i), 1e-6)
