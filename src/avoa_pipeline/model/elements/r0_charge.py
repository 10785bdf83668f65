"""A charge/discharge asymmetry of the ohmic and fast charge-transfer drop: R0 → R0·exp(ρ) while
charging (i < 0), as ESC models' separate charge and discharge resistances."""

from __future__ import annotations

import numpy as np

from .element import Element, Export, Kernel, Param, Piece, TableLaw


def _piece(p) -> Piece:
    return Piece(
        constants=(("R0_CHARGE_FACTOR", float(np.exp(p["rho"])), "R0 while charging / R0"),),
        factors=(("R0", "(1.0 + (R0_CHARGE_FACTOR - 1.0) * (current < 0))"),),
    )  # fmt: skip


KERNEL = Kernel(
    columns={"rho": "rho"},
    flags={"r0chg": "np.any(rho != 0.0)"},
    code={"r0_multiplier": "if r0chg and ip < 0.0:\n    ro *= np.exp(rho[c])"},
)
"""R0 is multiplied by exp(ρ) while charging (the cell's current, offset included, below 0)."""


ELEMENT = Element(
    name="r0_charge",
    params={
        "rho": Param(
            "r0_charge_log_ratio",
            "lin",
            0.0,
            (-1.5, 1.5),
            "R0 while charging 0.22-4.5 times R0 while discharging",
            prior_sd=0.5,
        )
    },
    starts=lambda row, imax: [dict(rho=0.0)],
    signature="hysteresis's charge_mv and discharge_mv (the load residual by direction) read it",
    pybamm=Export(
        "R0 times exp(ρ) where the current is a charge (I < 0 in PyBaMM's discharge-positive "
        "sign), as a function of PyBaMM's current",
        _piece,
    ),
    would_decide="charge pulses beside discharge pulses",
    compiled="extras",
    kernel=KERNEL,
    table=TableLaw(
        "exp(ρ) multiplies r0_charge_ohm",
        factors={"r0_charge": lambda p, s, tk, tref: np.exp(p["rho"])},
    ),
)
