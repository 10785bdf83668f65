"""Datasets with exactly one withheld effect: the test bench of the gap diagnosis.

Each dataset is a base cell of the paper's kind (rational OCV, R0, one RC branch, capacity,
initial SOC) plus at most one effect of :data:`avoa_pipeline.gap.EFFECTS`, driven by a current
profile, with sensor noise. The effects are simulated here with code of their own, written
without looking at the diagnosis's candidate models (``gap/models.py`` is never imported), so the
diagnosis is judged on data it was not built from.

Base cell (current ``I`` positive = discharge, 1 s steps, zero-order hold; ``I`` is what the cell
carries, which differs from the logged current only under ``current_offset``)::

    SOC_k+1 = SOC_k − Ts·I_k/(3600·Q)                     (charge: Ts·η·I_k, coulombic_efficiency)
    OCV(s)  = Vnom·s / (1 − β·(1 − s))                    the paper's eq. 5
    V1_k+1  = a1·V1_k + (1 − a1)·R1·I_k,   a1 = exp(−Ts/τ1)
    V_k     = OCV(SOC_k) − R0·I_k − V1_k

Effects (magnitude ``m`` in the unit of :data:`UNITS`; the effect's other parameters are drawn
per cell from their own seeded stream, independent of ``m``)::

    second_rc             V −= V2,  V2_k+1 = a2·V2_k + (1 − a2)·R2·I_k,  R2 = m, τ2 ∈ [600, 2400] s
    hysteresis            V += M·h,  h_k+1 = e_k·h_k − (1 − e_k)·sgn(I_k),
                          e_k = exp(−|γ·I_k·Ts/(3600·Q)|)  (Plett's one-state ESC hysteresis),
                          M = m, γ ∈ [20, 100], h_0 ∈ [−1, 1]
    butler_volmer         V −= (2RT/F)·asinh(I/(2·i0)); i0 chosen so that the overpotential at 1C
                          is m (symmetric transfer, α = 0.5)
    thermal               R0, R1 × exp(Ea/R·(1/T − 1/T_ref)), Ea = m, T the cell temperature
    ocv_shape             OCV += m·Σ_j w_j·tanh((s − s_j)/d_j): two steps (graphite staging-like
                          kinks and plateaus), s_1 ∈ [0.35, 0.55], s_2 ∈ [0.65, 0.85],
                          d_j ∈ [0.015, 0.04], w_1 = 1, w_2 ∈ [0.4, 1]
    current_offset        logged current = I + b, |b| = m, random sign
    voltage_offset        logged voltage = V + c, |c| = m, random sign
    coulombic_efficiency  charge enters the SOC with η = 1 − m

Temperature: every dataset, controls included, carries a varying ``temperature_c`` (an ambient
swing of 5-10 K plus lumped self-heating by the reference resistances: C·dT/dt = I²(R0 + R1) −
(T − T_amb)/R_th), so a varying temperature column gives nothing away; only ``thermal`` lets the
resistances follow it.

Detectability. Two residuals are recorded per dataset, both noise-free: ``raw_residual_mv`` = RMS
of (voltage with the effect − the identical dataset without it), and ``effect_residual_mv`` = RMS
left after the base model (all of Vnom, β, Q, SOC0, R0, R1, τ1 free) is refitted to the
noise-free voltage with the effect. The second is the detectability measure: most effects are
partly absorbed by the base parameters (a constant voltage offset by the OCV, the linear part of
Butler-Volmer and the mean of the Arrhenius factor by R0, a current offset and a coulombic
efficiency by Q and SOC0), and only what is left can be seen by any diagnosis. The raw one is
kept for comparison. The refit is a local least-squares fit started at the true base parameters,
so it can only overstate what is left, never hide it.

Pairing: the base cell, the profile, the temperature and the noise depend only on (base seed,
profile, replicate, noise level), so each effect dataset differs from its ``none`` control only
by the effect, and an effect at magnitude zero reproduces the control exactly.

Why hand-written numerics: the recursions above are a few lines each; the linear ones use
``scipy.signal.lfilter``; only the hysteresis state (its decay depends on the current at every
step) is a plain loop.
"""

from __future__ import annotations

import copy
import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import lfilter

from .. import __version__, seeds
from ..errors import ConfigError
from ..synthetic import Dataset, as_written
from ..synthetic import write as write_dataset
from . import EFFECTS, VERDICTS

PROFILES = ("pulse", "drive")
UNITS = {
    "second_rc": "ohm",
    "hysteresis": "V",
    "butler_volmer": "V at 1C",
    "thermal": "J/mol",
    "ocv_shape": "V",
    "current_offset": "A",
    "voltage_offset": "V",
    "coulombic_efficiency": "1 - efficiency",
    "none": "",
}
TS = 1.0
T_REF_K = 298.15
R_GAS = 8.314462618
FARADAY = 96485.33212
VOLTAGE_LSB_V = 1e-4  # a 0.1 mV logger: below every noise level of the grid
CURRENT_NOISE_A = 1e-3
CURRENT_LSB_A = 1e-3
TEMPERATURE_NOISE_K = 0.05
TEMPERATURE_LSB_K = 0.01


@dataclass(frozen=True)
class Cell:
    """The base cell: the paper's model with these parameters (resistances at T_ref)."""

    q_ah: float
    soc0: float
    vnom: float
    beta: float
    r0: float
    r1: float
    tau1: float

    def as_dict(self) -> dict:
        return {k: float(v) for k, v in self.__dict__.items()}


def base_cell(base_seed: int, profile: str, replicate: int) -> Cell:
    """A plausible cell, drawn from (base seed, profile, replicate) only."""
    rng = seeds.stream(base_seed, "gap-cell", profile, replicate)
    vnom = rng.uniform(4.05, 4.20)
    v50 = rng.uniform(3.60, 3.75)  # OCV at half charge; fixes β through eq. 5
    return Cell(
        q_ah=rng.uniform(2.0, 3.2),
        soc0=rng.uniform(0.85, 0.98),
        vnom=vnom,
        beta=2.0 * (1.0 - 0.5 * vnom / v50),
        r0=rng.uniform(0.02, 0.07),
        r1=rng.uniform(0.01, 0.03),
        tau1=rng.uniform(20.0, 120.0),
    )


def c_rate_profile(profile: str, base_seed: int, replicate: int) -> np.ndarray:
    """The current in C-rates, one value per 1 s sample (positive = discharge)."""
    segments: list[tuple[int, float]] = []  # (seconds, C-rate)
    if profile == "pulse":
        # HPPC-like: at each of five SOC steps a discharge and a charge pulse, then 1/12 of the
        # charge at C/2 and a rest long enough for the slow dynamics to show
        segments.append((600, 0.0))
        step = [(10, 1.0), (40, 0.0), (10, -0.75), (40, 0.0), (600, 0.5), (900, 0.0)]
        segments += step * 5
    elif profile == "drive":
        # urban-drive-like trips: piecewise-constant demand held 3-30 s, with regenerative
        # charging and stops; rests between trips; a CC charge and a rest at the end
        rng = seeds.stream(base_seed, "gap-profile", profile, replicate)
        segments.append((300, 0.0))
        for _ in range(3):
            left = 2000
            while left > 0:
                n = min(left, int(rng.integers(3, 31)))
                u = rng.random()
                if u < 0.15:
                    c = 0.0
                elif u < 0.35:
                    c = -rng.uniform(0.1, 1.0)
                else:
                    c = rng.uniform(0.05, 1.0)
                segments.append((n, c))
                left -= n
            segments.append((600, 0.0))  # a stop after each trip; the last before the charge
        segments += [(1800, -0.5), (600, 0.0)]
    else:
        raise ConfigError(f"gap: unknown profile {profile!r}; choose from {', '.join(PROFILES)}")
    return np.concatenate([*(np.full(n, float(c)) for n, c in segments), [0.0]])


def temperature_k(cell: Cell, current_a: np.ndarray, base_seed: int, profile: str, replicate: int):
    """Cell temperature: ambient swing plus lumped self-heating by the reference resistances."""
    rng = seeds.stream(base_seed, "gap-temperature", profile, replicate)
    n = current_a.size
    t = np.arange(n) * TS
    amp, period, phase = (
        rng.uniform(5.0, 10.0),
        rng.uniform(0.6, 1.2) * n * TS,
        rng.uniform(0, 6.283),
    )
    ambient = T_REF_K + amp * np.sin(2 * np.pi * t / period + phase)
    c_th = 40.0 * cell.q_ah / 2.5  # J/K: an 18650 of ~45 g at ~0.9 J/(g K), scaled with capacity
    r_th = rng.uniform(2.0, 4.0)  # K/W to ambient
    a = np.exp(-TS / (r_th * c_th))
    drive = ambient + r_th * current_a**2 * (cell.r0 + cell.r1)  # steady temperature per sample
    rise = lfilter([0.0, 1.0 - a], [1.0, -a], drive - ambient[0])
    return ambient[0] + rise


def effect_params(effect: str, magnitude: float, base_seed: int, profile: str, replicate: int):
    """The effect's parameters: its magnitude, the rest drawn from its own stream."""
    if effect not in VERDICTS:
        raise ConfigError(f"gap: unknown effect {effect!r}; choose from {', '.join(VERDICTS)}")
    if magnitude < 0:
        raise ConfigError(f"gap: effect {effect}: magnitude {magnitude} must be >= 0")
    rng = seeds.stream(base_seed, "gap-effect", effect, profile, replicate)
    m = float(magnitude)
    sign = 1.0 if rng.random() < 0.5 else -1.0
    return {
        "none": {},
        "second_rc": {"r2": m, "tau2": rng.uniform(600.0, 2400.0)},
        "hysteresis": {"m": m, "gamma": rng.uniform(20.0, 100.0), "h0": rng.uniform(-1.0, 1.0)},
        "butler_volmer": {"eta_1c": m},
        "thermal": {"ea": m},
        "ocv_shape": {
            "m": m,
            "s": [rng.uniform(0.35, 0.55), rng.uniform(0.65, 0.85)],
            "d": [rng.uniform(0.015, 0.04), rng.uniform(0.015, 0.04)],
            "w": [1.0, rng.uniform(0.4, 1.0)],
        },
        "current_offset": {"b": sign * m},
        "voltage_offset": {"c": sign * m},
        "coulombic_efficiency": {"eta": 1.0 - m},
    }[effect]


def _rc(current, r, tau):
    a = np.exp(-TS / tau)
    return lfilter([0.0, 1.0 - a], [1.0, -a], r * current)


def _hysteresis(current, q_ah, gamma, h0):
    e = np.exp(-np.abs(gamma * current * TS / (3600.0 * q_ah)))
    u = -np.sign(current)
    h = np.empty(current.size)
    hk = h0
    for k in range(current.size):
        h[k] = hk
        hk = e[k] * hk + (1.0 - e[k]) * u[k]
    return h


def simulate(cell: Cell, logged_a: np.ndarray, temp_k: np.ndarray, effects=None):
    """Noise-free terminal voltage of ``cell`` for the logged current, with ``effects`` (a dict
    effect -> its :func:`effect_params`; none, one or several, each on its own code path below)."""
    fx = effects or {}
    current = logged_a - fx["current_offset"]["b"] if "current_offset" in fx else logged_a
    if "coulombic_efficiency" in fx:
        charge = np.where(current < 0, fx["coulombic_efficiency"]["eta"] * current, current)
    else:
        charge = current
    soc = cell.soc0 - np.concatenate([[0.0], np.cumsum(charge[:-1])]) * TS / (3600.0 * cell.q_ah)
    ocv = cell.vnom * soc / (1.0 - cell.beta * (1.0 - soc))
    if "ocv_shape" in fx:
        p = fx["ocv_shape"]
        ocv = ocv + p["m"] * sum(
            w * np.tanh((soc - s) / d) for w, s, d in zip(p["w"], p["s"], p["d"], strict=True)
        )
    if "thermal" in fx:
        factor = np.exp(fx["thermal"]["ea"] / R_GAS * (1.0 / temp_k - 1.0 / T_REF_K))
    else:
        factor = 1.0
    v = ocv - cell.r0 * factor * current - _rc(current * factor, cell.r1, cell.tau1)
    if "second_rc" in fx:
        v = v - _rc(current, fx["second_rc"]["r2"], fx["second_rc"]["tau2"])
    if "hysteresis" in fx:
        p = fx["hysteresis"]
        v = v + p["m"] * _hysteresis(current, cell.q_ah, p["gamma"], p["h0"])
    if "butler_volmer" in fx and fx["butler_volmer"]["eta_1c"] > 0:
        thermal_v = 2.0 * R_GAS * T_REF_K / FARADAY
        i0 = cell.q_ah / (2.0 * np.sinh(fx["butler_volmer"]["eta_1c"] / thermal_v))
        v = v - thermal_v * np.arcsinh(current / (2.0 * i0))
    if "voltage_offset" in fx:
        v = v + fx["voltage_offset"]["c"]
    return v


def _base_voltage(x, logged_a):
    vnom, beta, q, soc0, r0, r1, tau1 = x
    return simulate(Cell(q, soc0, vnom, beta, r0, r1, tau1), logged_a, None)


def refit_residual(cell: Cell, logged_a: np.ndarray, voltage_v: np.ndarray) -> np.ndarray:
    """What is left of ``voltage_v`` after the base model is refitted to it (all 7 free)."""
    x0 = np.array([cell.vnom, cell.beta, cell.q_ah, cell.soc0, cell.r0, cell.r1, cell.tau1])
    lo = np.array([2.5, -5.0, 0.2, 0.05, 0.0, 0.0, 1.0])
    hi = np.array([5.0, 0.999, 20.0, 1.5, 1.0, 1.0, 5000.0])
    fit = least_squares(
        lambda x: _base_voltage(x, logged_a) - voltage_v,
        x0,
        bounds=(lo, hi),
        x_scale=np.maximum(np.abs(x0), 1e-3),
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=400,
    )
    return fit.fun


def _rms_mv(x) -> float:
    return float(1e3 * np.sqrt(np.mean(np.square(x))))


def sensor(x, rng, sd, lsb):
    return np.round((x + sd * rng.standard_normal(x.shape)) / lsb) * lsb


@functools.lru_cache(maxsize=8)
def _noise_free(base_seed: int, effects: tuple, profile: str, replicate: int):
    """Everything but the noise (shared by the noise levels of one set of effects), for
    ``effects`` = ((effect, magnitude), ...): one pair for a single-effect dataset, two for a
    pair dataset. Each effect's parameters come from its own stream, whatever it is paired with."""
    cell = base_cell(base_seed, profile, replicate)
    logged = c_rate_profile(profile, base_seed, replicate) * cell.q_ah
    temp = temperature_k(cell, logged, base_seed, profile, replicate)
    params = {e: effect_params(e, m, base_seed, profile, replicate) for e, m in effects}
    v_effect = simulate(cell, logged, temp, {e: p for e, p in params.items() if e != "none"})
    v_control = simulate(cell, logged, temp)
    if all(e == "none" or m == 0 for e, m in effects):
        left = v_effect - v_control
    else:
        left = refit_residual(cell, logged, v_effect)
    return cell, logged, temp, params, v_effect, _rms_mv(v_effect - v_control), _rms_mv(left)


def _measured(v_effect, logged, temp, base_seed: int, noise_mv: float, profile: str, replicate):
    """The sensors' readings: the noise stream depends on (seed, profile, replicate, noise level)
    only, so every dataset of one cell and noise level carries the same noise draw."""
    rng = seeds.stream(base_seed, "gap-noise", profile, replicate, round(noise_mv * 1000))
    v_meas = sensor(v_effect, rng, noise_mv * 1e-3, VOLTAGE_LSB_V)
    i_meas = sensor(logged, rng, CURRENT_NOISE_A, CURRENT_LSB_A)
    t_meas = sensor(temp - 273.15, rng, TEMPERATURE_NOISE_K, TEMPERATURE_LSB_K)
    return np.arange(logged.size) * TS, v_meas, i_meas, t_meas


SENSOR = {
    "voltage_lsb_v": VOLTAGE_LSB_V,
    "current_noise_a": CURRENT_NOISE_A,
    "current_lsb_a": CURRENT_LSB_A,
}


def make(
    base_seed: int, effect: str, magnitude: float, noise_mv: float, profile: str, replicate: int
) -> Dataset:
    """One dataset: the base cell of (profile, replicate) with ``effect`` at ``magnitude``."""
    return _dataset(
        base_seed,
        ((effect, float(magnitude)),),
        noise_mv,
        profile,
        replicate,
        # UNITS.get: an unknown effect is refused by _noise_free with a one-line ConfigError
        {"effect": effect, "magnitude": float(magnitude), "magnitude_unit": UNITS.get(effect)},
        lambda params: copy.deepcopy(params[effect]),
    )


def _dataset(base_seed, key, noise_mv, profile, replicate, head: dict, effect_params,
             middle: dict | None = None) -> Dataset:  # fmt: skip
    """The cell of (profile, replicate) with the effects of ``key`` and its sensor noise, and its
    sidecar: ``head`` (what the effects are), the residuals, ``middle``, the cell, the effects'
    parameters (``effect_params(params)``) and the provenance (one layout for single and pair
    datasets)."""
    cell, logged, temp, params, v_effect, raw_mv, left_mv = _noise_free(
        int(base_seed), key, profile, int(replicate)
    )
    t, v_meas, i_meas, t_meas = _measured(
        v_effect, logged, temp, base_seed, noise_mv, profile, replicate
    )
    noise_rmse = _rms_mv(v_meas - v_effect)
    meta = {
        **head,
        "noise_mv": float(noise_mv),
        "profile": profile,
        "replicate": int(replicate),
        "n_samples": int(t.size),
        "raw_residual_mv": raw_mv,
        "effect_residual_mv": left_mv,
        "noise_rmse_mv": noise_rmse,
        "ratio": left_mv / noise_rmse,
        **(middle or {}),
        "capacity_ah": cell.q_ah,
        "soc0": cell.soc0,
        "cell": cell.as_dict(),
        "effect_params": effect_params(params),
        "temperature_range_c": [float(t_meas.min()), float(t_meas.max())],
        "sensor": {"voltage_noise_v": noise_mv * 1e-3, **SENSOR},
        "seed_keys": [base_seed, profile, replicate],
        "generator": f"avoa_pipeline {__version__} gap.withheld",
    }
    return Dataset(as_written(t), as_written(i_meas), as_written(v_meas), as_written(t_meas), meta)


def pair_effects(magnitudes: dict) -> tuple[str, str]:
    """The two effects of a pair ``{effect: magnitude, effect: magnitude}``, in the order of
    :data:`EFFECTS` (so a pair has one name however the config lists it)."""
    unknown = [e for e in magnitudes if e not in EFFECTS]
    if unknown:
        raise ConfigError(
            f"gap: pair {dict(magnitudes)}: unknown effect {unknown[0]!r}; choose from "
            f"{', '.join(EFFECTS)}"
        )
    if len(magnitudes) != 2:
        raise ConfigError(f"gap: pair {dict(magnitudes)}: needs exactly two different effects")
    first, second = sorted(magnitudes, key=EFFECTS.index)
    return first, second


def make_pair(
    base_seed: int, magnitudes: dict, noise_mv: float, profile: str, replicate: int
) -> Dataset:
    """One dataset with two effects at once (``magnitudes`` = {effect: magnitude} of two).

    The cell, profile, temperature and noise are those of the cell's ``none`` control and each
    effect's parameters those of its single-effect dataset (same streams), so the two
    single-effect datasets made by :func:`make` at the same magnitudes are this dataset's "each
    effect alone"; their detectability is recorded under ``alone``.
    """
    effects = pair_effects(magnitudes)
    key = tuple((e, float(magnitudes[e])) for e in effects)
    alone = {}
    for effect, mag in key:
        single = make(base_seed, effect, mag, noise_mv, profile, replicate).meta
        alone[effect] = {
            k: single[k]
            for k in ("magnitude", "raw_residual_mv", "effect_residual_mv", "noise_rmse_mv")
        }
        alone[effect]["ratio"] = single["ratio"]
    head = {
        "effects": list(effects),
        "magnitudes": [m for _, m in key],
        "magnitude_units": [UNITS[e] for e in effects],
    }
    return _dataset(base_seed, key, noise_mv, profile, replicate, head, copy.deepcopy,
                    {"alone": alone})  # fmt: skip


# --- the grid --------------------------------------------------------------------------------


def dataset_name(effect: str, mag_index: int, noise_index: int) -> str:
    return f"{effect}_m{mag_index}_n{noise_index}"


def names(gcfg: dict, replicate: int) -> list[str]:
    """The datasets of one (profile, replicate): every effect × magnitude × noise, and the
    ``none`` control per noise level; replicates beyond ``replicates`` hold controls only."""
    noise = range(len(gcfg["noise_mv"]))
    out = [dataset_name("none", 0, j) for j in noise]
    if replicate in gcfg["replicates"]:
        for effect in EFFECTS:
            for i in range(len(gcfg["magnitudes"][effect])):
                out += [dataset_name(effect, i, j) for j in noise]
    return out


def all_replicates(gcfg: dict) -> list[int]:
    return sorted(set(gcfg["replicates"]) | set(gcfg["control_replicates"]))


def parse_name(name: str) -> tuple[str, int, int]:
    effect, m, n = name.rsplit("_", 2)
    return effect, int(m[1:]), int(n[1:])


def write_batch(base_seed: int, gcfg: dict, profile: str, replicate: int, out_dir) -> list[Path]:
    """Every dataset of one (profile, replicate) into ``out_dir`` (CSV + JSON sidecar each)."""
    written = []
    for name in names(gcfg, int(replicate)):
        effect, i, j = parse_name(name)
        mag = 0.0 if effect == "none" else gcfg["magnitudes"][effect][i]
        ds = make(base_seed, effect, mag, gcfg["noise_mv"][j], profile, int(replicate))
        ds.meta["name"] = name
        path = Path(out_dir) / f"{name}.csv"
        write_dataset(ds, path)
        written.append(path)
    return written


# --- two effects at once -----------------------------------------------------------------------


def pair_grid(gcfg: dict) -> list[tuple[str, dict]]:
    """``(stem, {effect: magnitude, effect: magnitude})`` per entry of ``gap.pairs.magnitudes``;
    the stem is ``<first>-<second>_m<k>``, k counting the earlier entries of the same two effects
    (as ``m<i>`` counts an effect's magnitudes)."""
    out, seen = [], {}
    for magnitudes in (gcfg.get("pairs") or {}).get("magnitudes", []):
        effects = pair_effects(magnitudes)
        k = seen.get(effects, 0)
        seen[effects] = k + 1
        out.append((f"{effects[0]}-{effects[1]}_m{k}", {e: magnitudes[e] for e in effects}))
    return out


def pair_names(gcfg: dict, replicate: int) -> list[str]:
    """The pair datasets of one (profile, replicate): every pair × noise level of ``gap.pairs``
    (``n<j>`` indexes ``gap.pairs.noise_mv``), on the cells that carry the single-effect grid."""
    grid = pair_grid(gcfg)
    if not grid or replicate not in gcfg["replicates"]:
        return []
    noise = range(len(gcfg["pairs"]["noise_mv"]))
    return [f"{stem}_n{j}" for stem, _ in grid for j in noise]


def write_pair_batch(
    base_seed: int, gcfg: dict, profile: str, replicate: int, out_dir
) -> list[Path]:
    """Every pair dataset of one (profile, replicate) into ``out_dir`` (CSV + JSON sidecar).
    ``alone.<effect>.dataset`` names the single-effect dataset of the grid that is the same
    effect at the same magnitude and noise on this cell, if the grid holds it."""
    magnitudes_of = dict(pair_grid(gcfg))
    written = []
    for name in pair_names(gcfg, int(replicate)):
        stem, n = name.rsplit("_", 1)
        noise_mv = gcfg["pairs"]["noise_mv"][int(n[1:])]
        ds = make_pair(base_seed, magnitudes_of[stem], noise_mv, profile, replicate)
        ds.meta["name"] = name
        for effect, alone in ds.meta["alone"].items():
            mags, noises = list(gcfg["magnitudes"][effect]), list(gcfg["noise_mv"])
            in_grid = alone["magnitude"] in mags and noise_mv in noises
            alone["dataset"] = (
                dataset_name(effect, mags.index(alone["magnitude"]), noises.index(noise_mv))
                if in_grid
                else None
            )
        path = Path(out_dir) / f"{name}.csv"
        write_dataset(ds, path)
        written.append(path)
    return written
