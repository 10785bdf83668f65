"""Arrhenius time constants: every RC branch's τ_j → τ_j·exp(θτ(1/T − 1/Tref)), T the cell
temperature. With ``thermal`` the RC resistances follow Arrhenius; a branch's capacitance need
not (τ = R·C), so the time constants get a law of their own, admitted only if the records
identify it (issue 28). Offered on top of ``thermal`` and only where the temperature moves."""

from __future__ import annotations

from .element import Element, Export, Param
from .thermal import THETA_LIMITS

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
        )
    },
    starts=lambda row, imax: [dict(thtau=3000.0)],
    signature="thermal's (the residual against I·ΔT) reads it",
    pybamm=Export(
        "PyBaMM's Thevenin model takes C_j as a function of T; the export writes τ_j's law "
        "into the branches' capacitances only where the export carries the cell temperature"
    ),
    would_decide="relaxations after pulses at several temperatures",
    compiled="extras",
    requires="thermal",
    needs_temperature=True,
)
