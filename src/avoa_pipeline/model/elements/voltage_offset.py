"""A voltage sensor's offset: V += c (with a measured OCV table the offset is part of the base)."""

from __future__ import annotations

import numpy as np

from .element import Element, Export, Kernel, Param, Piece, Signature, TableLaw, View


def _piece(p) -> Piece:
    return Piece(constants=(("VOLTAGE_OFFSET_V", p["voff"], "added to the OCV"),),
                 ocv_terms=("VOLTAGE_OFFSET_V",))  # fmt: skip


def _read(v: View) -> dict:
    return {"mean_residual_mv": 1e3 * float(np.mean(v.resid)), "mean_residual_t": v.t_mean(v.resid)}


KERNEL = Kernel(columns={"voff": "voff"}, code={"ocv": "e += voff[c]"})
"""c is added to the OCV (always: c = 0 adds nothing)."""


ELEMENT = Element(
    name="voltage_offset",
    params={
        "voff": Param(
            "voltage_offset_v",
            "lin",
            0.0,
            (-0.3, 0.3),
            "a voltage sensor's (or an OCV table's) offset: far below a cell's voltage",
            prior_sd=0.1,
        )
    },
    starts=lambda row, imax: [dict(voff=0.0)],
    signature=Signature("everywhere the same shift", _read),
    pybamm=Export("added to the OCV", _piece),
    would_decide="a slow OCV test (--ocv)",
    conflicts={"table": "a table OCV's offset is part of the base"},
    withheld=True,
    kernel=KERNEL,
    table=TableLaw("in ocv_v (ecm.ocv_values adds the offset)"),
)
