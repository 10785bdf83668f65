"""SOC estimation on the unseen Panasonic drive cycles (issue 29; the protocol, written before any
unseen number, is docs/real-data.md "SOC estimation (issue 29)").

At each temperature the model the per-temperature diagnosis selected (its ``model.json``) runs
``estimate`` (``avoa_pipeline.estimate``) on that temperature's unseen cycles, four runs each
(:data:`RUNS`): the true start, the start off by ±:data:`START_OFFSET`, and the true start with
the current read off by :data:`BIAS_OF_PEAK` of the record's peak |I|. The truth is coulomb
counting with the tester's current from the true start, which the library's one initial-SOC
rule fixes from the record's opening (``FittedModel.initial_soc``). One flat row per cycle and
run, beside plain coulomb counting from the same guess with the same current.

``python -m avoa_pipeline.jobs.estimate --models DIR --canonical DIR --out CSV`` runs it
without Snakemake (DIR/<temperature>/model.json, the cycles of :data:`UNSEEN`;
``--one-model M`` instead runs one model at every temperature, issue 28's joint model).
"""

from __future__ import annotations

from itertools import product

import numpy as np
import pandas as pd

from ... import estimate, records
from ...model import ecm, heat
from ...model.fitted import FittedModel

START_OFFSET = 0.20
"""The issue's wrong starts: 20 points of SOC either way, not clipped to [0, 1] (docs)."""
BIAS_OF_PEAK = 0.01
"""The issue's current bias: 1 % of the record's peak |I|, added to the current read."""
RUNS = ("true_start", "start_plus_20", "start_minus_20", "bias_plus_1pct")

RULES = {"expected-error": {},
         "training-residual": {"noise": "training-residual", "adapt": False},
         "expected-error+bms-events": {"bms_events": True}}  # fmt: skip
"""The filter's rules each run is made with (docs/soc-filter.md part 7): issue 40's rule (the
expected error, adapted; the default), issue 29's (the training residual, no adaptation), and
issue 40's with the BMS events as pseudo-measurements."""

UNSEEN = {"25degC": ("cycle_1", "us06", "hwfet"), "10degC": ("us06",),
          "0degC": ("us06", "hwfet"), "-10degC": ("us06",)}  # fmt: skip
"""The unseen cycles of the rule of issue 28 (docs/real-data.md), the default of ``main``; the
workflow passes those of its config (``real_dc.unseen_cycles``)."""

COVERAGE_GOAL = (0.90, 0.99)
"""Issue 40's ±2σ coverage goal on every record."""

GOALS = {0.01: "goal 25 °C: 1 %", 0.02: "goal 0 °C: 2 %"}
"""The issue's RMSE goals after the window, drawn on the figure."""


def run_settings(model: FittedModel, frame: pd.DataFrame) -> dict[str, tuple[float, float, float]]:
    """Per run: (the filter's start guess, the bias added to the current, the true start)."""
    soc0 = model.initial_soc(model.record(frame))
    bias = BIAS_OF_PEAK * float(np.max(np.abs(frame["current_a"].to_numpy())))
    return {"true_start": (soc0, 0.0, soc0), "start_plus_20": (soc0 + START_OFFSET, 0.0, soc0),
            "start_minus_20": (soc0 - START_OFFSET, 0.0, soc0),
            "bias_plus_1pct": (soc0, bias, soc0)}  # fmt: skip


def cycle_rows(model: FittedModel, checked: records.Checked, temperature: str, cycle: str,
               source: str = "model.json", rules: dict | None = None) -> list[dict]:  # fmt: skip
    """The four runs on one cycle under each rule (``rules``, default :data:`RULES`), one flat
    row each; the record's ambient as the command reads it (``heat.ambient_if_any``)."""
    rows = []
    frame = checked.frame
    rec = model.record(frame)
    ambient = heat.ambient_if_any(checked)
    settings = run_settings(model, frame).items()
    for (rule, kw), (run, (guess, bias, soc0)) in product((rules or RULES).items(), settings):
        res = estimate.estimate_record(model, frame, guess, bias, soc0, source=source,
                                       ambient=ambient, **kw)  # fmt: skip
        s, f, cc = res.summary, res.summary["filter"], res.summary["coulomb_counting"]
        rows.append({
            "temperature": temperature, "cycle": cycle, "rule": rule, "run": run,
            "model": model.config.name, "starts_at_rest": ecm.starts_at_rest(rec),
            "soc0_true": soc0, "soc0_guess": guess, "current_bias_a": bias,
            **f, **{f"cc_{k}": v for k, v in cc.items()},
            "noise_rule": s["noise"]["rule"], "adapt": s["noise"]["adapt"],
            "largest_scale": s["noise"].get("largest_scale"),
            "bms_events_applied": _applied(s.get("bms_events")),
            "innovation_rms_mv": s["innovation_rms_mv"], "duration_s": s["duration_s"],
            "wall_s": s["wall_s"], "times_real_time": s["times_real_time"],
        })  # fmt: skip
    return rows


def _applied(events: dict | None) -> int | None:
    """How many BMS events moved the SOC (None: the rule ran without them)."""
    if events is None:
        return None
    return sum(e["applied"] for found in events.values() if isinstance(found, list)
               for e in found)  # fmt: skip


def soc_estimation_table(models: dict[str, str], tests: dict[str, dict[str, str]]) -> pd.DataFrame:
    """Every temperature's unseen cycles (``tests``: temperature → cycle → canonical CSV) with
    that temperature's model (``models``: temperature → model.json)."""
    rows = []
    for temp, cycles in tests.items():
        model = FittedModel.load(models[temp])
        for cycle, path in cycles.items():
            rows += cycle_rows(model, records.read(path), temp, cycle, str(models[temp]))
    return pd.DataFrame(rows)


def rule_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per temperature, cycle and rule, over the four runs: the RMSE after the window and the
    ±2σ coverage (in %, lowest-highest) and how many runs hold the coverage goal
    (:data:`COVERAGE_GOAL`), the speed's lowest; the rules in the table's order."""
    lo, hi = COVERAGE_GOAL
    rows = []
    keys = ["temperature", "cycle", "rule"] if "rule" in table.columns else ["temperature", "cycle"]
    for key, g in table.groupby(keys, sort=False):
        rmse, cov = 100 * g["rmse_after_window"], 100 * g["coverage_2sd"]
        rows.append({**dict(zip(keys, key, strict=True)),
                     "rmse_pct": f"{rmse.min():.2f}-{rmse.max():.2f}",
                     "coverage_pct": f"{cov.min():.1f}-{cov.max():.1f}",
                     "runs_in_goal": f"{int(g['coverage_2sd'].between(lo, hi).sum())}/{len(g)}",
                     "times_real_time_min": float(g["times_real_time"].min())})  # fmt: skip
    return pd.DataFrame(rows)
