"""One-state dynamic hysteresis of Plett's enhanced self-correcting model (G. L. Plett,
J. Power Sources 134 (2004) 262-276, eq. 13): h → −1 while discharging, V += M·h."""

from __future__ import annotations

import numpy as np

from .element import Element, Export, Param, Signature, View


def last_direction(d: np.ndarray) -> np.ndarray:
    """+1 after discharge, −1 after charge, 0 before any current (per sample), from each
    sample's direction ``d`` (``records.direction``)."""
    idx = np.where(d != 0, np.arange(d.size), 0)
    idx = np.maximum.accumulate(idx)
    return d[idx]


def _read(v: View) -> dict:
    rest, last = v.direction == 0, last_direction(v.direction)
    return {
        "rest_after_charge_mv": v.mean_mv(rest & (last < 0)),
        "rest_after_discharge_mv": v.mean_mv(rest & (last > 0)),
        "charge_mv": v.mean_mv(v.direction < 0),
        "discharge_mv": v.mean_mv(v.direction > 0),
    }


ELEMENT = Element(
    name="hysteresis",
    params={
        "hm": Param(
            "hysteresis_m_v",
            "lin",
            0.0,
            (0.0, 0.3),
            "up to 300 mV: beyond the widest measured hysteresis (LFP, tens of mV)",
            prior_sd=0.05,
        ),
        "lgamma": Param(
            "hysteresis_gamma",
            "log10",
            2.0,
            (0.1, 1e4),
            "h settles over 10 capacities' charge (0.1) down to 0.01 % of one (1e4)",
        ),
        "h0": Param(
            "hysteresis_h0",
            "lin",
            0.0,
            (-1.0, 1.0),
            "h lies in [−1, 1]",
            per_record=True,
            prior_sd=1.0,
        ),
    },
    starts=lambda row, imax: [dict(hm=0.01, lgamma=lg, h0=0.0) for lg in (1.0, 2.0, 3.0)],
    signature=Signature(
        "rest voltage after charge above that after discharge; load offset ±M", _read
    ),
    pybamm=Export("PyBaMM's Thevenin model has no hysteresis state"),
    would_decide="rests at one SOC reached once by charge and once by discharge",
    withheld=True,
)
