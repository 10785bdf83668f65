"""The OCV's entropic term: OCV → OCV + (∂U/∂T)·(T − Tref), one coefficient for the whole SOC
range, T the cell temperature (issue 28). The OCV table is measured at one temperature (the
Panasonic C/20 test at 25 °C); a cell whose OCV moves with temperature needs this term to use
one table over the others. Offered only where the temperature moves."""

from __future__ import annotations

from .element import Element, Export, Param, Signature, View, slope_mv


def _read(v: View) -> dict:
    rec = v.rec
    if not rec.temperature_varies:
        return {"applicable": False}
    rest = v.direction == 0
    return {"rest_mv_per_k": slope_mv(rec.temp_c[rest], v.resid[rest]) if rest.any() else None}


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
        )
    },
    starts=lambda row, imax: [dict(dudt=1e-4), dict(dudt=-1e-4)],
    signature=Signature("rest: residual follows T − mean T", _read),
    pybamm=Export(
        "PyBaMM's Thevenin OCV is a function of SOC alone (its entropic change enters the heat "
        "only): the export adds (∂U/∂T)·(T − T_ref) to the OCV only where it writes its own model"
    ),
    would_decide="rests at several temperatures (an OCV measured at two temperatures)",
    compiled="extras",
    needs_temperature=True,
)
