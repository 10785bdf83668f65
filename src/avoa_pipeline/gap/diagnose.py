"""Sim-to-real gap diagnosis: where a model misses the training records, which unmodelled effect
it lacks, how much adding it helps, and the model a user should take (the method, its thresholds
and their reasons: docs/gap-diagnosis.md).

1. Base fit: the model library's base (``model/ecm.py``): the paper's rational OCV with free Vnom,
   β, capacity and initial SOC, or with ``--ocv`` the cell's measured OCV plus an offset; R0 and
   one RC branch. Several training records of one cell are fitted together (shared cell
   parameters, each record its own initial state).
2. Where: the base residual's energy by operating region, against a noise floor estimated from
   the residual's sample-to-sample differences where the current holds still.
3. Which, how far, and the ladder: every element of ``ecm.EFFECTS`` that the data can show,
   judged on held-out data by the one selection method (``avoa_pipeline.selection``).
4. The verdict's model (the ladder's last rung) is ``selected``; the model written as
   ``model.json`` is the one the hand-over rule chooses (``avoa_pipeline.handover``,
   docs/handover-rule.md), from candidates that include the verdict's model, with the error to
   expect on other profiles. Records passed for validation are predicted by every rung of the
   ladder and by the handed-over model, and never enter any choice.

Long records (issue 25; 10⁶ samples, 28 h at 10 Hz). What was done, and why this and not a
subset: the state (SOC, RC voltages, hysteresis) is a recursion through every sample, so every
sample is simulated; a fit's residuals are already every s-th sample (``fitting.MAX_FIT_POINTS``,
a fixed stride), and the held-out scores, tests, localization and signatures read every sample.
The cost was the simulator computing the terminal voltage (the OCV, its corrections, the
overpotentials) at all 10⁶ samples of every Jacobian pass although only 20,000 were returned.
The simulator now computes the voltage only at the samples returned, and across a held current
between two of them steps the state with the hold's increments computed once
(``ecm._loop``): the same operations in the same order, so every fit, score and verdict is bit
for bit what it was at every size (no size threshold is needed; 1e6-sample report identical to
the one before). Thinning *which* residuals enter a fit or a test, or coarsening the record,
would change verdicts and was not done. ``diagnosis.json``'s ``samples`` says it: given, fitted
per fit, the stride, and the residuals' correlation time and effective sample size (a stride
below the correlation time loses almost no information: neighbouring residuals repeat each
other). The cost still grows with the length and the ladder (measured in docs/benchmarks.md:
10⁶ samples 47 s of CPU, 0.66 GB; 2·10⁶ 192 s, 1.1 GB); after PROGRESS_AFTER_S a line per
finished stage goes to stderr.
"""

from __future__ import annotations

import sys
import time

import numpy as np
import pandas as pd
from scipy import stats
from threadpoolctl import threadpool_limits

from .. import __version__, handover, records, selection
from ..errors import DataError, UserError
from ..model import ecm, elements, fitting, intervals, ocv
from ..model.ecm import Record
from ..model.elements.element import View
from ..model.fitted import (
    FittedModel,
    reference_temperature,
)
from ..records import REST_FRACTION, STEP_FRACTION, Checked

MIN_SAMPLES = 2000
"""Shorter records cannot be split into the held-out blocks long enough to hold a relaxation."""
REGION_MIN_SHARE = 0.02
TIME_WINDOWS = 20
UNEXPLAINED_RATIO = 1.2  # base RMSE / noise floor above which a `none` verdict says a gap remains

PROGRESS_AFTER_S = 10.0
"""A diagnosis says where it is on stderr once it has run this long, never before: a quick one
(the tests' and the withheld-effect grid's records, seconds each) stays silent, and a long record
(10⁶ samples take minutes) is not silent for minutes. stdout keeps its one line."""

BLAS_THREADS = 1
"""BLAS threads during a diagnosis (issue 28's time goal). Its linear algebra is scipy's
``least_squares`` on tall, thin Jacobians (≤ 20,000 residuals × ≤ 30 parameters): an SVD and a
few products per iteration, far too small to share between threads. With OpenBLAS's default (one
thread per core) the threads wait for each other and spin, taking the cores from the compiled
simulator: on this 2-core machine under load, an SVD of a 20,000 × 25 Jacobian took 240 ms with 2
threads and 29 ms with one, and the first rung of a two-temperature Panasonic diagnosis (up to
its base held out, selection on one thread) fell from 58.7 s to 7.1 s, its SVDs from 11.2 s to
0.26 s (``benchmarks/bench_joint.py --until ... --profile``, docs/real-data.md "Time of the joint
fit"; the whole joint fit: 1,802 s before, 1,420 s after, with the selection's threads).
One thread also makes the diagnosis's numbers independent of the machine's core count: a
threaded BLAS splits its sums by the number of threads, which changes their last bits."""

# trimmed standard deviation of a normal (1 % per tail) relative to the untrimmed one
_Z_TRIM = stats.norm.ppf(0.99)
_TRIM_SD = float(stats.truncnorm(-_Z_TRIM, _Z_TRIM).std())


# ----------------------------------------------------------------------------------------------
# input: checked records (``inputs.py`` reads files; a frame given here is checked once, here)


def _checked(items, source) -> list[Checked]:
    """Checked records of records or frames (a dict: name → record or frame)."""
    if isinstance(items, dict):
        items, source = list(items.values()), list(items)
    items = [items] if isinstance(items, pd.DataFrame | Checked) else list(items)
    names = [source] if isinstance(source, str) else list(source)
    if len(names) != len(items):
        names = [f"{names[0]}[{j}]" for j in range(len(items))]
    return [x if isinstance(x, Checked) else records.check(x, s)
            for x, s in zip(items, names, strict=True)]  # fmt: skip


def check_options(train: list[Checked], validate: list[Checked], capacity_ah, soc0,
                  ocv_table, current_accuracy_a=None) -> None:  # fmt: skip
    """What the diagnosis needs of its checked inputs together, before any fit: long enough
    training records, the same columns everywhere, options in range, a capacity and an OCV that
    the records allow (``records.check_capacity``). One-line DataError/UserError."""
    if not train:
        raise UserError("no training record")
    for c in train:
        if c.n < MIN_SAMPLES:
            raise DataError(f"{c.source}: {c.n} samples; the diagnosis needs at least "
                            f"{MIN_SAMPLES}")  # fmt: skip
    cols = set(train[0].frame.columns)
    for c in (*train[1:], *validate):
        if set(c.frame.columns) != cols:
            raise DataError(f"{c.source}: columns {', '.join(c.frame.columns)} differ from the "
                            f"training record's {', '.join(train[0].frame.columns)}")  # fmt: skip
    if soc0 is not None:
        if len(train) > 1:
            raise UserError("--soc0 gives one record's initial SOC; with several training "
                            "records leave it out (each record's is fitted)")  # fmt: skip
        if not (np.isfinite(soc0) and 0.0 <= soc0 <= 1.0):
            raise UserError(f"--soc0 must lie in [0, 1], got {soc0}")
    if current_accuracy_a is not None and not (np.isfinite(current_accuracy_a)
                                               and current_accuracy_a > 0):  # fmt: skip
        raise UserError(f"--current-accuracy-a must be a positive current (A), got "
                        f"{current_accuracy_a}")  # fmt: skip
    every = [*train, *validate]
    swing = max(records.charge_swing_ah(c.frame["time_s"], c.frame["current_a"]) for c in every)
    scale = max(records.current_scale(c.frame["current_a"]) for c in train)
    if capacity_ah is not None:
        records.check_capacity(capacity_ah, swing, scale, "--capacity-ah")
    q_ocv = getattr(ocv_table, "capacity_ah", None)
    if q_ocv:  # the slow test's charge is a capacity in its own units: the units must agree
        records.check_capacity(q_ocv, 0.0, scale, f"{ocv_table.source}: the slow branch's")
        if swing > records.CAPACITY_MARGIN * q_ocv:
            raise DataError(f"{ocv_table.source}: the slow branch moves {q_ocv:.4g} Ah, less than "
                            f"the {swing:.4g} Ah the records move; it does not span the cell "
                            "(a partial test?)")  # fmt: skip
        if capacity_ah is not None and q_ocv * records.CAPACITY_MARGIN < capacity_ah:
            raise DataError(f"{ocv_table.source}: the slow branch moves {q_ocv:.4g} Ah, less than "
                            f"--capacity-ah {capacity_ah:g} Ah; its SOC 0-1 would cover part of "
                            "the cell only")  # fmt: skip
    known = capacity_ah if capacity_ah is not None else q_ocv
    if known:  # a known capacity tells units the records alone cannot (records.check_scale)
        for c in every:
            records.check_scale(c.frame, c.source, known)


def sanity(base_rmse_v: float, v: np.ndarray, sources) -> None:
    """Stop when the base model explains the records worse than their own mean voltage does: the
    inputs then do not describe one cell (a unit, a sign, an OCV of another cell)."""
    sd = float(np.std(v))
    if base_rmse_v > sd:
        raise DataError(f"{', '.join(sources)}: the base model misses the records by "
                        f"{1e3 * base_rmse_v:.4g} mV RMS, more than their voltage varies "
                        f"({1e3 * sd:.4g} mV SD): the inputs do not describe one cell (check the "
                        "units and sign of current_a and voltage_v, and the --ocv)")  # fmt: skip


class Progress:
    """One line per finished stage on ``stream`` (``diagnose: 41 s: rung 1: hysteresis fitted
    (4/12)``), from PROGRESS_AFTER_S on."""

    def __init__(self, stream, t0: float):
        self.stream, self.t0 = stream, t0

    def __call__(self, what: str) -> None:
        elapsed = time.perf_counter() - self.t0
        if self.stream is not None and elapsed >= PROGRESS_AFTER_S:
            print(f"diagnose: {elapsed:.0f} s: {what}", file=self.stream, flush=True)


# ----------------------------------------------------------------------------------------------
# pieces


def noise_floor(rec: Record, resid: np.ndarray) -> float:
    """Voltage noise RMS (V) from the residual's differences where the current holds still.

    White noise of RMS σ gives differences of RMS σ√2; the model's smooth misfit adds almost
    nothing between neighbouring samples. Samples next to a current step are left out (a misfit
    of R0 jumps there), and 1 % of each tail is trimmed (outliers) with the normal correction.
    """
    d = np.diff(resid)
    quiet = np.abs(np.diff(rec.i)) <= REST_FRACTION * rec.imax()
    if quiet.sum() >= 200:
        d = d[quiet]
    lo, hi = np.quantile(d, [0.01, 0.99])
    kept = d[(d >= lo) & (d <= hi)]
    if kept.size < 2 or np.std(kept) == 0:
        return float(np.sqrt(np.mean(d**2) / 2.0))
    return float(np.std(kept) / _TRIM_SD / np.sqrt(2.0))


# ----------------------------------------------------------------------------------------------
# where


def region_masks(rec: Record, soc: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
    """(group, region, mask) for every operating region of the localization."""
    imax = rec.imax()
    a = np.abs(rec.i)
    d = records.direction(rec.i, imax)
    out = [
        ("mode", "rest", d == 0),
        ("mode", "load", d != 0),
        ("direction", "discharge", d > 0),
        ("direction", "charge", d < 0),
    ]
    since, _ = steps_of(rec)
    out += [
        ("since_step", "since step < 10 s", since < 10.0),
        ("since_step", "since step 10-600 s", (since >= 10.0) & (since < 600.0)),
        ("since_step", "since step > 600 s", since >= 600.0),
    ]
    edges = np.linspace(0.0, 1.0, 6)
    sc = np.clip(soc, 0.0, 1.0)
    for j in range(5):
        m = (sc >= edges[j]) & ((sc < edges[j + 1]) if j < 4 else (sc <= 1.0))
        out.append(("soc", f"SOC {edges[j]:.1f}-{edges[j + 1]:.1f}", m))
    thr = REST_FRACTION * imax
    cut = [thr, imax / 3, 2 * imax / 3]
    out.append(("current", f"|I| < {thr:.3g} A", a < thr))
    out.append(("current", f"|I| {cut[0]:.3g}-{cut[1]:.3g} A", (a >= cut[0]) & (a < cut[1])))
    out.append(("current", f"|I| {cut[1]:.3g}-{cut[2]:.3g} A", (a >= cut[1]) & (a < cut[2])))
    out.append(("current", f"|I| >= {cut[2]:.3g} A", a >= cut[2]))
    if rec.temperature_varies:
        q = np.quantile(rec.temp_c, [0, 0.25, 0.5, 0.75, 1.0])
        for j in range(4):
            hi_ok = rec.temp_c <= q[j + 1] if j == 3 else rec.temp_c < q[j + 1]
            m = (rec.temp_c >= q[j]) & hi_ok
            out.append(("temperature", f"T {q[j]:.1f}-{q[j + 1]:.1f} °C", m))
    return out


def steps_of(rec: Record) -> tuple[np.ndarray, np.ndarray]:
    """Per sample, the seconds since the last current step (the record's start counts as one)
    and that step's sign (+1 a rising current, 0 before any step)."""
    di = np.diff(rec.i)
    idx = np.flatnonzero(np.abs(di) > STEP_FRACTION * rec.imax()) + 1
    last = np.zeros(rec.n, dtype=int)
    last[idx] = idx
    last = np.maximum.accumulate(last)
    sign = np.zeros(rec.n)
    sign[idx] = np.sign(di[idx - 1])
    return rec.t - rec.t[last], sign[last]


def localize(rec, resid, soc, noise_v) -> tuple[list[dict], list[dict]]:
    total = float(np.sum(resid**2))
    regions = []
    for group, name, m in region_masks(rec, soc):
        n = int(m.sum())
        if n == 0:
            continue
        e = float(np.sum(resid[m] ** 2))
        rmse = float(np.sqrt(e / n))
        regions.append(
            {
                "group": group,
                "region": name,
                "n": n,
                "time_share": n / rec.n,
                "share": e / total if total > 0 else 0.0,
                "rmse_mv": 1e3 * rmse,
                "ratio_to_noise": rmse / noise_v if noise_v > 0 else None,
                "mean_mv": 1e3 * float(np.mean(resid[m])),
            }
        )
    edges = np.linspace(rec.t[0], rec.t[-1], TIME_WINDOWS + 1)
    windows = []
    for j in range(TIME_WINDOWS):
        m = (rec.t >= edges[j]) & ((rec.t < edges[j + 1]) if j < TIME_WINDOWS - 1 else True)
        n = int(m.sum())
        if n == 0:
            continue
        e = float(np.sum(resid[m] ** 2))
        windows.append(
            {
                "t_start_s": float(edges[j]),
                "t_end_s": float(edges[j + 1]),
                "share": e / total if total > 0 else 0.0,
                "rmse_mv": 1e3 * float(np.sqrt(e / n)),
            }
        )
    return regions, windows


def gap_region(regions: list[dict], n: int) -> dict:
    """The region where the misfit concentrates: the highest RMSE among regions of size."""
    big = [r for r in regions if r["n"] >= max(100, REGION_MIN_SHARE * n) and r["time_share"] < 1]
    return max(big or regions, key=lambda r: r["rmse_mv"])


# ----------------------------------------------------------------------------------------------
# why: residual signatures


def signatures(rec, resid, soc, cands: dict, base: selection.Candidate, regions_of) -> dict:
    """Per element with a signature of its own (``Element.signature``): what the base residual
    looks like where that element would act, and how much of it the element's fit explains."""

    def t_mean(r):
        return selection.loss_test(r, np.zeros_like(r), regions_of)[0]

    since, step_sign = steps_of(rec)
    d = records.direction(rec.i, rec.imax())
    view = View(rec, resid, soc, since, step_sign, d, rec.imax(), t_mean)
    out = {e.name: {"acts": e.signature.acts, **e.signature.read(view)}
           for e in elements.REGISTRY.values() if not isinstance(e.signature, str)}  # fmt: skip
    for e, cand in cands.items():
        if e in out and cand is not None:
            delta = cand.v - base.v  # what the effect adds to the base model's voltage
            den = float(np.sum(resid**2))
            share = 1.0 - float(np.sum((resid - delta) ** 2)) / den if den else 0.0
            out[e]["explained_share"] = share
            out[e]["correction_rms_mv"] = 1e3 * float(np.sqrt(np.mean(delta**2)))
    return out


def samples_used(ctx: selection.Context, models: dict[str, selection.Candidate]) -> dict:
    """What of the records entered the diagnosis (``diagnosis.json``'s ``samples``): every
    sample is simulated and scored; each least-squares fit sees every s-th residual. Beside it,
    per model of ``models``, its residual's correlation time and effective sample size: a stride
    below the correlation time (fitted ≥ effective samples) drops residuals that repeat their
    neighbours and loses almost no information; on a residual at the white noise floor the fits
    average 1/stride of the noise they could (their parameters' noise SD √stride larger)."""
    idx = fitting.indices(ctx.recs, None, fitting.MAX_FIT_POINTS)
    strides = [int(i[1] - i[0]) if i.size > 1 else 1 for i in idx]
    tau = {k: intervals.autocorrelation_time(ctx.v - r.v) for k, r in models.items()}
    return {
        "given": ctx.n,
        "fitted": int(sum(i.size for i in idx)),
        "stride": strides[0] if len(strides) == 1 else strides,
        "method": "the state simulated through every sample; each fit's residuals at a fixed "
                  f"stride, at most {fitting.MAX_FIT_POINTS} per fit (the terminal voltage "
                  "computed only there); held-out scores, tests, localization and signatures on "
                  "every sample",
        "residual_correlation_samples": tau,
        "effective_samples": {k: ctx.n / max(t, 1.0) for k, t in tau.items()},
    }  # fmt: skip


# ----------------------------------------------------------------------------------------------
# the diagnosis


def diagnose_records(train, capacity_ah=None, soc0=None, source="<data>", ocv_table=None,
                     validate=(), warnings=(), progress=True,
                     current_accuracy_a=None):  # fmt: skip
    """The diagnosis report (JSON-able dict), the arrays its figure needs, and the selected model.

    ``train``: the cell's checked training records (``records.Checked``, as ``inputs.py`` reads
    them), one or a list; a DataFrame is checked here (``records.check``) and named by
    ``source``. ``ocv_table``: the cell's measured OCV (``model.ocv``), or None for the rational
    curve. ``validate``: checked records never used for any choice. ``warnings``: what the input
    layer found odd, carried into the report. Every option is checked before the first fit.
    ``progress``: where a long diagnosis says where it is (True: stderr; None or False: nowhere;
    or a text stream). ``current_accuracy_a``: the cycler channel's current accuracy the
    hand-over rule judges a current offset by (default: ``handover.CURRENT_ACCURACY_OF_IMAX`` of
    the largest current). Runs with ``BLAS_THREADS`` BLAS threads (why: its docstring).
    """
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"):
        return _diagnose_records(train, capacity_ah, soc0, source, ocv_table, validate, warnings,
                                 progress, current_accuracy_a)  # fmt: skip


def _diagnose_records(train, capacity_ah, soc0, source, ocv_table, validate, warnings, progress,
                      current_accuracy_a=None):  # fmt: skip
    """The body of :func:`diagnose_records`."""
    t_start = time.perf_counter()
    train = _checked(train, source)
    validate = _checked(validate, "<validate>") if validate is not None and len(validate) else []
    check_options(train, validate, capacity_ah, soc0, ocv_table, current_accuracy_a)
    sources = [c.source for c in train]
    vframes = {c.source: c.frame for c in validate}
    notes = list(dict.fromkeys([*warnings, *(w for c in (*train, *validate) for w in c.warnings)]))
    ctx = _context(train, ocv_table, capacity_ah, soc0)
    ctx.progress = Progress(sys.stderr if progress is True else progress or None, t_start)

    # 1. base fit, and the sanity gate before anything else is spent on it
    base = _fit_base(ctx, sources, capacity_ah, soc0)

    # 3. which, and the whole ladder: the one selection method
    lad = selection.ladder(ctx, base)
    base, cands, rows, final = lad.base, lad.candidates, lad.rows, lad.selected
    for r in rows:
        r["params"] = selection.parameters(ctx, cands[r["effect"]])
        r["applicable"] = True

    # 2. where (the base residual, against the noise floor)
    rec, resid, soc, noise_v, regions, windows = _where(ctx, base)
    gap = gap_region(regions, rec.n)
    sig = signatures(rec, resid, soc, cands, base, ctx.layout.batches)

    # 4. how far
    iv = intervals.of_fit(ctx.recs, final.st, final.X)
    undecided = _undecided(final, iv, len(ctx.recs))
    verdict, rungs = _verdict(ctx, lad, rec, soc, gap, noise_v, undecided)
    remaining = float(np.sqrt(ctx.ho_mse(final))) / noise_v if noise_v > 0 else None
    selected = _selected(ctx, final)

    # 5. the model handed over (docs/handover-rule.md): its own rule, the verdict's model among
    # its candidates
    ho = handover.hand_over(ctx, lad, current_accuracy_a)
    handed = {**handover.report(ho), "parameters": selection.parameters(ctx, ho.chosen.cand)}
    model = _handed_over_model(ctx, ho, selected["name"])
    notes += [w for w in ho.warnings if w not in notes]

    report = {
        "source": sources[0] if len(sources) == 1 else sources,
        "undecided": undecided,
        "intervals": model.intervals,
        "at_bounds": model.at_bounds(),  # set by the bounds, not by the records
        "n_samples": rec.n,
        "samples": samples_used(ctx, {"base": base, "selected": final}),
        "duration_s": float(sum(r.t[-1] - r.t[0] for r in ctx.recs)),
        "records": _records(ctx.recs, train),
        "warnings": notes,
        "ocv": _ocv(ctx.table),
        "base": {
            **_base(ctx, base, rec.n, noise_v, capacity_ah, soc0),
            **_degeneracy(ctx, base, iv if final is base else None, capacity_ah),
        },
        "localization": regions,
        "time_windows": windows,
        "gap_region": gap["region"],
        "candidates": rows + lad.skipped,
        "verdict": verdict,
        "ladder": lad.rungs,
        "pruned": [{k: v for k, v in p.items() if k != "params"} for p in lad.pruned],
        "selected": selected,
        "handed_over": handed,
        "final_heldout_rmse_to_noise": remaining,
        "signatures": sig,
        "method": _method(ctx),
        "wall_s": time.perf_counter() - t_start,
        "version": __version__,
    }
    if vframes:  # records never used for any choice, predicted by every rung
        ctx.say(f"ladder done ({selected['name']}); validation records")
        floor = selection.floors(ctx, final, vframes, capacity_ah)
        report["validation"] = selection.validation(ctx, rungs, vframes, floor)
        report["floors"] = [{"record": k, "model": selected["name"], **f} for k, f in floor.items()]
        _validate_handed_over(ctx, report, ho, final, vframes, floor, capacity_ah)
    return _jsonable(report), _arrays(ctx, lad, rec, soc), model


def _validate_handed_over(ctx, report: dict, ho, final, vframes: dict, floor: dict,
                          capacity_ah) -> None:  # fmt: skip
    """The validation rows of the handed-over model (model name ``handed_over``), beside each
    its own configuration's floor (the verdict's where the two configurations are one)."""
    chosen = ho.chosen.cand
    if frozenset(chosen.effects) != frozenset(final.effects):
        floor = selection.floors(ctx, chosen, vframes, capacity_ah)
        report["floors"] += [{"record": k, "model": "handed_over", **f} for k, f in floor.items()]
    report["validation"] += selection.validation(ctx, {"handed_over": chosen}, vframes, floor)


def _fit_base(ctx: selection.Context, sources, capacity_ah, soc0) -> selection.Candidate:
    """The base fit, refused (``sanity``) before anything else is spent on a base that does not
    fit at all."""
    base = selection.fit_base(ctx, capacity_ah, soc0)
    sanity(float(np.sqrt(base.rss / ctx.n)), ctx.v, sources)
    ctx.say(f"base fit done ({ctx.n:,} samples, "
            f"{sum(i.size for i in fitting.indices(ctx.recs, None, fitting.MAX_FIT_POINTS)):,} "
            "fitted)")  # fmt: skip
    return base


def _context(train: list[Checked], table, capacity_ah, soc0) -> selection.Context:
    """The selection's context of the training records: one reference temperature for all."""
    frames = [c.frame for c in train]
    tref = reference_temperature(frames)
    recs = [Record.from_frame(c.frame, tref_k=tref, source=c.source) for c in train]
    return selection.Context(recs, table, capacity_ah, soc0)


def _where(ctx: selection.Context, base: selection.Candidate):
    """The records joined, the base's residual and SOC, the noise floor, and where the base
    misses beyond it (``localize``)."""
    rec = Record.join(ctx.recs)
    resid = ctx.v - base.v
    soc = np.concatenate([ecm.simulate_rows(r, base.X[j], base.st.knots, ctx.table,
                                            traces=True)[1][0]
                          for j, r in enumerate(ctx.recs)])  # fmt: skip
    noise_v = noise_floor(rec, resid)
    regions, windows = localize(rec, resid, soc, noise_v)
    return rec, resid, soc, noise_v, regions, windows


def _handed_over_model(ctx, ho, verdict_model: str) -> FittedModel:
    """The model.json: the handed-over model, with its intervals (diagnosis.json carries the
    same), the error to expect on other profiles, and the verdict's model named beside the
    rule."""
    table = ctx.table
    model = selection.fitted_model(ctx, ho.chosen.cand, provenance={
        "selected_by": f"avoa_pipeline gap diagnosis: {handover.RULE}",
        "verdict_model": verdict_model,
        "training": [{"source": r.source, "n_samples": r.n} for r in ctx.recs],
        "ocv": None if table is None else {"source": table.source, "how": table.how},
        "package_version": __version__,
    })  # fmt: skip
    model.intervals = ho.chosen.iv.report()
    model.expected_error = _jsonable(handover.expected_error(ctx, ho))
    return model


def _heldout_mv(ctx: selection.Context, cand: selection.Candidate, m=None) -> float:
    return 1e3 * float(np.sqrt(ctx.ho_mse(cand, m)))


def _verdict(ctx, lad, rec: Record, soc: np.ndarray, gap: dict, noise_v: float, undecided):
    """The verdict (the ladder's first rung against the base, on held-out data and inside the
    gap region; ``cannot_tell``: the selected elements the records do not identify) and the
    models of the ladder by name (base, each rung, the pruned selection)."""
    base, cands, rows, winner, final = lad.base, lad.candidates, lad.rows, lad.winner, lad.selected
    verdict = {"effect": "none", "shrink": 0.0}
    rungs = {"base": base}
    if winner is not None:
        gap_mask = {name: m for _, name, m in region_masks(rec, soc)}[gap["region"]]
        w = cands[winner]
        row = next(r for r in rows if r["effect"] == winner)
        loss_b, loss_w = ctx.w * ctx.ho_loss(base), ctx.w * ctx.ho_loss(w)
        verdict = {
            "effect": winner,
            "shrink": row["shrink"],
            "heldout_rmse_before_mv": _heldout_mv(ctx, base),
            "heldout_rmse_after_mv": _heldout_mv(ctx, w),
            "region": gap["region"],
            "region_heldout_rmse_before_mv": _heldout_mv(ctx, base, gap_mask),
            "region_heldout_rmse_after_mv": _heldout_mv(ctx, w, gap_mask),
            "region_shrink": 1.0 - float(loss_w[gap_mask].sum() / loss_b[gap_mask].sum()),
            "delta_bic": row["delta_bic"],
            "t": row["t"],
        }
        for lr, r in zip(lad.rungs, lad.chosen, strict=True):
            lr["parameters"] = selection.parameters(ctx, r)
            rungs["+".join(r.effects)] = r
        rungs.setdefault("+".join(final.effects) or "base", final)  # after pruning
    else:
        _no_winner(verdict, lad, rec, noise_v)
    if undecided:
        verdict["cannot_tell"] = [u["effect"] for u in undecided]
    return verdict, rungs


def _no_winner(verdict: dict, lad, rec: Record, noise_v: float) -> None:
    """What the verdict says when no element pays: the best candidate, and whether the base
    already fits to the noise."""
    rows, base = lad.rows, lad.base
    best = max((r for r in rows if r["shrink"] is not None), key=lambda r: r["shrink"],
               default=None)  # fmt: skip
    if best is not None:
        verdict["best_candidate"] = best["effect"]
        verdict["best_candidate_shrink"] = best["shrink"]
    ratio = float(np.sqrt(base.rss / rec.n)) / noise_v if noise_v > 0 else np.inf
    verdict["note"] = (
        "the base model fits to about the noise floor"
        if ratio < UNEXPLAINED_RATIO
        else "a misfit beyond the noise floor that no candidate explains on held-out data"
    )


def _selected(ctx: selection.Context, final: selection.Candidate) -> dict:
    return {
        "name": "+".join(final.effects) or "base",
        "effects": list(final.effects),
        "heldout_rmse_mv": _heldout_mv(ctx, final),
        "parameters": selection.parameters(ctx, final),
    }


def _undecided(final: selection.Candidate, iv: intervals.Intervals, n_records: int) -> list:
    """The selected elements the records do not identify (docs/admission-rule.md), each with the
    record that would decide it."""
    return [
        {"effect": e, "why": why, "would_decide": elements.get(e).would_decide
         + ("; or a second profile of the cell" if n_records == 1 else "")}
        for e in final.effects if (why := selection.identified(iv, e)) is not None
    ]  # fmt: skip


def _records(recs: list[Record], train: list[Checked]) -> list[dict]:
    return [
        {
            "source": r.source,
            "n_samples": r.n,
            "starts_at_rest": ecm.starts_at_rest(r),
            "step_resistance_ohm": c.sign.resistance_ohm,
            "sign": c.sign.as_dict(),
            "read_as": c.origin.get("read_as", "frame"),
        }
        for r, c in zip(recs, train, strict=True)
    ]


def _ocv(table) -> dict:
    if table is None:
        return {"kind": "rational (eq. 5), Vnom and beta free"}
    return {"kind": "measured table + fitted offset", "source": table.source, "how": table.how,
            "capacity_ah": table.capacity_ah}  # fmt: skip


def _base(ctx, base: selection.Candidate, n: int, noise_v: float, capacity_ah, soc0) -> dict:
    rmse = float(np.sqrt(base.rss / n))
    return {
        "model": (
            "1-RC, "
            + ("rational OCV" if ctx.table is None else "measured OCV + offset")
            + ", free capacity; each record started by the opening rule"
        ),
        "parameters": selection.parameters(ctx, base),
        "rmse_mv": 1e3 * rmse,
        "heldout_rmse_mv": _heldout_mv(ctx, base),
        "noise_floor_mv": 1e3 * noise_v,
        "rmse_to_noise": rmse / noise_v if noise_v > 0 else None,
        "n_params": base.k,
        "capacity_given": capacity_ah is not None,
        "soc0_given": soc0 is not None,
        "fit_check": base.check.report() if base.check else None,  # fitting.check_fit
    }


def _degeneracy(ctx: selection.Context, base: selection.Candidate, iv, capacity_ah) -> dict:
    """What decides the base's offset and capacity, and which of its parameters the records do
    not tell apart (issue 37): the pairs of the base fit's intervals correlated beyond
    ``intervals.CORR_LIMIT`` (``iv``: the base's intervals if already computed). Each record's
    initial SOC is no free parameter but follows from the others by the opening rule, so a pair
    of the capacity with the OCV's level (the offset, or Vnom and β) moves it along."""
    iv = iv or intervals.of_fit(ctx.recs, base.st, base.X)
    out = {"degenerate": [[ecm.PARAMS[a].report, ecm.PARAMS[b].report, c]
                          for a, b, c in iv.pairs()]}  # fmt: skip
    if ctx.table is not None:
        sd, why = ocv.offset_prior(ctx.table)
        k = base.st.shared.index("voff")
        out["offset"] = {"prior_mean_v": 0.0, "prior_sd_v": sd, "why": why,
                         "bounds_v": [float(base.st.lo[k]), float(base.st.hi[k])]}  # fmt: skip
    cap = None if ctx.table is None else ocv.capacity_prior(ctx.table)
    if capacity_ah is not None:
        out["capacity"] = {"from": "given (--capacity-ah), held"}
    elif cap is not None:
        out["capacity"] = {"from": "the slow test's: start and Gaussian prior",
                           "prior_ah": cap[0], "prior_sd_ah": cap[1]}  # fmt: skip
    else:
        out["capacity"] = {"from": "the records alone (free, no prior)"}
    return out


def _method(ctx: selection.Context) -> dict:
    return {
        "held_out": (
            "whole records (leave one out)" if ctx.layout.by_record else "interleaved blocks"
        ),
        "folds": len(ctx.layout.folds),
        "blocks_per_fold": None if ctx.layout.by_record else selection.BLOCKS_PER_FOLD,
        "batches": len(ctx.layout.batches),
        "records_weighted_alike": True,
        "initial_state": f"SOC0 from the opening rest's last {ecm.OPENING_WINDOW_S:g} s, or, "
        "for a record that starts under load, the SOC that zeroes the model's mean residual "
        f"over its first {ecm.OPENING_WINDOW_S:g} s (each window at least "
        f"{ecm.MIN_OPENING_SAMPLES} samples where the record has them); h0 = 0",
        "min_shrink": selection.MIN_SHRINK,
        "alpha_family": selection.ALPHA,
        "bic_max": selection.BIC_MAX,
        "fit_points_max": fitting.MAX_FIT_POINTS,
        "fits": ctx.fits,
    }


def _arrays(ctx: selection.Context, lad, rec: Record, soc: np.ndarray) -> dict:
    """What the diagnosis figure draws."""
    base, final, cands, winner = lad.base, lad.selected, lad.candidates, lad.winner
    return {
        "t": rec.t,
        "i": rec.i,
        "v": rec.v,
        "v_base": base.v,
        "ho_base": base.ho,
        "v_final": final.v,
        "ho_final": final.ho,
        "v_verdict": cands[winner].v if winner else None,
        "ho_verdict": cands[winner].ho if winner else None,
        "soc": soc,
        "fold": ctx.layout.fold_of(),
        "by_record": ctx.layout.by_record,
    }


def diagnose(train, capacity_ah: float | None = None, soc0: float | None = None,
             source="<data>", **kw) -> dict:  # fmt: skip
    """The diagnosis (the dict written to diagnosis.json) of checked records or frames (as
    :func:`diagnose_records`); DataError on bad input."""
    return diagnose_records(train, capacity_ah, soc0, source, **kw)[0]


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.bool_ | bool):
        return bool(obj)
    if isinstance(obj, np.integer | int):
        return int(obj)
    if isinstance(obj, np.floating | float):
        x = float(obj)
        return x if np.isfinite(x) else None
    return obj
