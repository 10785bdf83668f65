"""The OCV's entropic term: OCV → OCV + (∂U/∂T)·(T − Tref), one coefficient for the whole SOC
range, T the cell temperature (issue 28). The OCV table is measured at one temperature (the
Panasonic C/20 test at 25 °C); a cell whose OCV moves with temperature needs this term to use
one table over the others. Offered only where the temperature moves.

**With slow tests at two temperatures or more** (docs/temperature-rule.md part 5) the table
carries their ∂U/∂T profile over SOC (``ocv.over_temperature``), and the term is
dudt·shape(SOC)·(T − Tref), the shape the profile over its largest |∂U/∂T|
(``OcvTable.dudt_shape``). The one parameter is then ∂U/∂T where the profile peaks: the scale
of the profile is dudt / peak (1: the slow tests' profile as measured, the first start), and
its bounds and physical prior, |∂U/∂T| ≤ 1 mV/K, bound the profile times the scale at every
SOC. Without a profile the shape is 1, as before."""

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


TABLE_DUDT_PEAK = "ocv_dudt_peak_v_per_k"
"""The key under which ``fitting.effect_starts`` hands the starts the OCV table's largest
|∂U/∂T| where it carries a profile (a fact of the table, not of a fitted row)."""
DUDT_SHAPE = "ocv_dudt_shape"
"""The key of the table law's ``p`` holding the profile's shape as a function of SOC
(``interop/table.py``), where the table carries one."""


def _flat(s):
    return 1.0


def _starts(row) -> list[dict]:
    """±0.1 mV/K without a profile (as before); with one, the profile as measured (scale 1)
    and mirrored (scale −1)."""
    peak = row.get(TABLE_DUDT_PEAK, 0.0)
    if peak > 0.0:
        return [dict(dudt=peak), dict(dudt=-peak)]
    return [dict(dudt=1e-4), dict(dudt=-1e-4)]


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


_OCV = """\
if entr:
    pf = 1.0  # the profile's shape at the SOC the OCV was read at; 1 without a profile
    if dudt_shape.shape[0] > 0:
        xp = (sc - tab_lo) / tab_step
        if xp <= 0.0:
            pf = dudt_shape[0]
        elif xp >= dudt_shape.shape[0] - 1:
            pf = dudt_shape[dudt_shape.shape[0] - 1]
        else:
            jp = int(xp)
            pf = (1.0 - (xp - jp)) * dudt_shape[jp] + (xp - jp) * dudt_shape[jp + 1]
    e += dudt[c] * pf * dtemp"""

KERNEL = Kernel(
    columns={"dudt": "dudt"},
    flags={"entr": "np.any(dudt != 0.0)"},
    reads=("dtemp",),
    code={"ocv": _OCV},
)
"""(∂U/∂T)·shape(SOC)·(T − Tref) is added to the OCV: the shape the table's profile over its
peak, read on the table's grid as the OCV is (flat beyond its ends), or 1 without a profile
(then dudt·1.0·dtemp, the same number as before the profile, bit for bit)."""


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
    starts=lambda row, imax: _starts(row),
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
        "(∂U/∂T)·(T − tref_k) added to ocv_v (times the slow tests' profile's shape over SOC "
        "where the table carries one)",
        ocv=lambda p, s, tk, tref: p["dudt"] * p.get(DUDT_SHAPE, _flat)(s) * (tk - tref),
    ),
)
