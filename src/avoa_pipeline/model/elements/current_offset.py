"""A current sensor's offset: i_true = i_meas + b, in the SOC, the ohmic drop, the RC branches
and the hysteresis."""

from __future__ import annotations

from .element import Element, Export, Param, Signature, View, slope_mv


def _read(v: View) -> dict:
    rest = v.direction == 0
    th = (v.rec.t - v.rec.t[0]) / 3600.0
    return {"rest_trend_mv_per_h": slope_mv(th[rest], v.resid[rest])}


ELEMENT = Element(
    name="current_offset",
    params={
        "ioff": Param(
            "current_offset_a",
            "lin",
            0.0,
            (-10.0, 10.0),
            "a current sensor's offset: far below any test current; in a "
            "fit, 10 % of the records' largest current at most",
            prior_sd=0.05,
            scale="a",
            scaled=(-0.1, 0.1),
        )
    },
    starts=lambda row, imax: [dict(ioff=0.0)],
    signature=Signature(
        "SOC drift with time (rest voltage trend) and a constant ohmic shift", _read
    ),
    pybamm=Export(
        "an offset of the training records' current sensor, not of the cell: PyBaMM's Thevenin "
        "model runs on the current it is given (its SOC and every drop see that current)"
    ),
    would_decide="a full charge and discharge between two rests",
    withheld=True,
)
