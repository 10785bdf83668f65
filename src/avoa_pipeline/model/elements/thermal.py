"""Arrhenius resistances: R0 → R0·exp(θ0(1/T − 1/Tref)), the RC resistances → ·exp(θ1(1/T −
1/Tref)), T the measured cell temperature. Only where the temperature moves
(``ecm.THERMAL_MIN_RANGE_C``): otherwise the factor is a constant R0 and R1 already absorb."""

from __future__ import annotations

import numpy as np

from .element import Element, Export, Kernel, Param, Piece, Signature, TableLaw, View

THETA_LIMITS = (0.0, 12000.0)
THETA_WHY = "θ = Ea/R up to 12,000 K (≈ 100 kJ/mol, above any cell's activation energy)"

R_GAS = 8.314462618
"""The molar gas constant, J/(mol·K) (CODATA 2018): θ = Ea/R."""
OHMIC_PRIOR = (5e3 / R_GAS, 40e3 / R_GAS,
               "an ohmic resistance's activation energy 5-40 kJ/mol (electrolyte conduction; "
               "Valøen & Reimers, J. Electrochem. Soc. 152 (2005) A882)")  # fmt: skip
"""θ of an ohmic resistance, 601-4,811 K (docs/temperature-rule.md part 2)."""
CHARGE_TRANSFER_PRIOR = (20e3 / R_GAS, 100e3 / R_GAS,
                         "a charge-transfer resistance's activation energy 20-100 kJ/mol (Jow "
                         "et al., J. Electrochem. Soc. 165 (2018) A361: 50-70 kJ/mol, widened "
                         "for other chemistries)")  # fmt: skip
"""θ of a charge-transfer resistance, an exchange current or an RC time constant, 2,405-12,027
K (docs/temperature-rule.md part 2). Sheet electrodes' charge-transfer resistances measured
30-60 kJ/mol (RSC Adv. 13 (2023) 21667) lie inside it."""


def theta(report: str, physical: tuple[float, float, str]) -> Param:
    """An Arrhenius θ = Ea/R (K): 0 (no temperature dependence) up to THETA_LIMITS, a weak
    prior at 0, and its physical prior (docs/temperature-rule.md part 2)."""
    return Param(report, "lin", 0.0, THETA_LIMITS, THETA_WHY, prior_sd=5000.0, physical=physical)


_ARRHENIUS = '''
def arrhenius(theta_k, T_cell):
    """thermal: exp(θ·(1/T − 1/T_REF_K)), T the cell temperature in K (PyBaMM passes °C)."""
    return pybamm.exp(theta_k * (1.0 / (T_cell + 273.15) - 1.0 / T_REF_K))
'''


def _piece(p) -> Piece:
    return Piece(
        constants=(("THERMAL_THETA_R0_K", p["th0"], "Arrhenius θ = Ea/R of R0"),
                   ("THERMAL_THETA_RC_K", p["th1"], "Arrhenius θ = Ea/R of the RC branches")),
        helpers=(_ARRHENIUS,),
        factors=(("R0", "arrhenius(THERMAL_THETA_R0_K, T_cell)"),
                 ("RC", "arrhenius(THERMAL_THETA_RC_K, T_cell)")),
    )  # fmt: skip


def _read(v: View) -> dict:
    rec = v.rec
    if not rec.temperature_varies:
        return {"applicable": False}
    load = v.direction != 0
    x = rec.i[load] * (rec.temp_c[load] - rec.temp_c.mean())
    c = float(np.corrcoef(x, v.resid[load])[0, 1]) if np.std(x) > 0 else None
    return {"corr_residual_vs_i_dT": c}


KERNEL = Kernel(
    columns={"th0": "th0", "th1": "th1"},
    flags={"therm0": "np.any(th0 != 0.0)", "therm1": "np.any(th1 != 0.0)"},
    code={
        "hold_setup": "tdep = tdep or therm1",
        "row": "if therm1:\n    f1 = np.exp(th1[c] * dinv)",
        "hold_row": "if therm1:\n    f1 = np.exp(th1[c] * dinv)",
        "r0_factor": "if therm0:\n    f0 = np.exp(th0[c] * dinv)",
    },
)
"""f0 = exp(θ0·(1/T − 1/Tref)) multiplies R0, f1 = exp(θ1·(1/T − 1/Tref)) the RC resistances
(``dinv``: 1/T − 1/Tref of the sample)."""


def _f0(p, s, tk, tref):
    return np.exp(p["th0"] * (1.0 / tk - 1.0 / tref))


def _f1(p, s, tk, tref):
    return np.exp(p["th1"] * (1.0 / tk - 1.0 / tref))


ELEMENT = Element(
    name="thermal",
    params={
        "th0": theta("thermal_theta_r0_k", OHMIC_PRIOR),
        "th1": theta("thermal_theta_rc_k", CHARGE_TRANSFER_PRIOR),
    },
    starts=lambda row, imax: [dict(th0=3000.0, th1=3000.0)],
    signature=Signature("load: residual follows I·(T − mean T)", _read),
    pybamm=Export(
        "R0 times exp(θ0·(1/T − 1/T_ref)) and every R_j times exp(θ1·(1/T − 1/T_ref)) as "
        "functions of PyBaMM's cell temperature; C_j = τ_j/R_j. The export makes the cell "
        "temperature follow the ambient temperature, which drive() sets from a measured one",
        _piece,
    ),
    would_decide="records at other temperatures",
    needs_temperature=True,
    withheld=True,
    kernel=KERNEL,
    table=TableLaw(
        "f0(T) multiplies r0_ohm, f1(T) every r_j_ohm",
        # after r0_soc's factor: the order the table's R0 was computed in since issue 19
        factors={"r0": (1, _f0), "rc": _f1},
    ),
)
