"""The one-page diagnosis figure: where the residual lives, the candidates' gains, and the voltage
and residual traces before and after the verdict effect.

Built on :class:`matplotlib.figure.Figure` directly (Agg canvas, no pyplot state), as
``report/figures.py`` does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

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
