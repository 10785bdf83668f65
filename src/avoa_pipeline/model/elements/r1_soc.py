"""R1 by SOC: R1 → R1·exp(l(s)), as ``r0_soc`` (τ1 stays fixed)."""

from __future__ import annotations

from .element import N_KNOTS, Element, Export, Param, Vector
from .r0_soc import LOG_LIMITS, LOG_WHY, soc_table

_report, _piece = soc_table("r1_soc", "R1")

ELEMENT = Element(
    name="r1_soc",
    params={
        f"r1u{j}": Param(f"r1_soc_u{j}", "lin", 0.0, LOG_LIMITS, LOG_WHY, prior_sd=1.0)
        for j in range(N_KNOTS - 1)
    },
    starts=lambda row, imax: [{}],  # flat, as r0_soc
    signature="the localisation's misfit by SOC band (diagnosis.json regions) reads it",
    pybamm=Export(
        "R1 times exp(l(SoC)) as r0_soc; C1 = τ1/R1(SoC), so τ1 stays fixed as in avoa-pipeline",
        _piece,
    ),
    would_decide="pulses at low and at high SOC",
    compiled="extras",
    vector=Vector(1, _report),
)
