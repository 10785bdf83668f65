"""Development records of issue 41 (docs/temperature-rule.md part 7): one NMC and one LFP cell,
each at several ambients, each with a drive cycle and an HPPC test, logged as cyclers log.

Why a module of its own: the pieces exist and are reused, not written again. The cells are the
transfer benchmark's (:data:`avoa_pipeline.gap.transfer.CELLS`: PyBaMM's SPMe with the lumped
thermal model and a contact resistance; Chen2020's LG M50 NMC811 and Prada2013's A123 LFP with a
26650 can's heat capacity and cooling), with the ambient and the initial temperature set by
:func:`~avoa_pipeline.gap.transfer.parameter_values`; the parameter sets' Arrhenius exchange
currents, diffusivities and electrolyte conductivity then make the temperature dependence. The
profiles are the withheld-effect check's 1-Hz pulse (HPPC-like) and drive profiles
(:func:`~avoa_pipeline.gap.withheld.c_rate_profile`), solved as
:func:`avoa_pipeline.gap.pybamm_data.solve` solves them (a 1-Hz current interpolant), with the
same sensor noise (:func:`~avoa_pipeline.gap.withheld.sensor`). What neither holds is what this
module adds: the fast cycle before the slow profile, the logging of a real cycler (the current
channel a sample late at each edge, rests every :data:`REST_LOG_S`), the sidecar that
``heat.ambient_of`` and ``records.read`` need, and the all-or-none writing of the set.
``pybamm_data`` is a fixed list of named datasets at a swinging ambient whose sidecars name the
effects present; ``transfer`` logs through PyBaMM's experiment periods with no current lag; a
third option in either would have changed their records.

The temperature written is the lumped model's cell temperature ("Volume-averaged cell
temperature [K]"): a lumped cell has one temperature, so its surface's is the same number.

``python -m avoa_pipeline.gap.temperature_cells --out DIR`` writes the set,
``DIR/<chemistry>_<ambient>degC_<profile>.csv`` and its ``.json`` sidecar, all files or none.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from .. import __version__, seeds
from ..errors import ConfigError
from ..io import atomic_paths, sidecar_of
from ..synthetic import Dataset, as_written
from ..synthetic import write as write_dataset
from . import pybamm_data, transfer, withheld

CHEMISTRIES = ("nmc", "lfp")
"""Keys of :data:`transfer.CELLS`: the NMC and the LFP cell of the transfer benchmark."""
AMBIENTS_C = (0.0, 10.0, 25.0, 40.0)
"""The rule's ambients (docs/temperature-rule.md part 7)."""
PROFILES = {"drive": "drive", "hppc": "pulse"}
"""Record profile → :func:`withheld.c_rate_profile`'s profile (its ``pulse`` is HPPC-like)."""
CITATIONS = {
    "Chen2020": "Chen et al., J. Electrochem. Soc. 167 (2020) 080534",
    "Prada2013": "Prada et al., J. Electrochem. Soc. 160 (2013) A616",
}
INITIAL_SOC = 0.8
"""As ``pybamm_data``: the profiles' net charge (drive ≈ 0.14, HPPC ≈ 0.42 of the capacity) and
the fast cycle's ±0.25 stay between 0.3 and 0.8, inside both parameter sets' stoichiometry
ranges at every ambient."""
FAST_C_RATE = 1.0
FAST_S = 900
"""The fast cycle: a 1C discharge of 15 min (a quarter of the charge), rest, a 1C charge back,
rest, as cyclers start a test (a capacity check or a conditioning cycle before the slow part)."""
FAST_REST_S = 600
"""Rest after each half of the fast cycle: long enough for the 1C overpotential to relax to
millivolts (the cells' slowest RC-like time constants are minutes)."""
LEAD_REST_S = 120
"""Rest before the fast cycle: the cell soaked at the ambient, logged as a cycler logs a rest."""
REST_LOG_S = 60.0
"""A cycler logs a rest every 60 s (as tests/unit/test_soc_filter.py's development records;
the architecture's "cyclers log rests every 60-300 s")."""
CUTOFF_MARGIN_V = 0.2
"""The parameter sets' upper cut-offs (4.2 V NMC, 3.6 V LFP) widened by this: a 1C charge at
0 °C overshoots them by up to ~0.1 V for its few seconds; the cell model does not stop there (a
cycler's safety limit is not what the records are for), as ``pybamm_data`` widens Chen2020's."""
NOISE_MV = transfer.NOISE_MV


def _pybamm():
    return transfer._pybamm()


def record_name(chemistry: str, ambient_c: float, profile: str) -> str:
    return f"{chemistry}_{ambient_c:g}degC_{profile}"


def c_rate(profile: str, base_seed: int) -> np.ndarray:
    """The 1-Hz current in C-rates (positive = discharge): the fast cycle, then the profile."""
    if profile not in PROFILES:
        raise ConfigError(f"temperature cells: unknown profile {profile!r}; choose from "
                          f"{', '.join(PROFILES)}")  # fmt: skip
    fast = np.concatenate([np.zeros(LEAD_REST_S), np.full(FAST_S, FAST_C_RATE),
                           np.zeros(FAST_REST_S), np.full(FAST_S, -FAST_C_RATE),
                           np.zeros(FAST_REST_S)])  # fmt: skip
    return np.concatenate([fast, withheld.c_rate_profile(PROFILES[profile], base_seed, 1)])


def solve(chemistry: str, ambient_c: float, rate: np.ndarray) -> dict:
    """Noise-free 1-Hz time, current (A, discharge positive), voltage and cell temperature (K)
    of the chemistry's cell soaked at ``ambient_c`` and driven by ``rate`` (C-rates)."""
    if chemistry not in CHEMISTRIES:
        raise ConfigError(f"temperature cells: unknown chemistry {chemistry!r}; choose from "
                          f"{', '.join(CHEMISTRIES)}")  # fmt: skip
    pybamm = _pybamm()
    spec = transfer.CELLS[chemistry]
    pv = transfer.parameter_values(chemistry, ambient_c)
    q = float(pv["Nominal cell capacity [A.h]"])
    t = np.arange(rate.size, dtype=float) * withheld.TS
    current = rate * q
    pv.update({
        # a zero-order-hold current sampled at 1 s, linear between samples as the solver needs
        "Current function [A]": pybamm.Interpolant(t, current, pybamm.t, interpolator="linear"),
        "Upper voltage cut-off [V]": float(pv["Upper voltage cut-off [V]"]) + CUTOFF_MARGIN_V,
    }, check_already_exists=False)  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # PyBaMM's own parameter names
        model = getattr(pybamm.lithium_ion, spec.model)(options=spec.options)
        sim = pybamm.Simulation(model, parameter_values=pv, solver=pybamm.IDAKLUSolver())
        sol = sim.solve(t_eval=[0.0, t[-1]], t_interp=t, initial_soc=INITIAL_SOC)
    voltage = sol["Voltage [V]"].entries
    if voltage.size != t.size:
        raise RuntimeError(f"PyBaMM {chemistry} at {ambient_c:g} °C: solution stopped at "
                           f"{sol.t[-1]:.0f} s of {t[-1]:.0f} s ({sol.termination})")  # fmt: skip
    return {"time_s": t, "current_a": current, "voltage_v": voltage, "capacity_ah": q,
            "temperature_k": sol["Volume-averaged cell temperature [K]"].entries}  # fmt: skip


def cycler_log(frame: pd.DataFrame, rest_log_s: float = REST_LOG_S,
               slow: np.ndarray | None = None) -> pd.DataFrame:  # fmt: skip
    """A 1-Hz record as a cycler logs it: the current channel one sample late (at an edge the
    logged current is the one before it); the slow rows kept every ``rest_log_s`` only (and the
    last row). ``slow`` marks the rows a cycler logs coarsely (a constant-voltage phase as well
    as a rest); by default the rests, rows where the true and the logged current are both zero,
    so an edge row is logged. The one rule for every development record logged so
    (tests/unit/test_soc_filter.py's and test_bms_events.py's records too)."""
    cur = frame["current_a"].to_numpy()
    lagged = np.r_[cur[:1], cur[:-1]]
    t = frame["time_s"].to_numpy()
    if slow is None:
        slow = (cur == 0.0) & (lagged == 0.0)
    keep = ~slow | (np.mod(t - t[0], rest_log_s) == 0.0) | (np.arange(t.size) == t.size - 1)
    return frame.assign(current_a=lagged)[keep].reset_index(drop=True)


def make(chemistry: str, ambient_c: float, profile: str, base_seed: int = 0,
         rate: np.ndarray | None = None) -> Dataset:  # fmt: skip
    """One development record with sensor noise; ``rate`` replaces the profile's current (tests
    use a short one), the name still says the profile."""
    if rate is None:
        rate = c_rate(profile, base_seed)
    clean = solve(chemistry, ambient_c, rate)
    columns = ("time_s", "current_a", "voltage_v", "temperature_k")
    logged = cycler_log(pd.DataFrame({k: clean[k] for k in columns}))
    name = record_name(chemistry, ambient_c, profile)
    rng = seeds.stream(base_seed, "temperature-cells-noise", name)
    sensor = withheld.sensor
    v_true = logged["voltage_v"].to_numpy()
    v = sensor(v_true, rng, NOISE_MV * 1e-3, withheld.VOLTAGE_LSB_V)
    i = sensor(logged["current_a"].to_numpy(), rng, withheld.CURRENT_NOISE_A,
               withheld.CURRENT_LSB_A)  # fmt: skip
    temp = sensor(logged["temperature_k"].to_numpy() - 273.15, rng, withheld.TEMPERATURE_NOISE_K,
                  withheld.TEMPERATURE_LSB_K)  # fmt: skip
    spec = transfer.CELLS[chemistry]
    pybamm = _pybamm()
    meta = {
        "name": name,
        "cell": f"{chemistry} ({spec.parameter_set}, PyBaMM {spec.model}, lumped thermal)",
        "chemistry": chemistry,
        "nominal_capacity_ah": clean["capacity_ah"],
        "ambient_temperature_c": float(ambient_c),
        "test_type": profile,
        "profile": profile,
        "profile_source": (
            f"gap.withheld.c_rate_profile({PROFILES[profile]!r}) after a "
            f"{FAST_C_RATE:g}C fast cycle"
        ),
        "source_file": f"{name}.csv",
        "source_sha256": None,  # simulated: no source file
        "citation": CITATIONS[spec.parameter_set],
        "licence": "simulated with PyBaMM (BSD-3-Clause); parameter set as cited",
        "source": "pybamm",
        "parameter_set": spec.parameter_set,
        "model": spec.model,
        "options": {k: list(x) if isinstance(x, tuple) else x for k, x in spec.options.items()},
        "temperature_column": (
            "lumped cell temperature (PyBaMM 'Volume-averaged cell temperature [K]'), in °C"
        ),
        "soc0": INITIAL_SOC,
        "contact_resistance_ohm": pybamm_data.CONTACT_OHM,
        "logging": {"rest_log_s": REST_LOG_S, "current_lag_samples": 1, "load_log_s": 1.0},
        "noise_mv": NOISE_MV,
        "noise_rmse_mv": float(1e3 * np.sqrt(np.mean((v - v_true) ** 2))),
        "n_samples": int(v.size),
        "seed": base_seed,
        "seed_keys": [base_seed, "temperature-cells-noise", name],
        "pybamm_version": pybamm.__version__,
        "generator": f"avoa_pipeline {__version__} gap.temperature_cells",
    }
    t = logged["time_s"].to_numpy()
    return Dataset(as_written(t), as_written(i), as_written(v), as_written(temp), meta)


def write_set(out: Path, chemistries=CHEMISTRIES, ambients=AMBIENTS_C, base_seed: int = 0,
              log=print) -> list[Path]:  # fmt: skip
    """Every (chemistry, ambient, profile) record into ``out``: all files or none. Every record
    is solved first (a failed solve writes nothing); each is written and checked by
    ``records.write`` into a staging folder, then all are renamed into place together
    (``io.atomic_paths``)."""
    out, log = Path(out), log or (lambda _message: None)
    sets = []
    for chem in chemistries:
        for amb in ambients:
            for profile in PROFILES:
                t0 = time.perf_counter()
                ds = make(chem, amb, profile, base_seed)
                log(f"solved {ds.meta['name']}: {ds.meta['n_samples']} rows "
                    f"({time.perf_counter() - t0:.1f} s)")  # fmt: skip
                sets.append(ds)
    out.mkdir(parents=True, exist_ok=True)
    targets = [out / f"{ds.meta['name']}.csv" for ds in sets]
    with tempfile.TemporaryDirectory(prefix=".staging-", dir=out) as stage:
        staged = []
        for ds, target in zip(sets, targets, strict=True):
            csv = Path(stage) / target.name
            write_dataset(ds, csv)  # records.write: validated, CSV and sidecar with its sha256
            staged += [csv, sidecar_of(csv)]
        finals = [p for t in targets for p in (t, sidecar_of(t))]
        with atomic_paths(*finals) as tmps:
            for src, tmp in zip(staged, tmps, strict=True):
                shutil.move(src, tmp)
    return finals


def pulse_drop_v(frame: pd.DataFrame, capacity_ah: float, c_rate_min: float = 0.9) -> float:
    """The voltage drop (V) of the first discharge pulse of at least ``c_rate_min`` C that lasts
    under a minute (the HPPC's 10-s pulse, not the fast cycle's 15-min discharge), read from the
    logged record: the last rest row before the pulse minus the pulse's last loaded row. The
    logged current is a sample late at both edges, so the row before the logged rise and the
    last row of the logged pulse are the ones the true current has already changed at."""
    i = frame["current_a"].to_numpy()
    v = frame["voltage_v"].to_numpy()
    t = frame["time_s"].to_numpy()
    on = i >= c_rate_min * capacity_ah
    rises = np.flatnonzero(~on[:-1] & on[1:]) + 1
    for a in rises:
        after = np.flatnonzero(~on[a:])
        if not after.size:
            break
        b = a + int(after[0])  # first row logged off
        if t[b - 1] - t[a] < 60.0:
            return float(v[a - 2] - v[b - 2])
    raise ValueError("no discharge pulse shorter than a minute in the record")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m avoa_pipeline.gap.temperature_cells",
                                description=__doc__.splitlines()[0])  # fmt: skip
    p.add_argument("--out", type=Path, required=True, help="folder for the records")
    p.add_argument("--chemistry", nargs="+", choices=CHEMISTRIES, default=list(CHEMISTRIES))
    p.add_argument("--ambients", nargs="+", type=float, default=list(AMBIENTS_C), metavar="C")
    p.add_argument("--seed", type=int, default=0, help="base seed (drive profile and noise)")
    a = p.parse_args(argv)
    t0 = time.perf_counter()
    paths = write_set(a.out, a.chemistry, a.ambients, a.seed)
    size = sum(f.stat().st_size for f in paths)
    print(f"wrote {len(paths)} files ({size / 1e6:.1f} MB) to {a.out} in "
          f"{time.perf_counter() - t0:.0f} s")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
