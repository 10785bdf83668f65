"""The model handed over (docs/handover-rule.md, avoa_pipeline.handover): its candidates, the
hand-over conditions and their reasons, the strict minimum, the forward stretches of one record,
the expected error in model.json and the command lines, on small synthetic records."""

import contextlib
import io
import json

import numpy as np
import pytest
from test_ecm import TRUTH, profile_frame, with_voltage

from avoa_pipeline import handover, selection, threads
from avoa_pipeline.cli import main
from avoa_pipeline.errors import DataError
from avoa_pipeline.model.ecm import IDX, Record
from avoa_pipeline.model.fitted import FittedModel

RC2 = {**TRUTH, "r2_ohm": 0.01, "tau2_s": 1000.0}


def _ctx(*frames) -> selection.Context:
    return selection.Context([Record.from_frame(f, source=f"r{k}.csv")
                              for k, f in enumerate(frames)])  # fmt: skip


@pytest.fixture(scope="module")
def one():
    """One record of the base model with 1 mV noise, its context and base fit."""
    ctx = _ctx(with_voltage(profile_frame(), TRUTH, noise_v=1e-3, seed=3))
    return ctx, selection.fit_base(ctx)


def _with(ctx, base, effect: str, **values) -> selection.Candidate:
    """``base`` plus ``effect`` with its parameters set (internal values), not fitted."""
    st = ctx.structure((effect,), base.st.knots)
    X = np.array(base.X)
    for k, v in values.items():
        X[:, IDX[k]] = v
    return ctx.evaluate(st, X)


def _ladder(base, final) -> selection.Ladder:
    """A ladder whose verdict's model is ``final`` (the rule reads only its base, first-rung
    candidates and selected model)."""
    return selection.Ladder(base, {}, [], [], None, [], [final], [], final)


def test_an_element_at_a_bound_is_not_handed_over_and_the_reason_is_said(one):
    ctx, base = one
    st = ctx.structure(("second_rc",), base.st.knots)
    k = st.shared.index("ltau2")
    cand = _with(ctx, base, "second_rc", r2=0.01, ltau2=st.hi[k])
    failed, _, _ = handover.failures(ctx, cand, 0.003)
    assert "at a bound of its searched range" in " ".join(failed["second_rc"])
    reduced, removed, _ = handover.reduce(ctx, cand, 0.003)
    assert reduced.effects == ()
    assert "tau2_s" in removed["second_rc"][0]
    ho = handover.hand_over(ctx, _ladder(base, cand))
    names = [e.name for e in ho.entries]
    assert names[:2] == ["base", "2rc"]  # always candidates
    (el,) = ho.verdict
    assert el["effect"] == "second_rc"
    assert "at a bound of its searched range" in el["why"]


def test_an_unidentified_element_is_not_handed_over(one):
    ctx, base = one
    # a second branch with the first one's time constant: the records cannot tell R1 from R2
    cand = _with(ctx, base, "second_rc", r2=0.005, ltau2=base.X[0, IDX["ltau1"]])
    failed, _, _ = handover.failures(ctx, cand, 0.003)
    assert failed["second_rc"][0].startswith("not identified: ")


def test_a_current_offset_beyond_three_times_the_accuracy_is_a_fault(one):
    ctx, base = one
    acc = handover.current_accuracy(ctx.recs)
    assert acc == pytest.approx(handover.CURRENT_ACCURACY_OF_IMAX * 3.0)  # the profile's 3 A
    cand = _with(ctx, base, "current_offset", ioff=0.05)
    failed, _, warnings = handover.failures(ctx, cand, acc)
    assert "instrument fault" in " ".join(failed["current_offset"])
    assert len(warnings) == 1
    assert "+0.05 A" in warnings[0]
    ho = handover.hand_over(ctx, _ladder(base, cand))
    assert ho.warnings == warnings
    assert "current_offset" not in ho.chosen.effects
    assert "instrument fault" in ho.verdict[0]["why"]
    # the user's accuracy (--current-accuracy-a): within it, but one record is no evidence
    failed, _, warnings = handover.failures(ctx, cand, 1.0)
    assert not warnings
    assert "needs two or more training records" in " ".join(failed["current_offset"])


def test_one_record_forward_stretches_hold_out_what_follows_the_cut(one):
    ctx, base = one
    n = ctx.recs[0].n
    r, after, err = handover.forward(ctx, base, 0.5)
    assert r == 0
    assert (after[0], after[-1]) == (n // 2, n - 1)
    # the samples after the cut do not enter the fit: shifted by 50 mV, the prediction stays
    frame = with_voltage(profile_frame(), TRUTH, noise_v=1e-3, seed=3)
    frame.loc[n // 2 :, "voltage_v"] += 0.05
    moved = _ctx(frame)
    _, after2, err2 = handover.forward(moved, base, 0.5)
    np.testing.assert_array_equal(after, after2)
    np.testing.assert_allclose(err - err2, 0.05, atol=1e-9)
    entry = handover.Entry("base", base)
    handover.score(ctx, entry)
    sq = [np.sum(e**2) for _, _, e in entry.held]
    assert [a.size for _, a, _ in entry.held] == [n - n // 2, n - round(0.75 * n)]
    assert entry.score == pytest.approx(sum(sq) / sum(e.size for _, _, e in entry.held))


def test_two_records_are_scored_leaving_one_out_and_the_minimum_is_taken():
    frames = [with_voltage(profile_frame(), RC2, noise_v=1e-3, seed=s) for s in (4, 5)]
    ctx = _ctx(*frames)
    assert ctx.layout.by_record
    base = selection.fit_base(ctx)
    ctx.cross_validate(base)
    ho = handover.hand_over(ctx, _ladder(base, base))
    assert ho.kind == "leave one record out"
    assert [e.name for e in ho.entries] == ["base", "2rc"]  # the reduced verdict is the base
    for e in ho.entries:
        assert e.score == pytest.approx(ctx.ho_mse(e.cand))
        if e.eligible:
            assert ho.chosen.score <= e.score
    assert ho.chosen.effects == ("second_rc",)  # the records have a second branch
    ee = handover.expected_error(ctx, ho)
    assert ee["rms_mv"] == pytest.approx(1e3 * np.sqrt(ho.chosen.score))
    assert ee["samples"] == ctx.n
    assert all(b["n"] >= handover.MIN_BIN_SAMPLES for b in ee["by_operating_point"])


def test_expected_error_bins_and_correlation_time():
    n = 4000
    rng = np.random.default_rng(0)
    e = np.zeros(n)  # an AR(1) error with a time constant of 20 samples
    for k in range(1, n):
        e[k] = np.exp(-1 / 20) * e[k - 1] + rng.standard_normal()
    frame = profile_frame()
    ctx = _ctx(frame)
    got = handover.correlation_time(ctx, [(0, np.arange(n), e)])
    assert got["correlation_time_samples"] == pytest.approx(20, rel=0.3)
    assert got["correlation_time_s"] == got["correlation_time_samples"]  # 1-s samples
    mode = np.array([0] * 300 + [1] * 300 + [-1] * 150)
    amps = np.array([0.0] * 300 + [1.0] * 150 + [3.0] * 150 + [1.0] * 150)
    soc = np.full(mode.size, 0.5)
    bins = handover._bins(np.full(mode.size, 2e-3), mode, amps, soc, 2.0)
    assert [(b["mode"], b["current"], b["n"]) for b in bins] == [("rest", "-", 300)]
    assert bins[0]["rms_mv"] == pytest.approx(2.0)


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory):
    """``diagnose`` of a 2RC record (one record): its folder and what it printed on stdout."""
    path = tmp_path_factory.mktemp("ho") / "rc.csv"
    with_voltage(profile_frame(), RC2, noise_v=1e-3, seed=2).to_csv(path, index=False)
    out = path.parent / "out"
    said = io.StringIO()
    with contextlib.redirect_stdout(said):
        code = main(["diagnose", str(path), "--out", str(out), "--current-accuracy-a", "0.01"])
    assert code == 0
    return path, out, said.getvalue()


def test_diagnose_hands_over_and_says_so(cli_run, capsys):
    path, out, said = cli_run
    assert said.count("\n") == 1
    report = json.loads((out / "diagnosis.json").read_text())
    ho = report["handed_over"]
    assert f"handed over {ho['name']}: held-out RMSE " in said
    assert (ho["current_accuracy_a"], ho["current_accuracy_given"]) == (0.01, True)
    assert ho["score"].startswith("forward stretches")
    eligible = [c["heldout_rmse_mv"] for c in ho["candidates"] if c["eligible"]]
    assert {"base", "2rc"} <= {c["candidate"] for c in ho["candidates"]}
    assert ho["heldout_rmse_mv"] == min(eligible)
    model = json.loads((out / "model.json").read_text())
    assert model["effects"] == ho["effects"]
    assert model["provenance"]["verdict_model"] == report["selected"]["name"]
    assert "hand-over rule" in model["provenance"]["selected_by"]
    ee = model["expected_error"]
    assert ee["rms_mv"] == pytest.approx(ho["heldout_rmse_mv"])
    loaded = FittedModel.load(out / "model.json")
    assert loaded.expected_error == ee
    assert json.loads(json.dumps(loaded.to_json())) == model  # round trip
    # a model.json written before the block loads, and simulate says it has none
    del model["expected_error"]
    old = out.parent / "old.json"
    old.write_text(json.dumps(model))
    assert FittedModel.load(old).expected_error is None
    assert main(["simulate", str(out / "model.json"), str(path), "--out",
                 str(out.parent / "p.csv")]) == 0  # fmt: skip
    assert f"expected {ee['rms_mv']:.2f} mV RMS" in capsys.readouterr().out
    assert main(["simulate", str(old), str(path), "--out", str(out.parent / "q.csv")]) == 0
    assert "no expected error in the model" in capsys.readouterr().out


def test_a_bad_expected_error_is_refused_naming_the_field(cli_run):
    _, out, _ = cli_run
    model = json.loads((out / "model.json").read_text())
    model["expected_error"]["rms_mv"] = -1.0
    with pytest.raises(DataError, match=r"field 'expected_error\.rms_mv'"):
        FittedModel.from_json(model)


def test_a_bad_current_accuracy_is_refused(tmp_path, capsys):
    path = tmp_path / "r.csv"
    with_voltage(profile_frame(), TRUTH, noise_v=1e-3).to_csv(path, index=False)
    out = tmp_path / "out"
    assert main(["diagnose", str(path), "--out", str(out), "--current-accuracy-a", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "--current-accuracy-a" in err
    assert not out.exists()


def test_the_rule_gives_the_same_on_one_thread_and_two(one, monkeypatch):
    """The candidates are checked and scored side by side (``selection.each``): the scores are
    the same to the bit whatever the number of threads, and so are the fits counted."""
    ctx, base = one
    got = {}
    for n in (1, 2):
        monkeypatch.setattr(threads, "given", lambda k=n: k)
        fits = ctx.fits
        ho = handover.hand_over(ctx, _ladder(base, base))
        got[n] = ([e.score for e in ho.entries], ho.name, ctx.fits - fits)
    assert got[1] == got[2]
