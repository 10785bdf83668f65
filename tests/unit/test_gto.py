"""GTO's own moves (reference MATLAB semantics): diagonal migration, following the silverback with
the sequentially updated mean, competition centred on the silverback; its settings.

The contract it shares with the other optimizers (bounds, budgets -- GTO spends 2 P evaluations
per iteration --, reproducibility, history, convergence) is in test_optimizer_contract.py.
"""

import numpy as np
import pytest
from optim_helpers import Recorder, runner, shifted

from avoa_pipeline.optimizers import Budget
from avoa_pipeline.optimizers.testfunctions import sphere

run = runner("gto")


def test_migration_to_unknown_place_is_on_the_box_diagonal():
    # reference: GX = (ub - lb) * rand + lb with ONE scalar rand per gorilla
    rec = Recorder(sphere)
    lb, ub = np.array([-3.0, 0.0, 10.0]), np.array([1.0, 2.0, 30.0])
    run(rec, lb, ub, Budget(pop_size=10, iterations=5), p=1.0)
    for explo in rec.calls[1::2]:  # the exploration evaluations
        frac = (explo - lb) / (ub - lb)
        assert np.allclose(frac, frac[:, :1])


def replay(calls, f):
    """Re-derive, from the evaluated populations alone, the memory X and the silverback S after
    each exploration evaluation (greedy replacement, best ever), with both candidate arrays."""
    X = calls[0].copy()
    cost = f(X)
    k = int(np.argmin(cost))
    S, s_cost = X[k].copy(), cost[k]
    for it in range(1, (len(calls) - 1) // 2 + 1):
        for phase in (1, 2):
            GX = calls[2 * it - 2 + phase]
            g = f(GX)
            better = g < cost
            X[better], cost[better] = GX[better], g[better]
            k = int(np.argmin(g))
            if g[k] < s_cost:
                S, s_cost = GX[k].copy(), g[k]
            if phase == 1:
                yield it, X.copy(), S.copy(), GX, calls[2 * it]


small_shifted_sphere = shifted(sphere, [0.61, -1.37, 2.05, -0.42, 1.11])


def test_follow_silverback_uses_the_sequentially_updated_mean_of_gx():
    # w = 0: every exploitation is "follow the silverback", GX_i = L M_i (X_i - S) + X_i, where
    # M_i = |mean(GX)| over the rows 1..i-1 already replaced and the exploration rows i..P (the
    # reference overwrites GX in place). Then one L per iteration explains every unclipped move;
    # a mean computed once (as mealpy does) leaves a spread of O(1).
    rec = Recorder(small_shifted_sphere)
    lb, ub = np.full(5, -5.12), np.full(5, 5.12)
    run(rec, lb, ub, Budget(pop_size=20, iterations=30), seed=0, w=0.0)
    checked = 0
    for _, X, S, explo, GX in replay(rec.calls, small_shifted_sphere):
        if np.any(lb >= GX) or np.any(ub <= GX):
            continue  # clipped rows hide the unclipped values the later means used
        Ls = []
        for i in range(len(GX)):
            M = np.abs(np.vstack([GX[:i], explo[i:]]).mean(axis=0))
            step = M * (X[i] - S)
            ok = np.abs(step) > 1e-6
            Ls.append((GX[i] - X[i])[ok] / step[ok])
        Ls = np.concatenate(Ls)
        assert np.ptp(Ls) <= 1e-8 * np.abs(Ls).mean()
        checked += 1
    assert checked >= 20


def test_competition_is_centred_on_the_silverback():
    # once C < w, GX_i = S + Q beta E (X_i - S) with Q ~ U(-1, 1): the ratio (GX_i - S)/(X_i - S)
    # has median 0 (it would be 1 if the move were centred on X_i)
    rec = Recorder(small_shifted_sphere)
    lb, ub, T = -5.12, 5.12, 100
    run(rec, [lb] * 5, [ub] * 5, Budget(pop_size=20, iterations=T), seed=0)
    ratios = []
    for it, X, S, _, GX in replay(rec.calls, small_shifted_sphere):
        if it > 0.6 * T:  # C <= 2 (1 - It/T) < w = 0.8
            d = X - S
            ok = (np.abs(d) > 1e-9) & (lb < GX) & (ub > GX)
            ratios.append((GX - S)[ok] / d[ok])
    ratios = np.concatenate(ratios)
    assert len(ratios) > 1000
    assert abs(np.median(ratios)) < 0.15


def test_invalid_settings_are_rejected():
    with pytest.raises(ValueError, match=r"must be"):
        run(sphere, [-1.0], [1.0], Budget(pop_size=5, iterations=2), p=1.5)
