"""The model handed over: which model predicts this cell best, chosen by a rule of its own beside
the ladder's verdict (docs/handover-rule.md, issue 37 parts 2 and 3).

The ladder (``selection.ladder``) answers "which unmodelled effect explains the gap" and keeps
its sensitivity; this module answers "which model does a user take". Its candidates: the base,
the base plus ``second_rc`` (the plain 2RC circuit), the verdict's model reduced to the elements
that pass the hand-over conditions (:func:`reduce`), and that reduced model with a second RC
branch. Each is fitted to all training records by the selection's one fit (``Context.fit``:
``fitting.best_of``, the same starts, fit check and initial-state rule), checked element by
element (:func:`failures`: identified as ``selection.identified`` judges it, no parameter at a
bound of its searched range, ``current_offset`` judged against the cycler's accuracy) and scored
on held-out training data used the way a model is used (:func:`score`: leave one record out with
two or more records, through the selection's ``Context.cross_validate``; forward stretches after
50 % and 75 % of a single record). The choice is the strict minimum of the score over the
eligible candidates, an exact tie going to fewer parameters (:func:`hand_over`).

The same held-out predictions give the error to expect on other profiles (:func:`expected_error`,
``model.json``'s ``expected_error``): the RMS, by operating point where at least
:data:`MIN_BIN_SAMPLES` held-out samples support it, and the correlation time of the error.

Hand-written: the rule is this project's own (the candidates, the conditions, the two held-out
layouts); the fitting, held-out prediction and intervals it uses are the selection's and the
model layer's.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from . import records, selection
from .model import ecm, fitting, heat, intervals
from .selection import Candidate, Context

RULE = (
    "the hand-over rule (docs/handover-rule.md): the eligible candidate with the lowest "
    "held-out error"
)

CURRENT_ACCURACY_OF_IMAX = 1e-3
"""A cycler channel's current accuracy as a share of the records' largest |current|: the stated
accuracy is about 0.05 % of the channel's range (Arbin LBT, Neware BTS4000, Maccor Series 4000
datasheets) and a range is set above the largest current, typically the next range up, about
twice it: 0.05 % × 2 = 0.1 % of the largest current. ``--current-accuracy-a`` states it instead."""
FAULT_FACTOR = 3.0
"""A fitted current offset beyond 3 × the channel's accuracy is no cell parameter but an
instrument fault (a channel within its specification stays inside its stated accuracy; three
times it leaves room for the accuracy being a typical, not a worst-case, figure)."""
FORWARD_CUTS = (0.5, 0.75)
"""One training record: the cuts of the forward stretches (a model fitted to the samples before
each predicts those after it): two cuts, so the score does not rest on one stretch, each leaving
at least a quarter of the record to predict."""
MIN_BIN_SAMPLES = 200
"""An operating-point bin of the expected error is reported only with at least 200 held-out
samples: the RMS of n samples whose error is correlated over τ samples has a relative standard
error of about √(τ/2n); with 200 samples it is below 25 % for τ up to 25 samples."""
SOC_EDGES = (0.2, 0.8)
"""The SOC bins of the expected error: below 0.2 and above 0.8 the OCV's slope and the
resistances change fastest (the two knees of a lithium-ion OCV), between them the plateau."""
ONE_OVER_E = float(np.exp(-1.0))
"""The correlation time is the lag at which the error's autocorrelation first falls below 1/e
(an AR(1) error's time constant)."""
SECOND_RC = selection.SECOND_RC


@dataclass
class Entry:
    """One candidate of the rule: its fit to all training records, the conditions its own
    elements fail (element → reasons), its score and held-out errors."""

    name: str
    cand: Candidate
    failed: dict[str, list[str]] = field(default_factory=dict)
    iv: intervals.Intervals | None = None
    warnings: list[str] = field(default_factory=list)
    score: float | None = None  # held-out mean squared error (V²), records alike
    held: list = field(default_factory=list)  # (record index, sample indices, errors) segments

    @property
    def effects(self) -> tuple[str, ...]:
        return self.cand.effects

    @property
    def eligible(self) -> bool:
        return not self.failed


@dataclass
class HandOver:
    """The rule's result: the chosen entry, every entry in order, the verdict's elements and what
    became of each, the warnings (instrument faults), the score's kind."""

    chosen: Entry
    entries: list[Entry]
    verdict: list[dict]
    warnings: list[str]
    kind: str
    accuracy_a: float
    accuracy_given: bool

    @property
    def name(self) -> str:
        return model_name(self.chosen.effects)


def model_name(effects) -> str:
    return "+".join(effects) or "base"


def current_accuracy(recs, given: float | None = None) -> float:
    """The cycler channel's current accuracy (A): ``given``, else CURRENT_ACCURACY_OF_IMAX of the
    records' largest |current|."""
    if given is not None:
        return float(given)
    return CURRENT_ACCURACY_OF_IMAX * max(float(np.max(np.abs(r.i))) for r in recs)


# ----------------------------------------------------------------------------------------------
# the hand-over conditions


def failures(ctx: Context, cand: Candidate, accuracy_a: float):
    """Per element of ``cand`` (on its fit to all training records), the hand-over conditions it
    fails (docs/handover-rule.md): (1) identified (``selection.identified``), (2) no parameter at
    a bound of its searched range (``fitting.at_bound``), (3) a current offset within
    FAULT_FACTOR × the channel's accuracy and backed by two or more training records. Returns
    (element → reasons, the fit's intervals, warning lines)."""
    iv = intervals.of_fit(ctx.recs, cand.st, cand.X)
    z = cand.st.z_of(cand.X)
    at = fitting.at_bound(z, cand.st.lo, cand.st.hi)
    params = iv.report()["parameters"]
    failed, warnings = {}, []
    for e in cand.effects:
        why = []
        pressed = [cand.st.shared[k] for k in range(len(z))
                   if at[k] and ecm.PARAMS[cand.st.shared[k]].element == e]  # fmt: skip
        if pressed:  # condition 2 (and the part of condition 1 it shares)
            why += [f"{ecm.PARAMS[n].report} = {params[ecm.PARAMS[n].report]['value']:.4g} at a "
                    "bound of its searched range (set by the range, not by the records)"
                    for n in pressed]  # fmt: skip
        elif (not_id := selection.identified(iv, e)) is not None:  # condition 1
            why.append(f"not identified: {not_id}")
        if e == "current_offset":  # condition 3
            off = float(ecm.report(cand.X[0], ["ioff"])["current_offset_a"])
            if abs(off) > FAULT_FACTOR * accuracy_a:
                why.append(f"an instrument fault, not a cell parameter: offset {off:+.4g} A, "
                           f"beyond {FAULT_FACTOR:g} x the channel's accuracy "
                           f"({accuracy_a:.3g} A)")  # fmt: skip
                warnings.append(f"the training records' current looks offset by {off:+.4g} A, "
                                f"over {FAULT_FACTOR:g} x the channel's accuracy "
                                f"({accuracy_a:.3g} A): an instrument fault (check the "
                                "channel's calibration); not handed over")  # fmt: skip
            elif len(ctx.recs) < 2:
                why.append(
                    f"an offset within the channel's accuracy ({off:+.4g} A) needs two or "
                    "more training records (one record's better fit is no evidence)"
                )
        if why:
            failed[e] = why
    return failed, iv, warnings


def _requiring(effects, gone: set[str]) -> set[str]:
    """``gone`` and every element of ``effects`` that needs one of them (``requires``), in turn."""
    gone = set(gone)
    while True:
        more = {e for e in effects if ecm.REQUIRES.get(e) in gone} - gone
        if not more:
            return gone
        gone |= more


def refit(ctx: Context, cand: Candidate, effects, pin=()) -> Candidate:
    """``cand``'s structure with only ``effects`` kept (and ``pin`` held at neutral besides the
    parameters it held already), refitted by the selection's one fit from ``cand``'s parameters
    with the others set back to neutral."""
    pinned = tuple(n for n in (*cand.st.pinned, *pin) if ecm.PARAMS[n].element in effects)
    st = ctx.structure(effects, cand.st.knots, pinned=pinned)
    start = fitting.neutralise(cand.X, [e for e in cand.effects if e not in effects])
    start[:, [ecm.IDX[n] for n in pinned]] = fitting.NEUTRAL[[ecm.IDX[n] for n in pinned]]
    return ctx.fit(st, [start], taus=())  # nested in the verdict's checked fit


def pinnable(cand: Candidate, effect: str) -> tuple[str, ...]:
    """The parameters of ``effect`` that ``cand``'s fit pressed to a bound where the element's
    neutral value lies, where others of it are free and not pressed: held there, the element is
    its other part (``thermal`` with the RC branches' θ at 0 is R0's Arrhenius factor alone), a
    model the records may identify. Empty where no part would be left."""
    z = cand.st.z_of(cand.X)
    at = fitting.at_bound(z, cand.st.lo, cand.st.hi)
    own = [k for k, n in enumerate(cand.st.shared) if ecm.PARAMS[n].element == effect]
    pressed = [k for k in own if at[k]]
    neutral = [k for k in pressed
               if min(abs(cand.st.lo[k] - fitting.NEUTRAL[ecm.IDX[cand.st.shared[k]]]),
                      abs(cand.st.hi[k] - fitting.NEUTRAL[ecm.IDX[cand.st.shared[k]]]))
               <= fitting.AT_BOUND * (cand.st.hi[k] - cand.st.lo[k])]  # fmt: skip
    if not neutral or len(neutral) < len(pressed) or len(pressed) == len(own):
        return ()
    return tuple(cand.st.shared[k] for k in neutral)


def reduce(ctx: Context, verdict: Candidate, accuracy_a: float):
    """The verdict's model with every element removed that fails a hand-over condition (with
    those that need it), refitted and checked again until every element left passes (at most
    twice as many rounds as elements). An element that fails only because the fit pressed some
    of its parameters to the bound where they vanish keeps its other part, those held at
    neutral (:func:`pinnable`; once: failing again, it is removed). Returns (the reduced
    candidate, element → why it was removed or what was held, the warnings of the fits
    checked)."""
    cand, removed, warnings = verdict, {}, []
    for _ in range(2 * len(verdict.effects) + 1):
        failed, _, said = failures(ctx, cand, accuracy_a)
        warnings += said
        if not failed:
            break
        pin = {e: pinnable(cand, e) for e in failed if e not in removed}
        pin = {e: p for e, p in pin.items() if p}
        for e, p in pin.items():
            removed[e] = [*failed[e], "held at neutral, the element kept without it: "
                          + ", ".join(ecm.PARAMS[n].report for n in p)]  # fmt: skip
        gone = _requiring(cand.effects, set(failed) - set(pin))
        for e in gone:
            removed[e] = failed.get(e) or [f"needs {ecm.REQUIRES[e]}, which was removed"]
        cand = refit(ctx, cand, tuple(e for e in cand.effects if e not in gone),
                     [n for p in pin.values() for n in p])  # fmt: skip
        said_now = [f"{e} kept with {', '.join(p)} held at neutral" for e, p in pin.items()]
        if gone:
            said_now.insert(0, f"{', '.join(sorted(gone))} removed from the verdict's model")
        ctx.say("hand-over: " + "; ".join(said_now))
    return cand, removed, warnings


def with_second_rc(ctx: Context, ref: Candidate) -> Candidate:
    """``ref`` plus a second RC branch, by the ladder's own way of adding an element (its starts;
    a nested model that fits worse keeps the reference's optimum)."""
    st = ctx.structure((*ref.effects, SECOND_RC), ref.st.knots, pinned=ref.st.pinned)
    c = ctx.fit(st, fitting.effect_starts(ctx.recs, ref.X, SECOND_RC))
    if c.rss > ref.rss:
        c = ctx.evaluate(st, fitting.neutralise(ref.X, (SECOND_RC,)))
    return c


# ----------------------------------------------------------------------------------------------
# the score


def score(ctx: Context, entry: Entry) -> None:
    """The entry's held-out score and errors: leave one record out (the selection's
    ``cross_validate``, by-record layout) with two or more records; forward stretches with one."""
    if ctx.layout.by_record:
        if entry.cand.ho is None:  # a copy: the ladder's own candidate stays as it left it
            entry.cand = replace(entry.cand, fold_X=[])
            ctx.cross_validate(entry.cand)
        entry.score = ctx.ho_mse(entry.cand)
        o = ctx.layout.offsets
        e = entry.cand.ho - ctx.v
        entry.held = [(r, np.arange(o[r + 1] - o[r]), e[o[r] : o[r + 1]])
                      for r in range(len(ctx.recs))]  # fmt: skip
    else:
        entry.held = selection.each(lambda cut: forward(ctx, entry.cand, cut), FORWARD_CUTS)
        sq = sum(float(np.sum(err**2)) for _, _, err in entry.held)
        entry.score = sq / sum(err.size for _, _, err in entry.held)
    if not np.isfinite(entry.score):  # a prediction that left the finite numbers: the worst
        entry.score = np.inf


def forward(ctx: Context, cand: Candidate, cut: float, r: int = 0):
    """One forward stretch of record ``r`` (a single record's score; part 4's joint model on a
    one-record temperature): ``cand`` fitted to the samples before ``cut`` of the record and to
    every other record whole (masks; warm-started from its full fit, as the selection's
    held-out fits are), the whole record simulated with those parameters, the samples after the
    cut scored. Returns (r, the scored sample indices, their errors)."""
    rec = ctx.recs[r]
    n0 = round(cut * rec.n)
    masks = [np.ones(x.n, dtype=bool) for x in ctx.recs]
    masks[r] = np.arange(rec.n) < n0
    st = cand.st
    if "ocv_shape" in st.effects:  # the correction spans the fitted samples' SOC
        st = replace(st, knots=fitting.knots_for(ctx.recs, cand.X, masks))
    # a held-out refit, not checked (as the selection's own held-out refits)
    fit = fitting.best_of(ctx.recs, st, [cand.X], masks=masks, max_nfev=100, check=False)
    ctx.count(1)
    v = ecm.simulate_rows(rec, fit.X[r], st.knots, st.config.table, st.config.load_ohm)[:, 0]
    after = np.arange(n0, rec.n)
    return r, after, v[after] - rec.v[after]


# ----------------------------------------------------------------------------------------------
# the rule


def candidates(ctx: Context, lad: selection.Ladder, accuracy_a: float):
    """The rule's candidates in order (base, 2rc, the verdict reduced, the reduced one with a
    second RC), each structure once, the verdict's elements removed by the reduction and its
    warnings."""
    base = lad.base
    two = lad.candidates.get(SECOND_RC) or with_second_rc(ctx, base)
    reduced, removed, warnings = reduce(ctx, lad.selected, accuracy_a)
    out = [Entry("base", base), Entry("2rc", two), Entry("verdict, reduced", reduced)]
    if (
        SECOND_RC not in reduced.effects
        and selection.applicable(ctx.recs, SECOND_RC, reduced.effects, ctx.table)[0]
    ):
        out.append(Entry("verdict, reduced + second_rc", None))
    seen, entries = set(), []
    for entry in out:
        if entry.cand is None:  # fitted only if its structure is new
            if frozenset((*reduced.effects, SECOND_RC)) in seen:
                continue
            entry.cand = with_second_rc(ctx, reduced)
        key = frozenset(entry.effects)
        if key not in seen:
            seen.add(key)
            entries.append(entry)
    return entries, reduced, removed, warnings


def hand_over(ctx: Context, lad: selection.Ladder, accuracy_a: float | None = None) -> HandOver:
    """The model handed over (docs/handover-rule.md): the candidates, each checked and scored,
    and the eligible one with the lowest score (an exact tie: fewer parameters)."""
    acc = current_accuracy(ctx.recs, accuracy_a)
    entries, reduced, removed, said = candidates(ctx, lad, acc)

    def check(entry: Entry) -> None:
        entry.failed, entry.iv, entry.warnings = failures(ctx, entry.cand, acc)
        score(ctx, entry)

    selection.each(check, entries)
    eligible = [e for e in entries if e.eligible]  # the base always (it has no elements)
    chosen = min(eligible, key=lambda e: (e.score, e.cand.k))
    ctx.say(f"hand-over: {model_name(chosen.effects)} handed over")
    warnings = list(dict.fromkeys([*said, *(w for e in entries for w in e.warnings)]))
    kind = ("leave one record out" if ctx.layout.by_record else
            "forward stretches after " + " and ".join(f"{c:.0%}" for c in FORWARD_CUTS)
            + " of the record")  # fmt: skip
    verdict = _verdict_elements(lad.selected, removed, chosen, entries, reduced)
    return HandOver(chosen, entries, verdict, warnings, kind, acc, accuracy_a is not None)


def _verdict_elements(verdict: Candidate, removed: dict, chosen: Entry, entries, reduced):
    """Per element of the verdict's model: handed over or not, and why."""
    red = next(e for e in entries if frozenset(e.effects) == frozenset(reduced.effects))
    out = []
    for el in verdict.effects:
        if el in chosen.effects:
            why = "passes the hand-over conditions; in the model with the lowest held-out error"
            if el in removed:  # the verdict's fit failed it, the chosen candidate's own passes
                why = (f"in {chosen.name}, whose own fit passes the hand-over conditions (in the "
                       f"verdict's fit: {'; '.join(removed[el])})")  # fmt: skip
            out.append({"effect": el, "handed_over": True, "why": why})
        elif el in removed:
            out.append({"effect": el, "handed_over": False, "why": "; ".join(removed[el])})
        else:
            out.append(
                {
                    "effect": el,
                    "handed_over": False,
                    "why": f"passes the conditions, but {model_name(chosen.effects)} "
                    f"predicts held-out training data better "
                    f"({_mv(chosen.score):.3g} mV against "
                    f"{_mv(red.score):.3g} mV for {model_name(red.effects)})",
                }
            )
    return out


def _mv(mse: float | None) -> float | None:
    return None if mse is None else 1e3 * float(np.sqrt(mse))


def report(ho: HandOver) -> dict:
    """``diagnosis.json``'s ``handed_over``."""
    by = {e.name: e for e in ho.entries}
    two = by.get("2rc")
    if two is not None and two.eligible:
        guarantee = ("no eligible candidate predicts held-out training data better, the 2RC "
                     "and the base included")  # fmt: skip
    else:
        guarantee = (
            "the 2RC is not eligible: no eligible candidate (the base included) "
            "predicts held-out training data better; the 2RC is not among them"
        )
    return {
        "name": ho.name,
        "candidate": ho.chosen.name,
        "effects": list(ho.chosen.effects),
        "n_params": ho.chosen.cand.k,
        "held_at_neutral": [ecm.PARAMS[n].report for n in ho.chosen.cand.st.pinned],
        "score": ho.kind,
        "heldout_rmse_mv": _mv(ho.chosen.score),
        "guarantee": guarantee,
        "candidates": [_row(e) for e in ho.entries],
        "verdict_elements": ho.verdict,
        "current_accuracy_a": ho.accuracy_a,
        "current_accuracy_given": ho.accuracy_given,
        "warnings": ho.warnings,
        "rule": RULE,
    }


def _row(e: Entry) -> dict:
    """One candidate of ``handed_over``: its held-out RMSE, whether it was eligible, why not."""
    return {"candidate": e.name, "name": model_name(e.effects), "effects": list(e.effects),
            "n_params": e.cand.k, "heldout_rmse_mv": _mv(e.score), "eligible": e.eligible,
            "why_not": [f"{el}: {w}" for el, ws in e.failed.items() for w in ws]}  # fmt: skip


def _shown(mv) -> str:
    """A held-out RMSE for a line (None in the JSON: not finite)."""
    return "inf" if mv is None else f"{mv:.3g}"


def summary_line(handed: dict) -> str:
    """``diagnose``'s one line: the model handed over, its held-out RMSE beside the 2RC's and the
    base's, and the verdict's elements left out with their reason."""
    rmse = {c["candidate"]: _shown(c["heldout_rmse_mv"]) for c in handed["candidates"]}
    line = (
        f"handed over {handed['name']}: held-out RMSE {_shown(handed['heldout_rmse_mv'])} mV "
        f"({handed['score']}; 2RC {rmse['2rc']} mV, base {rmse['base']} mV)"
    )
    left = [f"{v['effect']} ({v['why']})" for v in handed["verdict_elements"]
            if not v["handed_over"]]  # fmt: skip
    line += "; left out of the verdict's model: " + "; ".join(left) if left else ""
    if (table := handed.get("per_temperature_parameters")) is not None:
        line += (f"; per-temperature parameters ({table['held_out']}): "
                 f"{_shown(table['heldout_rmse_mv'])} mV against the laws' model's "
                 f"{_shown(table['laws_heldout_rmse_mv'])}, {table['kept']} kept")  # fmt: skip
    if handed.get("per_temperature"):
        line += "; " + per_temperature_summary(handed["per_temperature"])
    return line


# ----------------------------------------------------------------------------------------------
# the error to expect on other profiles (part 3)


def expected_error(ctx: Context, ho: HandOver, ambients_c: list[float] | None = None) -> dict:
    """``model.json``'s ``expected_error``: the handed-over model's held-out error (the score's
    predictions) as the error to expect on a profile unlike its training records: its RMS (records
    alike, as the score), by operating point (each bin's RMS over its held-out samples, with at
    least MIN_BIN_SAMPLES of them) and the error's correlation time. With the training records'
    ambients (``heat.ambient_of``) spanning two test temperatures or more, the same by each
    (``by_temperature``, docs/soc-filter.md part 6)."""
    chosen = ho.chosen
    cand = chosen.cand
    soc = [ecm.simulate_rows(rec, cand.X[r], cand.st.knots, ctx.table, traces=True)[1][0]
           for r, rec in enumerate(ctx.recs)]  # fmt: skip
    err, mode, amps, sc, which = [], [], [], [], []
    for r, idx, e in chosen.held:
        rec = ctx.recs[r]
        err.append(e)
        mode.append(records.direction(rec.i, rec.imax())[idx])
        amps.append(np.abs(rec.i[idx]))
        sc.append(soc[r][idx])
        which.append(np.full(e.size, r))
    err, mode, amps, sc, which = (np.concatenate(a) for a in (err, mode, amps, sc, which))
    load = mode != 0
    median = float(np.median(amps[load])) if load.any() else None
    out = {
        "rms_mv": _mv(chosen.score),
        "held_out": ho.kind,
        "samples": int(err.size),
        "by_operating_point": _bins(err, mode, amps, sc, median),
        "load_current_median_a": median,
        "min_bin_samples": MIN_BIN_SAMPLES,
        **correlation_time(ctx, chosen.held),
    }
    groups = [] if ambients_c is None else heat.ambient_groups(ambients_c)
    if len(groups) > 1:
        out["by_temperature"] = [
            {"ambient_c": group_ambient(ambients_c, g),
             "records": [ctx.recs[r].source for r in g], "samples": int(k.sum()),
             "rms_mv": 1e3 * float(np.sqrt(np.mean(err[k] ** 2))),
             "by_operating_point": _bins(err[k], mode[k], amps[k], sc[k], median)}
            for g in groups if (k := np.isin(which, g)).any()
        ]  # fmt: skip
    return out


def _bins(err, mode, amps, soc, median) -> list[dict]:
    """The bins with at least MIN_BIN_SAMPLES held-out samples: rest, discharge, charge (each
    under load split at ``median`` |current|) × SOC below, between and above SOC_EDGES."""
    lo, hi = SOC_EDGES
    socs = (("below 0.2", soc < lo), ("0.2-0.8", (soc >= lo) & (soc <= hi)),
            ("above 0.8", soc > hi))  # fmt: skip
    modes = [("rest", "-", mode == 0)]
    for name, sign in (("discharge", 1), ("charge", -1)):
        if median is not None:
            modes += [(name, "low", (mode == sign) & (amps < median)),
                      (name, "high", (mode == sign) & (amps >= median))]  # fmt: skip
    out = []
    for m, cur, mm in modes:
        for s, ms in socs:
            k = mm & ms
            n = int(k.sum())
            if n >= MIN_BIN_SAMPLES:
                out.append({"mode": m, "current": cur, "soc": s, "n": n,
                            "rms_mv": 1e3 * float(np.sqrt(np.mean(err[k] ** 2)))})  # fmt: skip
    return out


def correlation_time(ctx: Context, held) -> dict:
    """The lag at which the held-out error's autocorrelation first falls below 1/e, per
    contiguous held-out stretch (``intervals.autocorrelation``, up to Sokal's window), in samples
    and in seconds (the record's median step); the stretches' mean weighted by their samples.
    A stretch whose autocorrelation stays above 1/e over the whole window counts the window (a
    lower bound) and is said."""
    lags, secs, sizes, bounded = [], [], [], False
    for r, _, e in held:
        rho = intervals.autocorrelation(e)
        below = np.flatnonzero(rho < ONE_OVER_E)
        lag = int(below[0]) if below.size else int(rho.size)
        bounded |= not below.size
        lags.append(lag)
        secs.append(lag * float(np.median(ctx.recs[r].dt)))
        sizes.append(e.size)
    w = np.asarray(sizes, dtype=float)
    return {
        "correlation_time_samples": float(np.sum(w * lags) / w.sum()),
        "correlation_time_s": float(np.sum(w * secs) / w.sum()),
        "correlation_time_lower_bound": bool(bounded),
    }


# ----------------------------------------------------------------------------------------------
# never worse than one model per temperature (docs/temperature-rule.md part 4)

PER_TEMPERATURE = "per-temperature models"
"""``handed_over.name`` where the joint model would be worse at a test temperature than that
temperature's own diagnosis: one set per test temperature, the own model there and the joint
model at the others."""


def group_ambient(ambients_c, group: list[int]) -> float:
    """A test temperature's ambient: the mean of its records' ambients (``expected_error``'s
    labels and the per-temperature sets')."""
    return float(np.mean([ambients_c[r] for r in group]))


def joint_on_own(ctx: Context, ho: HandOver, group: list[int], mine: HandOver,
                 stretch=None) -> list:  # fmt: skip
    """Part 4: the joint hand-over's held-out errors on the samples a test temperature's own
    diagnosis (``mine``, the records ``group``) scored, the joint model having seen what the own
    one saw and the other temperatures' records besides: its leave-one-record-out errors where
    the own score held out whole records; where the temperature has one record (the own score's
    forward stretches), the joint structure refitted to the record's samples before each cut and
    every other record (:func:`forward`; ``stretch(cut)`` in its place where the joint model is
    no one structure, ``per_temperature.forward``). One error array per segment of
    ``mine.chosen.held``."""
    o = ctx.layout.offsets
    if len(group) == 1:
        fwd = stretch or (lambda cut: forward(ctx, ho.chosen.cand, cut, group[0]))
        return [e for _, _, e in selection.each(fwd, FORWARD_CUTS)]
    joint = np.empty(ctx.n)
    for r, idx, e in ho.chosen.held:  # leave one record out: every sample of every record
        joint[o[r] + idx] = e
    return [joint[o[group[r_local]] + idx] for r_local, idx, _ in mine.chosen.held]


def cell_unidentified(entry: Entry) -> list[str]:
    """The base parameters (the capacity, R0, R1, τ1, and the OCV's own where no table is
    given: every cell parameter that is no element's) that ``entry``'s fit does not identify
    (its intervals' ``identified``, a held one aside): where any is, the model is not handed
    over in another's place (docs/temperature-rule.md part 4, amended)."""
    params = entry.iv.report()["parameters"]
    out = []
    for n in entry.iv.names:
        if ecm.PARAMS[n].element in entry.effects:
            continue
        e = params[ecm.PARAMS[n].report]
        if not (e["identified"] or e["held"]):
            out.append(ecm.PARAMS[n].report)
    return out


def against_own(ctx: Context, joint: list[list], own: list[HandOver]) -> dict:
    """Part 4: at each test temperature (``ctx.groups``, with ``own[g]`` that temperature's own
    hand-over, its records alone, and ``joint[g]`` the joint model's errors on the same samples,
    :func:`joint_on_own`), the two sets of held-out errors compared by the selection's paired
    loss test (batch means, one-sided: is the own model's loss lower), each temperature at
    ALPHA / G (Bonferroni over the temperatures), every held-out segment weighing alike; an own
    model whose records do not identify its cell (:func:`cell_unidentified`) is not handed over
    where the joint model is worse. Returns diagnosis.json's ``handed_over.per_temperature``;
    its ``joint_worse`` says whether any temperature takes its own model."""
    level = selection.ALPHA / len(ctx.groups)
    rows = []
    for group, mine, theirs in zip(ctx.groups, own, joint, strict=True):
        a, b, w, batches, n = [], [], [], [], 0
        for (_, idx, e), ej in zip(mine.chosen.held, theirs, strict=True):
            a.append(ej)
            b.append(e)
            w.append(np.full(idx.size, 1.0 / idx.size))  # each segment counts once
            seg = np.arange(n, n + idx.size)
            batches += [x for x in np.array_split(seg, min(selection.BATCHES_PER_RECORD,
                                                           seg.size)) if x.size]  # fmt: skip
            n += idx.size
        la, lb, wt = np.concatenate(a) ** 2, np.concatenate(b) ** 2, np.concatenate(w)
        t, p, _ = selection.loss_test(la, lb, batches, wt)
        loose = cell_unidentified(mine.chosen)
        rows.append({
            "ambient_c": group_ambient(ctx.ambients_c, group),
            "records": [ctx.recs[r].source for r in group],
            "own_model": mine.name,
            "own_score": mine.kind,
            "joint_heldout_rmse_mv": _mv(float(np.sum(wt * la) / wt.sum())),
            "own_heldout_rmse_mv": _mv(float(np.sum(wt * lb) / wt.sum())),
            "t": t, "p": p,
            "joint_worse": bool(p < level),
            "own_not_identified": loose,
            "own_handed_over": bool(p < level) and not loose,
        })  # fmt: skip
    worse = any(r["own_handed_over"] for r in rows)
    return {
        "test": "the selection's paired loss test (batch means, one-sided), on the samples each "
                "temperature's own diagnosis held out, every held-out segment alike; the joint "
                "model fitted to what the own one saw and the other temperatures' records",
        "level": level,
        "groups": rows,
        "joint_worse": worse,
        "decision": PER_TEMPERATURE if worse else "the joint model",
    }  # fmt: skip


def per_temperature_summary(pt: dict) -> str:
    """The summary line's words for ``handed_over.per_temperature``."""
    said = []
    for r in pt["groups"]:
        if r["joint_worse"]:
            said.append(f"{r['ambient_c']:g} °C ({_shown(r['joint_heldout_rmse_mv'])} mV against "
                        f"{_shown(r['own_heldout_rmse_mv'])}"
                        + ("" if r["own_handed_over"] else
                           f"; its own model not handed over: {', '.join(r['own_not_identified'])}"
                           " not identified") + ")")  # fmt: skip
    if not said:
        return "not worse than the per-temperature models at any test temperature"
    line = f"the joint model is worse at {', '.join(said)}"
    if pt["joint_worse"]:
        return (
            line + ": there that temperature's own model handed over, the joint model at the others"
        )
    return line + ": the joint model kept"
