"""R1 by SOC: R1 → R1·exp(l(s)), as ``r0_soc`` (τ1 stays fixed)."""

from __future__ import annotations

import numpy as np

from .element import KNOTS, N_KNOTS, Element, Export, Kernel, Param, TableLaw, Vector
from .r0_soc import LOG_LIMITS, LOG_WHY, soc_table

_report, _piece = soc_table("r1_soc", "R1")

KERNEL = Kernel(
    columns={"l1": KNOTS},
    flags={"soc_r1": "np.any(l1 != 0.0)"},
    factors={"r1": "g1"},
    code={
        # the factor follows the SOC, a state: a hold cannot compute its increments once
        "hold_setup": "if soc_r1:\n    fast = False",
        "row": """g1 = 1.0
if soc_r1:
    xs = (s - k_lo) / k_step
    js = min(max(int(xs), 0), nk - 2) if xs > 0.0 else 0
    ws = min(max(xs - js, 0.0), 1.0)
    g1 = np.exp((1.0 - ws) * l1[c, js] + ws * l1[c, js + 1])""",
    },
)
"""R1 (the base's branch) is multiplied by exp of the log-multipliers interpolated at the bulk
SOC."""


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
    kernel=KERNEL,
    table=TableLaw(
        "exp(l1(s)) multiplies r1_ohm",
        factors={"r1": lambda p, s, tk, tref: np.exp(p["r1_soc"](s))},
    ),
)
