"""Experiment 1: fit on one Panasonic drive cycle, predict the drive cycles the fit never saw.

At each temperature of ``real.panasonic.experiment.train`` the models are fitted to one drive
cycle (the training cycle) and then simulated, with the fitted parameters unchanged, on every
other drive cycle at that temperature. Reported per unseen cycle: the RMSE and the maximum
absolute error of the terminal voltage over the whole record (drive part and closing rest).

Models (docs/real-data.md says why each):

- ``paper_rc`` / ``paper_norc``: the paper's model (eqs. 3-6; ``model/kernel.py``), with and
  without the RC branch, parameters (Vnom, Q, Vdis, R0[, Rtr, τtr]) searched by each of the
  seven optimizers over a few seeds in the wide box ``experiment.bounds``; Qdis, which with Vdis
  only places the curve's shape parameter β, is held at ``experiment.qdis_ah``.
- ``c20_rc`` and ``c20_2rc_lowsoc`` (:data:`C20_MODELS`): configurations of the model library
  (``model/ecm.py``) on the C/20 OCV table (``model/ocv.py``'s slow-test rule) plus a fitted
  offset, fitted by ``model.fitted.fit_model``: R0 and one RC; and with a second RC branch and
  resistances that rise at low SOC (``soc_resistance``).
- ``<prefix>_<effects>``: the diagnosis (``avoa_pipeline.gap.diagnose``) of training records, one
  row per rung of its ladder, ``<prefix>_selected`` the model it hands over (its model.json,
  docs/handover-rule.md: the model a user gets) and ``<prefix>_verdict`` the verdict's model
  (the ladder's last rung) (:func:`diagnosis_record`); the unseen cycles are its validation
  records, used for no choice.

**Initial SOC.** Unknown for a measured record. Every model takes it from the record's first
sample: the cell rests before each drive cycle, so its first voltage is the OCV less the ohmic
drop of the first second's current, and s0 solves OCV(s0) = V0 + R0·I0 through the model's own
(fitted) OCV: the library's one rule (``ecm.soc0_from_voltage``; for the rational OCV its closed
form ``ecm.rational_soc0``). In the paper-model fits this holds for every candidate, so the
fitted OCV and the start are consistent; the same rule starts each prediction.

Hand-written numerics: the ISE of one paper-model candidate is the package's compiled kernel
(``kernel.ise_serial``, the library's fast path for the paper's configuration), called per
candidate because s0 differs between candidates.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from ... import problem, seeds
from ...aggregate import median_position
from ...errors import ConfigError, DataError
from ...io import uniform_step
from ...model import ecm
from ...model.battery import PARAM_NAMES, first_sample_soc0, simulate_on_record
from ...model.fitted import fit_model, prediction_errors
from ...optimizers import ALGORITHMS, Budget, minimize

PAPER_MODELS = {"paper_rc": True, "paper_norc": False}  # name → dynamics (the RC branch)
C20_MODELS = {"c20_rc": (), "c20_2rc_lowsoc": ("second_rc", "soc_resistance")}
"""The C/20 circuits: name → the library elements added to the base (table OCV + offset, R0,
one RC, free capacity)."""


# --- the paper's model on a measured record ----------------------------------------------------


def paper_simulate(params: dict, frame: pd.DataFrame, dynamics: bool, qdis: float) -> np.ndarray:
    """The paper's model with ``params`` on a record, from its first sample
    (``battery.simulate_on_record``)."""
    p = np.array([float(params.get(n, 1.0 if n == "tau" else 0.0)) for n in PARAM_NAMES])
    return simulate_on_record(p, frame["current_a"].to_numpy(), frame["voltage_v"].to_numpy(),
                              _step(frame), dynamics, qdis)  # fmt: skip


def _step(frame: pd.DataFrame) -> float:
    return uniform_step("record", frame["time_s"].to_numpy())


# --- experiment settings and metrics -----------------------------------------------------------


def experiment(cfg: dict) -> dict:
    try:
        exp = cfg["real"]["panasonic"]["experiment"]
    except (KeyError, TypeError):
        raise ConfigError("config: field real.panasonic.experiment missing") from None
    temps = cfg["real"]["panasonic"]["temperatures"]
    for temp, cycle in exp["train"].items():
        if temp not in temps:
            raise ConfigError(f"config: field real.panasonic.experiment.train.{temp}: no such "
                              "temperature in real.panasonic.temperatures")  # fmt: skip
        if cycle not in temps[temp]["drive_cycles"]:
            raise ConfigError(f"config: field real.panasonic.experiment.train.{temp}: no drive "
                              f"cycle {cycle!r} at {temp}")  # fmt: skip
    for temp in exp.get("temperatures") or ():
        if temp not in exp["train"]:
            raise ConfigError(f"config: field real.panasonic.experiment.temperatures: {temp!r} has "
                              "no training cycle in real.panasonic.experiment.train")  # fmt: skip
    return exp


def temperatures(cfg: dict) -> list[str]:
    """The temperatures experiment 1 runs at: ``experiment.temperatures`` if given (a list, so
    that a smaller config laid over this one can narrow it; Snakemake merges mappings key by
    key), else every temperature of ``experiment.train``."""
    exp = experiment(cfg)
    return list(exp.get("temperatures") or exp["train"])


def unseen_cycles(cfg: dict, temp: str) -> list[str]:
    exp = experiment(cfg)
    cycles = cfg["real"]["panasonic"]["temperatures"][temp]["drive_cycles"]
    return [c for c in cycles if c != exp["train"][temp]]


def errors_mv(model_v: np.ndarray, frame: pd.DataFrame) -> dict:
    return prediction_errors(model_v, frame["voltage_v"].to_numpy())


# --- fits ------------------------------------------------------------------------------------


def fit_settings(cfg: dict, temp: str) -> dict:
    """What a paper-model fit at ``temp`` depends on beyond its data: the experiment's settings
    (bounds, budget, seeds, qdis_ah) and that temperature's training cycle, not the other
    temperatures, the list of optimizers, the figure or the gap and joint switches (a change to
    those neither reaches nor reruns it)."""
    exp = experiment(cfg)
    skip = ("train", "temperatures", "algorithms", "figure_cycle", "gap", "joint")
    return {**{k: v for k, v in exp.items() if k not in skip}, "train": exp["train"][temp]}


def paper_fit(exp: dict, base_seed: int, temp: str, model: str, algorithm: str,
              train: pd.DataFrame, tests: dict[str, pd.DataFrame]) -> dict:  # fmt: skip
    """All seeds of one optimizer on one paper model → a JSON-able record with predictions.
    ``exp``: :func:`fit_settings` of ``temp``."""
    if algorithm not in ALGORITHMS:
        raise ConfigError(f"unknown algorithm {algorithm!r}; choose from {', '.join(ALGORITHMS)}")
    if model not in PAPER_MODELS:
        raise ConfigError(f"unknown paper model {model!r}; choose from {', '.join(PAPER_MODELS)}")
    dynamics = PAPER_MODELS[model]
    names = PARAM_NAMES if dynamics else ("vnom", "q", "vdis", "r0")
    box = exp["bounds"]
    prob = problem.on_record(names, [box[n][0] for n in names], [box[n][1] for n in names],
                             train["current_a"].to_numpy(), train["voltage_v"].to_numpy(),
                             _step(train), dynamics, float(exp["qdis_ah"]))  # fmt: skip
    b = exp["budget"]
    budget = Budget(pop_size=int(b["pop_size"]), iterations=b.get("iterations"),
                    max_nfe=b.get("max_nfe"))  # fmt: skip
    prob.objective(((prob.lb + prob.ub) / 2)[None, :])  # compile/load before the clock starts
    runs = []
    for seed in exp["seeds"]:
        rng = seeds.stream(int(base_seed), "real-panasonic", temp, model, algorithm, int(seed))
        res = minimize(algorithm, prob.objective, prob.lb, prob.ub, budget, rng,
                       objective_one=prob.objective_one)  # fmt: skip
        params = dict(zip(names, map(float, res.best_x), strict=True))
        n = prob.voltage_v.size
        run = {
            "seed": int(seed),
            "params": params,
            "soc0_train": float(
                first_sample_soc0(
                    prob.full(res.best_x), prob.voltage_v[0], prob.current_a[0], prob.spec.qdis_ah
                )[0]
            ),
            "train_rmse_mv": 1e3 * float(np.sqrt(res.best_f / n)),
            "nfe": int(res.nfe),
            "wall_s": float(res.wall_s),
            "cycles": {},
        }
        for cycle, frame in tests.items():
            run["cycles"][cycle] = errors_mv(
                paper_simulate(params, frame, dynamics, prob.spec.qdis_ah), frame)  # fmt: skip
        runs.append(run)
    return {"temperature": temp, "model": model, "algorithm": algorithm, "runs": runs}


def median_run(runs: list[dict]) -> dict:
    """The run with the median training RMSE (``aggregate.median_position``)."""
    return runs[median_position([r["train_rmse_mv"] for r in runs])]


def fit_and_predict(train, config: ecm.Config, tests: dict[str, pd.DataFrame]) -> dict:
    """One library configuration fitted (``fit_model``) to ``train`` (a record or a list of them)
    and run on each record of ``tests``; the record keeps the fitted model (``to_json``). Each
    training record starts by the library's initial-SOC rule, as every prediction does (the
    hand-written C/20 circuits did the same; their numbers are reproduced: 17.3 / 46.8 mV)."""
    t0 = time.perf_counter()
    fit = fit_model(train, config)
    return {
        "effects": list(config.effects),
        "train_rmse_mv": fit.train_rmse_mv,
        "nfev": fit.nfev,
        "wall_s": time.perf_counter() - t0,
        "cycles": {c: errors_mv(fit.model.simulate(f), f) for c, f in tests.items()},
        "model": fit.model.to_json(),
    }


def c20_fits(temp: str, train: pd.DataFrame, tests: dict[str, pd.DataFrame],
             table: ecm.OcvTable) -> dict:  # fmt: skip
    """The C/20 circuits (:data:`C20_MODELS`) on the C/20 ``table``, fitted to the training cycle
    and run on the unseen ones."""
    return {
        "temperature": temp,
        "ocv": {"source": table.source, "how": table.how, "capacity_ah": table.capacity_ah},
        "models": {name: fit_and_predict(train, ecm.Config(effects, table), tests)
                   for name, effects in C20_MODELS.items()},
    }  # fmt: skip


VALIDATION_ERRORS = ("rmse_mv", "max_err_mv", "rmse_in_training_soc_mv", "share_in_training_soc")


def diagnosis_record(temp: str, report: dict, prefix: str, cycle_of: dict | None = None,
                     source: str = "diagnosis.json") -> dict:  # fmt: skip
    """The table's record of a diagnosis report (``diagnosis.json``) with validation rows: one
    model per rung of the ladder (``<prefix>_base``, ``<prefix>_<effects>``), the handed-over
    model (its rows named ``handed_over``, docs/handover-rule.md) as ``<prefix>_selected`` and
    the verdict's model again as ``<prefix>_verdict``. A report written before the hand-over rule
    (no ``handed_over``) gave the verdict's model as model.json: it is ``<prefix>_selected``
    there. ``cycle_of`` names the unseen cycle of each validation record (default: the record's
    own name). ``refused``: the validation records the diagnosis refused (``record``, its
    ``refusal``; ``diagnosis.diagnose``'s ``skip_refused_validation``), which have no rows."""
    refused = list(report.get("refused_validation", ()))
    if not report.get("validation") and not refused:
        raise DataError(f"{source}: field 'validation': missing (a diagnosis without --validate "
                        "records predicts no unseen cycle)")  # fmt: skip
    verdict = report["selected"]["name"]
    handed = report.get("handed_over")
    selected = handed["name"] if handed else verdict
    out = {
        "temperature": temp,
        "prefix": prefix,
        "train": report["source"],
        "ocv": report["ocv"],
        "verdict": report["verdict"],
        "ladder": [{"effect": r["effect"], "heldout_rmse_mv": r["heldout_rmse_mv"]}
                   for r in report["ladder"]],
        "selected": selected,
        "verdict_selected": verdict,
        "selected_heldout_rmse_mv": (handed or report["selected"])["heldout_rmse_mv"],
        "verdict_heldout_rmse_mv": report["selected"]["heldout_rmse_mv"],
        "diagnose_wall_s": report["wall_s"],
        "models": {},
        "refused": refused,
    }  # fmt: skip
    for row in report.get("validation") or ():
        cycle = row["record"] if cycle_of is None else cycle_of.get(row["record"])
        if cycle is None:
            raise DataError(f"{source}: field 'validation.record': {row['record']!r} is none of "
                            "the unseen cycles")  # fmt: skip
        for name in _names(row["model"], prefix, verdict, handed is not None):
            m = out["models"].setdefault(name, {"effects": row["effects"], "cycles": {},
                                                "train_rmse_mv": None})  # fmt: skip
            # a model of per-temperature sets has no one training SOC range: its rows carry
            # no in-range error (None here)
            m["cycles"][cycle] = {k: row.get(k) for k in VALIDATION_ERRORS}
    return out


def _names(model: str, prefix: str, verdict: str, handed: bool) -> list[str]:
    """The table's names of a validation row's model (:func:`diagnosis_record`)."""
    if model == "handed_over":
        return [f"{prefix}_selected"]
    names = [f"{prefix}_{model}"]
    if model == verdict:
        names.append(f"{prefix}_verdict" if handed else f"{prefix}_selected")
    return names


# --- the table ---------------------------------------------------------------------------------

TABLE_COLUMNS = ("temperature_c", "cycle", "model", "rmse_mv", "max_err_mv")


def table(records: list[dict], ambient: dict[str, float]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """``drive_cycle_rmse.csv`` (medians over seeds) and the per-seed rows behind it."""
    detail = []
    for rec in records:
        temp = rec["temperature"]
        if "runs" in rec:  # one paper model × optimizer, several seeds
            name = f"{rec['model']}_{rec['algorithm']}"
            for run in rec["runs"]:
                for cycle, err in run["cycles"].items():
                    detail.append({"temperature": temp, "cycle": cycle, "model": name,
                                   "seed": run["seed"], "train_rmse_mv": run["train_rmse_mv"],
                                   **err})  # fmt: skip
        else:  # the library's models: the C/20 circuits, a diagnosis's ladder
            for name, m in rec["models"].items():
                for cycle, err in m["cycles"].items():
                    detail.append({"temperature": temp, "cycle": cycle, "model": name,
                                   "seed": None, "train_rmse_mv": m["train_rmse_mv"],
                                   **err})  # fmt: skip
    det = pd.DataFrame(detail)
    if det.empty:
        return pd.DataFrame(columns=list(TABLE_COLUMNS)), det
    g = det.groupby(["temperature", "cycle", "model"], sort=False)
    summary = g[["rmse_mv", "max_err_mv"]].median().reset_index()
    summary.insert(0, "temperature_c", summary.pop("temperature").map(ambient))
    det.insert(0, "temperature_c", det["temperature"].map(ambient))
    return summary[list(TABLE_COLUMNS)], det
