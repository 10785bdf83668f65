"""The model library's OCV sources: where the ocv_shape correction's knots lie (:class:`Knots`),
a measured OCV on a uniform SOC grid (:class:`OcvTable`), and the OCV of a physical row
(:func:`ocv_values`; the compiled simulator evaluates the same, ``model/loopgen.py``). ``ecm``
re-exports every name here."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.interpolate import PchipInterpolator

from .elements.element import N_KNOTS
from .layout import D0, OMB, VNOM, VOFF

TABLE_POINTS = 4001
"""Measured OCV tables are resampled onto this uniform SOC grid (0.025 % steps) by a monotone
cubic (:meth:`OcvTable.from_points`); the simulator interpolates linearly between its points.
Why so fine (issue 37; 1001 points, linearly resampled, earlier): the model's voltage is then
piecewise linear in SOC, and a fit's finite-difference Jacobian (steps of about 1e-6) reads each
cell's slope, not the OCV's. Along the flat offset-capacity-initial-SOC valley that slope noise
passed for information: on issue 37's clean record with its true OCV given at 201 points the
offset's standard deviation came out 7.3 mV; with the monotone cubic at 4001 points 71 mV, near
the smooth limit (84 mV at 100,001 points). 4001 doubles are 32 kB, inside a core's L2 cache."""


_NO_SHAPE = np.zeros(0)


@dataclass(frozen=True)
class Knots:
    """Where the ocv_shape correction lives: N_KNOTS knots from ``lo`` in steps of ``step``."""

    lo: float
    step: float

    def grid(self) -> np.ndarray:
        return self.lo + self.step * np.arange(N_KNOTS)


@dataclass(frozen=True)
class OcvTable:
    """A measured OCV on a uniform SOC grid (``values`` strictly increasing)."""

    lo: float
    step: float
    values: np.ndarray
    capacity_ah: float | None = None  # the slow test's capacity, if it came from one
    source: str = ""
    how: str = ""  # how it was made (which branches, why)
    notes: tuple[str, ...] = ()  # what is odd about it (warnings for the user)
    # how far the table may lie from the cell's OCV (V, one standard deviation) and why; None:
    # not measured (``ocv.offset_prior`` then gives the default)
    offset_sd_v: float | None = None
    offset_why: str = ""
    capacity_sd_ah: float | None = None  # the slow test's capacity's uncertainty (ocv.py)
    # ∂U/∂T (V/K) at each point of the grid, from slow tests at several temperatures
    # (``ocv.over_temperature``); None: one temperature, no profile
    dudt_v_per_k: np.ndarray | None = None
    dudt_how: str = ""  # which slow tests, at which ambients, and how the table was chosen

    def dudt_peak(self) -> float:
        """The profile's largest |∂U/∂T| (V/K; 0 without a profile)."""
        return 0.0 if self.dudt_v_per_k is None else float(np.max(np.abs(self.dudt_v_per_k)))

    def dudt_shape(self) -> np.ndarray:
        """The profile over its peak (|shape| ≤ 1, 1 where |∂U/∂T| peaks; empty without a
        profile): what the ``entropic`` element's coefficient multiplies (elements/entropic.py).
        A profile of zeros has no shape: empty, so the coefficient stands alone."""
        return self._shape

    @cached_property
    def _shape(self) -> np.ndarray:  # once per table: every simulation passes it
        peak = self.dudt_peak()
        if peak == 0.0:
            return _NO_SHAPE
        return np.ascontiguousarray(self.dudt_v_per_k / peak)

    def entropic_shape(self, soc) -> np.ndarray | float:
        """The shape at ``soc`` (flat beyond the table's ends, as the simulator reads it), or 1
        without a profile."""
        shape = self.dudt_shape()
        return 1.0 if shape.size == 0 else np.interp(soc, self.grid(), shape)

    @classmethod
    def from_points(cls, soc, ocv_v, capacity_ah=None, source="", how="") -> OcvTable:
        """The table of points (soc, ocv_v) in any order, resampled onto TABLE_POINTS by the
        monotone cubic (scipy's PCHIP: it passes through the points, rises where they rise and
        has no overshoot; points at one SOC averaged), then made strictly increasing (the
        initial-SOC rule inverts it) by at most 1 µV."""
        soc = np.asarray(soc, dtype=float)
        v = np.asarray(ocv_v, dtype=float)
        soc, where = np.unique(soc, return_inverse=True)
        v = np.bincount(where, weights=v) / np.bincount(where)
        grid = np.linspace(soc[0], soc[-1], TABLE_POINTS)
        vals = PchipInterpolator(soc, v)(grid) if soc.size > 2 else np.interp(grid, soc, v)
        vals = np.maximum.accumulate(vals) + np.linspace(0.0, 1e-6, grid.size)
        step = (soc[-1] - soc[0]) / (TABLE_POINTS - 1)
        return cls(float(soc[0]), float(step), np.ascontiguousarray(vals), capacity_ah, source, how)

    def grid(self) -> np.ndarray:
        """The table's SOC points, made once per table (the initial-SOC rule reads the table at
        every iteration of every fit's simulations). Shared: never write to it (it stays
        writeable because numba types a read-only array apart, and the SOC filter's compiled
        step would be compiled again for it)."""
        return self._grid

    @cached_property
    def _grid(self) -> np.ndarray:
        return self.lo + self.step * np.arange(self.values.size)

    def __call__(self, soc) -> np.ndarray:
        return np.interp(soc, self._grid, self.values)


def ocv_values(P_row: np.ndarray, soc, knots: Knots, table: OcvTable | None) -> np.ndarray:
    """OCV (with correction and offset, no hysteresis) of physical row ``P_row`` at ``soc``."""
    soc = np.asarray(soc, dtype=float)
    if table is None:
        sc = np.clip(soc, 0.0, 1.2)
        omb = P_row[OMB]
        v = P_row[VNOM] * sc / (omb + (1.0 - omb) * sc)
    else:
        sc = soc
        v = table(sc)
    d = P_row[D0 : D0 + N_KNOTS]
    if np.any(d != 0.0):
        v = v + np.interp(sc, knots.grid(), d)
    return v + P_row[VOFF]
