"""SOC estimation's figures (issue 29), drawn from the estimate's own output.

- :func:`render`: one record (``estimate``'s SOC.png beside SOC.csv): the estimated SOC with its
  ±2σ band and, with a reference, the coulomb-counted truth; below, the error with the band, or
  the voltage innovation without a reference.
- :func:`soc_estimation_figure`: the experiment (``results/real/soc_estimation.png``/``.pdf``):
  the RMSE after the convergence window per unseen cycle and start, the issue's goals marked.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .figures import save

MAX_PLOT_POINTS = 5000  # a line of more points than a figure's pixels draws nothing more


def render(frame: pd.DataFrame, summary: dict, path, title: str = "") -> None:
    """One record's estimate to ``path`` (PNG)."""
    fig = Figure(figsize=(9, 6), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[2, 1])
    stride = max(1, int(np.ceil(len(frame) / MAX_PLOT_POINTS)))
    f = frame.iloc[::stride]
    th = (f["time_s"] - frame["time_s"].iloc[0]).to_numpy() / 3600.0
    soc, sd = f["soc"].to_numpy(), f["soc_sd"].to_numpy()
    top.fill_between(th, soc - 2 * sd, soc + 2 * sd, color="C0", alpha=0.25, lw=0, label="±2σ")
    top.plot(th, soc, color="C0", lw=1.0, label="filter")
    if "soc_reference" in f:
        full = summary.get("reference", {}).get("kind") == "full"
        how = "from SOC = 1 at each CC-CV end" if full else "from the known start"
        top.plot(th, f["soc_reference"], color="k", lw=0.8, ls="--",
                 label=f"coulomb counting {how}")  # fmt: skip
        err = f["soc_error"].to_numpy()
        bottom.fill_between(th, -2 * sd, 2 * sd, color="C0", alpha=0.25, lw=0)
        bottom.plot(th, err, color="C3", lw=0.8)
        bottom.axhline(0.02, color="0.5", lw=0.6, ls=":")
        bottom.axhline(-0.02, color="0.5", lw=0.6, ls=":")
        bottom.set_ylabel("SOC error")
        s = summary["filter"]
        top.set_title(f"{title} RMSE after 5 min {100 * s['rmse_after_window']:.2f} %, max "
                      f"{100 * s['max_error_after_window']:.2f} %, at the end "
                      f"{100 * s['error_at_end']:+.2f} %, ±2σ coverage "
                      f"{100 * s['coverage_2sd']:.0f} %; noise: {summary['noise']['rule']}",
                      fontsize=9)  # fmt: skip
    else:
        bottom.plot(th, 1e3 * f["innovation_v"].to_numpy(), color="C2", lw=0.6)
        bottom.set_ylabel("innovation (mV)")
        top.set_title(title, fontsize=9)
    t0 = frame["time_s"].iloc[0]
    for name, style in (("cc_cv_end", "C2"), ("lower_cutoff", "C1")):  # --bms-events
        for e in summary.get("bms_events", {}).get(name, []):
            top.axvline((e["time_s"] - t0) / 3600.0, color=style, lw=0.6,
                        ls="-" if e["applied"] else ":")  # fmt: skip
    top.set_ylabel("SOC")
    top.legend(fontsize=8, loc="best")
    bottom.set_xlabel("time (h)")
    fig.savefig(path, format="png")


def soc_estimation_figure(table: pd.DataFrame, stem, goals: dict | None = None) -> None:
    """The experiment's table as a figure: the filter's RMSE after the window per cycle (x) and
    run (bars), with plain coulomb counting from the same start as hollow marks; one panel per
    filter rule where the table has a ``rule`` column."""
    rules = list(dict.fromkeys(table["rule"])) if "rule" in table.columns else [None]
    fig = Figure(figsize=(10, 1.0 + 3.5 * len(rules)), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(len(rules), 1, sharex=True, squeeze=False)[:, 0])
    for ax, rule in zip(axes, rules, strict=True):
        rows = table if rule is None else table[table["rule"] == rule]
        _rmse_panel(ax, rows, goals, "" if rule is None else f"the filter's rule: {rule}")
    fig.suptitle("SOC estimation on the unseen Panasonic cycles (o: coulomb counting from the "
                 "same start with the same current; 0 from the true start)",
                 fontsize=9)  # fmt: skip
    save(fig, stem)


def _rmse_panel(ax, table: pd.DataFrame, goals: dict | None, title: str) -> None:
    cycles = list(dict.fromkeys(zip(table["temperature"], table["cycle"], strict=True)))
    runs = list(dict.fromkeys(table["run"]))
    width = 0.8 / max(len(runs), 1)
    for j, run in enumerate(runs):
        at = table[table["run"] == run].set_index(["temperature", "cycle"])
        x = np.arange(len(cycles)) + (j - (len(runs) - 1) / 2) * width
        y = [100 * at.loc[c, "rmse_after_window"] if c in at.index else np.nan for c in cycles]
        cc = [100 * at.loc[c, "cc_rmse_after_window"] if c in at.index else np.nan
              for c in cycles]  # fmt: skip
        ax.bar(x, y, width, color=f"C{j}", label=f"filter, {run}")
        ax.plot(x, cc, ls="none", marker="o", mfc="none", color=f"C{j}")
    for value, text in (goals or {}).items():  # goals as fractions of SOC, drawn in %
        ax.axhline(100 * value, color="0.4", lw=0.7, ls=":")
        ax.text(len(cycles) - 0.5, 100 * value, text, fontsize=7, va="bottom", ha="right")
    ax.set_xticks(np.arange(len(cycles)), [f"{t}\n{c}" for t, c in cycles], fontsize=8)
    ax.set_ylabel("SOC RMSE after 5 min (%)")
    ax.set_yscale("log")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, ncols=2)
