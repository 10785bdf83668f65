"""Arrhenius time constants: every RC branch's τ_j → τ_j·exp(θτ(1/T − 1/Tref)), T the cell
temperature. With ``thermal`` the RC resistances follow Arrhenius; a branch's capacitance need
not (τ = R·C), so the time constants get a law of their own, admitted only if the records
identify it (issue 28). Offered on top of ``thermal`` and only where the temperature moves."""

from __future__ import annotations

import numpy as np

from .element import Element, Export, Kernel, Param, Piece, TableLaw
from .thermal import CHARGE_TRANSFER_PRIOR, THETA_LIMITS


def _piece(p) -> Piece:
    # "TAU": a factor of every RC branch's time constant (interop/pybamm.py writes it into the
    # branches' capacitances C_j = τ_j·factor/R_j); thermal's arrhenius() helper is in the module
    return Piece(
        constants=(("THERMAL_THETA_TAU_K", p["thtau"], "Arrhenius θτ of the RC time constants"),),
        factors=(("TAU", "arrhenius(THERMAL_THETA_TAU_K, T_cell)"),),
    )  # fmt: skip


KERNEL = Kernel(
    columns={"thtau": "thtau"},
    flags={"ttau": "np.any(thtau != 0.0)"},
    code={
        "hold_setup": "tdep = tdep or ttau",
        "sample": """if ttau:
    for c in range(m):
        ft = np.exp(thtau[c] * dinv)
        @each_branch a{j}[c] = np.exp(-dtk / (tau{j}[c] * ft))""",
    },
)
"""Every RC branch's time constant τ_j·exp(θτ·(1/T − 1/Tref)) (its decay recomputed per
sample)."""


ELEMENT = Element(
    name="thermal_tau",
    params={
        "thtau": Param(
            "thermal_theta_tau_k",
            "lin",
            0.0,
            THETA_LIMITS,
            "θτ = Ea/R up to 12,000 K (as thermal's θ); not negative: a branch is not faster "
            "in the cold, its resistance rises and its capacitance does not grow with T",
            prior_sd=5000.0,
            physical=CHARGE_TRANSFER_PRIOR,  # an RC time constant's: the charge transfer's
        )
    },
    starts=lambda row, imax: [dict(thtau=3000.0)],
    signature="thermal's (the residual against I·ΔT) reads it",
    pybamm=Export(
        "every C_j = τ_j·exp(θτ·(1/T − 1/T_ref))/R_j as a function of PyBaMM's cell temperature "
        "(R_j with thermal's factor): the time constant follows its own Arrhenius law",
        _piece,
    ),
    would_decide="relaxations after pulses at several temperatures",
    compiled="extras",
    requires="thermal",
    needs_temperature=True,
    kernel=KERNEL,
    table=TableLaw(
        "exp(θτ·(1/T − 1/tref_k)) multiplies every tau_j_s",
        factors={"tau": lambda p, s, tk, tref: np.exp(p["thtau"] * (1.0 / tk - 1.0 / tref))},
    ),
)
