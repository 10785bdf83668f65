"""The second admission rule (docs/admission-rule.md, "Second variant"): criterion 1 on hand-built
intervals (the joint strength test, what blocks and what is only reported), criterion 2 on
hand-built held-out losses (harm on one part found, noise on every part not)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from avoa_pipeline import selection
from avoa_pipeline.model import intervals


def _iv(params: dict[str, tuple[float, float]], corr: dict | None = None,
        bounds: dict | None = None) -> intervals.Intervals:  # fmt: skip
    """Intervals of free parameters ``name: (value, sd)`` (internal), searched over ±10 unless
    ``bounds`` says otherwise, uncorrelated unless ``corr`` gives pairs."""
    names = tuple(params)
    value = np.array([params[n][0] for n in names], dtype=float)
    sd = np.array([params[n][1] for n in names], dtype=float)
    lo = np.array([(bounds or {}).get(n, (-10.0, 10.0))[0] for n in names])
    hi = np.array([(bounds or {}).get(n, (-10.0, 10.0))[1] for n in names])
    c = np.eye(len(names))
    for (a, b), r in (corr or {}).items():
        i, j = names.index(a), names.index(b)
        c[i, j] = c[j, i] = r
    c[~np.isfinite(sd), :] = np.nan
    c[:, ~np.isfinite(sd)] = np.nan
    return intervals.Intervals(names, value, lo, hi, sd, c, 1000, 100.0, 1e-3)


def test_vector_strength_judged_jointly():
    # two knots, each 1.5 sd off zero (neither 95 % interval excludes it), nearly independent:
    # W = 4.5 on 2 df, p 0.105 -> not identified; at 1.8 sd each (still neither interval off
    # zero), W = 6.48 on 2 df, p 0.039 -> it is: together they are
    weak = _iv({"r0": (0.05, 0.001), "r0u0": (1.5e-3, 1e-3), "r0u1": (1.5e-3, 1e-3)})
    assert "joint Wald" in selection.identified(weak, "r0_soc")
    clear = _iv({"r0": (0.05, 0.001), "r0u0": (1.8e-3, 1e-3), "r0u1": (1.8e-3, 1e-3)})
    assert not clear.excludes("r0u0", 0.0)
    assert selection.identified(clear, "r0_soc") is None
    # the same two knots strongly anticorrelated: their sum is what the records see, and it is
    # small against its own spread
    anti = _iv({"r0u0": (2e-3, 1e-3), "r0u1": (-1.5e-3, 1e-3)}, corr={("r0u0", "r0u1"): -0.95})
    assert "joint Wald" in selection.identified(anti, "r0_soc")


def test_one_strength_is_its_interval():
    assert selection.identified(_iv({"hm": (0.010, 0.004)}), "hysteresis") is None  # 2.5 sd
    assert selection.identified(_iv({"hm": (0.006, 0.004)}), "hysteresis") is not None  # 1.5 sd


def test_rate_only_reported():
    # the hysteresis size clear, its decay rate free: admitted, with a caveat
    iv = _iv({"hm": (0.015, 0.002), "lgamma": (2.0, np.inf)})
    assert selection.identified(iv, "hysteresis") is None
    (note,) = selection.caveats(iv, "hysteresis")
    assert "hysteresis_gamma not constrained" in note
    # the decay rate at its upper bound: admitted, the bound named
    at = _iv({"hm": (0.015, 0.002), "lgamma": (4.0, np.nan)}, bounds={"lgamma": (0.0, 4.0)})
    assert selection.identified(at, "hysteresis") is None
    (note,) = selection.caveats(at, "hysteresis")
    assert "at a bound" in note
    assert selection.caveats(_iv({"hm": (0.015, 0.002), "lgamma": (2.0, 0.1)}), "hysteresis") == []


def test_strength_at_bound_or_unconstrained_blocks_a_trade_is_reported():
    at = _iv({"kd": (0.0, np.nan), "ltaud": (3.0, 0.1)}, bounds={"kd": (0.0, 1.0)})
    assert "at a bound" in selection.identified(at, "diffusion")
    free = _iv({"kd": (0.3, np.inf), "ltaud": (3.0, 0.1)})
    assert "not constrained" in selection.identified(free, "diffusion")
    # a time constant trading with R0, the size clear on its marginal interval: admitted, named
    trade = _iv({"r0": (0.02, 0.001), "kd": (0.3, 0.01), "ltaud": (1.0, 0.1)},
                corr={("r0", "ltaud"): -0.995})  # fmt: skip
    assert selection.identified(trade, "diffusion") is None
    (note,) = selection.caveats(trade, "diffusion")
    assert "trades with r0_ohm" in note


def _ctx(v, sources=None, folds=None, batches=None):
    layout = SimpleNamespace(by_record=sources is not None, folds=folds, batches=batches)
    ctx = SimpleNamespace(v=v, n=v.size, layout=layout,
                          recs=[SimpleNamespace(source=s) for s in (sources or [])])  # fmt: skip
    ctx.ho_loss = lambda mr: (mr.ho - v) ** 2
    return ctx


def test_harm_on_one_record_found_noise_not():
    rng = np.random.default_rng(3)
    n = 2000
    v = np.zeros(2 * n)
    folds = [np.arange(n), np.arange(n, 2 * n)]
    batches = [b for f in folds for b in np.array_split(f, 50)]
    ref = SimpleNamespace(ho=rng.normal(0, 1e-3, 2 * n))
    same = SimpleNamespace(ho=rng.normal(0, 1e-3, 2 * n))  # as good, other noise
    ctx = _ctx(v, ["a.csv", "b.csv"], folds, batches)
    assert selection.harms_somewhere(ctx, ref, same) is None
    worse = SimpleNamespace(ho=same.ho + np.r_[np.zeros(n), np.full(n, 2e-3)])  # b.csv off 2 mV
    why = selection.harms_somewhere(ctx, ref, worse)
    assert why is not None
    assert "b.csv" in why


def test_harm_on_one_quarter_of_one_record():
    rng = np.random.default_rng(4)
    n = 6000
    batches = np.array_split(np.arange(n), 100)
    ref = SimpleNamespace(ho=rng.normal(0, 1e-3, n))
    near = SimpleNamespace(ho=rng.normal(0, 1e-3, n))
    ctx = _ctx(np.zeros(n), batches=batches)
    assert selection.harms_somewhere(ctx, ref, near) is None
    # better by far on the first three quarters, 1.5 mV off on the last: the total gains, the
    # last quarter is harmed
    bad = SimpleNamespace(ho=np.r_[0.3 * near.ho[: 3 * n // 4], near.ho[3 * n // 4 :] + 1.5e-3])
    why = selection.harms_somewhere(ctx, ref, bad)
    assert why is not None
    assert "part 4/4" in why
