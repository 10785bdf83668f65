"""An Arrhenius exchange current: Butler–Volmer's 1/i0 → (1/i0)·exp(θ(1/T − 1/Tref)); offered on
top of ``butler_volmer`` and only where the temperature moves."""

from __future__ import annotations

from .element import Element, Export, Kernel, Piece, TableLaw
from .thermal import CHARGE_TRANSFER_PRIOR, theta

KERNEL = Kernel(
    columns={"thbv": "thbv"},
    flags={"bvarr": "np.any(thbv != 0.0)"},
    code={"exchange_current": "if bvarr:\n    gb *= np.exp(thbv[c] * dinv)"},
)
"""1/i0 is multiplied by exp(θbv·(1/T − 1/Tref)) (butler_volmer's ``exchange_current`` slot)."""


ELEMENT = Element(
    name="bv_arrhenius",
    params={"thbv": theta("bv_theta_i0_k", CHARGE_TRANSFER_PRIOR)},  # an exchange current's
    starts=lambda row, imax: [dict(thbv=3000.0)],
    signature="thermal's (the residual against I·ΔT) reads it",
    # its θ is a constant of butler_volmer's piece, which it needs
    pybamm=Export(
        "butler_volmer's 1/i0 times exp(θ·(1/T − 1/T_ref)), T the cell temperature",
        lambda p: Piece(),
    ),
    would_decide="records at other temperatures",
    compiled="extras",
    requires="butler_volmer",
    needs_temperature=True,
    kernel=KERNEL,
    table=TableLaw("in r_bv0_ohm (butler_volmer's column): 1/i0 times exp(θ·(1/T − 1/tref_k))"),
)
