"""One-state dynamic hysteresis of Plett's enhanced self-correcting model (G. L. Plett,
J. Power Sources 134 (2004) 262-276, eq. 13): h → −1 while discharging, V += M·h."""

from __future__ import annotations

import numpy as np

from .coulombic_efficiency import counted_piece
from .element import Element, Export, Kernel, Param, Piece, Signature, State, TableLaw, View

_HYSTERESIS = '''
class Hysteresis(pybamm.BaseSubModel):
    """hysteresis (Plett 2004, eq. 13): a state h that goes to −1 while discharging and to +1
    while charging, at a rate γ per capacity of charge counted, and adds M·h to the voltage:
    dh/dt = −γ·|Ic|·(h + sgn I)/(3600·Q) = −γ·(|Ic|·h + Ic)/(3600·Q), Ic = counted(I, T). For a
    current held over each interval this is exactly avoa-pipeline's h_k+1 = e·h_k − (1 − e)·sgn I_k,
    e = exp(−|γ·Ic_k·Δt/(3600·Q)|); at I = 0 h holds, as there."""

    def __init__(self, param, options=None):
        super().__init__(param)
        self.model_options = options

    def get_fundamental_variables(self):
        h = pybamm.Variable("Hysteresis state")
        m = pybamm.Parameter("Hysteresis voltage [V]")
        return {"Hysteresis state": h, "Hysteresis overpotential [V]": m * h}

    def set_rhs(self, variables):
        h = variables["Hysteresis state"]
        current = counted(variables["Current [A]"], variables["Cell temperature [degC]"])
        gamma = pybamm.Parameter("Hysteresis rate")
        rate = gamma / (3600 * self.param.cell_capacity)
        self.rhs = {h: -rate * (abs(current) * h + current)}

    def set_initial_conditions(self, variables):
        initial = pybamm.Parameter("Initial hysteresis state")
        self.initial_conditions = {variables["Hysteresis state"]: initial}


class VoltageWithHysteresis(pybamm.equivalent_circuit_elements.VoltageModel):
    """PyBaMM's voltage of the Thevenin model plus the hysteresis overpotential M·h (and the
    power and resistance that follow from it)."""

    def get_coupled_variables(self, variables):
        hysteresis = variables["Hysteresis overpotential [V]"]
        variables = super().get_coupled_variables(variables)
        voltage = variables["Voltage [V]"] + hysteresis
        current = variables["Current [A]"]
        nonzero = (current > 0) + (current < 0)
        variables.update({
            "Voltage [V]": voltage,
            "Battery voltage [V]": voltage,
            "Power [W]": voltage * current,
            "Resistance [Ohm]": pybamm.sign(current) * voltage / (current + 1.0 - nonzero),
        })
        return variables
'''


def _piece(p) -> Piece:
    c = counted_piece(p)
    return Piece(
        constants=(("HYSTERESIS_M_V", p["hm"], "hysteresis: M, the voltage at h = ±1"),
                   ("HYSTERESIS_GAMMA", p["lgamma"], "hysteresis: γ, the rate per capacity of "
                    "charge"),
                   ("INITIAL_HYSTERESIS_STATE", 0.0, "h at the start (avoa-pipeline starts every "
                    "record at 0)"),
                   *c.constants),
        helpers=(*c.helpers, _HYSTERESIS),
        submodels=(("Hysteresis", "Hysteresis"), ("Voltage", "VoltageWithHysteresis")),
        parameters=(("Hysteresis voltage [V]", "HYSTERESIS_M_V"),
                    ("Hysteresis rate", "HYSTERESIS_GAMMA"),
                    ("Initial hysteresis state", "INITIAL_HYSTERESIS_STATE"), *c.parameters),
        states=(("Hysteresis state", "Initial hysteresis state"),),
    )  # fmt: skip


def last_direction(d: np.ndarray) -> np.ndarray:
    """+1 after discharge, −1 after charge, 0 before any current (per sample), from each
    sample's direction ``d`` (``records.direction``)."""
    idx = np.where(d != 0, np.arange(d.size), 0)
    idx = np.maximum.accumulate(idx)
    return d[idx]


def _read(v: View) -> dict:
    rest, last = v.direction == 0, last_direction(v.direction)
    return {
        "rest_after_charge_mv": v.mean_mv(rest & (last < 0)),
        "rest_after_discharge_mv": v.mean_mv(rest & (last > 0)),
        "charge_mv": v.mean_mv(v.direction < 0),
        "discharge_mv": v.mean_mv(v.direction > 0),
    }


KERNEL = Kernel(
    columns={"hm": "hm", "gam": "lgamma", "h": "h0"},
    flags={"hyst": "np.any(hm != 0.0)"},
    states={"h": State("h", lambda p, i: 1.0)},
    code={
        # hx: the decay of the last sample, per row (one exp per row and sample was most of a
        # hysteresis model's cost, so a held current's decay is reused); hs, hon: a hold's
        "setup": "hx = np.zeros(m)\nhs = np.zeros(m)\nhon = np.zeros(m, dtype=np.bool_)",
        # added after the other OCV terms (the hand-written loop's order: floats)
        "ocv": (1, "if hyst:\n    e += hm[c] * h[c]"),
        "trace": "tr[1, k] = h[c]",
        "hold_increment_charge": """hon[c] = hyst and i != 0.0
if hon[c]:
    hx[c] = np.exp(-abs(dqs[c] * gam[c]))
    hs[c] = (1.0 - hx[c]) * (1.0 if i > 0.0 else -1.0)""",
        "hold_step": """if hyst:
    for c in range(m):
        if hon[c]:
            h[c] = hx[c] * h[c] - hs[c]""",
        "update_charge": """if hyst and i != 0.0:
    if not held:
        hx[c] = np.exp(-abs(dq * gam[c]))
    ex = hx[c]
    h[c] = ex * h[c] - (1.0 - ex) * (1.0 if i > 0.0 else -1.0)""",
    },
)
"""V += M·h; h_k+1 = e_k·h_k − (1 − e_k)·sgn(i_k), e_k = exp(−|γ·Δs_k|) with Δs_k the SOC step
(the counted charge over the capacity); at zero current h holds."""


ELEMENT = Element(
    name="hysteresis",
    params={
        "hm": Param(
            "hysteresis_m_v",
            "lin",
            0.0,
            (0.0, 0.3),
            "up to 300 mV: beyond the widest measured hysteresis (LFP, tens of mV)",
            prior_sd=0.05,
        ),
        "lgamma": Param(
            "hysteresis_gamma",
            "log10",
            2.0,
            (0.1, 1e4),
            "h settles over 10 capacities' charge (0.1) down to 0.01 % of one (1e4)",
        ),
        "h0": Param(
            "hysteresis_h0",
            "lin",
            0.0,
            (-1.0, 1.0),
            "h lies in [−1, 1]",
            per_record=True,
            prior_sd=1.0,
        ),
    },
    starts=lambda row, imax: [dict(hm=0.01, lgamma=lg, h0=0.0) for lg in (1.0, 2.0, 3.0)],
    signature=Signature(
        "rest voltage after charge above that after discharge; load offset ±M", _read
    ),
    pybamm=Export(
        "a state of its own beside Thevenin's (a submodel): h, dh/dt = −γ·(|Ic|·h + Ic)/(3600·Q) "
        "with Ic the current as the SoC counts it, and M·h added to the voltage",
        _piece,
    ),
    would_decide="rests at one SOC reached once by charge and once by discharge",
    withheld=True,
    kernel=KERNEL,
    table=TableLaw("a state, not a column: the sidecar's scalars and recursion (V += M·h)"),
)
