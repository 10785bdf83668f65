"""The gap diagnosis's figures.

- :func:`render`: the one-page diagnosis figure: where the residual lives, the candidates' gains,
  and the voltage and residual traces before and after the verdict effect.
- :func:`fig_confusion`, :func:`fig_accuracy`, :func:`fig_shrink`, :func:`fig_detection_limit`:
  the withheld-effect check (:mod:`..gap.evaluate`), from its tables.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..gap import EFFECTS, VERDICTS
from ..gap.evaluate import RATIO_EDGES, TARGET, THRESHOLD, confusion, ratio_bin_labels
from .figures import save

MAX_PLOT_POINTS = 20000  # traces are thinned by a stride beyond this (drawing only)

_GROUP_COLOURS = {
    "mode": "#4c72b0",
    "direction": "#55a868",
    "since_step": "#c44e52",
    "soc": "#8172b2",
    "current": "#ccb974",
    "temperature": "#64b5cd",
}


def render(report: dict, arrays: dict, path: str | Path) -> None:
    """Write the figure to ``path`` (PNG)."""
    fig = Figure(figsize=(12, 12), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    gs = fig.add_gridspec(4, 2, height_ratios=[1.1, 1.0, 1.5, 0.35])
    stride = max(1, int(np.ceil(arrays["t"].size / MAX_PLOT_POINTS)))
    sl = slice(None, None, stride)
    th = (arrays["t"] - arrays["t"][0])[sl] / 3600.0
    verdict = report["verdict"]["effect"]
    after_v = arrays["v_verdict"] if arrays["v_verdict"] is not None else None
    after_ho = arrays["ho_verdict"]
    noise = report["base"]["noise_floor_mv"]

    ax = fig.add_subplot(gs[0, :])
    ax.plot(th, arrays["v"][sl], color="k", lw=1.0, label="measured")
    ax.plot(th, arrays["v_base"][sl], color="#c44e52", lw=0.9, label="base model (full fit)")
    if after_v is not None:
        ax.plot(th, after_v[sl], color="#4c72b0", lw=0.9, ls="--", label=f"base + {verdict}")
    ax.set_ylabel("voltage (V)")
    ax2 = ax.twinx()
    ax2.plot(th, arrays["i"][sl], color="0.6", lw=0.6)
    ax2.set_ylabel("current (A, + discharge)", color="0.45")
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title(
        f"{report['source']}: verdict {verdict}"
        + (f" (held-out shrink {report['verdict']['shrink']:.0%})" if verdict != "none" else "")
        + f"; base RMSE {report['base']['rmse_mv']:.2f} mV, noise floor {noise:.2f} mV",
        fontsize=10,
    )

    ax = fig.add_subplot(gs[1, :], sharex=fig.axes[0])
    ax.plot(th, 1e3 * (arrays["v"] - arrays["ho_base"])[sl], color="#c44e52", lw=0.6,
            label="base, held out")  # fmt: skip
    if after_ho is not None:
        ax.plot(th, 1e3 * (arrays["v"] - after_ho)[sl], color="#4c72b0", lw=0.6,
                label=f"base + {verdict}, held out")  # fmt: skip
    ax.axhspan(-noise, noise, color="0.85", zorder=0, label="± noise floor")
    # the folds the selection used: a line wherever the held-out part changes
    fold = arrays["fold"]
    t_all = (arrays["t"] - arrays["t"][0]) / 3600.0
    for k in np.flatnonzero(np.diff(fold)) + 1:
        ax.axvline(t_all[k], color="0.5", lw=0.5, ls=":")
    held = "held-out records" if arrays.get("by_record") else "held-out blocks"
    ax.set_xlabel(f"time (h, records end to end); dotted: {held}")
    ax.set_ylabel("measured − model (mV)")
    ax.legend(loc="upper right", fontsize=8)

    _localization(fig.add_subplot(gs[2, 0]), report)
    _candidates(fig.add_subplot(gs[2, 1]), report)

    ax = fig.add_subplot(gs[3, :])
    ax.axis("off")
    ax.text(0, 1, _summary(report), va="top", ha="left", fontsize=8.5, family="monospace")
    # not figures.save: ``path`` is the caller's temporary file, one of the diagnosis's
    # all-or-none outputs (cli diagnose), and the page keeps its own 110 dpi
    fig.savefig(path, format="png")


def _localization(ax, report):
    regions = report["localization"]
    names = [r["region"] for r in regions]
    y = np.arange(len(regions))[::-1]
    ax.barh(y, [r["rmse_mv"] for r in regions],
            color=[_GROUP_COLOURS.get(r["group"], "0.5") for r in regions])  # fmt: skip
    for yy, r in zip(y, regions, strict=True):
        ax.text(r["rmse_mv"], yy, f" {r['share']:.0%} of energy, {r['time_share']:.0%} of time",
                va="center", fontsize=7)  # fmt: skip
    ax.axvline(report["base"]["noise_floor_mv"], color="k", ls="--", lw=0.8, label="noise floor")
    ax.set_yticks(y, names, fontsize=7.5)
    ax.set_xlabel("base residual RMSE in region (mV)")
    ax.set_title(f"Where the residual lives (gap region: {report['gap_region']})", fontsize=9)
    ax.legend(loc="lower right", fontsize=7)
    ax.margins(x=0.45)


def _candidates(ax, report):
    rows = [c for c in report["candidates"] if c.get("applicable")]
    rows += [c for c in report["candidates"] if not c.get("applicable")]
    y = np.arange(len(rows))[::-1]
    shrink = [c["shrink"] if c.get("shrink") is not None else 0.0 for c in rows]
    colours = ["#55a868" if c.get("pays") else "0.7" for c in rows]
    ax.barh(y, shrink, color=colours)
    for yy, c, s in zip(y, rows, shrink, strict=True):
        if not c.get("applicable"):
            txt = f" n/a: {c['reason']}"
        else:
            dbic = c["delta_bic"]
            txt = f" ΔBIC {dbic:.0f}" if dbic is not None else ""
            if c.get("t") is not None:
                txt += f", t {c['t']:.1f}"
        ax.text(max(s, 0.0), yy, txt, va="center", fontsize=7)
    ax.axvline(0, color="k", lw=0.6)
    ax.set_yticks(y, [c["effect"] for c in rows], fontsize=8)
    ax.set_xlim(min(-0.1, min(shrink) - 0.05), 1.45)
    ax.set_xlabel("held-out shrink (fraction of held-out ISE removed)")
    ax.set_title("Candidates (green: pays — held-out test and ΔBIC < −10)", fontsize=9)


def _summary(report):
    v = report["verdict"]
    lines = []
    if v["effect"] == "none":
        lines.append(
            f"Verdict: none — no candidate beats the base model by more than noise explains "
            f"(best: {v.get('best_candidate')}, "
            f"held-out shrink {v.get('best_candidate_shrink', 0):.1%})."
        )
    else:
        lines.append(
            f"Verdict: {v['effect']}. Held-out RMSE {v['heldout_rmse_before_mv']:.2f} → "
            f"{v['heldout_rmse_after_mv']:.2f} mV overall; in '{v['region']}' "
            f"{v['region_heldout_rmse_before_mv']:.2f} → "
            f"{v['region_heldout_rmse_after_mv']:.2f} mV."
        )
    if report["ladder"]:
        steps = " → ".join(
            f"{s['effect']} ({s['heldout_rmse_mv']:.2f} mV)" for s in report["ladder"]
        )
        lines.append(f"Ladder: base ({report['base']['heldout_rmse_mv']:.2f} mV) → {steps}")
    p = report["base"]["parameters"]
    # numbers only: with several training records the initial states are a per-record list
    lines.append("Base: " + ", ".join(f"{k}={val:.4g}" for k, val in p.items()
                                      if isinstance(val, int | float)))  # fmt: skip
    return "\n".join(lines)


def fig_confusion(records_df: pd.DataFrame, stem) -> None:
    """Confusion matrices, all datasets and detectable ones (with the controls), row shares
    as colour and counts as text."""
    df = records_df
    parts = [
        ("all datasets", None),
        ("detectable effects and controls", df["detectable"] | (df["effect"] == "none")),
    ]
    fig = Figure(figsize=(13, 5.6), layout="constrained")
    axes = fig.subplots(1, 2)
    for ax, (title, only) in zip(axes, parts, strict=True):
        table = confusion(df, only)
        share = table.div(table.sum(axis=1).replace(0, np.nan), axis=0).fillna(0.0)
        ax.imshow(share.to_numpy(), cmap="Blues", vmin=0, vmax=1)
        for (i, j), n in np.ndenumerate(table.to_numpy()):
            if n:
                ax.text(
                    j,
                    i,
                    str(n),
                    ha="center",
                    va="center",
                    color="white" if share.iat[i, j] > 0.6 else "black",
                    fontsize=8,
                )
        ax.set_xticks(range(len(table.columns)), table.columns, rotation=60, ha="right",
                      fontsize=8)  # fmt: skip
        ax.set_yticks(range(len(table.index)), table.index, fontsize=8)
        ax.set_xlabel("verdict")
        ax.set_ylabel("withheld effect")
        ax.set_title(f"{title} (n = {int(table.to_numpy().sum())})", fontsize=10)
    save(fig, stem, pdf=False)


def fig_accuracy(acc: pd.DataFrame, stem, goal: float = TARGET) -> None:
    fig = Figure(figsize=(10, 4.2), layout="constrained")
    ax = fig.subplots()
    x = np.arange(len(acc))
    ax.bar(x - 0.2, acc["accuracy"].fillna(0), 0.4, label="all datasets", color="0.7")
    ax.bar(
        x + 0.2,
        acc["accuracy_detectable"].fillna(0),
        0.4,
        label="detectable (controls: all)",
        color="tab:blue",
    )
    for xi, (n, nd) in enumerate(zip(acc["n"], acc["n_detectable"], strict=True)):
        ax.text(xi, 1.02, f"{n}/{nd}", ha="center", fontsize=7)
    ax.axhline(goal, color="tab:red", ls="--", lw=1, label=f"target {goal:.0%}")
    ax.set_xticks(x, acc["effect"], rotation=30, ha="right", fontsize=8)
    ax.set_ylim(0, 1.1)
    ax.set_ylabel("right verdicts")
    ax.set_title(
        "Accuracy per withheld effect (numbers: datasets / detectable datasets)", fontsize=10
    )
    ax.legend(fontsize=8, loc="lower left")
    save(fig, stem, pdf=False)


def fig_shrink(records_df: pd.DataFrame, stem) -> None:
    fig = Figure(figsize=(10, 4.2), layout="constrained")
    ax = fig.subplots()
    said = records_df[records_df["verdict"] != "none"]
    for xi, effect in enumerate(VERDICTS):
        for right, colour, dx in ((True, "tab:blue", -0.12), (False, "tab:red", 0.12)):
            s = said.loc[(said["effect"] == effect) & (said["right"] == right), "shrink"]
            jitter = np.linspace(-0.06, 0.06, len(s)) if len(s) > 1 else np.zeros(len(s))
            ax.scatter(
                xi + dx + jitter,
                s,
                s=12,
                color=colour,
                alpha=0.7,
                label=("verdict right" if right else "verdict wrong") if xi == 0 else None,
            )
    ax.set_xticks(range(len(VERDICTS)), VERDICTS, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("shrink (held-out ISE removed)")
    ax.set_title("Shrink of the verdict effect, per withheld effect", fontsize=10)
    ax.legend(fontsize=8)
    save(fig, stem, pdf=False)


def fig_detection_limit(dl: pd.DataFrame, stem, threshold: float = THRESHOLD) -> None:
    """Right verdicts against effect residual / noise RMSE, per effect, for each noise level."""
    noises = list(dict.fromkeys(dl["noise_mv"]))
    fig = Figure(figsize=(4.6 * len(noises), 4.2), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(noises), sharey=True))
    labels = ratio_bin_labels()
    for ax, noise in zip(axes, noises, strict=True):
        part = dl[dl["noise_mv"] == noise]
        for effect in [*EFFECTS, "all effects"]:
            rows = part[(part["effect"] == effect) & (part["n"] > 0)]
            if rows.empty:
                continue
            x = [labels.index(b) for b in rows["ratio_bin"]]
            bold = effect == "all effects"
            ax.plot(
                x,
                rows["accuracy"],
                marker="o",
                ms=3 if not bold else 5,
                lw=2.5 if bold else 1,
                color="black" if bold else None,
                label=effect,
            )
        # the threshold sits on a bin edge: between the bins below and above it
        edge = sum(e <= threshold for e in RATIO_EDGES[1:]) - 0.5
        ax.axvline(edge, color="tab:red", ls="--", lw=1)
        ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right", fontsize=8)
        ax.set_xlabel("effect residual / noise RMSE")
        title = "all noise levels" if noise == "all" else f"noise {noise} mV"
        ax.set_title(title, fontsize=10)
        ax.set_ylim(-0.05, 1.05)
    axes[0].set_ylabel("right verdicts")
    axes[-1].legend(fontsize=7, loc="lower right")
    save(fig, stem, pdf=False)
