"""Tables 1-24 of Fahmy et al. 2023 as DataFrames, set against our results; one writer for all.

Every table function takes plain inputs (the config dict, the aggregate frames of
``docs/records.md``, the paper's numbers of ``config/paper/*.csv`` read with pandas) and returns
a DataFrame whose column headings are the ones shown; :func:`write_table` writes it as CSV
(full precision), Markdown and LaTeX.

- :func:`cell_table` — Table 1 (cell characteristics).
- :func:`constants_table` — Table 2 (constants, budget, and the fade δ derived from them).
- :func:`bounds_table` — Table 3 (bounds as printed and as searched, the truth).
- :func:`param_table` — Tables 4-19 (parameters and ISE of one scenario × case).
- :func:`objective_table` — Tables 20-23 (ISE and ranks of one scenario, with tests).
- :func:`accuracy_table` — beside Tables 20-23 (not in the paper): the share of seeds whose
  every identified parameter lies within 1 % / 5 % of the truth.
- :func:`time_table` — Table 24 (time per iteration, scenario 4 case 4).

For a table at equal evaluations, pass the frame of
:func:`avoa_pipeline.report.stats.at_budget` (``by="nfe"``) as ``runs`` to
:func:`objective_table`: it reads ``best_ise``, ``excess_ise`` (when the histories have it) and
the key columns; without ``excess_ise``, ``true_ise`` and ``n_samples`` the excess columns and
the margin are NaN and the tests compare ISE.
"""

from __future__ import annotations

import contextlib
import math
from numbers import Number
from pathlib import Path

import numpy as np
import pandas as pd
from tabulate import tabulate

from ..io import atomic_path
from ..model.battery import CASES, PARAM_LABELS, PARAM_NAMES, FadeLaw
from ..optimizers import ALGORITHMS, PAPER_LABELS
from . import stats

TABLE_NUMBERS = {(s, c): 4 + 4 * (s - 1) + (c - 1) for s in range(1, 5) for c in range(1, 5)}
"""The paper's table number of each (scenario, case) parameter table (4 = S1C1 … 19 = S4C4)."""

OBJECTIVE_TABLE_NUMBERS = {1: 20, 2: 21, 3: 22, 4: 23}

ISE_LABEL = "ISE (V²)"
VERDICT_TEXT = {
    "ref better": "AVOA lower",
    "ref worse": "AVOA higher",
    "no difference": "no difference",
    "too few seeds": "too few seeds",
}
"""The difference test's verdict (``holm_wilcoxon``'s ``verdict``) as Tables 20-23 word it."""
SIZE_TEXT = {
    stats.LOWER: "AVOA lower",
    stats.HIGHER: "AVOA higher",
    stats.EQUIVALENT: "practically equivalent",
    stats.INCONCLUSIVE: "inconclusive",
    stats.TOO_FEW: "too few seeds",
}
"""The size verdict (``holm_wilcoxon``'s ``size_verdict``, reproduction note E3) as worded."""
EXCESS_ROWS = ("excess (%) median", "excess (%) q25", "excess (%) q75")
ACCURACY_QUANTITY = "Parameter accuracy"
ACCURACY_ROWS = {
    tol: f"seeds within {round(100 * tol):d} % (all params) (%)"
    for tol in stats.ACCURACY_TOLERANCES
}


def param_label(name: str) -> str:
    """``"V_nom (V)"`` etc. from ``PARAM_LABELS``."""
    symbol, unit = PARAM_LABELS[name]
    return f"{symbol} ({unit})"


def _ratio(a: float, b: float) -> float:
    """a / b, NaN when either is missing or b is zero."""
    a, b = float(a), float(b)
    return a / b if b != 0 and not (math.isnan(a) or math.isnan(b)) else np.nan


def _paper(frame: pd.DataFrame | None) -> pd.DataFrame:
    if frame is None:
        return pd.DataFrame(columns=["scenario", "case", "algorithm"])
    out = frame.copy()
    if "algorithm" in out.columns:
        out["algorithm"] = out["algorithm"].map(stats.algorithm_key)
    return out


# ------------------------------------------------------------------------------------ writer
_LATEX_CHARS = {
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "$": r"\$",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "~": r"\textasciitilde{}",
    "^": r"\textasciicircum{}",
    "<": r"\textless{}",
    ">": r"\textgreater{}",
    "|": r"\textbar{}",
    "τ": r"$\tau$",
    "Ω": r"$\Omega$",
    "δ": r"$\delta$",
    "β": r"$\beta$",
    "α": r"$\alpha$",
    "±": r"$\pm$",
    "×": r"$\times$",
    "≤": r"$\leq$",
    "≥": r"$\geq$",
    "≈": r"$\approx$",
    "→": r"$\rightarrow$",
    "−": "-",
    "–": "--",
    "—": "---",
    "°": r"\textdegree{}",
    "²": r"$^2$",
    "…": r"\ldots{}",
}


def latex_escape(text: str) -> str:
    """Escape LaTeX specials and map the few non-ASCII symbols the tables use to math."""
    return "".join(_LATEX_CHARS.get(ch, ch) for ch in str(text))


def _is_missing(v) -> bool:
    if v is None or v is pd.NA or v is pd.NaT:
        return True
    return isinstance(v, float) and math.isnan(v)


def _fmt(v, floatfmt: str, missing: str) -> str:
    if _is_missing(v):
        return missing
    if isinstance(v, (bool, np.bool_)):
        return str(bool(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, Number):
        return format(float(v), floatfmt)
    return str(v)


def _cells(df: pd.DataFrame, floatfmt: str, missing: str) -> list[list[str]]:
    return [[_fmt(v, floatfmt, missing) for v in row] for row in df.itertuples(index=False)]


def _md_escape(text: str) -> str:
    return str(text).replace("|", "\\|")


def _numeric_columns(df: pd.DataFrame) -> list[bool]:
    return [pd.api.types.is_numeric_dtype(df[c]) for c in df.columns]


def to_markdown(df: pd.DataFrame, caption: str, floatfmt: str = ".6g") -> str:
    """The caption, a blank line, and a pipe table (tabulate); NaN shows as "—", "|" as "\\|"."""
    body = tabulate(
        [[_md_escape(v) for v in row] for row in _cells(df, floatfmt, "—")],
        headers=[_md_escape(c) for c in df.columns],
        tablefmt="pipe",
        colalign=["right" if n else "left" for n in _numeric_columns(df)] or None,
        disable_numparse=True,
    )
    return f"{caption}\n\n{body}\n"


def to_latex(df: pd.DataFrame, caption: str, floatfmt: str = ".6g") -> str:
    """A ``table`` float with a booktabs ``tabular`` (needs ``\\usepackage{booktabs}``)."""
    align = "".join("r" if n else "l" for n in _numeric_columns(df)) or "l"
    lines = [
        r"\begin{table}[htbp]",
        r"\centering",
        rf"\caption{{{latex_escape(caption)}}}",
        rf"\begin{{tabular}}{{{align}}}",
        r"\toprule",
        " & ".join(latex_escape(c) for c in df.columns) + r" \\",
        r"\midrule",
    ]
    for row in _cells(df, floatfmt, "--"):
        lines.append(" & ".join(latex_escape(v) for v in row) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}", r"\end{table}"]
    return "\n".join(lines) + "\n"


def write_table(
    df: pd.DataFrame, stem: str | Path, caption: str, floatfmt: str = ".6g"
) -> list[Path]:
    """Write ``stem.csv`` (full precision), ``stem.md`` and ``stem.tex``; return their paths.

    All three are rendered before anything is written, then written to temporary files and
    renamed together at the end, so an error leaves none of them (and never half of one).
    ``floatfmt`` formats floats in the Markdown and LaTeX versions.
    """
    if not isinstance(df, pd.DataFrame):
        raise TypeError(f"write_table needs a DataFrame, got {type(df).__name__}")
    stem = Path(stem)
    texts = {
        ".csv": df.to_csv(index=False),
        ".md": to_markdown(df, caption, floatfmt),
        ".tex": to_latex(df, caption, floatfmt),
    }
    paths = [stem.with_name(stem.name + ext) for ext in texts]
    with contextlib.ExitStack() as stack:
        for path, text in zip(paths, texts.values(), strict=True):
            tmp = stack.enter_context(atomic_path(path))
            tmp.write_text(text, encoding="utf-8")
    return paths


# ---------------------------------------------------------------------------- Tables 1 to 3
def cell_table(cfg: dict) -> pd.DataFrame:
    """Table 1: the cell's characteristics (``cfg["cell"]``). Columns: Characteristic, Value."""
    c = cfg["cell"]

    def rng(v):
        return f"{v[0]} to {v[1]}" if isinstance(v, (list, tuple)) else v

    rows = [
        ("Battery", c.get("name")),
        ("Nominal voltage (V)", c.get("nominal_voltage_v")),
        ("Minimum capacity (mAh)", c.get("minimum_capacity_mah")),
        ("Typical capacity (mAh)", c.get("typical_capacity_mah")),
        ("Internal resistance (Ω)", c.get("internal_resistance_ohm")),
        (
            "Max. current charging/discharging (A)",
            f"{c.get('max_charge_current_a')}/{c.get('max_discharge_current_a')}",
        ),
        ("Charging CC/CV (mA, V)", f"{c.get('charge_cc_ma')}, {c.get('charge_cv_v')}"),
        ("Charging time (h)", c.get("charge_time_h")),
        ("Ambient temperature, charge (°C)", rng(c.get("charge_temperature_c"))),
        ("Ambient temperature, discharge (°C)", rng(c.get("discharge_temperature_c"))),
        ("Weight (g)", c.get("weight_g")),
    ]
    return pd.DataFrame(
        [(k, "" if v is None else str(v)) for k, v in rows], columns=["Characteristic", "Value"]
    )


def constants_table(cfg: dict) -> pd.DataFrame:
    """Table 2: the constants as printed, the budget, and what the pipeline derives from them.

    Columns: Parameter, Value, Unit, Source ("Table 2" for printed values, "derived" for the δ
    of eqs. 7-9 computed by ``FadeLaw``, "config" for choices the paper does not state).
    """
    k = cfg["constants"]
    after, ref = k["after_n"], k["fade_reference"]
    fade = FadeLaw.from_constants(k)
    b = cfg["budget"]
    rows = [
        ("Battery discharge capacity Q_dis", k["qdis_ah"], "Ah", "Table 2"),
        ("Number of discharge cycles N", k["n_cycles_ref"], "", "Table 2"),
        ("Battery capacity Q_fade after N cycles", after["capacity_ah"], "Ah", "Table 2"),
        ("Internal resistance R_o after N cycles", after["r0_ohm"], "Ω", "Table 2"),
        ("Discharge voltage V_dis after N cycles", after["vdis_v"], "V", "Table 2"),
        ("Population size", b["pop_size"], "", "Table 2"),
        ("Number of iterations", b["iterations"], "", "Table 2"),
        ("Fresh capacity (fade reference)", ref["capacity_ah"], "Ah", "config"),
        ("Fresh R_o (fade reference)", ref["r0_ohm"], "Ω", "config"),
        ("Fresh V_dis (fade reference)", ref["vdis_v"], "V", "config"),
        ("δQ (eq. 8)", fade.delta_q_pct, "%", "derived"),
        ("δR_o (eq. 9)", fade.delta_r0_pct, "%", "derived"),
        ("δR_tr (eq. 9)", fade.delta_rtr_pct, "%", "derived"),
        ("δV_dis (eq. 7 form)", fade.delta_vdis_pct, "%", "derived"),
        ("δV_nom (eq. 7)", fade.delta_vnom_pct, "%", "derived"),
        ("Cycle n of the faded cell", k["cycle_n"], "", "config"),
        ("Load (scenarios 3, 4)", k["load_ohm"], "Ω", "config"),
    ]
    if b.get("max_nfe") is not None:
        rows.insert(7, ("Evaluation cap", b["max_nfe"], "", "config"))
    out = pd.DataFrame(rows, columns=["Parameter", "Value", "Unit", "Source"])
    out["Value"] = out["Value"].astype(float)
    return out


def bounds_table(cfg: dict) -> pd.DataFrame:
    """Table 3: bounds as printed and as searched, side by side, with the synthetic truth.

    One row per temperature × parameter. Columns: Temperature, Parameter, Printed lower,
    Printed upper, Used lower, Used upper, True, Note (why a used bound differs from the
    printed one; the T2 V_nom box is widened, reproduction note B1).
    """
    temps = cfg.get("temperatures_c", {})
    rows = []
    for temp in cfg["bounds_printed"]:
        printed, used = cfg["bounds_printed"][temp], cfg["bounds_used"][temp]
        truth = cfg.get("true_params", {}).get(temp, {})
        label = f"{temp} = {temps[temp]:g} °C" if temp in temps else temp
        for p in PARAM_NAMES:
            note = ""
            if list(printed[p]) != list(used[p]):
                note = "widened: every printed estimate lies outside the printed box"
                if p == "vnom":
                    note = (
                        "widened: all printed T2 V_nom estimates lie in 3.90-3.98 V, and the "
                        "printed box would make β > 1"
                    )
            rows.append(
                (
                    label,
                    param_label(p),
                    float(printed[p][0]),
                    float(printed[p][1]),
                    float(used[p][0]),
                    float(used[p][1]),
                    float(truth.get(p, np.nan)),
                    note,
                )
            )
    return pd.DataFrame(
        rows,
        columns=[
            "Temperature",
            "Parameter",
            "Printed lower",
            "Printed upper",
            "Used lower",
            "Used upper",
            "True",
            "Note",
        ],
    )


# -------------------------------------------------------------------------- Tables 4 to 19
def median_run(sub: pd.DataFrame) -> pd.Series | None:
    """The run of median ISE (``stats.median_position``), or None."""
    k = stats.median_position(sub["best_ise"], sub["seed"])
    return None if k is None else sub.iloc[k]


def param_table(
    runs: pd.DataFrame,
    paper_params: pd.DataFrame | None,
    scenario: int,
    case: int,
    truth: dict | None = None,
) -> pd.DataFrame:
    """Tables 4-19: identified parameters and ISE of one scenario × case, ours against the paper.

    Wide, like the paper: one column per algorithm (paper headings, paper order), plus
    ``Quantity`` (parameter with unit, or ISE), ``Row`` (what the row holds) and ``True`` (the
    synthetic cell's value). Rows, for each identified parameter p (paper row order):

    - ``ours (median-ISE run)``: p of the run whose ISE is the median over seeds (lower middle
      for an even count) — one coherent parameter set, not a per-parameter median;
    - ``paper``: the printed value;
    - ``ours rel. err. (%)``: 100·(est − true)/true of that run;
    - ``paper rel. err. (%)``: 100·(printed − true)/true. The paper's cell is not ours, so
      this is only the distance of the printed value from our synthetic truth;
    - ``ours median abs. rel. err. (%)``: the median over all seeds of 100·|est − true|/true.

    Then the ISE rows (``True`` = ISE of the true parameters on the same noisy data, the noise
    floor): ``ours mean``, ``ours sd`` (over seeds, ddof 1), ``ours median``, ``ours best``,
    ``ours worst``, ``paper``; then, still under the ISE, the excess over the truth in percent
    of the truth's ISE, 100·(ISE − ISE_true)/ISE_true over seeds (reproduction note E1; ``True``
    = 0): ``excess (%) median``, ``excess (%) q25``, ``excess (%) q75`` (quartiles, linear
    interpolation); then ``Parameter accuracy`` (E7): ``seeds within 1 % (all params) (%)`` and
    ``seeds within 5 % (all params) (%)``, the share of seeds whose every identified parameter
    lies within 1 % (5 %) of the truth; and ``seed of median run``, ``seeds`` (runs with an ISE).
    Older aggregates without ``excess_ise`` get it from ``true_ise``
    (:func:`~avoa_pipeline.report.stats.with_excess`).
    Missing values are NaN (the paper's Table 12, S3/C1, prints no ISE row; Table 22 has it).
    ``truth`` (parameter → fresh-cell value, e.g. the config's ``true_params`` of the case's
    temperature) fills the parameters' ``True`` column and the paper's relative errors when no
    run of this pair gives them (a pair the configuration does not run).
    """
    if case not in CASES:
        raise ValueError(f"unknown case {case}")
    sub = stats.with_excess(runs[(runs["scenario"] == scenario) & (runs["case"] == case)])
    paper = _paper_values(paper_params, scenario, case)
    med = {a: median_run(sub[sub["algorithm"] == a]) for a in ALGORITHMS}

    def true_of(col: str) -> float:
        if col in sub and sub[col].notna().any():
            return float(sub[col].median())
        name = col.removeprefix("true_")
        return float((truth or {}).get(name, np.nan)) if name in PARAM_NAMES else np.nan

    table = _WideRows()
    for p in CASES[case].free:
        _parameter_rows(table, p, true_of(f"true_{p}"), sub, med, paper)
    g = {a: sub[(sub["algorithm"] == a) & sub["best_ise"].notna()]["best_ise"] for a in ALGORITHMS}
    _ise_rows(table, true_of("true_ise"), sub, g, paper)
    acc = stats.accuracy_shares(sub).set_index("algorithm")
    for tol, row in ACCURACY_ROWS.items():
        col = stats.share_column(tol)
        table.add(
            ACCURACY_QUANTITY,
            row,
            np.nan,
            lambda a, col=col: 100.0 * float(acc.loc[a, col]) if a in acc.index else np.nan,
        )
    table.add(
        "Runs", "seed of median run", np.nan, lambda a: np.nan if med[a] is None else med[a]["seed"]
    )
    table.add("Runs", "seeds", np.nan, lambda a: float(len(g[a])))
    return table.frame()


def _paper_values(paper_params: pd.DataFrame | None, scenario: int, case: int) -> dict:
    """The paper's printed value of each (algorithm, parameter or "ise") of one scenario × case."""
    pp = _paper(paper_params)
    if not len(pp):
        return {}
    pp = pp[(pp["scenario"] == scenario) & (pp["case"] == case)]
    keys = zip(pp["algorithm"], pp["parameter"], strict=True)
    return {key: float(v) for key, v in zip(keys, pp["value"], strict=True)}


class _WideRows:
    """The rows of Tables 4-19: ``Quantity``, ``Row``, ``True``, then one number per algorithm
    (paper headings, paper order)."""

    def __init__(self):
        self.rows: list[list] = []

    def add(self, quantity: str, row: str, true: float, values) -> None:
        """A row whose algorithm ``a`` holds ``values(a)``."""
        self.rows.append([quantity, row, true, *[values(a) for a in ALGORITHMS]])

    def frame(self) -> pd.DataFrame:
        cols = ["Quantity", "Row", "True", *[PAPER_LABELS[a] for a in ALGORITHMS]]
        out = pd.DataFrame(self.rows, columns=cols)
        for c in cols[2:]:
            out[c] = out[c].astype(float)
        return out


def _parameter_rows(table: _WideRows, p: str, t: float, sub, med: dict, paper: dict) -> None:
    """Parameter ``p``'s five rows (true value ``t``): the median run's estimate, the paper's,
    their relative errors, and the median over seeds of ours."""
    q = param_label(p)

    def est(a):
        return np.nan if med[a] is None else float(med[a].get(f"est_{p}", np.nan))

    def rel(a):
        if med[a] is None:
            return np.nan
        v = med[a].get(f"relerr_{p}", np.nan)
        return 100.0 * (float(v) if pd.notna(v) else _ratio(est(a), t) - 1.0)

    def rel_all(a):
        r = sub[(sub["algorithm"] == a) & sub["best_ise"].notna()]
        if r.empty:
            return np.nan
        e = r[f"relerr_{p}"] if f"relerr_{p}" in r else r[f"est_{p}"] / t - 1.0
        return float(100.0 * e.abs().median())

    table.add(q, "ours (median-ISE run)", t, est)
    table.add(q, "paper", t, lambda a: paper.get((a, p), np.nan))
    table.add(q, "ours rel. err. (%)", np.nan, rel)
    table.add(
        q,
        "paper rel. err. (%)",
        np.nan,
        lambda a: 100.0 * (_ratio(paper.get((a, p), np.nan), t) - 1.0),
    )
    table.add(q, "ours median abs. rel. err. (%)", np.nan, rel_all)


def _ise_rows(table: _WideRows, t_ise: float, sub, g: dict, paper: dict) -> None:
    """The ISE rows (``g``: each algorithm's ISEs; ``t_ise``: the truth's): ours over seeds,
    the paper's, and the excess over the truth's ISE (its median and quartiles, in %)."""

    def agg(fn):
        return lambda a: float(fn(g[a])) if len(g[a]) else np.nan

    table.add(ISE_LABEL, "ours mean", t_ise, agg(np.mean))
    table.add(
        ISE_LABEL, "ours sd", np.nan, lambda a: float(g[a].std(ddof=1)) if len(g[a]) > 1 else np.nan
    )
    table.add(ISE_LABEL, "ours median", t_ise, agg(np.median))
    table.add(ISE_LABEL, "ours best", t_ise, agg(np.min))
    table.add(ISE_LABEL, "ours worst", t_ise, agg(np.max))
    table.add(ISE_LABEL, "paper", np.nan, lambda a: paper.get((a, "ise"), np.nan))
    ex = {a: 100.0 * sub.loc[g[a].index, "excess_ise"].dropna() for a in ALGORITHMS}
    t_ex = 0.0 if any(len(v) for v in ex.values()) else np.nan
    for row, q in zip(EXCESS_ROWS, (0.5, 0.25, 0.75), strict=True):
        table.add(
            ISE_LABEL, row, t_ex, lambda a, q=q: float(ex[a].quantile(q)) if len(ex[a]) else np.nan
        )


# ------------------------------------------------------------------------- Tables 20 to 23
def objective_table(
    runs: pd.DataFrame, paper_objective: pd.DataFrame | None, scenario: int, alpha: float = 0.05
) -> pd.DataFrame:
    """Tables 20-23: ISE and ranks of one scenario, per case × algorithm, with the tests.

    Long: one row per case × algorithm (paper order). Columns:

    - ``Case``, ``Algorithm`` (paper heading), ``Seeds`` (runs with an ISE);
    - ``Mean ISE``, ``Median ISE`` (ours, over seeds);
    - ``Median excess (%)``, ``Excess q25 (%)``, ``Excess q75 (%)``: median and quartiles over
      seeds of the excess over the truth, 100·(ISE − ISE_true)/ISE_true (reproduction note E1);
    - ``Rank (mean)``, ``Rank (median)``: rank of the mean / median ISE (1 = lowest);
    - ``Mean rank``: mean over seeds of the per-seed rank (Friedman-style; complete seeds);
    - ``Paper ISE``, ``Paper rank (printed)`` (verbatim, e.g. "7 (Max.)"), ``Paper rank``;
    - ``AVOA vs this``: Holm-Wilcoxon verdict of AVOA against this algorithm ("AVOA lower",
      "AVOA higher", "no difference", "too few seeds"; :data:`VERDICT_TEXT`; empty on the AVOA
      row) and ``p (Holm)`` (two-sided, Holm over the six rivals). Both test for *a*
      difference, however small (on the excess where every run has one, else on the ISE; the
      same p-values);
    - ``AVOA − this (median, % of ISE_true)``: the median over seeds of the paired difference
      of the excess, AVOA's minus this algorithm's, in percent of the truth's ISE (< 0: AVOA
      lower); ``Margin (%)``: the equivalence margin of the case, a model error of 0.1 mV RMS
      (E2; same on every row of a case); both NaN when the runs have no excess;
    - ``AVOA vs this (size)``: whether the difference matters (E3; :data:`SIZE_TEXT`):
      "practically equivalent" when the two one-sided tests put it inside ±margin (``p equiv.
      (Holm)`` < α, Holm over the six rivals), else "AVOA lower" / "AVOA higher" when the
      difference test is significant, else "inconclusive"; "too few seeds" below
      ``stats.MIN_SEEDS`` matched seeds. Empty on the AVOA row;
    - ``Friedman p``: the case's Friedman test over all algorithms (same on every row of a case).

    Aggregates written before ``excess_ise`` existed get it from ``true_ise``
    (:func:`~avoa_pipeline.report.stats.with_excess`).
    """
    runs = stats.with_excess(runs)
    sub = runs[runs["scenario"] == scenario]
    po = _paper(paper_objective)
    if len(po):
        po = po[po["scenario"] == scenario]
    cases = sorted(set(sub["case"].astype(int)) | set(po["case"].astype(int) if len(po) else []))
    rk = stats.ranks(sub)
    rows = []
    for c in cases:
        tests = _case_tests(sub, scenario, c, alpha)
        rkc = rk[rk["case"] == c].set_index("algorithm")
        poc = po[po["case"] == c].set_index("algorithm") if len(po) else po
        for a in ALGORITHMS:
            r = rkc.loc[a] if a in rkc.index else None
            p = poc.loc[a] if len(poc) and a in poc.index else None
            rows.append(_objective_row(c, a, r, p, tests))
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    for col in ("Rank (mean)", "Rank (median)", "Paper rank"):
        out[col] = out[col].astype("Int64")
    text = {"Case", "Algorithm", "Seeds", "Paper rank (printed)", "AVOA vs this"}
    text |= {"AVOA vs this (size)", "Rank (mean)", "Rank (median)", "Paper rank"}
    for col in out.columns.difference(list(text)):
        out[col] = out[col].astype(float)
    return out


def _case_tests(sub: pd.DataFrame, scenario: int, c: int, alpha: float) -> dict:
    """What Tables 20-23 say of case ``c`` beyond each algorithm's ranks: the Friedman test
    (``friedman``), AVOA against each rival (``holm``, indexed by the rival), the scale of a
    difference (``pct``: 100 on the excess, NaN on the ISE), the equivalence ``margin`` and
    the excess's quartiles (``excess``, in %, indexed by algorithm)."""
    fr = stats.friedman(sub, scenario, c) if len(sub[sub["case"] == c]) else {"p": np.nan}
    has_avoa = ((sub["case"] == c) & (sub["algorithm"] == "avoa") & sub["best_ise"].notna()).any()
    hw = stats.holm_wilcoxon(sub, scenario, c, "avoa", alpha) if has_avoa else pd.DataFrame()
    hw = hw.set_index("other") if len(hw) else hw
    on_excess = stats.value_column(sub) == "excess_ise"  # what holm_wilcoxon compares
    pct = 100.0 if on_excess else np.nan  # a difference in V² is not a percentage
    margin = pct * stats.margin_of(sub, scenario, c)
    ex = sub[(sub["case"] == c) & sub["best_ise"].notna()].groupby("algorithm")["excess_ise"]
    ex_q = 100.0 * ex.quantile([0.25, 0.5, 0.75]).unstack()
    return {"friedman": fr, "holm": hw, "pct": pct, "margin": margin, "excess": ex_q}


def _objective_row(c: int, a: str, r, p, tests: dict) -> dict:
    """Algorithm ``a``'s row of case ``c``: its ranks ``r`` (None without runs), the paper's
    ``p`` (None if not printed) and the case's ``tests`` (:func:`_case_tests`)."""
    hw, ex_q, pct = tests["holm"], tests["excess"], tests["pct"]
    h = hw.loc[a] if len(hw) and a in hw.index else None
    q = ex_q.loc[a] if a in ex_q.index else None
    return {
        "Case": int(c),
        "Algorithm": PAPER_LABELS[a],
        "Seeds": int(r["n_seeds"]) if r is not None else 0,
        "Mean ISE": r["mean_ise"] if r is not None else np.nan,
        "Median ISE": r["median_ise"] if r is not None else np.nan,
        "Median excess (%)": q[0.5] if q is not None else np.nan,
        "Excess q25 (%)": q[0.25] if q is not None else np.nan,
        "Excess q75 (%)": q[0.75] if q is not None else np.nan,
        "Rank (mean)": r["rank_by_mean"] if r is not None else pd.NA,
        "Rank (median)": r["rank_by_median"] if r is not None else pd.NA,
        "Mean rank": r["mean_rank"] if r is not None else np.nan,
        "Paper ISE": float(p["ise"]) if p is not None else np.nan,
        "Paper rank (printed)": str(p["rank_printed"]) if p is not None else "",
        "Paper rank": int(p["rank"]) if p is not None else pd.NA,
        "AVOA vs this": VERDICT_TEXT[h["verdict"]] if h is not None else "",
        "p (Holm)": h["p_holm"] if h is not None else np.nan,
        "AVOA − this (median, % of ISE_true)": (
            pct * h["median_diff"] if h is not None else np.nan
        ),
        "Margin (%)": tests["margin"],
        "AVOA vs this (size)": SIZE_TEXT[h["size_verdict"]] if h is not None else "",
        "p equiv. (Holm)": h["p_tost_holm"] if h is not None else np.nan,
        "Friedman p": tests["friedman"]["p"],
    }


def accuracy_table(runs: pd.DataFrame, scenario: int | None = None) -> pd.DataFrame:
    """Parameter accuracy (reproduction note E7; not in the paper): per scenario × case, the
    share of seeds whose every identified parameter lies within 1 % (5 %) of the truth.

    Wide, like Tables 4-19: one column per algorithm (paper headings, paper order) after
    ``Scenario``, ``Case`` and ``Row``; per scenario × case present in ``runs`` (only
    ``scenario`` if given) the rows ``seeds within 1 % (all params) (%)``, ``seeds within 5 %
    (all params) (%)`` (percent of the algorithm's seeds with an ISE) and ``seeds`` (that count).
    An algorithm without runs in a case has NaN.
    """
    sub = runs if scenario is None else runs[runs["scenario"] == scenario]
    acc = stats.accuracy_shares(sub)
    labels = [PAPER_LABELS[a] for a in ALGORITHMS]
    rows = []
    for (s, c), part in acc.groupby(["scenario", "case"], sort=True):
        part = part.set_index("algorithm").reindex(list(ALGORITHMS))
        for tol, row in ACCURACY_ROWS.items():
            rows.append([int(s), int(c), row, *(100.0 * part[stats.share_column(tol)])])
        rows.append([int(s), int(c), "seeds", *part["n_seeds"].astype(float)])
    out = pd.DataFrame(rows, columns=["Scenario", "Case", "Row", *labels])
    for col in labels:
        out[col] = out[col].astype(float)
    return out


# ---------------------------------------------------------------------------------- Table 24
def time_table(
    runs: pd.DataFrame, paper_time: pd.DataFrame | None, scenario: int = 4, case: int = 4
) -> pd.DataFrame:
    """Table 24: computation time of scenario 4 case 4 (by default), ours against the paper.

    One row per algorithm. Columns: ``Algorithm``, ``Runs``; ours, means over seeds:
    ``Time/iter (s)`` (``time_per_iter_s``; optimizer wall time / iterations) with
    ``Time/iter sd (s)``, ``Evals/iter`` (objective evaluations per iteration after the initial
    population), ``Time/eval (ms)`` (``time_per_eval_s`` × 1000), ``Ratio to AVOA (iter)`` and
    ``Ratio to AVOA (eval)`` (this algorithm's mean over AVOA's); the paper's ``Paper time/iter
    (s)`` and ``Paper ratio to AVOA``. A ratio > 1: slower than AVOA.
    """
    sub = runs[(runs["scenario"] == scenario) & (runs["case"] == case)]
    pt = _paper(paper_time)
    paper = dict(zip(pt["algorithm"], pt["seconds"].astype(float), strict=True)) if len(pt) else {}
    g = sub.groupby("algorithm")
    mean = g[["time_per_iter_s", "evals_per_iter", "time_per_eval_s"]].mean()
    sd = g["time_per_iter_s"].std(ddof=1)
    n = g.size()

    def m(a, col):
        return float(mean.loc[a, col]) if a in mean.index else np.nan

    rows = []
    for a in ALGORITHMS:
        rows.append(
            {
                "Algorithm": PAPER_LABELS[a],
                "Runs": int(n.get(a, 0)),
                "Time/iter (s)": m(a, "time_per_iter_s"),
                "Time/iter sd (s)": float(sd.get(a, np.nan)),
                "Evals/iter": m(a, "evals_per_iter"),
                "Time/eval (ms)": 1000.0 * m(a, "time_per_eval_s"),
                "Ratio to AVOA (iter)": _ratio(
                    m(a, "time_per_iter_s"), m("avoa", "time_per_iter_s")
                ),
                "Ratio to AVOA (eval)": _ratio(
                    m(a, "time_per_eval_s"), m("avoa", "time_per_eval_s")
                ),
                "Paper time/iter (s)": paper.get(a, np.nan),
                "Paper ratio to AVOA": _ratio(paper.get(a, np.nan), paper.get("avoa", np.nan)),
            }
        )
    return pd.DataFrame(rows)
