"""Charge counted with an efficiency η: s −= η·i·Δt/(3600 Q) while charging (i < 0), and in the
hysteresis rate (Plett's ESC model)."""

from __future__ import annotations

import numpy as np

from ... import records
from .element import Element, Export, Param, Signature, View, slope_mv


def _read(v: View) -> dict:
    rec, rest = v.rec, v.direction == 0
    charged = np.concatenate([[0.0], np.cumsum(np.minimum(rec.i[:-1], 0) * rec.dt[:-1])]) / -3600
    return {"rest_trend_mv_per_ah_charged": slope_mv(charged[rest], v.resid[rest])}


def _applies(recs, imax) -> str:
    charges = any((records.direction(r.i, imax) < 0).any() for r in recs)
    return "" if charges else "no charge current"


ELEMENT = Element(
    name="coulombic_efficiency",
    params={
        "eta": Param(
            "coulombic_efficiency",
            "lin",
            1.0,
            (0.7, 1.0),
            "at most all charge kept; 70 % lost at worst (a cell far beyond use)",
            prior_sd=0.1,
        )
    },
    starts=lambda row, imax: [dict(eta=0.98)],
    signature=Signature(
        "SOC falls behind after charging: rest residual against charge put in", _read
    ),
    pybamm=Export(
        "PyBaMM's Thevenin model counts charge with one capacity in both directions "
        "(dSoC/dt = −I/(3600·Q), Q a scalar)"
    ),
    would_decide="a full charge and discharge between two rests",
    applies=_applies,
    withheld=True,
)
