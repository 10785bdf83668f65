"""The one way models are chosen, judged the way a model is used: predicting data the fit did not
see, each predicted record started by the one initial-state rule, every record counting alike;
two held-out tests, BIC, a minimum shrink, and a greedy ladder (docs/gap-diagnosis.md, "Selection
judged like prediction" and "The method"). The diagnosis and the real-data experiment both call
it: :func:`fit_base`, then :func:`ladder` returns the whole ladder.

1. **Held out.** With two or more training records, whole records: each record is predicted from
   the fit to the others (leave one record out). With one record, ``N_FOLDS × BLOCKS_PER_FOLD``
   contiguous blocks of equal length; fold j holds blocks j, j + N_FOLDS, ..., so each held-out
   block lies between training data; a model is fitted with a fold's residuals left out (the
   state is simulated through the whole record; only the held-out samples are scored).
2. **Records alike.** Each sample's loss weighs n/(R·n_r): every record's mean squared error
   counts once, whatever its length (``Context.w``); the fits weigh records alike too
   (``fitting.Problem``).
3. **Pays.** A candidate that adds one element to a reference pays when (a) it removes at least
   ``MIN_SHRINK`` of the reference's held-out squared error, (b) by more than noise explains: the
   per-batch mean loss differential passes a batch-means t-test (Diebold–Mariano) or a signed-rank
   test, one-sided, Bonferroni over both tests and the candidates at family level ``ALPHA``, and
   (c) its fit to all training data has ΔBIC < ``BIC_MAX``.
4. **Winner.** Among those that pay, the largest held-out shrink wins, unless a candidate with
   fewer parameters is within one standard error of it (the one-standard-error rule).
5. **Ladder.** The winner becomes the reference and the remaining elements are tried on top of
   it, by the same rule, until none pays; then each element of the result stays only if it pays
   against the model without it (backward pruning, :func:`prune`).

Only training records enter: a record passed for validation is never seen here.

Time (issue 28: all four Panasonic temperatures, 8 records, 393,711 samples, ≤ 5 min on 2
cores): the fits that do not depend on each other run on the process's threads (:func:`each`):
the candidates of a rung (each one's fit and, where it can pay, its held-out fits), the
first rung's held-out fits, the held-out parts of a model held out alone, and the pruning's trials
(each element of the final model removed in turn, all tried at once; the first in the sequential
order that does not pay is taken, as the one-at-a-time loop would). The compiled simulator and
LAPACK release the GIL, and each fit computes the same numbers whichever thread runs it, so the
selection is the same, bit for bit, with any number of threads
(``tests/unit/test_selection_threads.py``). Measured (``benchmarks/bench_joint.py``,
docs/real-data.md "Time of the joint fit"): 1,802 s before (commit ce0cda2), 1,420 s with this,
one BLAS thread (``diagnose.BLAS_THREADS``) and the rests' held temperature
(``ecm.Record.rest_held``), on a loaded machine; the goal (300 s) is not met: the simulator's
passes in the held-out fits remain. Every fit to all training records is checked
(``fitting.check_fit``, issue 37; the held-out refits are not): on the transfer benchmark's nmc
HPPC record a diagnosis took twice the CPU time with the same selection (docs/gap-diagnosis.md,
"Fit check").
"""

from __future__ import annotations

import pickle
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

from . import threads
from .model import ecm, elements, fitting, heat, intervals
from .model.ecm import Config, Knots, Record
from .model.fitted import FittedModel, fit_model, model_of, prediction_errors

N_FOLDS = 5
BLOCKS_PER_FOLD = 4
"""Contiguous blocks per fold (one training record): the record is cut into N_FOLDS × 4 = 20
blocks and fold j holds blocks j, j + 5, j + 10, j + 15, so each held-out block lies between
training data. With one block per fold (a fifth of the record), a record that visits each SOC once
makes every model extrapolate in SOC, where capacity and the OCV are not identifiable: the
held-out error was dominated by that, whatever the effect (a 40 mV hysteresis fitted to the noise
on the full record but lost to ocv_shape held out). The price: a candidate can carry a slow misfit
from the neighbouring blocks into the held-out one (docs/gap-diagnosis.md)."""
BATCHES_PER_FOLD = 20
BATCHES_PER_RECORD = 50
"""Batches of each held-out record (two records or more): the same number per record, so each
record weighs alike in the t and rank tests; 50 contiguous batches keep each batch long against
the residual's autocorrelation and give the tests 100 batches or more."""
ALPHA = 0.05
BIC_MAX = -10.0
"""ΔBIC below −10: "very strong" evidence on Kass and Raftery's (1995) scale."""
SECOND_RC = "second_rc"
"""The element the hand-over adds to its candidates (``handover.SECOND_RC``)."""
RECORD, TEMPERATURE = "record", "temperature"
"""The two hold-outs (:meth:`Context.scheme`): by record (or block), and by test temperature."""
LEAVE_ONE_TEMPERATURE_OUT = "leave one temperature out"
IDENTIFICATION_AND_PRIOR = "identification and prior"
"""What admits a temperature law with three test temperatures or more, and with two
(:attr:`Context.law_rule`)."""
MIN_SHRINK = 0.05
"""A candidate must remove at least this share of the held-out ISE: a significant but smaller gain
is no diagnosis (on a badly misspecified record, a voltage offset removing 0.7 % passed the tests).
A true effect whose base residual is r (in noise RMS units) can remove up to r²/(1 + r²): 5 % bites
only below r ≈ 0.23, far under the 1.5 the validation targets."""


_WORKER = threading.local()


def each(fn, items) -> list:
    """``[fn(x) for x in items]``, on up to the threads this process was given
    (:func:`..threads.given`: its cores, or a job's ``threads:``, the CLI's ``--threads``), in
    the items' order. The heavy parts of a fit (the compiled simulator, ``nogil``; LAPACK's
    SVD, one BLAS thread each, ``diagnose.BLAS_THREADS``) release the GIL, so fits on two cores
    take about half as long; more threads than cores would only take turns. Any number gives
    the same results. Inside a task it runs them one by one (the tasks are as coarse as the
    caller could make them; a pool inside a pool could wait for itself). An exception in a task
    is raised here."""
    items = list(items)
    n = threads.given()
    if n <= 1 or len(items) <= 1 or getattr(_WORKER, "busy", False):
        return [fn(x) for x in items]

    def task(x):
        _WORKER.busy = True
        try:
            return fn(x)
        finally:
            _WORKER.busy = False

    with ThreadPoolExecutor(min(n, len(items))) as pool:
        return list(pool.map(task, items))


@dataclass
class Layout:
    """Where each record's samples sit in the concatenated sample axis, what is held out together
    (``folds``: index arrays into that axis; whole records with two records or more) and the
    batches of the tests."""

    offsets: np.ndarray  # offsets[r]: first index of record r; offsets[-1]: total
    folds: list[np.ndarray]
    batches: list[np.ndarray]
    by_record: bool = False

    @classmethod
    def of(cls, sizes, k: int = N_FOLDS, per_fold: int = BLOCKS_PER_FOLD) -> Layout:
        offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        if len(sizes) >= 2:  # leave one record out
            folds = [np.arange(offsets[r], offsets[r + 1]) for r in range(len(sizes))]
            batches = [b for f in folds
                       for b in np.array_split(f, min(BATCHES_PER_RECORD, f.size))]  # fmt: skip
            return cls(offsets, folds, batches, by_record=True)
        folds = [[] for _ in range(k)]
        batches = []
        for r, n in enumerate(sizes):
            blocks = np.array_split(np.arange(n) + offsets[r], k * per_fold)
            for j in range(k):
                folds[j].extend(blocks[j::k])
            per_block = max(1, BATCHES_PER_FOLD * k // len(blocks))
            batches += [b for blk in blocks for b in np.array_split(blk, per_block) if b.size]
        return cls(offsets, [np.sort(np.concatenate(f)) for f in folds], batches)

    def split(self, global_idx: np.ndarray) -> list[np.ndarray]:
        """Per record, the local indices of sorted global indices."""
        o = self.offsets
        return [global_idx[(global_idx >= o[r]) & (global_idx < o[r + 1])] - o[r]
                for r in range(o.size - 1)]  # fmt: skip

    def fold_of(self) -> np.ndarray:
        """Per sample, the fold (or held-out record) it belongs to (the figure draws them)."""
        out = np.empty(int(self.offsets[-1]), dtype=int)
        for j, f in enumerate(self.folds):
            out[f] = j
        return out


def loss_test(loss_a: np.ndarray, loss_b: np.ndarray, batches,
              weights: np.ndarray | None = None) -> tuple[float, float, float]:  # fmt: skip
    """Is ``loss_b`` lower than ``loss_a``? Batch-means t (Diebold–Mariano), one-sided p, SE.

    Returns (t, p, se) for the mean per-sample difference a − b, each batch weighing the sum of
    its samples' ``weights`` (its size without them); se is that mean's standard error.
    """
    d = loss_a - loss_b
    means = np.array([d[b].mean() for b in batches])
    sizes = np.array([b.size if weights is None else weights[b].sum() for b in batches],
                     dtype=float)  # fmt: skip
    mean = float(np.sum(means * sizes) / sizes.sum())
    se = float(np.std(means, ddof=1) / np.sqrt(means.size))
    if se == 0:
        return (np.inf if mean > 0 else 0.0), (0.0 if mean > 0 else 1.0), 0.0
    t = mean / se
    return float(t), float(stats.t.sf(t, means.size - 1)), se


def batch_rank_test(loss_a: np.ndarray, loss_b: np.ndarray, batches) -> tuple[float, float]:
    """Is ``loss_b`` systematically lower than ``loss_a``? Wilcoxon signed-rank test on the batch
    means of a − b, one-sided; returns (share of batches where b is lower, p).

    Robust where the t-test is not: one block of the record that no model can predict (an
    extrapolation to a region only that block visits) swamps a mean and its variance, but moves a
    rank test by its few batches only.
    """
    d = np.array([(loss_a[b] - loss_b[b]).mean() for b in batches])
    if not np.any(d != 0):
        return 0.0, 1.0
    p = stats.wilcoxon(d, alternative="greater", zero_method="zsplit").pvalue
    return float(np.mean(d > 0)), float(p)


def bic(rss: float, n: int, k: int) -> float:
    return float(n * np.log(rss / n) + k * np.log(n))


@dataclass
class Candidate:
    """A candidate: a structure fitted to all training data, its voltage and held-out voltage."""

    st: fitting.Structure
    X: np.ndarray  # per-record internal rows
    v: np.ndarray  # model voltage, all records concatenated
    rss: float
    ho: np.ndarray | None = None  # held-out voltage (each sample from the fit without its fold)
    fold_X: list = field(default_factory=list)
    check: fitting.Check | None = None  # what the fit check did to its fit (``fitting.check_fit``)
    ho_t: np.ndarray | None = None  # held out by test temperature (:data:`TEMPERATURE`)
    fold_X_t: list = field(default_factory=list)

    @property
    def k(self) -> int:
        return self.st.k

    def heldout(self, scheme: str) -> np.ndarray | None:
        """The held-out voltage under ``scheme`` (:data:`RECORD` or :data:`TEMPERATURE`), None
        where it was not held out so."""
        return self.ho_t if scheme == TEMPERATURE else self.ho

    @property
    def effects(self) -> tuple[str, ...]:
        return self.st.effects


def _weights(recs: list[Record], n: int) -> np.ndarray:
    """Per sample, its weight n/(R·n_r): every record's mean squared error counts once. Where
    every record has one length, the weights are one value: a read-only broadcast of it (no
    memory a sample; issue 42's long records), the same numbers wherever read."""
    if len({r.n for r in recs}) == 1:
        return np.broadcast_to(n / (len(recs) * recs[0].n), (n,))
    return np.concatenate([np.full(r.n, n / (len(recs) * r.n)) for r in recs])


class Context:
    """The training records, their layout and weights, and the fitting options shared by every
    candidate."""

    def __init__(self, recs: list[Record], table=None, capacity_ah=None, soc0=None,
                 ambients_c=None):  # fmt: skip
        self.recs = recs
        # the test temperatures (docs/temperature-rule.md part 1): the records' indices grouped
        # by ambient (``heat.ambient_groups``); one group where the ambients are not known
        self.ambients_c = ambients_c
        self.groups = (heat.ambient_groups(ambients_c) if ambients_c is not None
                       else [list(range(len(recs)))])  # fmt: skip
        self.table = table
        self.fix_q = capacity_ah is not None
        self.fix_s = soc0 is not None
        self.layout = Layout.of([r.n for r in recs])
        # one record: its own voltage, not a copy (issue 42: 8 bytes a sample of a long record)
        self.v = recs[0].v if len(recs) == 1 else np.concatenate([r.v for r in recs])
        self.n = self.v.size
        self.w = _weights(recs, self.n)
        self.fits = 0
        self._lock = threading.Lock()  # fits are counted from several threads (:func:`each`)
        self._made: dict[bytes, tuple] = {}  # the fits made: rows and check (:meth:`fit`)
        self.progress = None  # called with a short phrase after each stage (``diagnose.Progress``)

    def subset(self, idx: list[int]) -> Context:
        """The context of the records ``idx`` alone: the same OCV, fixed quantities and reference
        temperature (the records are the same objects), their ambients; its progress said
        through this one's, its fits counted apart (add them with :meth:`count`)."""
        sub = Context([self.recs[r] for r in idx], self.table,
                      ambients_c=None if self.ambients_c is None
                      else [self.ambients_c[r] for r in idx])  # fmt: skip
        sub.fix_q, sub.fix_s = self.fix_q, self.fix_s
        return sub

    def say(self, what: str) -> None:
        if self.progress is not None:
            with self._lock:
                self.progress(what)

    def count(self, fits: int) -> None:
        """Add to the fits the selection made (reported in ``diagnosis.json``)."""
        with self._lock:
            self.fits += fits

    def structure(self, effects, knots: Knots, recs=None, pinned=()) -> fitting.Structure:
        """``effects``' structure on ``recs`` (default the training records), ``pinned``
        parameters held where the rows put them (``fitting.Structure.pinned``)."""
        return fitting.structure(self.recs if recs is None else recs,
                                 Config(tuple(effects), self.table), knots, self.fix_q,
                                 self.fix_s, pinned)  # fmt: skip

    def simulate(self, st: fitting.Structure, X: np.ndarray) -> np.ndarray:
        return np.concatenate([
            ecm.simulate_rows(rec, X[r], st.knots, st.config.table, st.config.load_ohm)[:, 0]
            for r, rec in enumerate(self.recs)
        ])  # fmt: skip

    def sse(self, v: np.ndarray) -> float:
        """The records-alike sum of squared errors of a concatenated model voltage."""
        return float(np.sum(self.w * (v - self.v) ** 2))

    def evaluate(self, st, X) -> Candidate:
        X = fitting.complete(st, self.recs, X)
        v = self.simulate(st, X)
        return Candidate(st, np.array(X), v, self.sse(v))

    def fit(self, st, starts, taus=None) -> Candidate:
        """``st`` fitted to all training records from ``starts``, then checked
        (``fitting.check_fit``, restarting the time constants ``taus``, None: all; the check's
        restarts are not counted among the fits). A fit asked for again (the same structure,
        starts and restarts: the hand-over's second RC branch is a rung the ladder climbed) is
        not made again: the fit is deterministic, so its rows and check are kept (a few numbers
        a fit, not its voltage: on a long record that is 8 bytes a sample a candidate) and only
        its voltage is simulated again."""
        key = pickle.dumps((st, [np.asarray(x, dtype=float) for x in starts], taus))
        with self._lock:
            made = self._made.get(key)
        if made is None:
            self.count(len(starts))
            res = fitting.best_of(self.recs, st, starts, taus=taus)
            made = (res.X, res.checks[-1])
            with self._lock:
                self._made[key] = made
        return replace(self.evaluate(st, made[0]), check=made[1])

    def scheme(self, effect: str) -> str:
        """How a candidate adding ``effect`` is held out (docs/temperature-rule.md part 2): a
        temperature law by test temperature where there are three or more
        (:data:`TEMPERATURE`), everything else by record or block (:data:`RECORD`)."""
        return TEMPERATURE if is_law(effect) and len(self.groups) >= 3 else RECORD

    @property
    def law_rule(self) -> str:
        """What admits a temperature law on these records (docs/temperature-rule.md part 2)."""
        if len(self.groups) >= 3:
            return LEAVE_ONE_TEMPERATURE_OUT
        if len(self.groups) == 2:
            return IDENTIFICATION_AND_PRIOR
        return "leave one record out" if self.layout.by_record else "held-out blocks"

    def decided_by(self, effect: str) -> str | None:
        """What admits ``effect`` where it is a temperature law (:attr:`law_rule`), else None."""
        return self.law_rule if is_law(effect) else None

    def n_folds(self, scheme: str = RECORD) -> int:
        return len(self.groups) if scheme == TEMPERATURE else len(self.layout.folds)

    def cross_validate(self, cand: Candidate, scheme: str = RECORD) -> Candidate:
        """Each held-out part predicted from a fit that did not see it, warm-started from the
        full fit (the optimum of the training objective is what is scored; starting nearby only
        saves iterations): whole records with two or more, interleaved blocks with one; with
        ``scheme`` :data:`TEMPERATURE`, every test temperature's records at once."""
        ho = np.empty(self.n)
        if scheme == TEMPERATURE:
            cand.fold_X_t = each(lambda g: self._records_out(cand, g, ho), self.groups)
            cand.ho_t = ho
        else:
            cand.fold_X = each(lambda r: self._held_out(cand, r, ho),
                               range(len(self.layout.folds)))  # fmt: skip
            cand.ho = ho
        self.count(self.n_folds(scheme))
        return cand

    def held(self, cand: Candidate, scheme: str = RECORD) -> np.ndarray:
        """``cand``'s held-out voltage under ``scheme``, held out here if it was not yet."""
        if cand.heldout(scheme) is None:
            self.cross_validate(cand, scheme)
        return cand.heldout(scheme)

    def _held_out(self, cand: Candidate, r: int, ho: np.ndarray) -> np.ndarray:
        """Fold (or held-out record) ``r`` of :meth:`cross_validate`: its fit's rows; its
        held-out voltage written into ``ho``."""
        f = self.layout.folds[r]
        if self.layout.by_record:
            return self._records_out(cand, [r], ho)
        else:
            held = self.layout.split(f)
            masks = []
            for rec, h in zip(self.recs, held, strict=True):
                m = np.ones(rec.n, dtype=bool)
                m[h] = False
                masks.append(m)
            idxs = fitting.indices(self.recs, masks, fitting.MAX_FIT_POINTS)
            st = cand.st
            if "ocv_shape" in st.effects:  # the correction spans the training data's SOC
                st = replace(st, knots=fitting.knots_for(self.recs, cand.X, masks))
            X = fitting.fit_structure(self.recs, st, cand.X, idxs, max_nfev=100).X
            # the voltage at the held-out samples only (the state still runs through all)
            ho[f] = np.concatenate([
                ecm.simulate_rows(rec, X[r], st.knots, st.config.table, st.config.load_ohm,
                                  idx=h)[:, 0]
                for r, (rec, h) in enumerate(zip(self.recs, held, strict=True))
            ])  # fmt: skip
        return X

    def _records_out(self, cand: Candidate, out: list[int], ho: np.ndarray) -> np.ndarray:
        """The records ``out`` held out together: ``cand``'s structure fitted to the others,
        each of ``out`` predicted from its own start by the rule; their held-out voltage
        written into ``ho``; the fit's rows returned."""
        keep = [j for j in range(len(self.recs)) if j not in out]
        recs = [self.recs[j] for j in keep]
        st = self.structure(cand.effects, cand.st.knots, recs, cand.st.pinned)
        if "ocv_shape" in st.effects:  # the correction spans the training data's SOC
            st = replace(st, knots=fitting.knots_for(recs, cand.X[keep]))
        res = fitting.fit_structure(recs, st, cand.X[keep],
                                    fitting.indices(recs, None, fitting.MAX_FIT_POINTS),
                                    max_nfev=100)  # fmt: skip
        X = np.array(cand.X)
        X[:, st.shared_idx] = res.X[0, st.shared_idx]
        X = fitting.complete(st, self.recs, X)  # the held-out records start by the rule
        o = self.layout.offsets
        for r in out:
            ho[o[r] : o[r + 1]] = ecm.simulate_rows(
                self.recs[r], X[r], st.knots, st.config.table, st.config.load_ohm
            )[:, 0]
        return X

    def ho_loss(self, cand: Candidate, scheme: str = RECORD) -> np.ndarray:
        """Per sample, the squared held-out error (unweighted; :meth:`ho_mse` weighs records)."""
        return (self.held(cand, scheme) - self.v) ** 2

    def ho_mse(self, cand: Candidate, mask: np.ndarray | None = None) -> float:
        """The records-alike held-out mean squared error (over ``mask`` if given)."""
        loss = self.w * self.ho_loss(cand)
        if mask is None:
            return float(loss.sum() / self.n)
        return float(loss[mask].sum() / max(self.w[mask].sum(), 1e-300))


# ----------------------------------------------------------------------------------------------
# candidates


def is_law(effect: str) -> bool:
    """Whether ``effect`` is a temperature law (``Element.needs_temperature``; a name outside
    the library, e.g. a hand-over's label, is not)."""
    return effect in elements.REGISTRY and elements.get(effect).needs_temperature


def temperature_moves(recs: list[Record]) -> bool:
    """Whether the training records' measured temperature spans ``ecm.THERMAL_MIN_RANGE_C``:
    within one record (self-heating), or between records at different temperatures, each held
    constant (docs/temperature-rule.md, implementation notes: records at several chambers
    whose temperature does not move within any one of them still tell an Arrhenius factor from
    a constant)."""
    if any(r.temperature_varies for r in recs):
        return True
    temps = [r.temp_c for r in recs if r.temp_c is not None]
    if len(temps) < 2:
        return False
    span = max(float(t.max()) for t in temps) - min(float(t.min()) for t in temps)
    return span >= ecm.THERMAL_MIN_RANGE_C


def applicable(recs: list[Record], effect: str, effects_now=(), table=None) -> tuple[bool, str]:
    """Whether an element can be a candidate on these records (and why not)."""
    el = elements.get(effect)
    if el.needs_temperature and not temperature_moves(recs):
        if all(r.temp_c is None for r in recs):
            return False, "no temperature_c column"
        return False, f"temperature_c spans less than {ecm.THERMAL_MIN_RANGE_C:g} °C"
    why = el.applies(recs, max(r.imax() for r in recs)) if el.applies else ""
    if why:
        return False, why
    if el.requires and el.requires not in effects_now:
        return False, f"needs {el.requires} first"
    why = el.conflict(table is not None, load=False)  # the diagnosis fits without a load
    if why:
        return False, why
    return True, ""


def try_effects(ctx: Context, ref: Candidate, remaining, cv: bool,
                rung: int = 1) -> dict[str, Candidate]:  # fmt: skip
    """Fit ref + each remaining element; with ``cv``, cross-validate those that can pay (a fit
    with ΔBIC ≥ BIC_MAX fails the criterion whatever its held-out error). The candidates are
    fitted side by side (:func:`each`)."""
    done = []

    def one(e: str) -> Candidate:
        st = ctx.structure((*ref.effects, e), ref.st.knots)
        # every time constant restarted, the reference's too: an element that changes how the
        # others act (thermal's Arrhenius factors) can move their best time constants (fit back,
        # thermal seed 0: 4.26 mV against 0.99 mV of noise with only the element's own)
        c = ctx.fit(st, fitting.effect_starts(ctx.recs, ref.X, e, st.config.table))
        if c.rss > ref.rss:  # a nested model cannot fit worse: fit again from the reference's
            # optimum, the element neutral (as fitted.fit_model); if still worse, keep that
            neutral = fitting.neutralise(ref.X, (e,))
            c = ctx.fit(st, [neutral])
            if c.rss > ref.rss:
                c = ctx.evaluate(st, neutral)
        held = cv and bic(c.rss, ctx.n, c.k) - bic(ref.rss, ctx.n, ref.k) < BIC_MAX
        if held:
            ctx.cross_validate(c, ctx.scheme(e))
        done.append(e)
        ctx.say(f"rung {rung}: {e} fitted{', held out' if held else ''} "
                f"({len(done)}/{len(remaining)})")  # fmt: skip
        return c

    return dict(zip(remaining, each(one, remaining), strict=True))


def judge(ctx: Context, ref: Candidate, cands: dict[str, Candidate]) -> list[dict]:
    """Held-out comparison of each candidate against ``ref``, both held out the way the added
    element is judged (:meth:`Context.scheme`; ``ref`` held out here where it was not yet). A
    temperature law on two test temperatures must also be identified and inside its physical
    prior (:func:`law_prior`)."""
    n = ctx.n
    bic_ref = bic(ref.rss, n, ref.k)
    m = max(1, len(cands))
    out = []
    for e, c in cands.items():
        scheme = ctx.scheme(e)
        row = {
            "effect": e,
            "n_params": c.k - ref.k,
            "rmse_mv": 1e3 * float(np.sqrt(c.rss / n)),
            "delta_bic": bic(c.rss, n, c.k) - bic_ref,
        }
        if (decided := ctx.decided_by(e)) is not None:
            row["decided_by"] = decided
        if c.heldout(scheme) is None:
            # not cross-validated: its fit already fails the BIC criterion
            row.update(heldout_rmse_mv=None, shrink=None, t=None, p=None, pays=False)
        else:
            row.update(compare(ctx, ctx.ho_loss(ref, scheme), ctx.ho_loss(c, scheme), m,
                               row["delta_bic"]))  # fmt: skip
            if decided == IDENTIFICATION_AND_PRIOR and row["pays"]:
                row.update(law_prior(ctx, c, e))
                row["pays"] = row["identified"] is None and all(
                    q["inside"] for q in row["prior"].values()
                )
        out.append(row)
    return out


def compare(ctx: Context, loss_ref: np.ndarray, loss: np.ndarray, m: int,
            delta_bic: float) -> dict:  # fmt: skip
    """Whether a candidate with held-out losses ``loss`` pays against a reference with
    ``loss_ref`` (per sample, the training records' samples), one of ``m`` candidates, its fit to
    all training data ``delta_bic`` from the reference's: the held-out RMSE, the shrink, both
    tests and the verdict (the module's point 3)."""
    ise_ref = float(np.sum(ctx.w * loss_ref))
    t, p_mean, _ = loss_test(loss_ref, loss, ctx.layout.batches, ctx.w)
    wins, p_rank = batch_rank_test(loss_ref, loss, ctx.layout.batches)
    shrink = 1.0 - float(np.sum(ctx.w * loss)) / ise_ref
    # two tests, each at ALPHA / (2 m): the mean test sees a gain confined to a few batches (an
    # effect that acts only in pulses), the rank test a gain spread over most batches that one
    # unpredictable block hides from the mean
    p = min(1.0, 2.0 * min(p_mean, p_rank))
    return {
        "heldout_rmse_mv": 1e3 * float(np.sqrt(float(np.sum(ctx.w * loss)) / ctx.n)),
        "shrink": shrink, "t": t, "p_mean": p_mean, "batches_better": wins, "p_rank": p_rank,
        "p": p, "pays": bool(p < ALPHA / m and delta_bic < BIC_MAX and shrink >= MIN_SHRINK),
    }  # fmt: skip


def law_prior(ctx: Context, cand: Candidate, effect: str) -> dict:
    """Part 2 of docs/temperature-rule.md on two test temperatures: whether the temperature
    law ``effect`` is identified in ``cand``'s fit (:func:`identified`: None, or why not) and,
    per parameter, its fitted value against its physical prior (``Param.physical``)."""
    iv = intervals.of_fit(ctx.recs, cand.st, cand.X)
    report = iv.report()["parameters"]
    prior = {}
    for p in elements.get(effect).params.values():
        if p.physical is None:
            continue
        lo, hi, source = p.physical
        value = float(report[p.report]["value"])
        prior[p.report] = {"value": value, "range": [lo, hi], "source": source,
                           "inside": bool(lo <= value <= hi)}  # fmt: skip
    return {"identified": identified(iv, effect), "prior": prior}


def identified(iv: intervals.Intervals, effect: str) -> str | None:
    """None if the records identify ``effect``'s parameters in a fit's intervals ``iv``
    (docs/admission-rule.md, criterion 1: none at a bound or unconstrained, a strength
    parameter's interval off its neutral value, none trading with the rest); else why not."""
    own = [n for n in iv.names if ecm.PARAMS[n].element == effect]
    k = {n: iv.names.index(n) for n in own}
    report = iv.report()["parameters"]
    for n in own:
        rep = ecm.PARAMS[n].report
        if iv.at_bound[k[n]]:
            return f"{rep} at a bound of its fit ({report[rep]['value']:.4g})"
        if not np.isfinite(iv.sd[k[n]]):
            return f"{rep} not constrained by these records"
    strength = [n for n in own if ecm.PARAMS[n].transform == "lin"]
    if strength and not any(iv.excludes(n, ecm.PARAMS[n].neutral) for n in strength):
        names = ", ".join(ecm.PARAMS[n].report for n in strength)
        return f"the 95 % interval of {names} includes the value that switches it off"
    for a, b, c in iv.pairs():
        if (a in own) != (b in own):
            mine, other = (a, b) if a in own else (b, a)
            return (f"{ecm.PARAMS[mine].report} trades with {ecm.PARAMS[other].report} "
                    f"(correlation {c:+.3f})")  # fmt: skip
    return None


def choose(ctx: Context, rows: list[dict], cands: dict[str, Candidate]) -> str | None:
    """The winner among candidates that pay: largest shrink, or a simpler one within one SE."""
    paying = [r for r in rows if r["pays"]]
    if not paying:
        return None
    best = max(paying, key=lambda r: r["shrink"])
    simpler = []
    for r in paying:
        if r["n_params"] < best["n_params"]:
            # on one hold-out: the two's own where they share it, else by test temperature
            pair = {ctx.scheme(r["effect"]), ctx.scheme(best["effect"])}
            scheme = pair.pop() if len(pair) == 1 else TEMPERATURE
            t, _, _ = loss_test(ctx.ho_loss(cands[r["effect"]], scheme),
                                ctx.ho_loss(cands[best["effect"]], scheme),
                                ctx.layout.batches, ctx.w)  # fmt: skip
            if t <= 1.0:  # worse than the best by at most one standard error
                simpler.append(r)
    if simpler:
        best = min(simpler, key=lambda r: (r["n_params"], -r["shrink"]))
    return best["effect"]


def ladder_row(ctx: Context, effect: str, c: Candidate, prev: Candidate, base: Candidate) -> dict:
    mse = ctx.ho_mse(c)
    return {
        "effect": effect,
        "heldout_rmse_mv": 1e3 * float(np.sqrt(mse)),
        "shrink": 1.0 - mse / ctx.ho_mse(prev),
        "shrink_vs_base": 1.0 - mse / ctx.ho_mse(base),
        "delta_bic": bic(c.rss, ctx.n, c.k) - bic(prev.rss, ctx.n, prev.k),
        "effects": list(c.effects),
    }


def climb(ctx: Context, base: Candidate, first: str, first_cand: Candidate, candidates):
    """The ladder from ``base`` through ``first``: greedily add what pays. Returns (rows, chosen)
    with one candidate per rung (the last is the selected model)."""
    rows = [ladder_row(ctx, first, first_cand, base, base)]
    chosen = [first_cand]
    final = first_cand
    remaining = [e for e in candidates if e != first]
    while True:
        now = [e for e in remaining if applicable(ctx.recs, e, final.effects, ctx.table)[0]]
        if not now:
            break
        step = try_effects(ctx, final, now, cv=True, rung=len(rows) + 1)
        nxt = choose(ctx, judge(ctx, final, step), step)
        if nxt is None:
            break
        rows.append(ladder_row(ctx, nxt, step[nxt], final, base))
        chosen.append(step[nxt])
        final = step[nxt]
        remaining = [e for e in remaining if e != nxt]
    return rows, chosen


# ----------------------------------------------------------------------------------------------
# the whole ladder


def fit_base(ctx: Context, capacity_ah=None, soc0=None) -> Candidate:
    """The base model (the context's OCV, R0, one RC, capacity) fitted to all training records
    from a handful of starts; its OCV-shape knots set on the SOC range it visits."""
    st = ctx.structure((), Knots(0.0, 0.2))
    base = ctx.fit(st, fitting.base_starts(ctx.recs, Config(table=ctx.table), capacity_ah, soc0))
    st.knots = fitting.knots_for(ctx.recs, base.X)
    return base


@dataclass
class Ladder:
    """The whole selection: the first rung (every applicable candidate against the base), the
    rungs that followed, and what was not tried and why."""

    base: Candidate
    candidates: dict[str, Candidate]  # the first rung's fits
    rows: list[dict]  # the first rung's comparisons (``judge``)
    skipped: list[dict]  # {effect, applicable: False, reason}
    winner: str | None
    rungs: list[dict]  # one row per rung (``ladder_row``), the winner's first
    chosen: list[Candidate]  # one per rung; the last is the climb's end
    pruned: list[dict] = field(default_factory=list)  # elements dropped after the climb
    final: Candidate | None = None  # the selected model: the climb's end, pruned
    repolished: list[str] = field(default_factory=list)  # first-rung elements that, set back to
    # neutral, fitted better than the base (the base refitted from there; empty when the fit
    # check found the base's optimum)

    @property
    def selected(self) -> Candidate:
        if self.final is not None:
            return self.final
        return self.chosen[-1] if self.chosen else self.base


def prune(ctx: Context, final: Candidate) -> tuple[Candidate, list[dict]]:
    """Backward pruning (docs/gap-diagnosis.md, the addendum): each element of ``final``, the
    latest added first, stays only if ``final`` pays against the model without it (refitted from
    ``final`` with the element neutral, held out the same way); else it is dropped and the search
    starts again from the smaller model. Returns the pruned model and one row per drop."""
    dropped = []
    while final.effects:
        order = [e for e in reversed(final.effects)
                 if not any(ecm.REQUIRES.get(x) == e for x in final.effects if x != e)]  # fmt: skip
        for scheme in dict.fromkeys(ctx.scheme(e) for e in order):  # before the trials share it
            ctx.held(final, scheme)
        # every element's trial at once (:func:`each`); taken in the sequential order, up to
        # the first drop, as the one-at-a-time loop would
        trials = each(lambda e, f=final: _without(ctx, f, e), order)
        drop = next((k for k, (_, _, row) in enumerate(trials) if not row["pays"]), None)
        needed = trials if drop is None else trials[: drop + 1]
        for e, _, row in needed:
            ctx.say(f"pruning: {e} {'stays' if row['pays'] else 'dropped'}")
        # the fits counted are those the one-at-a-time rule makes (a reduced model's fit, then
        # one per held-out part, per trial up to the first drop), not those tried ahead
        ctx.count(-sum(1 + ctx.n_folds(ctx.scheme(e)) for e, _, _ in trials[len(needed) :]))
        if drop is None:
            break
        _, reduced, row = trials[drop]
        dropped.append({**row, "from": list(final.effects)})
        final = reduced
    return final, dropped


def _without(ctx: Context, final: Candidate, e: str) -> tuple[str, Candidate, dict]:
    """One trial of :func:`prune`: ``final`` refitted with ``e`` neutral, held out, and judged
    against ``final``."""
    st = ctx.structure(tuple(x for x in final.effects if x != e), final.st.knots)
    reduced = ctx.fit(st, [fitting.neutralise(final.X, (e,))], taus=())  # nested in a checked fit
    ctx.cross_validate(reduced, ctx.scheme(e))
    (row,) = judge(ctx, reduced, {e: final})
    return e, reduced, row


def _let_go(ctx: Context, cands: dict[str, Candidate], winner: str | None) -> None:
    """The first rung's held-out voltages that nothing reads once its winner is chosen, let go
    before the climb (issue 42: each is 8 bytes a sample, and a long record's first rung holds
    out most of its ~12 candidates while the later rungs hold out theirs). Kept: the winner's
    (the climb's first row, the verdict, the figure) and the second RC's where the hand-over
    scores it by record (``handover.score`` would hold it out again); the base is no candidate.
    The rung's rows are judged already."""
    for e, c in cands.items():
        if e != winner and not (e == SECOND_RC and ctx.layout.by_record):
            c.ho = c.ho_t = None


def ladder(ctx: Context, base: Candidate, effects=ecm.EFFECTS) -> Ladder:
    """Every applicable element tried on ``base`` (fitted to all training data, then, where its
    fit can pay, held out), the base re-polished where a candidate found it a better optimum, the
    winner, and the climb from it. The base and every candidate are cross-validated here."""
    tried = [e for e in effects if applicable(ctx.recs, e, (), ctx.table)[0]]
    cands = try_effects(ctx, base, tried, cv=False)
    # a candidate whose element, set back to neutral, fits better than the base found a better
    # base optimum: refit the base from there (the base must be at its best, or a candidate
    # "wins" by better optimisation alone). The fit check (fitting.check_fit) should leave
    # nothing to find here; ``Ladder.repolished`` says where it did not
    repolished = []
    for e, c in cands.items():
        rb = ctx.evaluate(base.st, fitting.neutralise(c.X, (e,)))
        if rb.rss < base.rss * (1 - 1e-9):
            res = fitting.best_of(ctx.recs, base.st, [rb.X])
            base = replace(ctx.evaluate(base.st, res.X), check=base.check.then(res.checks[-1]))
            repolished.append(e)
    # only a candidate whose full fit can pay is held out (as on the later rungs): one whose
    # ΔBIC ≥ BIC_MAX fails the criterion whatever its held-out error (against a re-polished,
    # better base its ΔBIC only rises), so holding it out would change no verdict
    held = {"base": base}
    held.update((e, c) for e, c in cands.items()
                if bic(c.rss, ctx.n, c.k) - bic(base.rss, ctx.n, base.k) < BIC_MAX)  # fmt: skip

    # the base held out every way a candidate held out is (``Context.scheme``)
    jobs = [
        ("base", s) for s in dict.fromkeys([RECORD, *(ctx.scheme(e) for e in held if e != "base")])
    ]
    jobs += [(e, ctx.scheme(e)) for e in held if e != "base"]

    def hold_out(job) -> None:
        e, scheme = job
        ctx.cross_validate(held[e], scheme)
        ctx.say(f"rung 1: {e} held out{' by temperature' if scheme == TEMPERATURE else ''}")

    each(hold_out, jobs)
    rows = judge(ctx, base, cands)
    winner = choose(ctx, rows, cands)
    _let_go(ctx, cands, winner)
    ctx.say(f"rung 1: {len(cands)} candidates, {winner or 'none'} wins")
    skipped = [{"effect": e, "applicable": False,
                "reason": applicable(ctx.recs, e, (), ctx.table)[1]}
               for e in effects if e not in cands]  # fmt: skip
    rungs, chosen = climb(ctx, base, winner, cands[winner], effects) if winner else ([], [])
    final, pruned = prune(ctx, chosen[-1]) if chosen else (base, [])
    return Ladder(base, cands, rows, skipped, winner, rungs, chosen, pruned, final, repolished)


# ----------------------------------------------------------------------------------------------
# what the ladder's models say and predict (the diagnosis reports it; nothing here is a choice)


def parameters(ctx: Context, cand: Candidate) -> dict:
    """Report-named parameters of a candidate: the cell's, then each record's initial SOC as
    the rule set it (flat for one record, as ``per_record`` for several; h0 is 0 by the rule)."""
    fm = fitted_model(ctx, cand)
    out = fm.parameters()
    per = [{"soc0": float(cand.X[r, ecm.IDX["soc0"]])} for r in range(len(ctx.recs))]
    if len(per) == 1:
        out.update(per[0])
    else:
        out["per_record"] = [
            {"source": rec.source, **p} for rec, p in zip(ctx.recs, per, strict=True)
        ]
    if {"thermal", "butler_volmer"} & set(cand.effects):
        out["tref_k"] = ctx.recs[0].tref_k
    return out


def fitted_model(ctx: Context, cand: Candidate, provenance=None) -> FittedModel:
    return model_of(ctx.recs, cand.st.config, cand.X, cand.st.knots, ctx.fix_q, provenance,
                    cand.st.pinned)  # fmt: skip


def training_soc_range(ctx: Context, cand: Candidate) -> tuple[float, float]:
    """The SOC range the training records cover under a model (its own SOC trajectory)."""
    lo, hi = np.inf, -np.inf
    for r, rec in enumerate(ctx.recs):
        _, tr = ecm.simulate_rows(rec, cand.X[r], cand.st.knots, cand.st.config.table, traces=True)
        lo, hi = min(lo, float(tr[0].min())), max(hi, float(tr[0].max()))
    return lo, hi


def floors(config: Config, frames: dict, capacity_ah=None) -> dict[str, dict]:
    """Per validation record, the configuration ``config`` fitted to that record alone (started
    by the same rule): what the model family reaches on it when it may see it."""
    out = {}
    for source, frame in frames.items():
        fit = fit_model(frame, config, capacity_ah)
        out[source] = {"rmse_mv": fit.train_rmse_mv, "parameters": fit.model.parameters()}
    return out


def validation(ctx, rungs: dict[str, Candidate], frames: dict,
               floor: dict[str, dict]) -> list[dict]:  # fmt: skip
    """One row per validation record × model of the ladder: errors over the record and inside
    the SOC range the training data covered, and beside each the record's floor (the selected
    configuration fitted to it). Nothing here feeds back into any choice."""
    rows = []
    for name, cand in rungs.items():
        fm = fitted_model(ctx, cand)
        lo, hi = training_soc_range(ctx, cand)
        for source, frame in frames.items():
            v, tr = fm.simulate(frame, traces=True)
            inside = (tr[0] >= lo) & (tr[0] <= hi)
            err = prediction_errors(v, frame["voltage_v"].to_numpy(), inside)
            rows.append({"record": source, "model": name, "effects": list(cand.effects),
                         "starts_at_rest": ecm.starts_at_rest(fm.record(frame)),
                         "soc0": float(tr[0][0]), "training_soc_range": [lo, hi], **err,
                         "floor_rmse_mv": floor[source]["rmse_mv"],
                         "above_floor_mv": err["rmse_mv"] - floor[source]["rmse_mv"]})  # fmt: skip
    return rows
