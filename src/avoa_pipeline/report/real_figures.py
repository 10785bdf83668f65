"""The real-data experiments' figures, drawn from their tables alone (docs/real-data.md).

- :func:`drive_cycle_figure`: experiment 1, measured against predicted voltage on each
  temperature's figure cycle, with the error below; the paper model shown is its best optimizer
  by median RMSE (:func:`shown_models`).
- :func:`arrhenius_figure`: experiment 2, R0, Rtr, τ against SOC and their Arrhenius plots.
- :func:`fade_figure`: experiment 3, capacity and resistance against the fade laws.
- :func:`joint_temperature_figure`: issue 28, the unseen error against temperature, one model
  over every temperature beside each temperature's own.
- :func:`joint_heat_figure`: issue 28, the cell temperature of each unseen cycle predicted from
  the ambient alone against the thermocouple.

Each writes ``<stem>.png`` and ``<stem>.pdf`` with :func:`.figures.save`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from ..real.experiments.arrhenius import GAS_CONSTANT, ZERO_C
from ..real.experiments.fade import LAWS
from .figures import save


def shown_models(rmse: pd.DataFrame, temperature_c: float) -> list[str]:
    """The models drawn at one temperature: the best paper model with and without the RC
    branch and every other model (those with predicted voltages: the C/20 circuits and each
    diagnosis's selected model)."""
    at = rmse[rmse["temperature_c"] == temperature_c]
    med = at.groupby("model")["rmse_mv"].median()
    out = []
    for prefix in ("paper_rc_", "paper_norc_"):
        cands = med[med.index.str.startswith(prefix)]
        if len(cands):
            out.append(str(cands.idxmin()))
    out += [m for m in med.index if not m.startswith("paper_")]
    return out


def drive_cycle_figure(pred: pd.DataFrame, rmse: pd.DataFrame, ambient: dict[str, float],
                       stem) -> None:  # fmt: skip
    """Measured and predicted voltage of each temperature's figure cycle → stem.png, stem.pdf."""
    temps = list(dict.fromkeys(pred["temperature"]))
    fig = Figure(figsize=(10, 3.4 * max(1, len(temps))), layout="constrained")
    axes = fig.subplots(2 * max(1, len(temps)), 1, height_ratios=[2, 1] * max(1, len(temps)))
    for k, temp in enumerate(temps):
        ax_v, ax_e = axes[2 * k], axes[2 * k + 1]
        part = pred[pred["temperature"] == temp]
        cycle = part["cycle"].iloc[0]
        first = part[part["model"] == part["model"].iloc[0]]
        t_h = first["time_s"].to_numpy() / 3600.0
        measured = first["measured_v"].to_numpy()
        ax_v.plot(t_h, measured, color="k", lw=0.6, label="measured")
        tc = ambient.get(temp, np.nan)
        here = rmse[(rmse["temperature_c"] == tc) & (rmse["cycle"] == cycle)].set_index("model")
        for model in shown_models(rmse, tc):
            m = part[part["model"] == model]
            if m.empty:
                continue
            v = m["model_v"].to_numpy()
            r = here["rmse_mv"].get(model, np.nan)
            line = ax_v.plot(t_h, v, lw=0.6, label=f"{model} (RMSE {r:.0f} mV)")[0]
            ax_e.plot(t_h, 1e3 * (v - measured), lw=0.5, color=line.get_color())
        ax_v.set_ylabel("voltage [V]")
        ax_v.set_title(f"{temp}: {cycle} (not seen by any fit)", fontsize=10)
        ax_v.legend(fontsize=7, loc="lower left", ncol=2)
        ax_e.axhline(0.0, color="k", lw=0.4)
        ax_e.set_ylim(-150, 150)
        ax_e.set_ylabel("model − measured [mV]")
        ax_e.set_xlabel("time [h]")
    save(fig, stem)


_QUANTITY_LABELS = {
    "r0_step_ohm": ("$R_o$ (1 s step)", "mΩ", 1e3),
    "r0_fit_ohm": ("$R_o$ (fit)", "mΩ", 1e3),
    "rtr_ohm": ("$R_{tr}$", "mΩ", 1e3),
    "tau_s": (r"$\tau_{tr}$", "s", 1.0),
}


def arrhenius_figure(rc: pd.DataFrame, arr: pd.DataFrame, stem) -> None:
    """R0, Rtr, τ against SOC per temperature (top) and their Arrhenius plots (bottom)."""
    shown = ("r0_step_ohm", "rtr_ohm", "tau_s")
    fig = Figure(figsize=(11, 6.6), layout="constrained")
    axes = fig.subplots(2, 3)
    temps = sorted(rc["ambient_c"].unique())
    colors = dict(zip(temps, ("#1f77b4", "#2ca02c", "#d62728", "#9467bd", "#8c564b"), strict=False))
    for col, q in enumerate(shown):
        name, unit, scale = _QUANTITY_LABELS[q]
        ax = axes[0, col]
        for t in temps:
            sub = rc[rc["ambient_c"] == t].sort_values("soc_pct")
            ax.plot(sub["soc_pct"], sub[q] * scale, "o-", ms=3, color=colors[t], label=f"{t:g} °C")
        ax.set_xlabel("SOC [%] (nominal 3.0 Ah)")
        ax.set_ylabel(f"{name} [{unit}]")
        ax.invert_xaxis()
        ax.grid(alpha=0.3)
        if col == 0:
            ax.legend(fontsize=8)
        ax = axes[1, col]
        pool = rc[rc["pooled"]]
        ln = np.log(pool[q].to_numpy())
        adj = ln - pool.assign(ln=ln).groupby("pulse")["ln"].transform("mean").to_numpy()
        x = 1000.0 / (pool["cell_temp_c"].to_numpy() + ZERO_C)
        ax.scatter(x, adj, s=8, c=[colors[t] for t in pool["ambient_c"]], alpha=0.6)
        text = []
        for scope in ("pooled_pulses", "pooled_runs"):
            row = arr[(arr["quantity"] == q) & (arr["scope"] == scope)]
            if row.empty:
                continue
            r = row.iloc[0]
            text.append(
                f"{scope.replace('_', ' ')}: Ea = {r['ea_kj_mol']:.1f} kJ/mol, "
                f"95 % CI [{r['ea_ci_low_kj_mol']:.1f}, {r['ea_ci_high_kj_mol']:.1f}]"
            )
            if scope == "pooled_pulses":
                slope = r["ea_kj_mol"] * 1e3 / GAS_CONSTANT / 1000.0
                xx = np.linspace(x.min(), x.max(), 10)
                ax.plot(xx, slope * (xx - x.mean()) + adj.mean(), "k-", lw=1)
        ax.set_title("\n".join(text), fontsize=7)
        ax.set_xlabel("1000 / T [1/K] (cell temperature)")
        ax.set_ylabel(f"ln {name} − its SOC mean")
        ax.grid(alpha=0.3)
    fig.suptitle(
        "Samsung INR18650-30Q (cell DNN01) HPPC 1C pulses: 1-RC parameters against temperature",
        fontsize=10,
    )
    save(fig, stem)


_LAW_STYLE = {
    "sqrt": ("#d62728", "-", "√n (eqs. 8-9)"),
    "linear": ("#1f77b4", "--", "linear in n"),
    "power": ("#2ca02c", ":", "n^z, z free"),
}


def fade_figure(table: pd.DataFrame, fits: pd.DataFrame, stem) -> None:
    """Measured capacity and resistance against the fade laws (top), sqrt-law residuals (bottom)."""
    fig = Figure(figsize=(11, 6.6), layout="constrained")
    axes = fig.subplots(2, 2, sharex=True, height_ratios=(2, 1))
    k = table["discharge"].to_numpy()
    rest = table["after_long_rest"].to_numpy(dtype=bool)
    for col, (q, label, scale) in enumerate(
        (
            ("capacity_ah", "capacity to 2.7 V [Ah]", 1.0),
            ("resistance_ohm", "20-s DC resistance [mΩ]", 1e3),
        )
    ):
        ax = axes[0, col]
        y = table[q].to_numpy() * scale
        ax.plot(k, y, "o", ms=3, color="0.35", label="measured")
        ax.plot(k[rest], y[rest], "o", ms=7, mfc="none", color="#ff7f0e", label="after a long rest")
        for law in LAWS:
            color, ls, text = _LAW_STYLE[law]
            f = fits[(fits["quantity"] == q) & (fits["law"] == law)].iloc[0]
            ax.plot(
                k,
                table[f"{q}_{law}"] * scale,
                ls,
                color=color,
                lw=1.5,
                label=f"{text}: RMSE {f['rmse'] * scale:.3g}, ΔAIC {f['delta_aic']:.1f}"
                + (f", z = {f['z']:.2f}" if law == "power" else ""),
            )
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        ax = axes[1, col]
        ax.axhline(0, color="0.5", lw=0.8)
        resid = (table[q] - table[f"{q}_sqrt"]).to_numpy() * scale
        ax.plot(k, resid, "-", color="#d62728", lw=0.8)
        ax.plot(k[rest], resid[rest], "o", ms=6, mfc="none", color="#ff7f0e")
        ax.set_ylabel("measured − √n law")
        ax.set_xlabel("discharge k (n = k − 1)")
        ax.grid(alpha=0.3)
    fig.suptitle(
        "NASA PCoE B0005, 2 A discharges at 168 ageing states: the paper's fade law", fontsize=10
    )
    save(fig, stem)


def joint_temperature_figure(df: pd.DataFrame, stem) -> None:
    """RMSE on each unseen cycle against temperature (``joint_temperature.csv``): the model
    fitted over every temperature (filled) beside each temperature's own (open); the lines join
    the medians over each temperature's cycles (the comparison docs/real-data.md reports)."""
    fig = Figure(figsize=(6.4, 4.2), layout="constrained")
    ax = fig.subplots()
    med = df.groupby("temperature_c")[["joint_rmse_mv", "per_temperature_rmse_mv"]].median()
    for col, label, color, fill in (
        ("joint_rmse_mv", "one model, every temperature", "#1f77b4", True),
        ("per_temperature_rmse_mv", "each temperature's own model", "#d62728", False),
    ):
        ax.plot(df["temperature_c"], df[col], "o", ms=6, color=color,
                mfc=color if fill else "none", alpha=0.8)  # fmt: skip
        ax.plot(med.index, med[col], "-", color=color, lw=1.5, label=f"{label} (median)")
    ax.set_yscale("log")
    ax.set_xlabel("chamber temperature [°C]")
    ax.set_ylabel("RMSE on the unseen cycles [mV]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.suptitle("Panasonic NCR18650PF: unseen drive cycles, predicted with the measured "
                 "temperature", fontsize=9)  # fmt: skip
    save(fig, stem)


def joint_heat_figure(traces: pd.DataFrame, df: pd.DataFrame, stem) -> None:
    """The cell temperature predicted from the ambient alone (the joint model's heat block)
    against the thermocouple, one panel per unseen cycle (``joint_temperature_heat.csv``), its
    RMSE from ``joint_temperature.csv`` in the panel's title; a note where the joint model has
    no heat block (no traces)."""
    keys = list(dict.fromkeys(traces["key"]))
    cols = 2
    rows = max(1, -(-len(keys) // cols))
    fig = Figure(figsize=(7.2, 1.9 * rows + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False).ravel())
    rmse = {f"{r.temperature_c:g} °C {r.cycle}": r.temperature_rmse_k for r in df.itertuples()}
    for ax, k in zip(axes, keys, strict=False):
        tr = traces[traces["key"] == k]
        minutes = (tr["time_s"] - tr["time_s"].iloc[0]) / 60.0
        ax.plot(minutes, tr["temperature_c"], "-", color="0.2", lw=1.0, label="thermocouple")
        ax.plot(minutes, tr["temperature_c_predicted"], "-", color="#d62728", lw=1.0,
                label="predicted from the ambient")  # fmt: skip
        temp, cycle = k.split("/", 1)
        name = f"{float(temp.removesuffix('degC')):g} °C {cycle}"
        ax.set_title(f"{name}: {rmse.get(name, np.nan):.2f} K RMS", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
        ax.set_ylabel("cell [°C]", fontsize=7)
    for ax in axes[len(keys) :]:
        ax.axis("off")
    if keys:
        axes[0].legend(fontsize=7)
        for ax in axes[max(len(keys) - cols, 0) : len(keys)]:
            ax.set_xlabel("time [min]", fontsize=7)
    else:
        axes[0].text(0.5, 0.5, "the joint model has no heat block", ha="center", va="center")
    fig.suptitle("Panasonic NCR18650PF, unseen drive cycles: the cell temperature predicted "
                 "from the ambient alone\n(one model of every temperature, its heat block)",
                 fontsize=9)  # fmt: skip
    save(fig, stem)
