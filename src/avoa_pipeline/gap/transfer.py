"""Transfer benchmark: does the model the diagnosis hands over predict a cell's unseen records
better than plain constant-parameter circuits fitted to the same training records? (issue 26; the
cells, profiles, protocol and measured table: docs/transfer-benchmark.md). The model handed over
(``model.json``, docs/handover-rule.md) is the "selected" one, the model a user gets; the
verdict's model (the ladder's last rung, ``diagnosis.json``'s ``selected``) is reported beside it.

Cells are simulated by PyBaMM's physics models with a lumped thermal model (:data:`CELLS`), so
their physics is known and every choice of the selection rule may be tuned here; the real
cells' unseen records are never used for any choice.

Each cell runs each profile of :data:`PROFILES` at each ambient of :data:`AMBIENTS_C` (the cell
soaked at the ambient first), and a C/20 OCV test (discharge, rest, charge) at the training
ambient. The records are written as a cycler logs them: 1-s logging under load, 1 s for the
first :data:`REST_FAST_S` of a rest (a cycler's voltage-change trigger), then every
:data:`REST_LOG_S`; the slow test every :data:`SLOW_LOG_S`. Sensor noise and quantisation are the
withheld-effect datasets' (:func:`avoa_pipeline.gap.withheld.sensor`).

Protocol, as a user's (:data:`SPLITS`): training = the split's records at the training ambient,
``--ocv`` = the slow test, the cell's other records (both ambients) unseen. The diagnosis runs
through the pipeline behind ``python -m avoa_pipeline diagnose`` (``avoa_pipeline.diagnosis``,
its inputs read from the written CSV files; ``benchmarks/bench_transfer.py`` drives it); fixed
1RC and 2RC circuits on the same training records and the ``--ocv`` table (``inputs.read_ocv``)
are fitted by ``model.fitted.fit_model``.
"""

from __future__ import annotations

import json
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .. import __version__, seeds
from ..errors import ConfigError
from ..model.ecm import Config
from ..model.fitted import fit_model
from ..synthetic import Dataset, as_written
from ..synthetic import write as write_dataset
from . import pybamm_data, withheld


@dataclass(frozen=True)
class CellSpec:
    """One simulated cell: a PyBaMM parameter set, model and options."""

    parameter_set: str
    model: str
    options: dict
    hysteresis: bool = False
    extra: dict = field(default_factory=dict)  # parameter values the set lacks or we change


LFP_26650 = {
    # Prada2013 (A123 ANR26650 LFP) has no thermal or current-collector parameters; those of
    # Chen2020 (an LG M50 21700) are taken, with the volume and surface of a 26650 can
    # (26 mm × 65 mm), which set the lumped model's heat capacity and its cooling
    "Cell volume [m3]": np.pi * 0.013**2 * 0.065,
    "Cell cooling surface area [m2]": np.pi * 0.026 * 0.065 + 2 * np.pi * 0.013**2,
}
CELLS = {
    "nmc": CellSpec("Chen2020", "SPMe", {"thermal": "lumped", "contact resistance": "true"}),
    "lfp": CellSpec(
        "Prada2013", "SPMe", {"thermal": "lumped", "contact resistance": "true"}, extra=LFP_26650
    ),
    "nmc_hysteresis": CellSpec(
        "Chen2020",
        "SPMe",
        {
            "thermal": "lumped",
            "contact resistance": "true",
            "open-circuit potential": ("one-state hysteresis", "single"),
        },
        hysteresis=True,
    ),
    # graphite + silicon oxide negative electrode: each phase its own particles; the silicon's
    # OCP has PyBaMM's current-sigmoid hysteresis (lithiation and delithiation branches ~0.1 V
    # apart, switched by the current's sign)
    "nmc_composite": CellSpec(
        "Chen2020_composite",
        "SPMe",
        {
            "thermal": "lumped",
            "contact resistance": "true",
            "particle phases": ("2", "1"),
            "open-circuit potential": (("single", "current sigmoid"), "single"),
        },
    ),
}
PHASE_KEYS = (
    "Negative electrode density [kg.m-3]",
    "Negative electrode specific heat capacity [J.kg-1.K-1]",
    "Negative electrode thermal conductivity [W.m-1.K-1]",
)
"""The lumped thermal model reads these for the whole electrode; a composite set gives the
density per phase only, and the primary (graphite) phase's value stands for the electrode."""
PROFILES = ("hppc", "gitt", "la92", "hwfet")
SLOW = "ocv"
AMBIENTS_C = (25.0, 10.0)
TRAIN_AMBIENT_C = 25.0
SPLITS = {"hppc": ("hppc",), "hppc+la92": ("hppc", "la92")}
QUICK = {"cells": ("nmc",), "splits": ("hppc",), "ambients": (25.0,), "profiles": ("hppc", "la92")}
"""The ``--quick`` benchmark: one cell, one split, one ambient, one unseen drive cycle."""

REST_FAST_S = 10
"""A cycler logs the first seconds after a current step at its fastest rate (a voltage-change
trigger: the ohmic jump and the first relaxation move the voltage by millivolts per second)."""
REST_LOG_S = 30
"""Then a rest is logged every 30 s (cyclers' usual 10-60 s time trigger once the voltage has
slowed to well under a millivolt per second)."""
SLOW_LOG_S = 30
"""The C/20 test is logged every 30 s: at C/20 the voltage moves < 1 mV per 30 s in the middle
of the curve, and 1-s logging would make a 40-h test 144,000 rows."""
PANASONIC_AH = 2.9
"""Nominal capacity of the Panasonic NCR18650PF whose drive-cycle currents are replayed (its
datasheet's 2.9 Ah): the currents are replayed at the same C-rate on the simulated cell."""
_DRIVES_25C = "Panasonic 18650PF Data/25degC/Drive cycles"
PANASONIC_DRIVE = {
    "la92": f"{_DRIVES_25C}/03-21-17_09.38 25degC_LA92_Pan18650PF.mat",
    "hwfet": f"{_DRIVES_25C}/03-20-17_05.56 25degC_HWFTa_Pan18650PF.mat",
}
DRIVE_S = 2400
"""Seconds of each drive cycle replayed: 40 min of driving, which moves 16 % (LA92, mean 0.23C,
peaks 2.4C) and 28 % (HWFET, mean 0.42C) of the charge: one trip's SOC range, and at least the
diagnosis's minimum of samples (``diagnose.MIN_SAMPLES``), so a drive can be a training record."""
QUICK_SCALE = 0.5
"""``--quick`` halves every profile's repeated part (4 HPPC SOC steps instead of 7, 20 min of
driving): the HPPC record then still holds the diagnosis's minimum of samples
(``diagnose.MIN_SAMPLES``), and the quick benchmark runs in about a minute."""
INITIAL_SOC = {"hppc": 0.95, "gitt": 0.9, "la92": 0.9, "hwfet": 0.75, "ocv": 1.0}
NOISE_MV = pybamm_data.NOISE_MV


def _pybamm():
    os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")
    import pybamm

    return pybamm


def default_panasonic_root() -> Path:
    return Path(os.environ.get("AVOA_PANASONIC", "/work/shared/data/real/panasonic_18650pf"))


def drive_c_rate(profile: str, root: Path, seconds: int) -> np.ndarray:
    """``seconds`` of a Panasonic drive cycle's current at 1 s, in C-rates of the Panasonic cell
    (positive = discharge). Read by the project's importer
    (``importers.panasonic.read_mat``); each 1-s value is the exact mean of the logged
    current (held between its 0.1-s samples) over that second, so the replayed charge is the
    logged one."""
    from ..importers import panasonic

    df = panasonic.read_mat(root / PANASONIC_DRIVE[profile])
    t = df["Time"].to_numpy()
    i = -df["Current"].to_numpy()  # the tester writes discharge negative
    start = t[np.flatnonzero(np.abs(i) > panasonic.REST_A)[0]]
    if t[-1] - start < seconds:
        raise ConfigError(f"transfer: {profile}: the record holds {t[-1] - start:.0f} s of "
                          f"driving, fewer than {seconds} s")  # fmt: skip
    charge = np.concatenate([[0.0], np.cumsum(i[:-1] * np.diff(t))])  # A·s, held current
    edges = start + np.arange(seconds + 1, dtype=float)
    return np.diff(np.interp(edges, t, charge)) / PANASONIC_AH


def _rest(seconds: float) -> list[str]:
    """A rest logged at 1 s for :data:`REST_FAST_S`, then every :data:`REST_LOG_S` (the coarse
    part rounded up to whole logging intervals, which PyBaMM would otherwise spread evenly)."""
    coarse = REST_LOG_S * int(np.ceil(max(seconds - REST_FAST_S, 0) / REST_LOG_S))
    out = [f"Rest for {REST_FAST_S} seconds (1 second period)"]
    if coarse:
        out.append(f"Rest for {coarse} seconds ({REST_LOG_S} second period)")
    return out


def experiment_steps(profile: str, capacity_ah: float, v_min: float, v_max: float,
                     scale: float = 1.0, root: Path | None = None) -> list:  # fmt: skip
    """PyBaMM experiment steps of ``profile`` (``scale`` < 1 shortens its repeated part)."""
    pybamm = _pybamm()
    steps = _rest(600)
    if profile == "hppc":
        # at each SOC step a 1C discharge and a 0.75C charge pulse (10 s each, 40 s rests),
        # then 10 % of the charge at C/2 and a 20-min rest (the usual HPPC layout)
        for _ in range(max(2, round(7 * scale))):
            steps += [
                "Discharge at 1C for 10 seconds (1 second period)", *_rest(40),
                "Charge at 0.75C for 10 seconds (1 second period)", *_rest(40),
                "Discharge at 0.5C for 12 minutes (1 second period)", *_rest(1200),
            ]  # fmt: skip
    elif profile == "gitt":
        # 5 % of the charge at C/4 per titration, then a 40-min relaxation
        for _ in range(max(2, round(8 * scale))):
            steps += ["Discharge at 0.25C for 12 minutes (1 second period)", *_rest(2400)]
    elif profile in PANASONIC_DRIVE:
        c = drive_c_rate(profile, root or default_panasonic_root(), round(DRIVE_S * scale))
        t = np.arange(c.size + 1, dtype=float)
        amps = np.append(c, c[-1]) * capacity_ah
        steps += [pybamm.step.current(np.column_stack([t, amps]), period=1.0), *_rest(1800)]
    elif profile == SLOW:
        steps += [f"Discharge at C/20 until {v_min:g} V ({SLOW_LOG_S} second period)",
                  f"Rest for 1 hour ({SLOW_LOG_S} second period)",
                  f"Charge at C/20 until {v_max:g} V ({SLOW_LOG_S} second period)",
                  f"Rest for 1 hour ({SLOW_LOG_S} second period)"]  # fmt: skip
    else:
        raise ConfigError(f"transfer: unknown profile {profile!r}; choose from "
                          f"{', '.join((*PROFILES, SLOW))}")  # fmt: skip
    return steps


def parameter_values(cell: str, ambient_c: float):
    pybamm = _pybamm()
    spec = CELLS[cell]
    with warnings.catch_warnings():
        # Chen2020_composite still names a parameter by its pre-v25 name (PyBaMM's own
        # DeprecationWarning, nothing of ours)
        warnings.simplefilter("ignore", DeprecationWarning)
        pv = pybamm.ParameterValues(spec.parameter_set)
    if "particle phases" in spec.options:
        pv.update({k: pv[f"Primary: {k}"] if f"Primary: {k}" in pv else pv[k]
                   for k in PHASE_KEYS}, check_already_exists=False)  # fmt: skip
    if spec.extra:
        donor = pybamm.ParameterValues("Chen2020")
        thermal = ("collector", "density", "specific heat", "thermal conductivity", "heat transfer")
        missing = {k: donor[k] for k in donor
                   if k not in pv and any(w in k for w in thermal)}  # fmt: skip
        pv.update({**missing, **spec.extra}, check_already_exists=False)
    t_amb = ambient_c + 273.15
    pv.update({"Ambient temperature [K]": t_amb, "Initial temperature [K]": t_amb,
               "Contact resistance [Ohm]": pybamm_data.CONTACT_OHM},
              check_already_exists=False)  # fmt: skip
    if spec.hysteresis:  # as gap.pybamm_data's hysteresis cell
        ocp = pv["Negative electrode OCP [V]"]
        half, rate = pybamm_data.HYSTERESIS_HALF_V, pybamm_data.HYSTERESIS_DECAY
        pv.update({
            "Negative electrode lithiation OCP [V]": lambda sto: ocp(sto) - half,
            "Negative electrode delithiation OCP [V]": lambda sto: ocp(sto) + half,
            "Negative particle lithiation hysteresis decay rate": lambda sto, T: rate,
            "Negative particle delithiation hysteresis decay rate": lambda sto, T: rate,
            "Initial hysteresis state in negative electrode": 0.0,
        }, check_already_exists=False)  # fmt: skip
    return pv


def solve(cell: str, profile: str, ambient_c: float, scale: float = 1.0,
          root: Path | None = None) -> dict:  # fmt: skip
    """Noise-free logged samples (time, current discharge positive, voltage, temperature)."""
    pybamm = _pybamm()
    spec = CELLS[cell]
    pv = parameter_values(cell, ambient_c)
    q = float(pv["Nominal cell capacity [A.h]"])
    v_min, v_max = float(pv["Lower voltage cut-off [V]"]), float(pv["Upper voltage cut-off [V]"])
    with warnings.catch_warnings():
        # PyBaMM warns at every build of a hysteresis model that the decay-rate definition
        # changed in v25.10 (gap.pybamm_data sets the rate for the current one)
        warnings.simplefilter("ignore", UserWarning)
        warnings.simplefilter("ignore", DeprecationWarning)  # Chen2020_composite's old name
        model = getattr(pybamm.lithium_ion, spec.model)(options=spec.options)
        steps = experiment_steps(profile, q, v_min, v_max, scale, root)
        sim = pybamm.Simulation(model, parameter_values=pv, experiment=pybamm.Experiment(steps),
                                solver=pybamm.IDAKLUSolver())  # fmt: skip
        sol = sim.solve(initial_soc=INITIAL_SOC[profile])
    t = sol["Time [s]"].entries
    out = {
        "time_s": t,
        "current_a": sol["Current [A]"].entries,
        "voltage_v": sol["Voltage [V]"].entries,
        "temperature_k": sol["X-averaged cell temperature [K]"].entries,
    }
    # consecutive steps share their boundary instant: keep the later sample, which carries the
    # new step's current and the voltage after its ohmic jump (as a cycler logs a step's start)
    keep = np.r_[np.diff(np.round(t, 6)) > 0, True]
    out = {k: v[keep] for k, v in out.items()}
    out["capacity_ah"] = q
    out["termination"] = str(sol.termination)
    return out


def make(cell: str, profile: str, ambient_c: float, base_seed: int = 0, scale: float = 1.0,
         root: Path | None = None) -> Dataset:  # fmt: skip
    """One record with the sensor noise of the withheld-effect datasets."""
    clean = solve(cell, profile, ambient_c, scale, root)
    name = record_name(cell, profile, ambient_c)
    rng = seeds.stream(base_seed, "transfer-noise", name)
    sensor = withheld.sensor
    v = sensor(clean["voltage_v"], rng, NOISE_MV * 1e-3, withheld.VOLTAGE_LSB_V)
    i = sensor(clean["current_a"], rng, withheld.CURRENT_NOISE_A, withheld.CURRENT_LSB_A)
    temp = sensor(clean["temperature_k"] - 273.15, rng, withheld.TEMPERATURE_NOISE_K,
                  withheld.TEMPERATURE_LSB_K)  # fmt: skip
    spec = CELLS[cell]
    t = clean["time_s"] - clean["time_s"][0]
    meta = {
        "name": name,
        "source": "pybamm",
        "cell": cell,
        "parameter_set": spec.parameter_set,
        "model": spec.model,
        "options": {k: list(x) if isinstance(x, tuple) else x for k, x in spec.options.items()},
        "hysteresis_half_width_v": pybamm_data.HYSTERESIS_HALF_V if spec.hysteresis else 0.0,
        "profile": profile,
        "drive_source": PANASONIC_DRIVE.get(profile),
        "ambient_c": ambient_c,
        "capacity_ah": clean["capacity_ah"],
        "soc0": INITIAL_SOC[profile],
        "scale": scale,
        "termination": clean["termination"],
        "noise_mv": NOISE_MV,
        "noise_rmse_mv": float(1e3 * np.sqrt(np.mean((v - clean["voltage_v"]) ** 2))),
        "n_samples": int(v.size),
        "seed_keys": [base_seed, "transfer-noise", name],
        "generator": f"avoa_pipeline {__version__} gap.transfer, pybamm {_pybamm().__version__}",
    }
    return Dataset(as_written(t), as_written(i), as_written(v), as_written(temp), meta)


def record_name(cell: str, profile: str, ambient_c: float) -> str:
    return f"{cell}_{profile}_{ambient_c:g}C"


def build(data: Path, cells, ambients, profiles, scale: float = 1.0, base_seed: int = 0,
          root: Path | None = None, log=print) -> dict[str, Path]:  # fmt: skip
    """Write every record not yet in ``data`` (a cache: PyBaMM runs are slow); name → path."""
    data.mkdir(parents=True, exist_ok=True)
    wanted = [(c, p, a) for c in cells for a in ambients for p in profiles]
    wanted += [(c, SLOW, TRAIN_AMBIENT_C) for c in cells]
    out = {}
    for cell, profile, amb in wanted:
        name = record_name(cell, profile, amb)
        path = data / f"{name}.csv"
        if not path.exists():
            ds = make(cell, profile, amb, base_seed, scale, root)
            write_dataset(ds, path)
            log(f"wrote {path} ({ds.meta['n_samples']} samples)")
        out[name] = path
    return out


def _rmse_mv(model_v, v) -> float:
    return 1e3 * float(np.sqrt(np.mean((np.asarray(model_v) - np.asarray(v)) ** 2)))


FIXED = {"1rc": (), "2rc": ("second_rc",)}
"""The fixed circuits: constant parameters, the ``--ocv`` table, one or two RC branches."""


def fit_fixed(frames, table) -> dict:
    """The fixed circuits of :data:`FIXED` fitted to the training frames (``fitting.Fit`` each)."""
    return {key: fit_model(frames, Config(effects, table)) for key, effects in FIXED.items()}


def split_inputs(paths: dict[str, Path], cell: str, split: str, ambients,
                 profiles) -> tuple[list[str], list[str], str]:  # fmt: skip
    """One cell's split as a user gives it: (training records, unseen records, the slow test
    given as ``--ocv``). The benchmark diagnoses them through the one pipeline
    (``avoa_pipeline.diagnosis``, called from ``benchmarks/bench_transfer.py``: a layer above
    this one)."""
    train = [str(paths[record_name(cell, p, TRAIN_AMBIENT_C)]) for p in SPLITS[split]]
    unseen = [str(paths[record_name(cell, p, a)]) for a in ambients for p in profiles
              if str(paths[record_name(cell, p, a)]) not in train]  # fmt: skip
    return train, unseen, str(paths[record_name(cell, SLOW, TRAIN_AMBIENT_C)])


def unseen_rows(cell: str, split: str, report: dict, unseen, fixed: dict,
                train_mv: dict) -> list[dict]:  # fmt: skip
    """One row per unseen record (``records.Checked``, the diagnosis's validation records) with
    every model's RMSE (mV): the diagnosis's (``report``: its validation rows) and the fixed
    circuits' (``fixed``: key → FittedModel; ``train_mv``: key → training RMSE)."""
    verdict = report["selected"]["name"]
    by = {(r["record"], r["model"]): r for r in report["validation"]}
    rows = []
    for c in unseen:
        v = c.frame["voltage_v"].to_numpy()
        sel, base = by[(c.source, "handed_over")], by[(c.source, "base")]
        side = json.loads(Path(c.source).with_suffix(".json").read_text())
        rows.append({
            "cell": cell, "split": split, "record": Path(c.source).stem,
            "profile": side["profile"], "ambient_c": side["ambient_c"],
            "handed_over_model": report["handed_over"]["name"],
            "handed_over_mv": sel["rmse_mv"],
            "verdict_model": verdict, "verdict_mv": by[(c.source, verdict)]["rmse_mv"],
            "base_mv": base["rmse_mv"],
            "fixed_1rc_mv": _rmse_mv(fixed["1rc"].simulate(c.frame), v),
            "fixed_2rc_mv": _rmse_mv(fixed["2rc"].simulate(c.frame), v),
            "floor_mv": sel["floor_rmse_mv"],
            # how well each fitted the training records (the diagnosis's base over them joined)
            "base_train_mv": report["base"]["rmse_mv"],
            "fixed_1rc_train_mv": train_mv["1rc"], "fixed_2rc_train_mv": train_mv["2rc"],
        })  # fmt: skip
    return rows


SUMMARY_COLUMNS = ("handed_over_mv", "verdict_mv", "base_mv", "fixed_1rc_mv", "fixed_2rc_mv",
                   "floor_mv")  # fmt: skip
TRAIN_COLUMNS = ("base_train_mv", "fixed_1rc_train_mv", "fixed_2rc_train_mv")


def summarize(rows: list[dict], by=("cell", "split")) -> pd.DataFrame:
    """Per cell and split (or ``by``): each model's median unseen RMSE and the ratios of the
    handed-over model (and of the verdict's) to the 2RC and the base."""
    df = pd.DataFrame(rows)
    g = df.groupby(list(by), sort=False)
    out = g[list(SUMMARY_COLUMNS)].median()
    out.insert(0, "handed_over_model", g["handed_over_model"].first())
    out.insert(1, "verdict_model", g["verdict_model"].first())
    out.insert(2, "n_unseen", g.size())
    out["handed_over_over_2rc"] = out["handed_over_mv"] / out["fixed_2rc_mv"]
    out["handed_over_over_base"] = out["handed_over_mv"] / out["base_mv"]
    out["verdict_over_2rc"] = out["verdict_mv"] / out["fixed_2rc_mv"]
    for col in TRAIN_COLUMNS:  # one value per split (absent in rows of an older run)
        if col in df.columns:
            out[col] = g[col].first()
    return out.reset_index()


def markdown(summary: pd.DataFrame, by=("cell", "split")) -> str:
    """The summary as a markdown table, and the training RMSEs of the same fits below it."""
    keys = [str(k).replace("_c", " °C").replace("_", " ") for k in by]
    head = " | ".join([*keys, "handed over", "n unseen", "handed-over mV", "verdict's model",
                       "verdict mV", "base mV", "1RC mV", "2RC mV", "floor mV", "h.o./2RC",
                       "h.o./base", "verdict/2RC"])  # fmt: skip
    lines = [f"| {head} |", "|" + "---|" * (len(by) + 12)]
    for r in summary.itertuples(index=False):
        key = " | ".join(f"{getattr(r, k):g}" if isinstance(getattr(r, k), float)
                         else str(getattr(r, k)) for k in by)  # fmt: skip
        lines.append(
            f"| {key} | {r.handed_over_model} | {r.n_unseen} | {r.handed_over_mv:.2f} | "
            f"{r.verdict_model} | {r.verdict_mv:.2f} | "
            f"{r.base_mv:.2f} | {r.fixed_1rc_mv:.2f} | {r.fixed_2rc_mv:.2f} | {r.floor_mv:.2f} | "
            f"{r.handed_over_over_2rc:.2f} | {r.handed_over_over_base:.2f} | "
            f"{r.verdict_over_2rc:.2f} |"
        )
    if tuple(by) == ("cell", "split") and set(TRAIN_COLUMNS) <= set(summary.columns):
        lines += ["", "Training RMSE (mV) of the same fits (base: the training records joined; "
                  "1RC, 2RC: records alike):", "",
                  "| cell | split | base | 1RC | 2RC |", "|---|---|---|---|---|"]  # fmt: skip
        for r in summary.itertuples(index=False):
            lines.append(f"| {r.cell} | {r.split} | {r.base_train_mv:.2f} | "
                         f"{r.fixed_1rc_train_mv:.2f} | {r.fixed_2rc_train_mv:.2f} |")  # fmt: skip
    return "\n".join(lines) + "\n"
