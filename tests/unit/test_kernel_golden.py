"""The compiled simulator, generated from the elements' statements (issue 39), gives the voltages
of the hand-written loop it replaced bit for bit: every element alone and all together, rational
OCV and table, under the paper's load, whole, thinned (the held-current shortcut) and traced.
The reference values were recorded on main at a81259e by tests/data/make_kernel_golden.py."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parents[1] / "data"


@pytest.fixture(scope="module")
def now():
    spec = importlib.util.spec_from_file_location("make_kernel_golden",
                                                  DATA / "make_kernel_golden.py")  # fmt: skip
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.simulate_all()


@pytest.fixture(scope="module")
def golden():
    with np.load(DATA / "kernel_golden.npz") as z:
        return {k: z[k] for k in z.files}


def test_whole_pass_bit_for_bit(now, golden):
    full, _ = now
    names = set(golden) - {"digest_names", "digests"}
    assert set(full) == names
    for name in sorted(names):
        v, ref = full[name], golden[name]
        assert v.tobytes() == ref.tobytes(), (name, float(np.max(np.abs(v - ref))))


def test_thinned_and_traced_bit_for_bit(now, golden):
    _, digests = now
    ref = dict(zip(golden["digest_names"].tolist(), golden["digests"].tolist(), strict=True))
    assert set(digests) == set(ref)
    assert [n for n in sorted(ref) if digests[n] != ref[n]] == []
