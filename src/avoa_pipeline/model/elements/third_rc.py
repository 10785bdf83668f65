"""A third RC branch, offered only on top of ``second_rc``."""

from __future__ import annotations

from .element import Element, Export, Param, TableLaw
from .second_rc import R_LIMITS, R_WHY, TAU_LIMITS, TAU_WHY, rc_kernel, rc_piece


def _starts(row, imax):
    slow, fast = max(row["ltau1"], row["ltau2"]), min(row["ltau1"], row["ltau2"])
    r1 = max(row["r1"], 1e-4)
    return [dict(r3=0.3 * r1, ltau3=slow + 1.0), dict(r3=0.3 * r1, ltau3=fast - 1.0)]


ELEMENT = Element(
    name="third_rc",
    params={
        "r3": Param("r3_ohm", "lin", 0.0, R_LIMITS, R_WHY, prior_sd=0.1),
        "ltau3": Param("tau3_s", "log10", 3.0, TAU_LIMITS, TAU_WHY, scale="tau"),
    },
    starts=_starts,
    signature="second_rc's (relaxation after current steps) reads it too",
    pybamm=Export("an RC branch: R3 [Ohm], C3 [F] = τ3/R3", rc_piece(3)),
    would_decide="a long rest after a load (relaxation over an hour or more)",
    requires="second_rc",
    kernel=rc_kernel(3),
    table=TableLaw("its RC branch: columns r3_ohm, tau3_s, c3_f"),
)
