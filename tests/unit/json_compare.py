"""One comparison of two JSON documents for the tests that load a saved model and write it again.

A model keeps its log-scaled parameters as log10 of the value (``ecm.internal_value``), so
writing a loaded model gives ``10**log10(v)``, which is often not ``v``: the log's floats are
coarser than the values' over most of the range, so no pair of conversions returns every value,
and which values move depends on the C library's log10 and pow, picked by the CPU at run time
(seen: a bound of 0.257 written back as 0.25700000000000006 on one CPU, unchanged on another;
with numpy's log10 on that CPU 33 % of random values in [0.1, 0.5] move, 92 % in [1e-6, 1e-4]).
One round trip moves a value by about ln(10)·|log10 v|·2⁻⁵² relative, plus one ULP: under 10⁻¹⁴
for the library's ranges (|log10 v| ≤ 12). RTOL leaves room for that and still fails on any
change a reader would see in a digit that matters."""

from __future__ import annotations

import math

RTOL = 1e-13


def assert_same_json(got, want, rtol: float = RTOL, at: str = "") -> None:
    """Every key, list length, string and boolean equal; every number to ``rtol``."""
    if isinstance(want, dict):
        assert isinstance(got, dict), (at, got)
        assert set(got) == set(want), (at, sorted(got), sorted(want))
        for k in want:
            assert_same_json(got[k], want[k], rtol, f"{at}.{k}")
    elif isinstance(want, list):
        assert isinstance(got, list), (at, got)
        assert len(got) == len(want), (at, got, want)
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            assert_same_json(g, w, rtol, f"{at}[{i}]")
    elif _number(want) and _number(got) and (isinstance(want, float) or isinstance(got, float)):
        assert math.isclose(got, want, rel_tol=rtol, abs_tol=0.0), (at, got, want)
    else:
        assert type(got) is type(want), (at, got, want)
        assert got == want, (at, got, want)


def _number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)
