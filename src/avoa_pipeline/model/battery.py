"""The paper's battery model: parameters, scenarios, cases, fade, and simulation.

Scenarios (Sec. 4): 1 neither load nor fade, 2 fade, 3 load, 4 load and fade.
Cases (Sec. 4, Tables 4-7): 1 T1 without charge dynamics, 2 T1 with, 3 T2 without, 4 T2 with.
Which parameters each case identifies follows the paper's Tables 4-7; the others are held at the
cell's known (true) values. Fade, eqs. 7-9: the cell is at cycle ``n`` of ``N``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import threads
from . import kernel

PARAM_NAMES = ("vnom", "q", "vdis", "r0", "rtr", "tau")
"""Column order of every full parameter vector."""

PARAM_LABELS = {
    "vnom": ("V_nom", "V"),
    "q": ("Q", "Ah"),
    "vdis": ("V_dis", "V"),
    "r0": ("R_o", "Ω"),
    "rtr": ("R_tr", "Ω"),
    "tau": ("τ_tr", "s"),
}


@dataclass(frozen=True)
class Case:
    number: int
    temperature: str  # "T1" or "T2"
    dynamics: bool
    free: tuple[str, ...]  # identified parameters, in the row order of the paper's table


CASES = {
    1: Case(1, "T1", False, ("vnom", "r0", "q", "vdis")),  # Table 4
    2: Case(2, "T1", True, ("vnom", "r0", "vdis", "rtr", "tau")),  # Table 5
    3: Case(3, "T2", False, ("vnom", "r0", "vdis")),  # Table 6
    4: Case(4, "T2", True, ("vnom", "r0", "vdis", "rtr", "tau")),  # Table 7
}


@dataclass(frozen=True)
class Scenario:
    number: int
    fade: bool
    load: bool


SCENARIOS = {
    1: Scenario(1, fade=False, load=False),
    2: Scenario(2, fade=True, load=False),
    3: Scenario(3, fade=False, load=True),
    4: Scenario(4, fade=True, load=True),
}


@dataclass(frozen=True)
class FadeLaw:
    """δ percentages of eqs. 7-9, derived from Table 2's values after N cycles."""

    n_ref: int
    delta_q_pct: float
    delta_r0_pct: float
    delta_rtr_pct: float
    delta_vdis_pct: float
    delta_vnom_pct: float = 0.0  # Table 2 gives no Vnom after N cycles

    @classmethod
    def from_constants(cls, constants: dict) -> FadeLaw:
        after, ref = constants["after_n"], constants["fade_reference"]
        d_q = 100.0 * (after["capacity_ah"] / ref["capacity_ah"] - 1.0)
        d_r0 = 100.0 * (after["r0_ohm"] / ref["r0_ohm"] - 1.0)
        d_vdis = 100.0 * (after["vdis_v"] / ref["vdis_v"] - 1.0)
        return cls(
            n_ref=int(constants["n_cycles_ref"]),
            delta_q_pct=d_q,
            delta_r0_pct=d_r0,
            delta_rtr_pct=d_r0 if constants.get("fade_rtr_like_r0", True) else 0.0,
            delta_vdis_pct=d_vdis,
        )

    def factors(self, n: float) -> np.ndarray:
        """Multipliers of (vnom, q, vdis, r0, rtr, tau) at cycle ``n``."""
        lin = n / self.n_ref  # eq. 7: voltages fade linearly in n
        root = np.sqrt(n / self.n_ref)  # eqs. 8-9: capacity and resistances with √n
        return np.array(
            [
                1.0 + self.delta_vnom_pct / 100.0 * lin,
                1.0 + self.delta_q_pct / 100.0 * root,
                1.0 + self.delta_vdis_pct / 100.0 * lin,
                1.0 + self.delta_r0_pct / 100.0 * root,
                1.0 + self.delta_rtr_pct / 100.0 * root,
                1.0,
            ]
        )


@dataclass(frozen=True)
class ModelSpec:
    """Everything but the parameters that the simulation needs."""

    dynamics: bool
    fade_factors: np.ndarray  # shape (6,), ones without fade
    load_ohm: float | None  # None = no load
    soc0: float
    qdis_ah: float

    @property
    def g_load(self) -> float:
        return 0.0 if self.load_ohm is None else 1.0 / self.load_ohm

    @classmethod
    def for_scenario_case(cls, constants: dict, scenario: int, case: int, dynamics=None):
        sc, cs = SCENARIOS[scenario], CASES[case]
        fade = FadeLaw.from_constants(constants)
        factors = fade.factors(constants["cycle_n"]) if sc.fade else np.ones(6)
        return cls(
            dynamics=cs.dynamics if dynamics is None else dynamics,
            fade_factors=factors,
            load_ohm=float(constants["load_ohm"]) if sc.load else None,
            soc0=float(constants["soc0"]),
            qdis_ah=float(constants["qdis_ah"]),
        )


def kernel_args(P_full: np.ndarray, current: np.ndarray, voltage: np.ndarray, ts: float,
                spec: ModelSpec) -> tuple:  # fmt: skip
    """The population kernel's arguments (``kernel.ise_serial``; ``kernel.ise_population`` takes
    the number of blocks after them) for rows of fresh-cell parameters ``P_full``."""
    P = np.ascontiguousarray(np.atleast_2d(P_full) * spec.fade_factors, dtype=float)
    return (
        P,
        np.ascontiguousarray(current, dtype=float),
        np.ascontiguousarray(voltage, dtype=float),
        float(ts),
        spec.soc0,
        spec.qdis_ah,
        spec.g_load,
        spec.dynamics,
    )


def ise(P_full: np.ndarray, current: np.ndarray, voltage: np.ndarray, ts: float, spec: ModelSpec):
    """ISE (eq. 13) of each row of fresh-cell parameters ``P_full`` (columns = PARAM_NAMES)."""
    args = kernel_args(P_full, current, voltage, ts, spec)
    n_blocks = threads.kernel_blocks(args[0].shape[0], args[1].size)  # the thread policy
    if n_blocks == 1:
        return kernel.ise_serial(*args)
    return kernel.ise_population(*args, n_blocks)


def simulate(p_full: np.ndarray, current: np.ndarray, ts: float, spec: ModelSpec) -> dict:
    """Terminal voltage, battery current (load included), SOC and Vtr of one parameter vector."""
    p = np.ascontiguousarray(np.asarray(p_full, dtype=float) * spec.fade_factors)
    tr = kernel.simulate_one(
        p,
        np.ascontiguousarray(current, dtype=float),
        float(ts),
        spec.soc0,
        spec.qdis_ah,
        spec.g_load,
        spec.dynamics,
    )
    return {"voltage_v": tr[0], "battery_current_a": tr[1], "soc": tr[2], "vtr_v": tr[3]}


def vector(params: dict) -> np.ndarray:
    """Full parameter vector (PARAM_NAMES order) from a name → value mapping."""
    return np.array([float(params[n]) for n in PARAM_NAMES])


def first_sample_soc0(P_full: np.ndarray, v0: float, i0: float, qdis_ah: float) -> np.ndarray:
    """The paper's model on a measured record starts each row of full parameter vectors where its
    OCV meets the first sample, ohmic drop corrected: Vocv(s0) = V0 + R0·I0 (eq. 5 in closed
    form, ``ecm.rational_soc0``; β by ``kernel.paper_beta``). The record decides the start, as
    the library's opening rule does, so no SOC0 is fitted."""
    from .ecm import rational_soc0

    P = np.atleast_2d(P_full)
    vnom, q, vdis, r0 = (P[:, PARAM_NAMES.index(n)] for n in ("vnom", "q", "vdis", "r0"))
    beta = kernel.paper_beta(vnom, vdis, qdis_ah / q)
    return rational_soc0(vnom, 1.0 - beta, v0 + r0 * i0)


def simulate_on_record(p_full: np.ndarray, current: np.ndarray, voltage: np.ndarray, ts: float,
                       dynamics: bool, qdis_ah: float) -> np.ndarray:  # fmt: skip
    """Terminal voltage of the paper's model (no load, no fade) on a measured record, started by
    :func:`first_sample_soc0`."""
    p = np.asarray(p_full, dtype=float)
    s0 = float(first_sample_soc0(p[None, :], voltage[0], current[0], qdis_ah)[0])
    spec = ModelSpec(dynamics=dynamics, fade_factors=np.ones(6), load_ohm=None, soc0=s0,
                     qdis_ah=qdis_ah)  # fmt: skip
    return simulate(p, current, ts, spec)["voltage_v"]
