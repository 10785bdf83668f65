"""Charge counted with an efficiency η: s −= η·i·Δt/(3600 Q) while charging (i < 0), and in the
hysteresis rate (Plett's ESC model). Its PyBaMM piece holds the module's one charge count
(:func:`counted_piece`, :func:`charge_piece`), which capacity_temperature's Q(T) shares."""

from __future__ import annotations

import numpy as np

from ... import records
from .element import Element, Export, Kernel, Param, Piece, Signature, TableLaw, View, slope_mv

_COUNTED = '''
def counted(current, T_cell):
    """The current as the SoC counts it, per cell capacity at T_REF_K: a charge (I < 0) times the
    coulombic efficiency η (1: all of it), over the capacity's temperature factor
    1 + κQ·(T − T_REF_K) (capacity_temperature; κQ = 0: none), T_cell in °C. The SoC, the
    hysteresis rate and the interval-start SoC count this current."""
    eta = pybamm.Parameter("Coulombic efficiency")
    kq = pybamm.Parameter("Capacity temperature coefficient [1/K]")
    capacity_factor = 1.0 + kq * (T_cell + 273.15 - T_REF_K)
    return current * (1.0 + (eta - 1.0) * (current < 0)) / capacity_factor
'''

_COUNTED_CHARGE = '''
class CountedCharge(pybamm.equivalent_circuit_elements.OCVElement):
    """coulombic_efficiency, capacity_temperature: PyBaMM's OCV element, its SoC counting charge
    times η at the capacity of the cell temperature: dSoC/dt = −counted(I, T)/(3600·Q)."""

    def set_rhs(self, variables):
        soc = variables["SoC"]
        current = counted(variables["Current [A]"], variables["Cell temperature [degC]"])
        self.rhs = {soc: -current / self.param.cell_capacity / 3600}
'''


def counted_piece(p) -> Piece:
    """The counted current (charge times η, η = 1 without this element; over capacity_
    temperature's factor, κQ = 0 without it), which the SoC, hysteresis's rate and the
    interval-start SoC read: shared by their pieces, written once into the module."""
    return Piece(
        constants=(("COULOMBIC_EFFICIENCY", p["eta"], "η: the share of a charge the SoC counts "
                    "(1: all)"),
                   ("CAPACITY_TEMP_COEFF_PER_K", p["kq"], "κQ: the capacity is "
                    "Q·(1 + κQ·(T − T_REF_K)) (0: one capacity)")),
        helpers=(_COUNTED,),
        parameters=(("Coulombic efficiency", "COULOMBIC_EFFICIENCY"),
                    ("Capacity temperature coefficient [1/K]", "CAPACITY_TEMP_COEFF_PER_K")),
    )  # fmt: skip


def charge_piece(p) -> Piece:
    """The counted current and the OCV element whose SoC counts it (coulombic_efficiency's
    piece, and capacity_temperature's: the same text, written once)."""
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


KERNEL = Kernel(columns={"eta": "eta"},
                code={"counted": "ie = i if i > 0.0 else eta[c] * i"})  # fmt: skip
"""The SOC counts η·i of a charging current (always: η = 1 counts it all)."""


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
        charge_piece,
    ),
    would_decide="a full charge and discharge between two rests",
    applies=_applies,
    withheld=True,
    kernel=KERNEL,
    table=TableLaw("a scalar of the sidecar, in the recursion's charge count"),
)
