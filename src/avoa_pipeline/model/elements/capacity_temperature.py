"""A capacity that follows temperature: Q → Q·(1 + κQ·(T − Tref)), T the cell temperature, in
the SOC's coulomb count (issue 28). A cold cell delivers less of its charge before the same
voltage; with one capacity for every temperature the fitted initial SOCs are pushed to their
bounds. Linear: over the span of a cell's records (tens of kelvin) a first-order term is what
the records can identify. Offered only where the temperature moves."""

from __future__ import annotations

from .coulombic_efficiency import charge_piece
from .element import Element, Export, Kernel, Param, TableLaw

KERNEL = Kernel(
    columns={"kq": "kq"},
    flags={"qlaw": "np.any(kq != 0.0)"},
    reads=("dtemp",),
    factors={"capacity": "qf"},
    code={
        "hold_setup": "tdep = tdep or qlaw",
        # the hysteresis decay's charge step follows the temperature's capacity
        "held": "if qlaw and held:\n    held = dinv_t[k] == dinv_t[k - 1]",
        "capacity": "qf = 1.0 + kq[c] * dtemp if qlaw else 1.0",
    },
)
"""The capacity is Q·(1 + κQ·(T − Tref)) in the SOC's step."""


def _capacity(p, s, tk, tref):
    return p["lq"] * (1.0 + p["kq"] * (tk - tref))


ELEMENT = Element(
    name="capacity_temperature",
    params={
        "kq": Param(
            "capacity_temp_coeff_per_k",
            "lin",
            0.0,
            (-0.02, 0.02),
            "±2 %/K: a lithium-ion cell's accessible capacity changes by well under 1 %/K "
            "between −20 and 45 °C",
            prior_sd=0.01,
            physical=(
                0.0,
                0.01,
                "0 ≤ κQ ≤ 1 %/K: capacity falls toward the cold, and a cell "
                "losing more than 1 %/K would lose all of it within 100 K",
            ),
        )
    },
    starts=lambda row, imax: [dict(kq=0.002)],
    signature="none of its own: a wrong capacity shows as a residual drifting with charge, "
    "which the base's capacity and ocv_shape's signature read",
    pybamm=Export(
        "PyBaMM's Thevenin capacity is a number: the export counts the charge itself, at "
        "Q·(1 + κQ·(T − T_ref)) of the cell temperature, wherever it is counted (PyBaMM's OCV "
        "element's SoC in a submodel in its slot, hysteresis's rate, the interval-start SoC of "
        "SOC-dependent resistances; the module's counted())",
        charge_piece,
    ),
    would_decide="full discharges at several temperatures",
    compiled="extras",
    needs_temperature=True,
    kernel=KERNEL,
    table=TableLaw(
        "the capacity the SOC counts at each temperature, column capacity_ah",
        columns={
            "capacity_ah": (
                "A·h",
                "capacity_temperature: the capacity the SOC counts at "
                "this row's temperature, Q·(1 + κQ·(T − tref_k)) (the same at "
                "every SOC)",
                _capacity,
            )
        },
    ),
)
