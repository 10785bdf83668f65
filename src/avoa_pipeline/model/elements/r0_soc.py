"""R0 by SOC: R0 → R0·exp(l(s)), l linear between the N_KNOTS knots (flat beyond), l = B1·u with
B1 the discrete orthogonal polynomials of degree 1-5 (no constant: R0's own). The R0(SOC) table
of Plett's ESC model (Battery Management Systems, vol. I, Artech House 2015, ch. 2) and of
Simscape's table-based battery block."""

from __future__ import annotations

import numpy as np

from .element import (
    KNOTS,
    N_KNOTS,
    Element,
    Export,
    Kernel,
    Param,
    Piece,
    TableLaw,
    Vector,
    flat_ends,
)

LOG_LIMITS = (-3.0, 3.0)
LOG_WHY = "a log-multiplier at a knot: a factor of e^±3 (0.05-20) at most"


def soc_table(element: str, resistor: str):
    """The knot report and the PyBaMM piece of a resistance-by-SOC element (r0_soc, r1_soc)."""
    key, name = resistor.lower(), f"{resistor}_SOC"

    def report(p) -> dict:
        out = {}
        for j, s in enumerate(p.knots):
            out[f"{key}_knot{j}_soc"] = float(s)
            out[f"{key}_knot{j}_factor"] = float(np.exp(p.at_knots[element][j]))
        return out

    def piece(p) -> Piece:
        logs = p.at_knots[element]
        return Piece(
            constants=((f"{name}_SOC", flat_ends(p.knots), f"{element}: knots (and a point beyond "
                        "each end: avoa-pipeline holds the end values)"),
                       (f"{name}_LOG", [logs[0], *logs, logs[-1]],
                        f"{element}: log of the factor at the knots")),
            factors=((resistor, f'pybamm.exp(pybamm.Interpolant({name}_SOC, {name}_LOG, soc, '
                                f'"{name.lower()}"))'),),
        )  # fmt: skip

    return report, piece


_report, _piece = soc_table("r0_soc", "R0")

KERNEL = Kernel(
    columns={"l0": KNOTS},
    flags={"soc_r0": "np.any(l0 != 0.0)"},
    code={
        "r0_multiplier": """if soc_r0:  # log-multipliers at the knots, by the (bulk) SOC
    xs = (s - k_lo) / k_step
    js = min(max(int(xs), 0), nk - 2) if xs > 0.0 else 0
    ws = min(max(xs - js, 0.0), 1.0)
    ro *= np.exp((1.0 - ws) * l0[c, js] + ws * l0[c, js + 1])""",
    },
)
"""R0 is multiplied by exp of the log-multipliers interpolated at the bulk SOC (flat beyond the
knots)."""


ELEMENT = Element(
    name="r0_soc",
    params={
        f"r0u{j}": Param(f"r0_soc_u{j}", "lin", 0.0, LOG_LIMITS, LOG_WHY, prior_sd=1.0)
        for j in range(N_KNOTS - 1)
    },
    # flat: the data bend it (the log-multipliers' derivatives are not zero there)
    starts=lambda row, imax: [{}],
    signature="the localisation's misfit by SOC band (diagnosis.json regions) reads it",
    pybamm=Export(
        "R0 times exp(l(SoC)), l a linear interpolant through the knots (flat beyond them)", _piece
    ),
    would_decide="pulses at low and at high SOC",
    compiled="extras",
    vector=Vector(1, _report),
    kernel=KERNEL,
    table=TableLaw(
        "exp(l0(s)) multiplies r0_ohm",
        factors={"r0": lambda p, s, tk, tref: np.exp(p["r0_soc"](s))},
    ),
)
