"""Per-temperature parameters as a candidate (docs/temperature-rule.md part 2-3): the hand-over's
circuit, its R0, RC branches and capacity fitted per test temperature, as a BMS table holds them,
judged against the temperature laws by the selection's own tests.

The candidate (:func:`fit`) takes the structure handed over (``handover.hand_over``) without its
temperature laws, fitted to every training record (``handover.refit``: the circuit); each test
temperature's records then get their own R0, RC resistances and time constants and capacity
(:data:`FREE`), every other parameter (the OCV's offset and shape, hysteresis, the
SOC-dependent terms) held at the circuit's values (``fitting.Structure.pinned``). Between two
test temperatures a set is interpolated linearly in 1/T of the ambient, outside their span the
nearest is used (``FittedModel.at_ambient``, part 3's format).

Held out (:func:`hold_out`):

- by test temperature (G ≥ 3, part 2): a temperature's records predicted by the other
  temperatures' sets interpolated at its ambient (the nearest set at an end). The sets are each
  fitted to their own temperature's records only, so no set has seen the temperature it
  predicts; the held parameters are the circuit's, fitted to every record (they carry no
  temperature dependence: that is what the sets are);
- by record (G = 2, and the hand-over's score): a record predicted by its temperature's set
  fitted to that temperature's other records, or, where it is its temperature's only record,
  by the other temperatures' sets as above.

Judged (:func:`judge`): the table pays against the laws' model by ``selection.compare`` (both
held-out tests at ALPHA, ``MIN_SHRINK``, ΔBIC < ``BIC_MAX`` counting every set's parameters);
where neither pays against the other the one with fewer parameters stays (the laws' model,
whenever the table has more). Each set must pass the hand-over conditions on its records
(``handover.failures``) and identify its cell's parameters (``handover.cell_unidentified``).

Hand-written: the candidate and its hold-outs are this project's rule; the fits, tests,
interpolation and conditions are the selection's, the model layer's and the hand-over's.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import handover, selection
from .model import ecm, fitting, intervals
from .model.fitted import FittedModel
from .selection import TEMPERATURE, Candidate, Context

NAME = "per-temperature parameters"
"""The candidate's name in diagnosis.json (``handed_over.per_temperature_parameters``)."""
LAWS = "the laws' model"
"""What :func:`judge` keeps where the table does not win: the model handed over, its laws."""
FREE = ("r0", "r1", "ltau1", "r2", "ltau2", "r3", "ltau3", "lq")
"""What a BMS table holds per temperature (part 3): R0, each RC branch's R and τ, the
capacity."""


@dataclass
class Table:
    """The candidate: the circuit (every record), each test temperature's context and set, the
    sets' per-record rows on the training records as one candidate (``cand``: the circuit's
    structure, each record's row its temperature's set), and its parameter count."""

    ctx: Context
    circuit: Candidate
    subs: list[Context]
    sets: list[Candidate]
    ambients: list[float]
    cand: Candidate
    k: int
    models: list[FittedModel] = field(default_factory=list)  # each set as a model of its records


def circuit_of(ctx: Context, cand: Candidate) -> Candidate:
    """``cand`` without its temperature laws, refitted to every training record (itself where
    it has none)."""
    keep = tuple(e for e in cand.effects if not selection.is_law(e))
    return cand if keep == cand.effects else handover.refit(ctx, cand, keep)


def fit(ctx: Context, cand: Candidate) -> Table:
    """The candidate of the structure ``cand`` (the model handed over): its circuit fitted to
    every record, then each test temperature's :data:`FREE` parameters to its records, warm
    started from the circuit (:func:`selection.each`, one set per thread)."""
    circuit = circuit_of(ctx, cand)
    held = tuple(n for n in circuit.st.shared if n not in FREE)

    def one(group):
        sub = ctx.subset(group)
        st = sub.structure(circuit.effects, circuit.st.knots,
                           pinned=(*circuit.st.pinned, *held))  # fmt: skip
        return sub, sub.fit(st, [circuit.X[group]])

    pairs = selection.each(one, ctx.groups)
    subs, sets = [s for s, _ in pairs], [c for _, c in pairs]
    ctx.count(sum(s.fits for s in subs))
    X = np.array(circuit.X)
    for group, c in zip(ctx.groups, sets, strict=True):
        X[group] = c.X
    v = ctx.simulate(circuit.st, X)
    free = len(sets[0].st.shared)
    ambients = [handover.group_ambient(ctx.ambients_c, g) for g in ctx.groups]
    table = Table(ctx, circuit, subs, sets, ambients, Candidate(circuit.st, X, v, ctx.sse(v)),
                  len(ctx.groups) * free + len(held))  # fmt: skip
    table.models = [selection.fitted_model(s, c) for s, c in zip(subs, sets, strict=True)]
    ctx.say(f"{NAME}: {len(sets)} sets fitted")
    return table


def _from_others(table: Table, g: int) -> FittedModel:
    """The other test temperatures' sets at ``g``'s ambient (interpolated in 1/T; the nearest at
    an end)."""
    others = [(a, m) for h, (a, m) in enumerate(zip(table.ambients, table.models, strict=True))
              if h != g]  # fmt: skip
    if len(others) == 1:
        return others[0][1]
    return FittedModel.per_temperature(others).at_ambient(table.ambients[g])


def _predict(table: Table, model: FittedModel, r: int) -> np.ndarray:
    """Training record ``r`` predicted by ``model`` (a set of the circuit's structure), started
    by the initial-state rule."""
    st, rec = table.circuit.st, table.ctx.recs[r]
    row = fitting.complete(st, [rec], np.array(model.x)[None, :])[0]
    return ecm.simulate_rows(rec, row, st.knots, st.config.table, st.config.load_ohm)[:, 0]


def hold_out(table: Table, scheme: str) -> np.ndarray:
    """The table's held-out voltage on the training records by ``scheme`` (the module's
    docstring), stored on ``table.cand`` as the selection's candidates store theirs."""
    ctx, o = table.ctx, table.ctx.layout.offsets
    ho = np.empty(ctx.n)
    for g, group in enumerate(ctx.groups):
        if scheme != TEMPERATURE and len(group) >= 2:
            sub = table.subs[g]
            table.sets[g].ho = None  # its own records, one out at a time
            sub.cross_validate(table.sets[g])
            ctx.count(sub.n_folds())
            for k, r in enumerate(group):
                ho[o[r] : o[r + 1]] = table.sets[g].ho[sub.layout.offsets[k] :
                                                        sub.layout.offsets[k + 1]]  # fmt: skip
            continue
        model = _from_others(table, g)
        for r in group:
            ho[o[r] : o[r + 1]] = _predict(table, model, r)
    if scheme == TEMPERATURE:
        table.cand.ho_t = ho
    else:
        table.cand.ho = ho
    return ho


def forward(table: Table, g: int, cut: float):
    """Part 4 on a one-record test temperature: its set fitted to the record's samples before
    ``cut`` (``handover.forward`` on the temperature's own context), the samples after it
    scored; returns (the record's index among the training records, indices, errors)."""
    _, after, err = handover.forward(table.subs[g], table.sets[g], cut, 0)
    return table.ctx.groups[g][0], after, err


def judge(ctx: Context, ref: Candidate, table: Table, accuracy_a: float) -> dict:
    """The table against the laws' model ``ref`` (part 2): held out by test temperature with
    three or more, else by record; whether it pays (``selection.compare``), whether the laws'
    model pays against it, each set's hand-over conditions, and which is kept. Returns
    diagnosis.json's ``handed_over.per_temperature_parameters``."""
    scheme = TEMPERATURE if len(ctx.groups) >= 3 else selection.RECORD
    if table.cand.heldout(scheme) is None:
        hold_out(table, scheme)
    if scheme != selection.RECORD and table.cand.ho is None:
        hold_out(table, selection.RECORD)  # the hand-over's score and part 4's errors
    loss_ref, loss = ctx.ho_loss(ref, scheme), ctx.ho_loss(table.cand, scheme)
    dbic = (selection.bic(table.cand.rss, ctx.n, table.k)
            - selection.bic(ref.rss, ctx.n, ref.k))  # fmt: skip
    row = selection.compare(ctx, loss_ref, loss, 1, dbic)
    back = selection.compare(ctx, loss, loss_ref, 1, -dbic)
    failed = {}
    for g, (sub, c) in enumerate(zip(table.subs, table.sets, strict=True)):
        why, iv, _ = handover.failures(sub, c, accuracy_a)
        if loose := handover.cell_unidentified(handover.Entry(NAME, c, iv=iv)):
            why["cell"] = [f"not identified: {', '.join(loose)}"]
        if why:
            failed[f"{table.ambients[g]:g} °C"] = why
    # the better of the two by the tests; where neither pays against the other, the one with
    # fewer parameters (part 2); a table whose sets fail the hand-over conditions is not kept
    if row["pays"]:
        kept = NAME
    elif back["pays"]:
        kept = LAWS
    else:
        kept = NAME if table.k < ref.k else LAWS
    if failed:
        kept = LAWS
    return {
        "held_out": selection.LEAVE_ONE_TEMPERATURE_OUT if scheme == TEMPERATURE
        else "leave one record out",
        "effects": list(table.circuit.effects),
        "free": [ecm.PARAMS[n].report for n in FREE if n in table.sets[0].st.shared],
        "n_params": table.k,
        "laws_n_params": ref.k,
        "ambients_c": table.ambients,
        "laws_heldout_rmse_mv": 1e3 * float(np.sqrt(float(np.sum(ctx.w * loss_ref)) / ctx.n)),
        **row,
        "laws_pay_against_it": back["pays"],
        "failed": failed,
        "kept": kept,
    }  # fmt: skip


def combined(table: Table, provenance: dict) -> FittedModel:
    """The table handed over as one model.json (part 3's ``by_temperature``), each set with its
    intervals on its records."""
    models = []
    for g, m in enumerate(table.models):
        sub, c = table.subs[g], table.sets[g]
        m.intervals = intervals.of_fit(sub.recs, c.st, c.X).report()
        models.append((table.ambients[g], m))
    return FittedModel.per_temperature(models, provenance=provenance)
