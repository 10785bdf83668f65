"""Charge counted with an efficiency η: s −= η·i·Δt/(3600 Q) while charging (i < 0), and in the
hysteresis rate (Plett's ESC model)."""

from __future__ import annotations

import numpy as np

from ... import records
from .element import Element, Export, Param, Piece, Signature, View, slope_mv

_COUNTED = '''
def counted(current):
    """The current as the SoC counts it: a charge (I < 0) times the coulombic efficiency η
    (1: all of it; the SoC and the hysteresis rate count this current)."""
    eta = pybamm.Parameter("Coulombic efficiency")
    return current * (1.0 + (eta - 1.0) * (current < 0))
'''

_COUNTED_CHARGE = '''
class CountedCharge(pybamm.equivalent_circuit_elements.OCVElement):
    """coulombic_efficiency: PyBaMM's OCV element, its SoC counting charge times η:
    dSoC/dt = −counted(I)/(3600·Q)."""

    def set_rhs(self, variables):
        soc = variables["SoC"]
        current = counted(variables["Current [A]"])
        self.rhs = {soc: -current / self.param.cell_capacity / 3600}
'''


def counted_piece(p) -> Piece:
    """The counted current (charge times η; η = 1 without this element), which the SoC and
    hysteresis's rate read: shared with hysteresis's piece, written once into the module."""
    return Piece(
        constants=(("COULOMBIC_EFFICIENCY", p["eta"], "η: the share of a charge the SoC counts "
                    "(1: all)"),),
        helpers=(_COUNTED,),
        parameters=(("Coulombic efficiency", "COULOMBIC_EFFICIENCY"),),
    )  # fmt: skip


def _piece(p) -> Piece:
    c = counted_piece(p)
    return Piece(constants=c.constants, helpers=(*c.helpers, _COUNTED_CHARGE),
                 parameters=c.parameters,
                 submodels=(("Open-circuit voltage", "CountedCharge"),))  # fmt: skip


def _read(v: View) -> dict:
    rec, rest = v.rec, v.direction == 0
    charged = np.concatenate([[0.0], np.cumsum(np.minimum(rec.i[:-1], 0) * rec.dt[:-1])]) / -3600
    return {"rest_trend_mv_per_ah_charged": slope_mv(charged[rest], v.resid[rest])}


def _applies(recs, imax) -> str:
    charges = any((records.direction(r.i, imax) < 0).any() for r in recs)
    return "" if charges else "no charge current"


ELEMENT = Element(
    name="coulombic_efficiency",
    params={
        "eta": Param(
            "coulombic_efficiency",
            "lin",
            1.0,
            (0.7, 1.0),
            "at most all charge kept; 70 % lost at worst (a cell far beyond use)",
            prior_sd=0.1,
        )
    },
    starts=lambda row, imax: [dict(eta=0.98)],
    signature=Signature(
        "SOC falls behind after charging: rest residual against charge put in", _read
    ),
    pybamm=Export(
        "PyBaMM's OCV element with its SoC counting a charge (I < 0) times η: dSoC/dt = "
        "−I·(1 + (η − 1)·[I < 0])/(3600·Q) (a submodel in the slot of Thevenin's OCV element)",
        _piece,
    ),
    would_decide="a full charge and discharge between two rests",
    applies=_applies,
    withheld=True,
)
