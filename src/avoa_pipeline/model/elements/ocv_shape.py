"""A correction of the OCV's shape: OCV += Σ d_j·φ_j(s), hat functions on the N_KNOTS knots
(flat beyond), d = B·u with B the discrete orthogonal polynomials of degree 2-5 on the knots. B
has no constant or linear part: those are in Vnom, β, Q, SOC0's reach, and leaving them in made
the fit singular and let the shape mimic a voltage offset."""

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
    Signature,
    TableLaw,
    Vector,
    View,
    flat_ends,
)


def _report(p) -> dict:
    out = {}
    for j, s in enumerate(p.knots):
        out[f"ocv_knot{j}_soc"] = float(s)
        out[f"ocv_d{j}_v"] = float(p.at_knots["ocv_shape"][j])
    return out


def _piece(p) -> Piece:
    d = p.at_knots["ocv_shape"]
    return Piece(
        constants=(("OCV_SHAPE_SOC", flat_ends(p.knots), "ocv_shape: knots (and a point beyond "
                    "each end: avoa-pipeline holds the end values)"),
                   ("OCV_SHAPE_V", [d[0], *d, d[-1]], "ocv_shape: the correction at the knots")),
        ocv_terms=('pybamm.Interpolant(OCV_SHAPE_SOC, OCV_SHAPE_V, sc, "ocv_shape")',),
    )  # fmt: skip


def _read(v: View) -> dict:
    late = (v.direction == 0) & (v.since >= 600.0)
    edges = np.linspace(0, 1, 6)
    by_soc = {}
    for j in range(5):
        m = late & (v.soc >= edges[j]) & (v.soc < edges[j + 1] + (j == 4))
        by_soc[f"{edges[j]:.1f}-{edges[j + 1]:.1f}"] = v.mean_mv(m)
    return {"late_rest_by_soc_mv": by_soc}


KERNEL = Kernel(
    columns={"d": KNOTS},
    flags={"shape": "np.any(d != 0.0)"},
    code={
        "ocv": """if shape:
    x = (sc - k_lo) / k_step
    if x <= 0.0:
        e += d[c, 0]
    elif x >= nk - 1:
        e += d[c, nk - 1]
    else:
        j = int(x)
        w = x - j
        e += (1.0 - w) * d[c, j] + w * d[c, j + 1]""",
    },
)
"""The correction's values at the knots, interpolated linearly at the SOC the OCV curve was read
at and held flat beyond the knots."""


ELEMENT = Element(
    name="ocv_shape",
    params={
        f"u{j}": Param(
            f"ocv_shape_u{j}_v",
            "lin",
            0.0,
            (-0.5, 0.5),
            "a shape coordinate of at most ±0.5 V (a cell's whole OCV swing is ~1-2 V)",
            prior_sd=0.05,
        )
        for j in range(N_KNOTS - 2)
    },
    starts=lambda row, imax: [{}],
    signature=Signature("relaxed rest voltage against SOC", _read),
    pybamm=Export(
        "added to the OCV as a linear interpolant through its knots (flat beyond them)", _piece
    ),
    would_decide="a slow OCV test (--ocv)",
    vector=Vector(2, _report),
    withheld=True,
    kernel=KERNEL,
    table=TableLaw("in ocv_v (ecm.ocv_values adds the correction at the SOC)"),
)
