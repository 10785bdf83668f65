"""A surface-SOC lag: the OCV sees s − δ, δ a first-order lag of the current (the slowest mode of
a single-particle model); unlike an RC branch its voltage scales with the OCV's slope."""

from __future__ import annotations

from .element import Element, Export, Param

ELEMENT = Element(
    name="diffusion",
    params={
        "kd": Param(
            "diffusion_soc_per_a",
            "lin",
            0.0,
            (0.0, 300.0),
            "surface-SOC lag: 30 % of SOC at 1 mA at most; in a fit, at "
            "the records' largest current",
            prior_sd=0.1,
            scale="per_a",
            scaled=(0.0, 0.3),
        ),
        "ltaud": Param(
            "diffusion_tau_s",
            "log10",
            3.0,
            (0.05, 2e4),
            "50 ms (a logger's fastest useful step) to 5.6 h",
            scale="tau",
        ),
    },
    starts=lambda row, imax: [dict(kd=0.02 / imax, ltaud=ltd) for ltd in (2.0, 3.0)],
    signature="second_rc's (relaxation after current steps) reads it too",
    pybamm=Export(
        "PyBaMM's diffusion element (Fan 2022) is Fickian diffusion in a slab with one "
        "parameter τ_D, which fixes both the time scales (τ_D/(n²π²)) and the size of the "
        "surface-SOC lag (τ_D·I/(3·3600·Q) in steady state); avoa-pipeline's is a first-order lag "
        "with its own size κ and time constant τ_d: no τ_D gives the same voltage"
    ),
    would_decide="a long rest after a load (relaxation over an hour or more)",
)
