"""Resistances that rise towards empty: R0 and every RC resistance × g(s) = 1 + k·exp(−s/σ)
(solid-state diffusion and charge transfer at low lithium content; the hand-built Panasonic
circuit's low-SOC term)."""

from __future__ import annotations

import numpy as np

from .element import Element, Export, Kernel, Param, Piece, TableLaw

_SOC_FACTOR = '''
def soc_factor(soc):
    """soc_resistance: 1 + k·exp(−SOC/σ) (SOC clipped to [−0.5, 2], as avoa-pipeline does)."""
    s = pybamm.minimum(pybamm.maximum(soc, -0.5), 2.0)
    return 1.0 + SOC_RESISTANCE_K * pybamm.exp(-s / SOC_RESISTANCE_SIGMA)
'''


def _piece(p) -> Piece:
    return Piece(
        constants=(("SOC_RESISTANCE_K", p["klow"], "rise of the resistances at SOC 0"),
                   ("SOC_RESISTANCE_SIGMA", p["lsig"], "SOC width of the rise")),
        helpers=(_SOC_FACTOR,),
        factors=(("R0", "soc_factor(soc)"), ("RC", "soc_factor(soc)")),
    )  # fmt: skip


KERNEL = Kernel(
    columns={"klow": "klow", "sig": "lsig"},
    flags={"low": "np.any(klow != 0.0)"},
    code={
        # g follows the SOC, a state: a hold cannot compute its increments once
        "hold_setup": "fast = fast and not low",
        "row": "if low:\n    g = 1.0 + klow[c] * np.exp(-min(max(s, -0.5), 2.0) / sig[c])",
    },
)
"""g(s) = 1 + k_low·exp(−s/σ) multiplies R0 and the RC resistances (s clipped to [−0.5, 2]: the
exponential overflows far outside)."""


def _g(p, s, tk, tref):  # its SOC clipped as the simulator clips it
    if p["klow"] == 0.0:
        return np.ones_like(s)
    return 1.0 + p["klow"] * np.exp(-np.clip(s, -0.5, 2.0) / p["lsig"])


ELEMENT = Element(
    name="soc_resistance",
    params={
        "klow": Param(
            "soc_resistance_k",
            "lin",
            0.0,
            (0.0, 50.0),
            "the rise near empty: up to 50× at SOC 0",
            prior_sd=5.0,
        ),
        "lsig": Param(
            "soc_resistance_sigma", "log10", -1.3, (0.005, 0.5), "over an SOC width of 0.5-50 %"
        ),
    },
    starts=lambda row, imax: [dict(klow=k, lsig=np.log10(s)) for k, s in ((0.5, 0.05), (2.0, 0.1))],
    signature="the localisation's misfit by SOC band (diagnosis.json regions) reads it",
    pybamm=Export(
        "R0 and every R_j times 1 + k·exp(−SOC/σ) as functions of PyBaMM's SoC; C_j = τ_j/R_j, "
        "so the time constants stay fixed as in avoa-pipeline",
        _piece,
    ),
    would_decide="pulses at low and at high SOC",
    kernel=KERNEL,
    table=TableLaw(
        "g(s) multiplies r0_ohm and every r_j_ohm",
        factors={"r0": _g, "rc": _g},
    ),
)
