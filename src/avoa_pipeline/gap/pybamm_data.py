"""Physics-based test data from PyBaMM, whose effects only this generator knows.

Where :mod:`avoa_pipeline.gap.withheld` adds one effect to the paper's model, these records come
from electrochemical models (Chen et al. 2020's LG M50 parameters, 5 Ah) that hold several effects
at once, none of them written in the paper's form:

- ``dfn_thermal``: Doyle-Fuller-Newman model, lumped thermal model with an ambient swing of ±7 K,
  a contact resistance. Holds ``ocv_shape`` (the measured graphite and NMC811 OCP curves, with
  their plateaus), ``second_rc`` (solid and electrolyte diffusion: slow relaxation),
  ``butler_volmer`` (the kinetics) and ``thermal`` (Chen2020's Arrhenius exchange currents with
  the lumped cell temperature).
- ``spme_hysteresis``: single-particle model with electrolyte, the same thermal set-up, and a
  one-state hysteresis OCP in the negative electrode (Axen et al. 2022, PyBaMM's
  ``one-state hysteresis``): ±15 mV between lithiation and delithiation branches. Holds the
  effects above plus ``hysteresis``.

Each is driven by the pulse and drive profiles of :mod:`withheld` (C-rates × 5 Ah, our own
arrays: no data are downloaded), from 80 % SOC, and written with the same sensor noise as the
withheld-effect datasets. A dataset's verdict counts as right when it names one of the effects
the record holds (``effects_present`` in its sidecar); which of them dominates is not known in
advance, which is the point of the check.

PyBaMM is an optional dependency (``pip install avoa-pipeline[pybamm]``, pinned in
environment.txt); its telemetry is switched off before import.
"""

from __future__ import annotations

import os
import warnings

import numpy as np

from .. import __version__, seeds
from ..errors import ConfigError
from ..synthetic import Dataset, as_written
from . import withheld

MODELS = {
    "dfn_thermal": {
        "model": "DFN",
        "options": {"thermal": "lumped", "contact resistance": "true"},
        "effects_present": ["ocv_shape", "second_rc", "butler_volmer", "thermal"],
    },
    "spme_hysteresis": {
        "model": "SPMe",
        "options": {
            "thermal": "lumped",
            "contact resistance": "true",
            "open-circuit potential": ("one-state hysteresis", "single"),
        },
        "effects_present": ["ocv_shape", "second_rc", "butler_volmer", "thermal", "hysteresis"],
    },
}
CAPACITY_AH = 5.0  # Chen2020 nominal capacity
INITIAL_SOC = 0.8
CONTACT_OHM = 0.005
AMBIENT_SWING_K = 7.0
HYSTERESIS_HALF_V = 0.015
HYSTERESIS_DECAY = 50.0
NOISE_MV = 1.0


def _pybamm():
    os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")
    import pybamm

    return pybamm


def dataset_names() -> list[str]:
    return [f"{m}_{p}" for m in MODELS for p in withheld.PROFILES]


def split_name(name: str) -> tuple[str, str]:
    model, _, profile = name.rpartition("_")
    if model not in MODELS or profile not in withheld.PROFILES:
        raise ConfigError(f"gap: unknown PyBaMM dataset {name!r}; choose from {dataset_names()}")
    return model, profile


def solve(model_name: str, c_rate: np.ndarray) -> dict:
    """Noise-free time, current, voltage and temperature of one PyBaMM model run."""
    pybamm = _pybamm()
    spec = MODELS[model_name]
    t = np.arange(c_rate.size, dtype=float) * withheld.TS
    current = c_rate * CAPACITY_AH
    with warnings.catch_warnings():
        # PyBaMM warns at every build of a hysteresis model that the decay-rate definition
        # changed in v25.10; the rate below is set for the current definition
        warnings.simplefilter("ignore", UserWarning)
        model = getattr(pybamm.lithium_ion, spec["model"])(options=spec["options"])
    pv = pybamm.ParameterValues("Chen2020")
    period = 0.8 * t[-1]
    update = {
        # a zero-order-hold current sampled at 1 s, linear between samples as the solver needs
        "Current function [A]": pybamm.Interpolant(t, current, pybamm.t, interpolator="linear"),
        "Contact resistance [Ohm]": CONTACT_OHM,
        "Ambient temperature [K]": lambda y, z, tt: (
            withheld.T_REF_K + AMBIENT_SWING_K * pybamm.sin(2 * np.pi * tt / period)
        ),
        # the profiles' regenerative pulses reach above 4.2 V briefly; the cell model does not
        # stop there (a cycler's safety limit is not part of the check)
        "Upper voltage cut-off [V]": 4.4,
        "Lower voltage cut-off [V]": 2.5,
    }
    if spec["options"].get("open-circuit potential"):
        ocp = pv["Negative electrode OCP [V]"]
        update |= {
            "Negative electrode lithiation OCP [V]": lambda sto: ocp(sto) - HYSTERESIS_HALF_V,
            "Negative electrode delithiation OCP [V]": lambda sto: ocp(sto) + HYSTERESIS_HALF_V,
            "Negative particle lithiation hysteresis decay rate": lambda sto, T: HYSTERESIS_DECAY,
            "Negative particle delithiation hysteresis decay rate": lambda sto, T: HYSTERESIS_DECAY,
            "Initial hysteresis state in negative electrode": 0.0,
        }
    pv.update(update, check_already_exists=False)
    sim = pybamm.Simulation(model, parameter_values=pv, solver=pybamm.IDAKLUSolver())
    sol = sim.solve(t_eval=[0.0, t[-1]], t_interp=t, initial_soc=INITIAL_SOC)
    voltage = sol["Voltage [V]"].entries
    if voltage.size != t.size:
        raise RuntimeError(
            f"PyBaMM {model_name}: solution stopped at {sol.t[-1]:.0f} s of {t[-1]:.0f} s "
            f"({sol.termination})"
        )
    return {
        "time_s": t,
        "current_a": current,
        "voltage_v": voltage,
        "temperature_k": sol["X-averaged cell temperature [K]"].entries,
    }


def make(base_seed: int, name: str, c_rate: np.ndarray | None = None) -> Dataset:
    """The PyBaMM dataset ``name`` (``<model>_<profile>``) with sensor noise.

    ``c_rate`` replaces the profile (tests use a short one); the name still picks the model.
    """
    model_name, profile = split_name(name)
    if c_rate is None:
        c_rate = withheld.c_rate_profile(profile, base_seed, 1)
    clean = solve(model_name, c_rate)
    rng = seeds.stream(base_seed, "gap-pybamm-noise", name)
    sensor = withheld.sensor
    v = sensor(clean["voltage_v"], rng, NOISE_MV * 1e-3, withheld.VOLTAGE_LSB_V)
    i = sensor(clean["current_a"], rng, withheld.CURRENT_NOISE_A, withheld.CURRENT_LSB_A)
    temp = sensor(
        clean["temperature_k"] - 273.15,
        rng,
        withheld.TEMPERATURE_NOISE_K,
        withheld.TEMPERATURE_LSB_K,
    )
    pybamm = _pybamm()
    spec = MODELS[model_name]
    meta = {
        "name": name,
        "source": "pybamm",
        "model": spec["model"],
        "options": {k: list(v) if isinstance(v, tuple) else v for k, v in spec["options"].items()},
        "parameter_set": "Chen2020",
        "effects_present": spec["effects_present"],
        "profile": profile,
        "capacity_ah": CAPACITY_AH,
        "soc0": INITIAL_SOC,
        "contact_resistance_ohm": CONTACT_OHM,
        "ambient_swing_k": AMBIENT_SWING_K,
        "hysteresis_half_width_v": HYSTERESIS_HALF_V if "hysteresis" in model_name else 0.0,
        "noise_mv": NOISE_MV,
        "noise_rmse_mv": float(1e3 * np.sqrt(np.mean((v - clean["voltage_v"]) ** 2))),
        "n_samples": int(v.size),
        "seed_keys": [base_seed, "gap-pybamm-noise", name],
        "generator": f"avoa_pipeline {__version__} gap.pybamm_data, pybamm {pybamm.__version__}",
    }
    return Dataset(
        as_written(clean["time_s"]), as_written(i), as_written(v), as_written(temp), meta
    )
