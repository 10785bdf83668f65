"""The comparison the save-and-load tests use (json_compare.py) takes a log-stored value's round
trip and nothing a reader would see."""

from __future__ import annotations

import numpy as np
import pytest
from json_compare import assert_same_json

DOC = {"bounds": {"tau1_s": [0.257, 1e4]}, "ocv": "table", "flags": [True, 2], "x": 0.0}


def test_a_values_round_trip_through_its_log_passes():
    back = {**DOC, "bounds": {"tau1_s": [0.25700000000000006, 10.0 ** float(np.log10(1e4))]}}
    assert_same_json(back, DOC)


@pytest.mark.parametrize("edit", [
    lambda d: d["bounds"].__setitem__("tau1_s", [0.2570001, 1e4]),
    lambda d: d["bounds"].__setitem__("tau1_s", [0.257]),
    lambda d: d.__setitem__("ocv", "rational"),
    lambda d: d.__setitem__("flags", [1, 2]),
    lambda d: d.__setitem__("extra", 1),
    lambda d: d.__setitem__("x", 1e-300),
])  # fmt: skip
def test_any_other_change_fails(edit):
    import copy

    got = copy.deepcopy(DOC)
    edit(got)
    with pytest.raises(AssertionError):
        assert_same_json(got, DOC)
