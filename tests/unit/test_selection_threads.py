"""The selection's independent fits on several threads (``selection.each``) and the diagnosis's
one BLAS thread (``diagnose.BLAS_THREADS``): the same results, bit for bit, whatever the number
of threads; the fits counted are those the one-at-a-time rule makes."""

import threading
from types import SimpleNamespace

import pytest
from test_ecm import TRUTH, profile_frame, with_voltage
from threadpoolctl import threadpool_info

from avoa_pipeline import selection, threads
from avoa_pipeline.gap import diagnose
from avoa_pipeline.model import ecm


def test_each_keeps_the_order_and_runs_a_task_inside_a_task_in_its_thread(monkeypatch):
    monkeypatch.setattr(threads, "given", lambda: 2)
    main = threading.get_ident()

    def task(x):
        me = threading.get_ident()
        inner = selection.each(lambda y: (y, threading.get_ident()), range(3))
        assert [i for i, _ in inner] == [0, 1, 2]
        assert {t for _, t in inner} == {me}  # one by one, in the task's own thread
        return x * x, me

    out = selection.each(task, range(6))
    assert [v for v, _ in out] == [x * x for x in range(6)]
    assert all(t != main for _, t in out)  # on the pool's threads
    monkeypatch.setattr(threads, "given", lambda: 1)
    assert {t for _, t in selection.each(task, range(3))} == {main}


def test_each_raises_a_tasks_error(monkeypatch):
    monkeypatch.setattr(threads, "given", lambda: 2)

    def task(x):
        if x == 3:
            raise ValueError("three")
        return x

    with pytest.raises(ValueError, match="three"):
        selection.each(task, range(5))


EFFECTS = ("second_rc", "current_offset", "hysteresis")
"""The elements tried (the whole registry would make the test minutes long)."""


def _two_records():
    truth = {**TRUTH, "r2_ohm": 0.01, "tau2_s": 1000.0}
    a = with_voltage(profile_frame(), truth, noise_v=1e-3, seed=2)
    other = profile_frame([(300, 0.0), (1500, 1.5), (600, 0.0), (900, -1.0), (300, 0.0)])
    b = with_voltage(other, {**truth, "soc0": 0.7}, noise_v=1e-3, seed=7)
    return {"a.csv": a, "b.csv": b}


def test_a_ladder_is_the_same_on_one_thread_and_on_two(monkeypatch):
    """Two records (each held out whole): the candidates of every rung, the first rung's held-out
    fits and the pruning's trials run side by side, and the ladder is the same to the bit."""
    recs = [ecm.Record.from_frame(f, tref_k=298.15) for f in _two_records().values()]
    out = {}
    for n in (1, 2):
        monkeypatch.setattr(threads, "given", lambda k=n: k)
        ctx = selection.Context(recs)
        lad = selection.ladder(ctx, selection.fit_base(ctx), EFFECTS)
        out[n] = ctx.fits, lad
    (fits1, one), (fits2, two) = out[1], out[2]
    assert one.rungs  # the climb and the pruning ran
    assert one.final is not None
    assert fits1 == fits2
    assert (one.rows, one.rungs, one.pruned) == (two.rows, two.rungs, two.pruned)
    assert (one.final.X == two.final.X).all()
    assert (one.final.ho == two.final.ho).all()
    for e, c in one.candidates.items():
        assert (c.X == two.candidates[e].X).all()


def test_held_out_parts_of_one_record_are_the_same_on_one_thread_and_on_two(monkeypatch):
    """One record (interleaved blocks): a model held out alone runs its folds side by side."""
    frame = with_voltage(profile_frame(), TRUTH, noise_v=1e-3, seed=1)
    ctx = selection.Context([ecm.Record.from_frame(frame)])
    base = selection.fit_base(ctx)
    out = {}
    for n in (1, 2):
        monkeypatch.setattr(threads, "given", lambda k=n: k)
        fits = ctx.fits
        c = ctx.cross_validate(selection.Candidate(base.st, base.X, base.v, base.rss))
        out[n] = c
        assert ctx.fits - fits == len(ctx.layout.folds)
    assert (out[1].ho == out[2].ho).all()
    assert all((x == y).all() for x, y in zip(out[1].fold_X, out[2].fold_X, strict=True))


def test_pruning_counts_only_the_trials_the_one_at_a_time_rule_makes(monkeypatch):
    """All of a round's trials run at once; the first that does not pay (in the sequential
    order, the latest element first) is dropped, and the fits of the trials after it are not
    counted."""
    monkeypatch.setattr(threads, "given", lambda: 2)
    ctx = SimpleNamespace(fits=0, layout=SimpleNamespace(folds=[0, 1, 2]), said=[], held=[])
    ctx.count = lambda n: setattr(ctx, "fits", ctx.fits + n)
    ctx.say = ctx.said.append
    ctx.scheme = lambda e: selection.RECORD
    ctx.n_folds = lambda scheme: len(ctx.layout.folds)
    ctx.held = lambda cand, scheme: None
    per_trial = 1 + len(ctx.layout.folds)

    def without(ctx, final, e):
        ctx.count(per_trial)
        rest = tuple(x for x in final.effects if x != e)
        return e, SimpleNamespace(effects=rest), {"pays": e != "second_rc", "effect": e}

    monkeypatch.setattr(selection, "_without", without)
    final = SimpleNamespace(effects=("second_rc", "current_offset", "hysteresis"))
    pruned, dropped = selection.prune(ctx, final)
    assert pruned.effects == ("current_offset", "hysteresis")
    assert [d["effect"] for d in dropped] == ["second_rc"]
    # round 1: hysteresis, current_offset stay, second_rc dropped (3 trials, all needed);
    # round 2: hysteresis and current_offset stay (2 trials)
    assert ctx.fits == 5 * per_trial
    assert ctx.said == ["pruning: hysteresis stays", "pruning: current_offset stays",
                        "pruning: second_rc dropped", "pruning: hysteresis stays",
                        "pruning: current_offset stays"]  # fmt: skip

    ctx.fits, ctx.said[:] = 0, []
    final = SimpleNamespace(effects=("current_offset", "second_rc", "hysteresis"))
    pruned, _ = selection.prune(ctx, final)
    # round 1: hysteresis stays, second_rc dropped; current_offset's trial ran but is not
    # counted; round 2: both stay
    assert ctx.fits == 4 * per_trial
    assert pruned.effects == ("current_offset", "hysteresis")

    # a temperature law is held out by test temperature (two groups here): its trial's fits
    # are 1 + 2 when it is not counted; the final model is held out that way before the trials
    held = []
    ctx.scheme = lambda e: selection.TEMPERATURE if e == "thermal" else selection.RECORD
    ctx.n_folds = lambda scheme: 2 if scheme == selection.TEMPERATURE else 3
    ctx.held = lambda cand, scheme: held.append((cand.effects, scheme))

    def without_law(ctx, final, e):
        ctx.count(1 + ctx.n_folds(ctx.scheme(e)))
        rest = tuple(x for x in final.effects if x != e)
        return e, SimpleNamespace(effects=rest), {"pays": e != "hysteresis", "effect": e}

    monkeypatch.setattr(selection, "_without", without_law)
    ctx.fits = 0
    final = SimpleNamespace(effects=("thermal", "hysteresis"))
    pruned, _ = selection.prune(ctx, final)
    # round 1: hysteresis dropped first, thermal's trial (1 + 2 fits) not counted; round 2:
    # thermal stays (1 + 2)
    assert pruned.effects == ("thermal",)
    assert ctx.fits == (1 + 3) + (1 + 2)
    assert held == [(("thermal", "hysteresis"), selection.RECORD),
                    (("thermal", "hysteresis"), selection.TEMPERATURE),
                    (("thermal",), selection.TEMPERATURE)]  # fmt: skip


def test_a_diagnosis_runs_with_one_blas_thread(monkeypatch):
    seen = []

    def body(*args):
        seen.extend(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas")
        return "report"

    monkeypatch.setattr(diagnose, "_diagnose_records", body)
    assert diagnose.diagnose_records(None) == "report"
    assert seen
    assert set(seen) == {diagnose.BLAS_THREADS}
