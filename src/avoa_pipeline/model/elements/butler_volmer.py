"""A symmetric Butler–Volmer overpotential (α = ½) beside the linear R0:
V −= (2RT/F)·asinh(i/(2 i0))
(A. J. Bard, L. R. Faulkner, Electrochemical Methods, 2nd ed., Wiley 2001, ch. 3)."""

from __future__ import annotations

import numpy as np

from ...records import REST_FRACTION
from .element import (
    FARADAY,
    GAS_R,
    Element,
    Export,
    Kernel,
    Param,
    Piece,
    Signature,
    TableLaw,
    View,
)

_BUTLER_VOLMER = '''
def butler_volmer(T_cell, current):
    """butler_volmer as a resistance in series with R0: the drop (2RT/F)·asinh(I/(2·i0)) divided
    by I; asinh(x)/x is 1 at x = 0, so it tends to RT/(F·i0) at rest. With bv_arrhenius, 1/i0
    follows exp(θ·(1/T − 1/T_REF_K)) (θ = 0 without it)."""
    inv_i0 = BV_INV_I0_PER_A * pybamm.exp(BV_THETA_I0_K * (1.0 / (T_cell + 273.15) - 1.0 / T_REF_K))
    x = 0.5 * inv_i0 * current
    nonzero = (x > 0) + (x < 0)
    asinh_over_x = nonzero * pybamm.arcsinh(x) / (x + 1.0 - nonzero) + (1.0 - nonzero)
    two_rt_f = 2.0 * GAS_R * (T_cell + 273.15) / FARADAY
    return two_rt_f * 0.5 * inv_i0 * asinh_over_x
'''


def _piece(p) -> Piece:
    return Piece(
        constants=(("BV_INV_I0_PER_A", p["bvg"], "1/i0, the inverse exchange current"),
                   ("BV_THETA_I0_K", p["thbv"], "bv_arrhenius: θ of 1/i0 (0: none)"),
                   ("GAS_R", GAS_R, "J/(mol K)"), ("FARADAY", FARADAY, "C/mol")),
        helpers=(_BUTLER_VOLMER,),
        terms=(("R0", "butler_volmer(T_cell, current)"),),
    )  # fmt: skip


def current_bands(v: View) -> dict:
    """sign(I)·residual in bands of |I| (an overpotential that is not linear in the current)."""
    bands = {}
    a = np.abs(v.rec.i)
    for lo, hi in ((REST_FRACTION, 1 / 3), (1 / 3, 2 / 3), (2 / 3, np.inf)):
        m = (a >= lo * v.imax) & (a < hi * v.imax)
        bands[f"{lo:.2f}-{hi:.2f} Imax"] = (
            1e3 * float(np.mean(np.sign(v.rec.i[m]) * v.resid[m])) if m.any() else None
        )
    return {"signed_residual_by_current_mv": bands}


KERNEL = Kernel(
    columns={"bvg": "bvg"},
    flags={"bv": "np.any(bvg != 0.0)"},
    code={
        "overpotential": """if bv:
    gb = bvg[c]
    @slot exchange_current
    v -= rtf * np.arcsinh(0.5 * gb * i)""",
    },
)
"""V −= (2RT/F)·asinh(i/(2 i0)), 1/i0 = bvg (not under the paper's load: its current would follow
a voltage that is not linear in it). bv_arrhenius fills ``exchange_current``."""


def _r_bv0(p, s, tk, tref):  # RT/F times 1/i0(T) (bv_arrhenius's factor: 1 without it)
    return GAS_R * tk / FARADAY * (p["bvg"] * np.exp(p["thbv"] * (1.0 / tk - 1.0 / tref)))


ELEMENT = Element(
    name="butler_volmer",
    params={
        "bvg": Param(
            "bv_inv_i0_per_a",
            "lin",
            0.0,
            (0.0, 1e5),
            "1/i0: an exchange current of 10 µA at least; in a fit, of "
            "1 % of the records' largest current",
            prior_sd=10.0,
            scale="per_a",
            scaled=(0.0, 100.0),
        )
    },
    starts=lambda row, imax: [dict(bvg=1.0 / imax), dict(bvg=5.0 / imax)],
    signature=Signature(
        "load: sign(I)·residual changes with |I| (a linear R0 cannot follow asinh)", current_bands
    ),
    pybamm=Export(
        "a current- and temperature-dependent resistance in series with R0: "
        "(2RT/F)·asinh(I/(2 i0))/I, T the cell temperature (the drop is exactly the element's)",
        _piece,
    ),
    would_decide="pulses of several currents at one SOC",
    conflicts={"load": "the load is solved for a linear ohmic drop"},
    withheld=True,
    kernel=KERNEL,
    table=TableLaw(
        "its slope at I = 0, RT/(F·i0(T)), in column r_bv0_ohm (the law itself in the sidecar)",
        columns={
            "r_bv0_ohm": (
                "Ω",
                "Butler–Volmer: the slope of its overpotential at I = 0, RT/(F·i0(T)) (see cannot)",
                _r_bv0,
            )
        },
    ),
)
