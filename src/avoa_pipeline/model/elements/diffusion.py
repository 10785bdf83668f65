"""A surface-SOC lag: the OCV sees s − δ, δ a first-order lag of the current (the slowest mode of
a single-particle model); unlike an RC branch its voltage scales with the OCV's slope."""

from __future__ import annotations

from .element import Element, Export, Kernel, Param, Piece, State, TableLaw

_SURFACE_SOC_LAG = '''
class SurfaceSocLag(pybamm.BaseSubModel):
    """diffusion: the OCV sees the surface SoC, SoC − δ, where δ lags the current:
    dδ/dt = (κ·I − δ)/τ_d. For a current held over each interval this is exactly avoa-pipeline's
    δ_k+1 = a·δ_k + (1 − a)·κ·I_k, a = exp(−Δt/τ_d). It fills the slot of PyBaMM's diffusion
    element (Fan 2022), a Fickian slab with one parameter, which is not this lag."""

    def __init__(self, param, options=None):
        super().__init__(param)
        self.model_options = options

    def get_fundamental_variables(self):
        return {"Surface SoC lag": pybamm.Variable("Surface SoC lag")}

    def get_coupled_variables(self, variables):
        soc = variables["SoC"]
        surface = soc - variables["Surface SoC lag"]
        variables.update({
            "Surface SoC": surface,
            "Diffusion overpotential [V]": self.param.ocv(surface) - self.param.ocv(soc),
        })
        return variables

    def set_rhs(self, variables):
        lag = variables["Surface SoC lag"]
        kappa = pybamm.Parameter("Surface SoC lag per current [1/A]")
        tau = pybamm.Parameter("Surface SoC lag time constant [s]")
        self.rhs = {lag: (kappa * variables["Current [A]"] - lag) / tau}

    def set_initial_conditions(self, variables):
        initial = pybamm.Parameter("Initial surface SoC lag")
        self.initial_conditions = {variables["Surface SoC lag"]: initial}
'''


def _piece(p) -> Piece:
    return Piece(
        constants=(("DIFFUSION_SOC_PER_A", p["kd"], "diffusion: κ, the surface-SOC lag per A "
                    "held (steady state)"),
                   ("DIFFUSION_TAU_S", p["ltaud"], "diffusion: τ_d, the lag's time constant"),
                   ("INITIAL_SURFACE_SOC_LAG", 0.0, "δ at the start (avoa-pipeline starts "
                    "every record at 0)")),
        helpers=(_SURFACE_SOC_LAG,),
        submodels=(("Diffusion", "SurfaceSocLag"),),
        parameters=(("Surface SoC lag per current [1/A]", "DIFFUSION_SOC_PER_A"),
                    ("Surface SoC lag time constant [s]", "DIFFUSION_TAU_S"),
                    ("Initial surface SoC lag", "INITIAL_SURFACE_SOC_LAG")),
        states=(("Surface SoC lag", "Initial surface SoC lag"),),
    )  # fmt: skip


KERNEL = Kernel(
    columns={"kd": "kd", "taud": "ltaud"},
    flags={"diff": "np.any(kd != 0.0)"},
    states={"dl": State("delta", lambda p, i: abs(p["kd"]) * i)},
    code={
        "setup": "ad = np.exp(-dt[0] / taud)\ndl = np.zeros(m)\nbd = np.zeros(m)",
        "uneven": "ad[c] = np.exp(-dtk / taud[c])",
        "surface": "if diff:\n    so = s - dl[c]",
        "hold_increment": "bd[c] = (1.0 - ad[c]) * kd[c] * i",
        "hold_step": "if diff:\n    for c in range(m):\n        dl[c] = ad[c] * dl[c] + bd[c]",
        "update": "if diff:\n    dl[c] = ad[c] * dl[c] + (1.0 - ad[c]) * kd[c] * i",
    },
)
"""The OCV sees s − δ; δ_k+1 = a_d·δ_k + (1 − a_d)·κ·i_k, a_d = exp(−Δt/τ_d)."""


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
        "a state of its own beside Thevenin's (a submodel in the slot of PyBaMM's diffusion "
        "element): the surface-SOC lag δ, dδ/dt = (κ·I − δ)/τ_d, and the OCV at SoC − δ. "
        "PyBaMM's own diffusion element (Fan 2022, a Fickian slab) is not used: its one "
        "parameter τ_D fixes both the time scales (τ_D/(n²π²)) and the size of the lag "
        "(τ_D·I/(3·3600·Q) in steady state), where ours has its own size κ and time constant τ_d",
        _piece,
    ),
    would_decide="a long rest after a load (relaxation over an hour or more)",
    kernel=KERNEL,
    table=TableLaw(
        "a state, not a column: the sidecar's scalars and recursion (ocv_v read at s − δ)"
    ),
)
