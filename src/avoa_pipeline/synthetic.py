"""Synthetic "measured" datasets: the paper's model, the paper's test profile, sensor effects.

The paper's measurements are not public. One dataset per scenario × case is simulated from the
configured true parameters with the Figure 2 profile, then degraded as a real logger would:
Gaussian noise and quantisation on voltage and current. Deterministic from (base seed, scenario,
case). The CSV holds the *cycler* current (positive = discharge); in the load scenarios the
1 kΩ resistor's current is part of the experiment, not of the logged current.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from . import __version__, records, seeds
from .model.battery import CASES, PARAM_NAMES, ModelSpec, simulate, vector

CSV_FLOAT = "%.10g"


@dataclass
class Dataset:
    time_s: np.ndarray
    current_a: np.ndarray
    voltage_v: np.ndarray
    temperature_c: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def ts(self) -> float:
        return float(self.time_s[1] - self.time_s[0])

    def frame(self) -> pd.DataFrame:
        return pd.DataFrame(
            {
                "time_s": self.time_s,
                "current_a": self.current_a,
                "voltage_v": self.voltage_v,
                "temperature_c": self.temperature_c,
            }
        )


def profile(cfg: dict) -> tuple[np.ndarray, np.ndarray, list[dict]]:
    """Time, cycler current and segment table (name, start, end) of the Figure 2 test."""
    ts = float(cfg["profile"]["sample_s"])
    currents, table, t0 = [], [], 0.0
    for seg in cfg["profile"]["segments"]:
        n = round(seg["duration_s"] / ts)
        currents.append(np.full(n, float(seg["current_a"])))
        table.append(
            {
                "name": seg["name"],
                "start_s": t0,
                "end_s": t0 + n * ts,
                "current_a": float(seg["current_a"]),
            }
        )
        t0 += n * ts
    current = np.concatenate([*currents, [0.0]])  # one closing sample at the end of the rest
    return np.arange(current.size) * ts, current, table


def as_written(x: np.ndarray) -> np.ndarray:
    """The values exactly as the CSV will hold them (so in-memory and on-disk data agree)."""
    return np.char.mod(CSV_FLOAT, x).astype(float)


def _sensor(x, rng, sd, lsb):
    y = x + sd * rng.standard_normal(x.shape) if sd > 0 else x.copy()
    return np.round(y / lsb) * lsb if lsb > 0 else y


def generate(cfg: dict, scenario: int, case: int, noise: bool = True) -> Dataset:
    """The synthetic measured record of ``scenario`` × ``case`` (noise-free if ``noise=False``)."""
    c = CASES[case]
    truth = cfg["true_params"][c.temperature]
    dcfg = cfg["data"]
    spec = ModelSpec.for_scenario_case(
        cfg["constants"], scenario, case, dynamics=dcfg["cell_has_charge_dynamics"] or c.dynamics
    )
    t, ip, segments = profile(cfg)
    ts = float(cfg["profile"]["sample_s"])
    sim = simulate(vector(truth), ip, ts, spec)
    rng = seeds.stream(cfg["base_seed"], "data", scenario, case)
    if noise:
        v = _sensor(sim["voltage_v"], rng, dcfg["voltage_noise_v"], dcfg["voltage_lsb_v"])
        i = _sensor(ip, rng, dcfg["current_noise_a"], dcfg["current_lsb_a"])
    else:
        v, i = sim["voltage_v"], ip
    temp = float(cfg["temperatures_c"][c.temperature])
    meta = {
        "scenario": scenario,
        "case": case,
        "temperature": c.temperature,
        "temperature_c": temp,
        "true_params": {n: float(truth[n]) for n in PARAM_NAMES},
        "effective_params": dict(
            zip(PARAM_NAMES, map(float, vector(truth) * spec.fade_factors), strict=False)
        ),
        "cell_has_charge_dynamics": spec.dynamics,
        "load_ohm": spec.load_ohm,
        "cycle_n": cfg["constants"]["cycle_n"] if spec.fade_factors[1] != 1.0 else 0,
        "fade_factors": dict(zip(PARAM_NAMES, map(float, spec.fade_factors), strict=False)),
        "soc0": spec.soc0,
        "qdis_ah": spec.qdis_ah,
        "sample_s": ts,
        "segments": segments,
        "noise": bool(noise),
        "sensor": {
            k: dcfg[k]
            for k in ("voltage_noise_v", "voltage_lsb_v", "current_noise_a", "current_lsb_a")
        }
        if noise
        else None,
        "seed_keys": [cfg["base_seed"], "data", scenario, case],
        "generator": f"avoa_pipeline {__version__}",
    }
    return Dataset(as_written(t), as_written(i), as_written(v), np.full(t.size, temp), meta)


def write(ds: Dataset, csv_path) -> None:
    """The CSV and its JSON sidecar (``<name>.json``, with the CSV's ``csv_sha256``): both or
    none (``records.write``)."""
    records.write(ds.frame(), ds.meta, csv_path, keys=(), float_format=CSV_FLOAT,
                  digest="csv_sha256")  # fmt: skip
