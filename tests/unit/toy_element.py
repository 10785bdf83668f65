"""A toy element defined in the test folder only (issue 39): an OCV tilt, k·(s − 0.5) added to
the OCV at the SOC the curve is read at. Its module states every part an element declares; one
registry line (``elements.register(ELEMENT)``, before the model library is imported) adds it,
and tests/unit/test_toy_element.py shows simulate, a fit, estimate, the table export and the
PyBaMM export all run it and agree."""

from __future__ import annotations

from avoa_pipeline.model.elements.element import (
    Element,
    Export,
    Kernel,
    Param,
    Piece,
    TableLaw,
)

TILT_V = 0.04
"""The truth the test's records are made with (V per unit SOC, about half the Panasonic cell's
OCV slope over its middle)."""


def _piece(p) -> Piece:
    return Piece(
        constants=(("OCV_TILT_V", p["tilt"], "toy: the OCV's tilt per unit SOC"),),
        ocv_terms=("OCV_TILT_V * (sc - 0.5)",),
    )


ELEMENT = Element(
    name="toy_tilt",
    params={
        "tilt": Param(
            "ocv_tilt_v",
            "lin",
            0.0,
            (-0.2, 0.2),
            "±0.2 V per unit SOC: a tilt the size of an OCV's own slope",
            prior_sd=0.1,
        )
    },
    starts=lambda row, imax: [dict(tilt=0.0), dict(tilt=0.02)],
    signature="a toy: the base's OCV fit absorbs most of a tilt, so it has no signature",
    pybamm=Export("added to the OCV, k·(sc − 0.5)", _piece),
    would_decide="a record that visits the whole SOC range",
    kernel=Kernel(
        columns={"tilt": "tilt"},
        flags={"tilted": "np.any(tilt != 0.0)"},
        code={"ocv": "if tilted:\n    e += tilt[c] * (sc - 0.5)"},
    ),
    table=TableLaw("k·(s − 0.5) added to ocv_v", ocv=lambda p, s, tk, tref: p["tilt"] * (s - 0.5)),
)
