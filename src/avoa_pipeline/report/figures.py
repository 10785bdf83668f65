"""Figures 1-21 of Fahmy et al. 2023 (Mathematics 11, 2215), drawn from the pipeline's outputs.

Every drawing function writes ``<stem>.png`` (150 dpi) and ``<stem>.pdf`` and returns ``None``.
Both files are rendered to temporary files beside the targets and renamed only when both
rendered, so a failure leaves neither (nor half of either) behind. Inputs are checked before
anything is drawn.

Figures are built on :class:`matplotlib.figure.Figure` objects directly, without pyplot: the Agg
canvas renders them, nothing is registered in pyplot's figure manager (so nothing is kept in
memory after a call and nothing needs closing), and the interactive backend of a notebook that
imports this module is left alone.

- :func:`fig01`: the 1-RC equivalent circuit (Figure 1), with the 1 kΩ load of scenarios 3-4.
- :func:`fig02`: the test profile, current and voltage against time, intervals i0-i4 (Figure 2).
- :func:`fig03`: the AVOA flowchart (Figure 3), drawn from :mod:`..optimizers.avoa` (its branch
  conditions and parameter defaults are read from the code).
- :func:`convergence`: Figures 4-19, median best-ISE over seeds with the interquartile band,
  against iterations and against objective evaluations; numbers from :func:`convergence_bands`.
- :func:`fig20` / :func:`fig21`: scenario 4 case 4 before / after optimisation (Figures 20, 21).
- :func:`fig_budget` (beyond the paper): fixed-budget curves of one scenario, ECDFs of the
  evaluations to reach excess targets and the mean per-seed rank against evaluations (E8).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.patches import FancyBboxPatch, Polygon

from ..io import atomic_path, atomic_paths
from ..model.battery import CASES, PARAM_LABELS, PARAM_NAMES
from ..optimizers import ALGORITHMS, PAPER_LABELS
from ..optimizers import avoa as avoa_mod
from . import budget, stats
from .stats import EXCESS_TARGETS

DPI = 150
"""Resolution of the PNG files (the PDF files are vector graphics)."""

ISE_FLOOR = 1e-12
"""V². Plotted ISE values are clipped at this floor so a zero ISE (noise-free data fitted
exactly) stays drawable on the logarithmic axis; the statistics themselves are not clipped."""

ALGORITHM_COLORS = {
    "nelder_mead": "#1f77b4",
    "quasi_newton": "#ff7f0e",
    "ga": "#2ca02c",
    "gwo": "#9467bd",
    "run": "#8c564b",
    "avoa": "#d62728",
    "gto": "#17becf",
}
"""One fixed colour per algorithm in every figure (AVOA, the paper's method, in red)."""

ALGORITHM_STYLES = {"nelder_mead": "--", "quasi_newton": "--"}
"""Line styles (solid unless listed): the two local searches dashed, for greyscale prints."""

HISTORY_COLUMNS = ("scenario", "case", "algorithm", "seed", "iteration", "best_ise", "nfe")
"""Columns of ``histories.parquet`` (docs/records.md) that :func:`convergence` needs."""

RUN_EST_PREFIX = "est_"
"""Column prefix of the estimates in ``runs.parquet`` (``est_vnom``, ...)."""

_SCENARIO_TEXT = {
    1: "no load, no fade",
    2: "fade, no load",
    3: "1 kΩ load, no fade",
    4: "1 kΩ load and fade",
}


# --------------------------------------------------------------------------------------------
# helpers


def figure_number(scenario: int, case: int) -> int:
    """The paper's number of the convergence figure of ``scenario`` × ``case`` (4 ... 19)."""
    for name, value in (("scenario", scenario), ("case", case)):
        if isinstance(value, bool) or int(value) != value or not 1 <= value <= 4:
            raise ValueError(f"{name} must be an integer in 1..4, got {value!r}")
    return 4 + 4 * (int(scenario) - 1) + (int(case) - 1)


def describe(scenario: int, case: int) -> str:
    """One line naming what a scenario × case contains (Sec. 4 of the paper)."""
    c = CASES[case]
    dyn = "with charge dynamics" if c.dynamics else "without charge dynamics"
    temp = "T1 = 25 °C" if c.temperature == "T1" else "T2 = 45 °C"
    return f"{_SCENARIO_TEXT[scenario]}; {dyn}, {temp}"


def _paths(stem) -> tuple[Path, Path]:
    stem = Path(stem)
    # not with_suffix: a stem may itself contain dots ("fig04.v2")
    return stem.with_name(stem.name + ".png"), stem.with_name(stem.name + ".pdf")


def save(fig: Figure, stem, pdf: bool = True) -> None:
    """The package's one way to write a figure: ``fig`` to ``<stem>.png`` (at DPI) and, with
    ``pdf``, ``<stem>.pdf``; all or none appear (``io.atomic_paths``)."""
    png, pdf_path = _paths(stem)
    paths = (png, pdf_path) if pdf else (png,)
    with atomic_paths(*paths) as tmps:
        fig.savefig(tmps[0], format="png", dpi=DPI)
        if pdf:  # no creation date: the same inputs give the same PDF bytes
            fig.savefig(tmps[1], format="pdf", metadata={"CreationDate": None})


_MATH_SYMBOLS = {
    "vnom": r"$V_{nom}$",
    "q": r"$Q$",
    "vdis": r"$V_{dis}$",
    "r0": r"$R_o$",
    "rtr": r"$R_{tr}$",
    "tau": r"$\tau_{tr}$",
}


def _label(name: str, value: float) -> str:
    """``V_nom = 3.93 V`` with the symbol in mathtext and the unit of ``PARAM_LABELS``."""
    return f"{_MATH_SYMBOLS[name]} = {value:.6g} {PARAM_LABELS[name][1]}"


# --------------------------------------------------------------------------------------------
# Figure 1: equivalent circuit


def fig01(stem) -> None:
    """Figure 1: the paper's 1-RC model (eqs. 1-6) and the optional 1 kΩ load of scenarios 3-4.

    OCV source Vocv(SOC) (eq. 5), series ohmic resistance R_o, the transient branch R_tr ∥ C_tr
    (τ_tr = R_tr C_tr) with its voltage V_tr, the terminals with V_t and the battery current
    I_batt (positive = discharge). The load (dashed) is present in scenarios 3 and 4 only; there
    the cycler's (logged) current is I_p = I_batt − V_t / R_L.
    """
    import schemdraw
    import schemdraw.elements as elm

    fig = Figure(figsize=(8.0, 3.9))
    ax = fig.add_axes((0.02, 0.16, 0.96, 0.82))
    d = schemdraw.Drawing(canvas=ax, show=False)
    d.config(unit=2.6, fontsize=12)

    h = 0.9  # half the spacing of the R_tr and C_tr branches
    src = d.add(elm.SourceV().up().label(r"$V_{ocv}(SOC)$", loc="bottom", ofst=0.35))
    d.add(elm.Resistor().right().label(r"$R_o$"))
    a = d.here
    d.add(elm.Line().up(h))
    d.add(elm.Resistor().right().label(r"$R_{tr}$"))
    d.add(elm.Line().down(h))
    b = d.here
    d.add(elm.Line().at(a).down(h))
    d.add(elm.Capacitor().right().label(r"$C_{tr}$", loc="bottom"))
    d.add(elm.Line().up(h))
    d.add(elm.Gap().at((a[0] + 0.35, a[1])).to((b[0] - 0.35, b[1])).label(("+", r"$V_{tr}$", "−")))
    top = d.add(elm.Line().at(b).right(2.6))
    d.add(elm.CurrentLabel(ofst=0.25, length=1.2).at(top).label(r"$I_{batt}$"))
    plus = d.add(elm.Dot(open=True))
    d.add(elm.Line().at(src.start).right().tox(plus.center))
    minus = d.add(elm.Dot(open=True))
    d.add(elm.Gap().at(plus.center).to(minus.center).label(("+", r"$V_t$", "−"), ofst=0.45))
    # the load of scenarios 3-4 (dashed: optional)
    grey = "dimgray"
    d.add(elm.Line().at(plus.center).right(2.4).linestyle("--").color(grey))
    d.add(
        elm.Resistor()
        .down()
        .toy(minus.center)
        .color(grey)
        .label(r"$R_L$ = 1 kΩ" "\n(scenarios 3–4)", loc="bottom", ofst=0.3)
    )
    d.add(elm.Line().left().tox(minus.center).linestyle("--").color(grey))
    try:
        d.draw(show=False)
        bb = d.get_bbox()
        ax.set_xlim(bb.xmin - 0.3, bb.xmax + 2.6)  # room for the load's label
        ax.set_ylim(bb.ymin - 0.3, bb.ymax + 0.3)
        ax.set_aspect("equal")
        ax.set_axis_off()
        fig.text(
            0.5,
            0.035,
            "Figure 1. Li-ion battery model (1-RC, eqs. 1–6). $I_{batt}$ > 0 discharging; "
            r"$\tau_{tr} = R_{tr}C_{tr}$."
            "\nGrey, dashed: the 1 kΩ load of scenarios 3–4, where the logged (cycler) current is "
            r"$I_p = I_{batt} - V_t/R_L$.",
            ha="center",
            fontsize=9,
        )
        save(fig, stem)
    finally:
        fig.clear()


# --------------------------------------------------------------------------------------------
# Figure 2: the test profile

_SEGMENT_COLORS = ("#f2f2f2", "#fde0dd", "#e5f5e0", "#deebf7", "#f2f2f2")


def _shade_segments(axes, segments: Sequence[Mapping], label_ax=None, scale: float = 1.0):
    for k, seg in enumerate(segments):
        for ax in axes:
            ax.axvspan(
                seg["start_s"] * scale,
                seg["end_s"] * scale,
                color=_SEGMENT_COLORS[k % len(_SEGMENT_COLORS)],
                zorder=0,
                lw=0,
            )
            if k:
                ax.axvline(seg["start_s"] * scale, color="0.6", lw=0.6, ls=":", zorder=1)
        if label_ax is not None:
            name = str(seg["name"])
            text = f"$i_{{{name[1:]}}}$" if name[:1] == "i" and name[1:].isdigit() else name
            label_ax.text(
                0.5 * (seg["start_s"] + seg["end_s"]) * scale,
                1.02,
                text,
                transform=label_ax.get_xaxis_transform(),
                ha="center",
                va="bottom",
                fontsize=10,
            )


def fig02(dataset, stem) -> None:
    """Figure 2: current and terminal voltage against time, intervals i0-i4 shaded and named.

    ``dataset`` is a :class:`avoa_pipeline.synthetic.Dataset` (``meta["segments"]`` gives the
    intervals: name, start_s, end_s). The current is the cycler's (logged) current, positive =
    discharge, as in the CSV.
    """
    segments = dataset.meta.get("segments")
    if not segments:
        raise ValueError("fig02: dataset.meta has no 'segments' (name, start_s, end_s) to shade")
    for k, seg in enumerate(segments):
        missing = [key for key in ("name", "start_s", "end_s") if key not in seg]
        if missing:
            raise ValueError(f"fig02: dataset.meta['segments'][{k}] lacks {', '.join(missing)}")
    t = np.asarray(dataset.time_s, dtype=float) / 60.0
    fig = Figure(figsize=(8.0, 5.6), layout="constrained")
    try:
        ax_i, ax_v = fig.subplots(2, 1, sharex=True)
        _shade_segments((ax_i, ax_v), segments, label_ax=ax_i, scale=1 / 60.0)
        ax_i.plot(t, dataset.current_a, color="#08519c", lw=1.2)
        ax_i.axhline(0.0, color="0.3", lw=0.6)
        ax_i.set_ylabel("current $I$ (A)\n(> 0 discharge)")
        ax_v.plot(t, dataset.voltage_v, color="#a50f15", lw=1.0)
        ax_v.set_ylabel("terminal voltage $V_t$ (V)")
        ax_v.set_xlabel("time (min)")
        ax_v.set_xlim(t[0], t[-1])
        meta = dataset.meta
        where = ""
        if "scenario" in meta and "case" in meta:
            where = f" — scenario {meta['scenario']}, case {meta['case']}"
        fig.suptitle(
            "Figure 2. Output voltage and current during discharging and charging" + where,
            fontsize=10.5,
        )
        save(fig, stem)
    finally:
        fig.clear()


# --------------------------------------------------------------------------------------------
# Figure 3: the AVOA flowchart


def avoa_settings() -> dict:
    """The AVOA parameters and their defaults, read from :func:`..optimizers.avoa.avoa`."""
    sig = inspect.signature(avoa_mod.avoa)
    out = {
        name: p.default
        for name, p in sig.parameters.items()
        if p.default is not inspect.Parameter.empty
    }
    out["levy_beta"] = avoa_mod.LEVY_BETA
    out["levy_sigma"] = avoa_mod.levy_sigma()
    return out


def _box(ax, x, y, w, h, text, *, fc="#ffffff", ec="0.2", round_=False, fontsize=7.6):
    style = "round,pad=0.02,rounding_size=0.25" if round_ else "square,pad=0.02"
    ax.add_patch(FancyBboxPatch((x - w / 2, y - h / 2), w, h, boxstyle=style, fc=fc, ec=ec, lw=1.0))
    ax.text(x, y, text, ha="center", va="center", fontsize=fontsize, linespacing=1.35)


def _diamond(ax, x, y, w, h, text, fontsize=7.6):
    pts = [(x, y + h / 2), (x + w / 2, y), (x, y - h / 2), (x - w / 2, y)]
    ax.add_patch(Polygon(pts, closed=True, fc="#fff7bc", ec="0.2", lw=1.0))
    ax.text(x, y, text, ha="center", va="center", fontsize=fontsize, linespacing=1.3)


def _arrow(ax, points, text=None, text_at=None, fontsize=7.4):
    """A polyline from points[0] to points[-1] with an arrowhead at the end."""
    xs, ys = zip(*points, strict=True)
    if len(points) > 2:
        ax.plot(xs[:-1], ys[:-1], color="0.2", lw=1.0)
    ax.annotate(
        "",
        xy=points[-1],
        xytext=points[-2],
        arrowprops={"arrowstyle": "-|>", "color": "0.2", "lw": 1.0, "shrinkA": 0, "shrinkB": 0},
    )
    if text:
        tx, ty = text_at if text_at is not None else points[0]
        ax.text(tx, ty, text, fontsize=fontsize, ha="left", va="center", color="0.15")


_FIG03_X, _FIG03_W = 6.0, 7.4
"""Figure 3's spine: the centre and width of its full-width boxes."""
_FIG03_STAGES = (2.05, 6.0, 9.95)
"""Figure 3's three stage columns (exploration, medium and late exploitation)."""
_FIG03_MOVES = (1.88, 1.55, 5.0)
"""Figure 3's move boxes: width, height and centre height."""


def fig03(stem, cfg: dict | None = None) -> None:
    """Figure 3: the AVOA flowchart of this package's implementation (the reference code's).

    The probabilities (p1, p2, p3, α, β), γ (the paper's k) and the Lévy exponent are read from
    :mod:`avoa_pipeline.optimizers.avoa`, so the chart shows what the code does; in particular
    the medium stage (0.5 ≤ |F| < 1) is decided by **p3** and the late stage (|F| < 0.5) by
    **p2**, as in the authors' code (the module docstring, items 5-6, lists how the printed
    equations differ). ``cfg`` (optional) adds the population size and iteration budget.
    """
    s = avoa_settings()
    budget = ""
    if cfg is not None:
        b = cfg["budget"]
        budget = f" (P = {b['pop_size']}, T = {b['iterations']})"

    fig = Figure(figsize=(11.0, 12.5))
    try:
        ax = fig.add_axes((0.0, 0.0, 1.0, 0.965))
        ax.set_xlim(0, 12)
        ax.set_ylim(0.4, 16.2)
        ax.set_axis_off()
        _fig03_iteration_head(ax, s, budget)
        _fig03_stages(ax, s)
        _fig03_bounds_and_loop(ax)
        fig.suptitle("Figure 3. AVOA flowchart (as implemented)", fontsize=11, y=0.985)
        save(fig, stem)
    finally:
        fig.clear()


def _fig03_iteration_head(ax, s: dict, budget: str) -> None:
    """Figure 3 from the start to the |F| decision: the start and its settings, the
    initialisation, the evaluation, the stop test, the hunger and the guide vulture."""
    p1, p2, p3 = s["p1"], s["p2"], s["p3"]
    alpha, beta, gamma = s["alpha"], s["beta"], s["gamma"]
    X, W = _FIG03_X, _FIG03_W
    _box(
        ax,
        X,
        15.6,
        4.6,
        0.7,
        f"Start{budget}\n"
        f"p1 = {p1:g}, p2 = {p2:g}, p3 = {p3:g}, α = L1 = {alpha:g}, "
        f"β = L2 = {beta:g}, γ (k) = {gamma:g}",
        fc="#e0ecf4",
        round_=True,
    )
    _box(ax, X, 14.55, W, 0.6, "Initialise P vultures uniformly in [lb, ub];  t = 0")
    _box(
        ax,
        X,
        13.45,
        W,
        0.8,
        "Evaluate the ISE of every vulture (eq. 13)\n"
        "update the best-two memories B1 (best so far), B2 (second best)  [stage 1]",
    )
    _diamond(ax, X, 12.15, 2.6, 1.0, "t ≥ T ?\n(budget spent)")
    _box(ax, 10.3, 12.15, 2.6, 0.7, "Stop:\nreturn B1 and its ISE", fc="#e0ecf4", round_=True)
    _box(
        ax,
        X,
        10.7,
        W,
        1.05,
        "Hunger, stage 2 (eqs. 17–18): once per iteration h ~ U(−2, 2), r ~ U(0, 1)\n"
        r"$g = h\,(\sin^{\gamma}(\frac{\pi}{2}\frac{t}{T}) + \cos(\frac{\pi}{2}\frac{t}{T})"
        r" - 1)$,   "
        r"$F_i = [(2r+1)(1 - t/T) + g]\,(2r_i - 1)$" + f"   (γ = {gamma:g})",
    )
    _box(
        ax,
        X,
        9.45,
        W,
        0.75,
        "Guide vulture, eq. 15 (roulette on L1, L2):\n"
        rf"$R_i = B_1$ if $r_i \leq \alpha = {alpha:g}$, else $B_2$  "
        f"(β = {beta:g})",
    )
    _diamond(ax, X, 8.25, 2.4, 0.95, r"$|F_i|$ ?")


def _fig03_stages(ax, s: dict) -> None:
    """Figure 3's three stages: each column's branch decision and its two moves."""
    p1, p2, p3 = s["p1"], s["p2"], s["p3"]
    xs = _FIG03_STAGES
    dw = 1.96  # decision width: its side corners sit above the two move boxes
    _diamond(ax, xs[0], 6.85, dw, 0.9, f"rand < p1 = {p1:g} ?")
    _diamond(ax, xs[1], 6.85, dw, 0.9, f"rand < p3 = {p3:g} ?")
    _diamond(ax, xs[2], 6.85, dw, 0.9, f"rand < p2 = {p2:g} ?")
    for xc, title in zip(
        xs,
        ("exploration, stage 3", "medium exploitation, stage 4", "late exploitation, stage 5"),
        strict=True,
    ):
        ax.text(xc + 0.1, 7.52, title, ha="left", fontsize=8, weight="bold")
    bw, bh, by = _FIG03_MOVES
    moves = (
        (
            "eqs. 19a, 20\n" r"$X = R - |2rR - X|\,F$",
            "eq. 19b\n" r"$X = R - F$" "\n" r"$+\, r\,((ub - lb)\,r' + lb)$",
        ),
        (
            "food competition\neqs. 21–22\n" r"$X = |2rR - X|\,(F + r')$" "\n" r"$-\,(R - X)$",
            "rotating flight\neqs. 23–25\n"
            r"$X = R - (S_1 + S_2)$"
            "\n"
            r"$S_1 = R\,\frac{rX}{2\pi}\cos X$"
            "\n"
            r"$S_2 = R\,\frac{r'X}{2\pi}\sin X$",
        ),
        (
            "aggregation\neqs. 26–28\n"
            r"$X = (A_1 + A_2)/2$"
            "\n"
            r"$A_k = B_k - \frac{B_k X}{B_k - X^2}F$",
            "attack, Lévy flight\neqs. 29–31\n"
            r"$X = R - |R - X|\,F\,\mathrm{Levy}$"
            "\n"
            f"(β = {s['levy_beta']:g}, σ = {s['levy_sigma']:.4f})",
        ),
    )
    for xc, (yes, no) in zip(xs, moves, strict=True):
        for dx, text, tag in ((-0.98, yes, "yes"), (0.98, no, "no")):
            _box(ax, xc + dx, by, bw, bh, text, fc="#f7fcf5", fontsize=7.2)
            _arrow(
                ax,
                [(xc + dx, 6.85), (xc + dx, by + bh / 2)],
                tag,
                (xc + dx + 0.06, 6.6),
                fontsize=7,
            )


def _fig03_bounds_and_loop(ax) -> None:
    """Figure 3 below the moves: the bounds box, every arrow between the boxes, the loop back
    to the evaluation and the footnote."""
    X, W, xs = _FIG03_X, _FIG03_W, _FIG03_STAGES
    _, bh, by = _FIG03_MOVES
    _box(
        ax,
        X,
        3.15,
        W,
        0.85,
        "Bounds: X ← clip(X, lb, ub) (a NaN coordinate keeps its old value)\n"
        "t ← t + 1   (no greedy selection: every vulture moves; B1, B2 keep the elite)",
    )
    # main spine
    _arrow(ax, [(X, 15.25), (X, 14.85)])
    _arrow(ax, [(X, 14.25), (X, 13.85)])
    _arrow(ax, [(X, 13.05), (X, 12.65)])
    _arrow(ax, [(X + 1.3, 12.15), (10.3 - 1.3, 12.15)], "yes", (X + 1.4, 12.3))
    _arrow(ax, [(X, 11.65), (X, 11.225)], "no", (X + 0.1, 11.45))
    _arrow(ax, [(X, 10.175), (X, 9.825)])
    _arrow(ax, [(X, 9.075), (X, 8.725)])
    # three-way split on |F|
    _arrow(ax, [(X - 1.2, 8.25), (xs[0], 8.25), (xs[0], 7.75)], r"$|F_i| \geq 1$", (2.25, 8.42))
    _arrow(ax, [(X, 7.775), (X, 7.3)])
    ax.text(X - 0.1, 7.56, r"$0.5 \leq |F_i| < 1$", ha="right", fontsize=7.4, color="0.15")
    _arrow(ax, [(X + 1.2, 8.25), (xs[2], 8.25), (xs[2], 7.75)], r"$|F_i| < 0.5$", (8.3, 8.42))
    # all six moves join the bounds box
    for xc in xs:
        for dx in (-0.98, 0.98):
            ax.plot([xc + dx, xc + dx], [by - bh / 2, 3.95], color="0.2", lw=1.0)
    ax.plot([xs[0] - 0.98, xs[2] + 0.98], [3.95, 3.95], color="0.2", lw=1.0)
    _arrow(ax, [(X, 3.95), (X, 3.575)])
    # loop back to the evaluation
    _arrow(ax, [(X, 2.725), (X, 2.25), (0.25, 2.25), (0.25, 13.45), (X - W / 2, 13.45)])
    ax.text(0.32, 8.9, "next iteration", rotation=90, fontsize=7.5, va="center")
    ax.text(
        X,
        1.2,
        "Per vulture i (vectorised): r, r', rand ~ U(0, 1) are one scalar per vulture, "
        "Levy is drawn per dimension.\n"
        "Branch conditions and defaults as in the authors' reference code "
        "(avoa_pipeline.optimizers.avoa); "
        "Fahmy et al. print p2 for the medium and p3 for the late stage.",
        ha="center",
        va="center",
        fontsize=7.6,
        color="0.25",
    )


# --------------------------------------------------------------------------------------------
# Figures 4-19: convergence


def _check_histories(histories: pd.DataFrame, need=HISTORY_COLUMNS) -> None:
    if not isinstance(histories, pd.DataFrame):
        raise TypeError(f"histories must be a pandas DataFrame, got {type(histories).__name__}")
    missing = [c for c in need if c not in histories.columns]
    if missing:
        raise ValueError(
            f"histories: missing column(s) {', '.join(missing)} "
            f"(need {', '.join(need)}; see docs/records.md)"
        )


def _select(histories: pd.DataFrame, scenario: int, case: int) -> pd.DataFrame:
    _check_histories(histories)
    sel = histories[(histories["scenario"] == scenario) & (histories["case"] == case)]
    if sel.empty:
        raise ValueError(f"histories: no rows for scenario {scenario}, case {case}")
    unknown = sorted(set(sel["algorithm"]) - set(ALGORITHMS))
    if unknown:
        raise ValueError(
            f"histories: unknown algorithm(s) {', '.join(map(str, unknown))} "
            f"(expected {', '.join(ALGORITHMS)})"
        )
    dup = sel.duplicated(["algorithm", "seed", "iteration"])
    if dup.any():
        row = sel[dup].iloc[0]
        raise ValueError(
            f"histories: duplicate entry algorithm {row['algorithm']}, seed {row['seed']}, "
            f"iteration {row['iteration']} (scenario {scenario}, case {case})"
        )
    values = sel["best_ise"].to_numpy(dtype=float)
    if np.isnan(values).any() or (values < 0).any():
        raise ValueError("histories: best_ise must be non-negative numbers (found NaN or < 0)")
    return sel


def convergence_bands(
    histories: pd.DataFrame,
    scenario: int,
    case: int,
    x: str = "iteration",
    grid=None,
) -> pd.DataFrame:
    """Median and interquartile range of the best-so-far ISE over seeds, per algorithm.

    Each run (one seed) is a step function of ``x`` (``"iteration"`` or ``"nfe"``): its best
    ISE at ``x`` is that of its last history entry with ``x_k <= x``, and after its last entry
    it keeps its final value (a run that stopped early -- a converged local search -- keeps its
    best). The runs are evaluated on a common grid and the quartiles (numpy's linear
    interpolation) taken across seeds at each grid point.

    ``grid``: the x values (one grid for all algorithms). Default, per algorithm: every x at
    which one of its runs has an entry, from the latest first entry to the latest last entry,
    so every grid point has a value for every run (the step functions are represented exactly).
    A grid point before some run's first entry gets NaN statistics.

    Returns columns ``algorithm, <x>, median, q25, q75, n_runs``; algorithms in the paper's
    column order.
    """
    if x not in ("iteration", "nfe"):
        raise ValueError(f"x must be 'iteration' or 'nfe', got {x!r}")
    sel = _select(histories, scenario, case)
    out = []
    for algo in [a for a in ALGORITHMS if a in set(sel["algorithm"])]:
        runs = []
        for _seed, run in sel[sel["algorithm"] == algo].groupby("seed", sort=True):
            run = run.sort_values("iteration")
            xs = run[x].to_numpy(dtype=float)
            if np.any(np.diff(xs) < 0):
                raise ValueError(
                    f"histories: {x} decreases with iteration in {algo} seed {_seed} "
                    f"(scenario {scenario}, case {case})"
                )
            runs.append((xs, run["best_ise"].to_numpy(dtype=float)))
        if grid is None:
            lo = max(xs[0] for xs, _ in runs)
            hi = max(xs[-1] for xs, _ in runs)
            g = np.unique(np.concatenate([xs for xs, _ in runs]))
            g = g[(g >= lo) & (g <= hi)]
        else:
            g = np.asarray(grid, dtype=float)
        M = np.empty((len(runs), g.size))
        for r, (xs, ys) in enumerate(runs):
            idx = np.searchsorted(xs, g, side="right") - 1
            M[r] = np.where(idx >= 0, ys[np.clip(idx, 0, None)], np.nan)
        complete = ~np.isnan(M).any(axis=0)
        q = np.full((3, g.size), np.nan)
        if complete.any():
            q[:, complete] = np.quantile(M[:, complete], [0.25, 0.5, 0.75], axis=0)
        out.append(
            pd.DataFrame(
                {
                    "algorithm": algo,
                    x: g,
                    "median": q[1],
                    "q25": q[0],
                    "q75": q[2],
                    "n_runs": len(runs),
                }
            )
        )
    return pd.concat(out, ignore_index=True)


def convergence(histories: pd.DataFrame, scenario: int, case: int, stem, paper_label=True):
    """Figures 4-19: best-so-far ISE against iterations (left) and evaluations (right).

    Per algorithm the median over seeds (line) and the interquartile range (band), on a log
    axis, from :func:`convergence_bands`; ISE values are clipped at :data:`ISE_FLOOR` for
    drawing only. ``paper_label``: title with the paper's figure number and caption, else a
    plain title (e.g. for a figure that is not the paper's).
    """
    fig_no = figure_number(scenario, case)
    bands = {x: convergence_bands(histories, scenario, case, x=x) for x in ("iteration", "nfe")}
    fig = Figure(figsize=(11.0, 4.6), layout="constrained")
    try:
        axes = fig.subplots(1, 2, sharey=True)
        floor_hit = False
        for ax, x, xlabel in (
            (axes[0], "iteration", "iteration (0 = initial population)"),
            (axes[1], "nfe", "objective evaluations (cumulative)"),
        ):
            b = bands[x]
            for algo, grp in b.groupby("algorithm", sort=False):
                grp = grp.dropna(subset=["median"])
                if grp.empty:
                    continue
                med, lo, hi = (
                    np.clip(grp[k].to_numpy(), ISE_FLOOR, None) for k in ("median", "q25", "q75")
                )
                floor_hit |= bool((grp[["median", "q25", "q75"]] < ISE_FLOOR).to_numpy().any())
                xs = grp[x].to_numpy()
                colour = ALGORITHM_COLORS[algo]
                ax.fill_between(xs, lo, hi, step="post", color=colour, alpha=0.18, lw=0)
                ax.step(
                    xs,
                    med,
                    where="post",
                    color=colour,
                    ls=ALGORITHM_STYLES.get(algo, "-"),
                    lw=2.0 if algo == "avoa" else 1.3,
                    label=f"{PAPER_LABELS[algo]} (n = {int(grp['n_runs'].iloc[0])})",
                )
            ax.set_yscale("log")
            ax.set_xlabel(xlabel)
            ax.grid(True, which="major", color="0.88", lw=0.6)
        axes[0].set_ylabel("best ISE so far (V²): median, IQR band")
        axes[0].legend(fontsize=8, loc="upper right", framealpha=0.9)
        what = f"Scenario ({scenario})—Case ({case}) convergence curves for Li-ion battery"
        title = f"Figure {fig_no}. {what}" if paper_label else f"Scenario {scenario}, case {case}"
        note = f"{describe(scenario, case)}; median and interquartile range over seeds"
        if floor_hit:
            note += f"; values below {ISE_FLOOR:g} V² drawn at {ISE_FLOOR:g}"
        fig.suptitle(f"{title}\n{note}", fontsize=10)
        save(fig, stem)
    finally:
        fig.clear()


# --------------------------------------------------------------------------------------------
# Beyond the paper: fixed-budget curves (docs/reproduction-notes.md, E8)


def fig_budget(histories: pd.DataFrame, scenario: int, stem, targets=EXCESS_TARGETS) -> None:
    """Fixed-budget curves of one scenario: columns = its cases, one ECDF row per target (share
    of seeds whose best excess over the truth is ≤ target after b evaluations) and a last row
    with each algorithm's mean per-seed rank at b (1 = lowest excess; drawn at the top, so up is
    better in every row). Evaluations on a log axis up to the pair's common N (dotted line).

    ``histories`` needs ``excess_ise`` (:func:`.stats.with_excess` adds it to older aggregates).
    Besides ``<stem>.png`` / ``.pdf`` writes the curves as ``<stem>_ecdf.csv`` (of
    :func:`.budget.ecdf`, with ``common_nfe``) and ``<stem>_rank.csv`` (of
    :func:`.budget.rank_curve`). For AVOA, GTO and RUN a reading at b is their full-budget run
    seen at b (:mod:`.budget`).
    """
    _check_histories(histories, need=(*HISTORY_COLUMNS, "excess_ise"))
    sel = histories[histories["scenario"] == scenario]
    if sel.empty:
        raise ValueError(f"histories: no rows for scenario {scenario}")
    cases = sorted(int(c) for c in sel["case"].unique())
    for c in cases:
        _select(histories, scenario, c)  # the same checks as the convergence figures
    targets = [float(t) for t in targets]
    hits = budget.hitting_nfe(sel, targets)
    ecdfs, ranks, commons = [], [], {}
    for c in cases:
        grid = budget.budget_grid(sel, scenario, c)
        commons[c] = stats.common_nfe(sel, scenario, c)
        ecdfs.append(budget.ecdf(hits, scenario, c, grid).assign(common_nfe=commons[c]))
        ranks.append(budget.rank_curve(sel, scenario, c, grid).assign(common_nfe=commons[c]))
    ecdf_df = pd.concat(ecdfs, ignore_index=True)
    rank_df = pd.concat(ranks, ignore_index=True)
    algos = stats.algorithm_order(sel["algorithm"])

    nrow, ncol = len(targets) + 1, len(cases)
    fig = Figure(figsize=(3.3 * ncol + 1.0, 2.3 * nrow + 1.4), layout="constrained")
    try:
        axes = np.asarray(fig.subplots(nrow, ncol, sharex="col", squeeze=False))
        for j, c in enumerate(cases):
            e = ecdf_df[ecdf_df["case"] == c]
            r = rank_df[rank_df["case"] == c]
            for algo in algos:
                style = {
                    "color": ALGORITHM_COLORS.get(algo, "0.3"),
                    "ls": ALGORITHM_STYLES.get(algo, "-"),
                    "lw": 2.0 if algo == "avoa" else 1.2,
                    "label": PAPER_LABELS.get(algo, algo),
                }
                for i, t in enumerate(targets):
                    cur = e[(e["algorithm"] == algo) & (e["target"] == t)]
                    axes[i, j].step(cur["nfe"], cur["share"], where="post", **style)
                cur = r[r["algorithm"] == algo]
                axes[-1, j].plot(cur["nfe"], cur["mean_rank"], **style)
            for i, t in enumerate(targets):
                ax = axes[i, j]
                ax.set_ylim(-0.03, 1.03)
                if j == 0:
                    ax.set_ylabel(f"share of seeds\nwith e ≤ {100 * t:g} %")
            axes[-1, j].set_ylim(len(algos) + 0.3, 0.7)
            axes[-1, j].set_yticks(range(1, len(algos) + 1))
            axes[-1, j].set_xlabel("objective evaluations")
            axes[0, j].set_title(f"case {c}: {describe(scenario, c).split('; ')[1]}", fontsize=9)
            for ax in axes[:, j]:
                ax.set_xscale("log")
                ax.axvline(commons[c], color="0.4", lw=0.8, ls=":")
                ax.grid(True, which="major", color="0.88", lw=0.6)
        axes[-1, 0].set_ylabel("mean per-seed rank\n(1 = lowest excess)")
        handles, labels = axes[-1, 0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside lower center", ncol=len(algos), fontsize=8)
        fig.suptitle(
            f"Scenario {scenario} ({_SCENARIO_TEXT.get(scenario, '')}): fixed-budget curves of "
            "the excess over the truth e = (ISE − ISE_true) / ISE_true\n"
            "dotted: common N; AVOA, GTO, RUN schedule exploration by iteration, so a reading "
            "at b is their full-budget run seen at b",
            fontsize=10,
        )
        save(fig, stem)
    finally:
        fig.clear()
    stem = Path(stem)
    for name, df in (("ecdf", ecdf_df), ("rank", rank_df)):
        with atomic_path(stem.with_name(f"{stem.name}_{name}.csv")) as tmp:
            df.to_csv(tmp, index=False)


# --------------------------------------------------------------------------------------------
# Figures 20-21: before and after optimisation


def free_vector(problem, params) -> np.ndarray:
    """The free-parameter vector (``problem.names`` order) from one of several forms.

    ``params``: a sequence/array of ``len(problem.names)`` values in ``problem.names`` order; a
    mapping name → value (e.g. a fit record's ``best_params``); or a row of ``runs.parquet``
    (a :class:`pandas.Series` with ``est_<name>`` columns).
    """
    names = tuple(problem.names)
    if isinstance(params, pd.Series) and any(f"{RUN_EST_PREFIX}{n}" in params.index for n in names):
        missing = [n for n in names if f"{RUN_EST_PREFIX}{n}" not in params.index]
        if missing:
            raise ValueError(f"runs row lacks column(s) {', '.join('est_' + n for n in missing)}")
        x = np.array([float(params[f"{RUN_EST_PREFIX}{n}"]) for n in names])
    elif isinstance(params, Mapping | pd.Series):
        missing = [n for n in names if n not in params]
        if missing:
            raise ValueError(f"parameters lack {', '.join(missing)} (need {', '.join(names)})")
        x = np.array([float(params[n]) for n in names])
    else:
        x = np.asarray(params, dtype=float).ravel()
        if x.size != len(names):
            raise ValueError(f"expected {len(names)} values ({', '.join(names)}), got {x.size}")
    if not np.isfinite(x).all():
        raise ValueError(f"parameters must be finite, got {dict(zip(names, x, strict=True))}")
    return x


def initial_guess(problem) -> np.ndarray:
    """The "before optimisation" parameters: the centre of the searched box, (lb + ub) / 2."""
    return 0.5 * (np.asarray(problem.lb, dtype=float) + np.asarray(problem.ub, dtype=float))


def median_run(runs: pd.DataFrame, scenario: int = 4, case: int = 4, algorithm: str = "avoa"):
    """The run (a ``runs.parquet`` row) with the median best ISE of ``algorithm``
    (``stats.median_position``: the lower middle run, ties broken by the smaller seed)."""
    need = ("scenario", "case", "algorithm", "seed", "best_ise")
    missing = [c for c in need if c not in runs.columns]
    if missing:
        raise ValueError(f"runs: missing column(s) {', '.join(missing)}")
    sel = runs[
        (runs["scenario"] == scenario) & (runs["case"] == case) & (runs["algorithm"] == algorithm)
    ]
    if sel.empty:
        raise ValueError(f"runs: no {algorithm} rows for scenario {scenario}, case {case}")
    k = stats.median_position(sel["best_ise"], sel["seed"])
    if k is None:
        raise ValueError(f"runs: no finished {algorithm} run for scenario {scenario}, case {case}")
    return sel.iloc[k]


def _states(problem, x_free) -> dict:
    sim = problem.simulate(x_free)
    p_eff = problem.full(x_free)[0] * problem.spec.fade_factors
    r0 = p_eff[PARAM_NAMES.index("r0")]
    # eq. 4 solved for the OCV: Vocv = Vt + Vtr + R0 I_batt (I_batt includes the load current)
    sim["ocv_v"] = sim["voltage_v"] + sim["vtr_v"] + r0 * sim["battery_current_a"]
    sim["ise"] = float(problem.objective(np.atleast_2d(x_free))[0])
    return sim


def _param_line(problem, x) -> str:
    labels = [_label(n, v) for n, v in zip(problem.names, x, strict=True)]
    # three per line: two panels side by side have room for no more
    return "\n".join(",  ".join(labels[i : i + 3]) for i in range(0, len(labels), 3))


def _subtitle(problem) -> str:
    sc, cs = problem.scenario, problem.case
    text = f"scenario {sc}, case {cs}: {describe(sc, cs)}"
    if np.any(problem.spec.fade_factors != 1.0):
        text += "; parameters are fresh-cell values, the model applies the fade"
    return text


def _before_after(problem, after, before):
    x_after = free_vector(problem, after)
    x_before = initial_guess(problem) if before is None else free_vector(problem, before)
    before_what = "centre of the searched box" if before is None else "given initial guess"
    return x_before, x_after, before_what


def _before_after_panels(problem, after, before, after_label, **subplots):
    """Figure and 2 × 2 axes of Figures 20-21, and per column (top, bottom, states, x, title)."""
    x_before, x_after, before_what = _before_after(problem, after, before)
    fig = Figure(figsize=(11.0, 6.8), layout="constrained")
    axes = fig.subplots(2, 2, sharex=True, sharey="row", **subplots)
    tags = (f"(a) before optimisation ({before_what})", f"(b) after {after_label}")
    panels = []
    for col, (x, tag) in enumerate(zip((x_before, x_after), tags, strict=True)):
        st = _states(problem, x)
        title = f"{tag}\n{_param_line(problem, x)}\nISE = {st['ise']:.4g} V²"
        panels.append((axes[0, col], axes[1, col], st, x, title))
    return fig, axes, panels


def _time_axis_and_grids(top, bottom) -> None:
    """A column of Figures 20-21: time (min) under it, light grids on both panels."""
    bottom.set_xlabel("time (min)")
    top.grid(True, color="0.9", lw=0.6)
    bottom.grid(True, color="0.9", lw=0.6)


def _finish_before_after(fig, axes, problem, ylabels, legend_loc: str, title: str, stem) -> None:
    """Figures 20-21's labels of the left column (top, bottom), the legend of the top-left
    panel, the title over the problem's description; written to ``stem``."""
    axes[0, 0].set_ylabel(ylabels[0])
    axes[1, 0].set_ylabel(ylabels[1])
    axes[0, 0].legend(fontsize=8, loc=legend_loc)
    fig.suptitle(title + "\n" + _subtitle(problem), fontsize=10)
    save(fig, stem)


def fig20(problem, after, stem, before=None, after_label: str = "AVOA") -> None:
    """Figure 20: the model's voltage characteristics before (a) and after (b) optimisation.

    ``problem``: :func:`avoa_pipeline.problem.build` of the case to show (the paper: scenario 4,
    case 4). ``after``: the optimised parameters (see :func:`free_vector`; the pipeline passes
    AVOA's median-ISE run, :func:`median_run`). ``before``: the initial guess; default
    :func:`initial_guess`, the centre of the searched box (the point a search knows before it
    starts; the paper does not say which guess it used) -- the figure title says which.

    Each column: terminal voltage V_t of the model with its open-circuit voltage Vocv(SOC)
    (top) and the transient voltage V_tr with the battery current (bottom), over the test.
    """
    t = np.asarray(problem.time_s, dtype=float) / 60.0
    fig, axes, panels = _before_after_panels(problem, after, before, after_label)
    try:
        for top, bottom, st, _x, title in panels:
            top.plot(t, st["ocv_v"], color="0.45", lw=1.0, ls="--", label=r"model $V_{ocv}(SOC)$")
            top.plot(t, st["voltage_v"], color="#a50f15", lw=1.2, label=r"model $V_t$")
            top.set_title(title, fontsize=9)
            bottom.plot(t, 1e3 * st["vtr_v"], color="#54278f", lw=1.1, label=r"$V_{tr}$")
            twin = bottom.twinx()
            twin.plot(t, st["battery_current_a"], color="#08519c", lw=0.8, alpha=0.6)
            twin.set_ylabel(r"$I_{batt}$ (A)", color="#08519c", fontsize=9)
            _time_axis_and_grids(top, bottom)
        _finish_before_after(
            fig,
            axes,
            problem,
            ("voltage (V)", r"transient voltage $V_{tr}$ (mV)"),
            "lower left",
            "Figure 20. Battery voltage characteristics before and after optimisation",
            stem,
        )
    finally:
        fig.clear()


def fig21(problem, after, stem, before=None, after_label: str = "AVOA") -> None:
    """Figure 21: measured vs model voltage before (a) and after (b) optimisation, and the error.

    Arguments as :func:`fig20` (``before`` defaults to the centre of the searched box). Top row:
    the measured voltage (``problem.voltage_v``) and the model's; bottom row: the error
    model − measured in mV, with its ISE (eq. 13) and RMS.
    """
    t = np.asarray(problem.time_s, dtype=float) / 60.0
    v_meas = np.asarray(problem.voltage_v, dtype=float)
    fig, axes, panels = _before_after_panels(
        problem, after, before, after_label, height_ratios=(2, 1)
    )
    try:
        for top, bottom, st, _x, title in panels:
            err = st["voltage_v"] - v_meas
            top.plot(t, v_meas, color="0.2", lw=2.2, alpha=0.35, label="measured")
            top.plot(t, st["voltage_v"], color="#a50f15", lw=1.0, label="model")
            top.set_title(title, fontsize=9)
            bottom.plot(t, 1e3 * err, color="#a50f15", lw=0.8)
            bottom.axhline(0.0, color="0.3", lw=0.6)
            rms = math.sqrt(float(np.mean(err**2)))
            bottom.set_title(
                f"error: RMS {1e3 * rms:.3g} mV, max |e| {1e3 * np.max(np.abs(err)):.3g} mV",
                fontsize=8.5,
            )
            _time_axis_and_grids(top, bottom)
        _finish_before_after(
            fig,
            axes,
            problem,
            ("terminal voltage (V)", "error model − measured (mV)"),
            "lower right",
            "Figure 21. Measured and model voltage before and after optimisation",
            stem,
        )
    finally:
        fig.clear()


def not_run(stem, title: str, reason: str) -> None:
    """A figure that says plainly why there is nothing to draw (e.g. not in this config)."""
    fig = Figure(figsize=(8, 3))
    ax = fig.add_subplot()
    ax.axis("off")
    ax.text(0.5, 0.62, title, ha="center", va="center", fontsize=12)
    ax.text(0.5, 0.38, reason, ha="center", va="center", fontsize=10, color="0.35", wrap=True)
    save(fig, stem)
