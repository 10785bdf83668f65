"""A current sensor's offset: i_true = i_meas + b, in the SOC, the ohmic drop, the RC branches
and the hysteresis."""

from __future__ import annotations

from .element import Element, Export, Kernel, Param, Piece, Signature, TableLaw, View, slope_mv


def _piece(p) -> Piece:
    return Piece(constants=(("CURRENT_OFFSET_A", p["ioff"], "current_offset: drive() adds it to a "
                             "measured current (0 for a true one)"),),
                 current_terms=("CURRENT_OFFSET_A",))  # fmt: skip


def _read(v: View) -> dict:
    rest = v.direction == 0
    th = (v.rec.t - v.rec.t[0]) / 3600.0
    return {"rest_trend_mv_per_h": slope_mv(th[rest], v.resid[rest])}


KERNEL = Kernel(columns={"ioff": "ioff"}, code={"current": "ip += ioff[c]"})
"""The cell's current is the measured one plus b (always added: b = 0 adds nothing)."""


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
        "an offset of the training records' current sensor, not of the cell: drive() adds it to "
        "a measured current (as avoa-pipeline's simulator does with any record); PyBaMM's "
        "parameters and a current given to PyBaMM directly do not carry it",
        _piece,
    ),
    would_decide="a full charge and discharge between two rests",
    withheld=True,
    kernel=KERNEL,
    table=TableLaw("a scalar of the sidecar (current_offset_a), added to a measured current"),
)
