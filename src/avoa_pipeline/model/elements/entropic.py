"""The OCV's entropic term: OCV → OCV + (∂U/∂T)·(T − Tref), one coefficient for the whole SOC
range, T the cell temperature (issue 28). The OCV table is measured at one temperature (the
Panasonic C/20 test at 25 °C); a cell whose OCV moves with temperature needs this term to use
one table over the others. Offered only where the temperature moves."""

from __future__ import annotations

from .element import Element, Export, Kernel, Param, Piece, Signature, TableLaw, View, slope_mv

_ENTROPIC = '''
class EntropicOcv(pybamm.BaseSubModel):
    """entropic: the OCV plus (∂U/∂T)·(T − T_REF_K), T the cell temperature. ∂U/∂T is PyBaMM's
    own "Entropic change [V/K]" (which its Thevenin model puts into the reversible heat only);
    built before the voltage (model() builds the voltage last), it adds the term to the OCV
    the voltage reads."""

    def __init__(self, param, options=None):
        super().__init__(param)
        self.model_options = options

    def get_coupled_variables(self, variables):
        ocv = variables["Open-circuit voltage [V]"]
        T_cell = variables["Cell temperature [degC]"]
        term = self.param.dUdT(ocv, T_cell) * (T_cell + 273.15 - T_REF_K)
        variables.update({"Open-circuit voltage [V]": ocv + term, "Entropic term [V]": term})
        return variables
'''


def _piece(p) -> Piece:
    return Piece(
        constants=(("ENTROPIC_DUDT_V_PER_K", p["dudt"], "entropic: ∂U/∂T, one for every SOC"),),
        helpers=(_ENTROPIC,),
        submodels=(("Entropic", "EntropicOcv"),),
        parameters=(("Entropic change [V/K]", "ENTROPIC_DUDT_V_PER_K"),),
    )  # fmt: skip


def _read(v: View) -> dict:
    rec = v.rec
    if not rec.temperature_varies:
        return {"applicable": False}
    rest = v.direction == 0
    return {"rest_mv_per_k": slope_mv(rec.temp_c[rest], v.resid[rest]) if rest.any() else None}


KERNEL = Kernel(
    columns={"dudt": "dudt"},
    flags={"entr": "np.any(dudt != 0.0)"},
    reads=("dtemp",),
    code={"ocv": "if entr:\n    e += dudt[c] * dtemp"},
)
"""(∂U/∂T)·(T − Tref) is added to the OCV."""


ELEMENT = Element(
    name="entropic",
    params={
        "dudt": Param(
            "entropic_dudt_v_per_k",
            "lin",
            0.0,
            (-1e-3, 1e-3),
            "±1 mV/K: beyond the measured entropic coefficients of lithium-ion cells (within "
            "about ±0.5 mV/K over SOC for graphite/NMC, LFP and LCO)",
            prior_sd=5e-4,
            physical=(
                -1e-3,
                1e-3,
                "|∂U/∂T| ≤ 1 mV/K: full-cell entropic coefficients of "
                "graphite against LFP, NMC, NCA and LCO (Viswanathan et al., J. Power "
                "Sources 195 (2010) 3720)",
            ),
        )
    },
    starts=lambda row, imax: [dict(dudt=1e-4), dict(dudt=-1e-4)],
    signature=Signature("rest: residual follows T − mean T", _read),
    pybamm=Export(
        "PyBaMM's Thevenin OCV is a function of SOC alone (its 'Entropic change [V/K]' enters "
        "the reversible heat only): a submodel adds (∂U/∂T)·(T − T_ref) to the OCV, T the cell "
        "temperature, ∂U/∂T PyBaMM's entropic change (so its heat has it too)",
        _piece,
    ),
    would_decide="rests at several temperatures (an OCV measured at two temperatures)",
    compiled="extras",
    needs_temperature=True,
    kernel=KERNEL,
    table=TableLaw(
        "(∂U/∂T)·(T − tref_k) added to ocv_v", ocv=lambda p, s, tk, tref: p["dudt"] * (tk - tref)
    ),
)
