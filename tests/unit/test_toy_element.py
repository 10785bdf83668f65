"""A new element is one module plus one registry line (issue 39): the toy element of
tests/unit/toy_element.py, registered at run time, runs through simulate, a fit, the SOC filter,
the table export and the PyBaMM export, and they agree. It runs in a process of its own
(toy_driver.py): the model library lays out its columns and compiles its simulator for the
registry it finds when imported, so the toy gets a loop generated for it, compiled into a
temporary numba cache."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from avoa_pipeline.model import ecm, elements

HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    pytest.importorskip("pybamm", reason="pybamm is not installed (the PyBaMM export's check)")
    cache = tmp_path_factory.mktemp("numba")
    src = str(HERE.parents[1] / "src")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache),
           "PYTHONPATH": os.pathsep.join([src, str(HERE)])}  # fmt: skip
    res = subprocess.run([sys.executable, str(HERE / "toy_driver.py")], env=env, cwd=HERE,
                         capture_output=True, text=True, timeout=900)  # fmt: skip
    assert res.returncode == 0, res.stderr[-3000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


def test_the_toy_gets_a_loop_of_its_own_and_acts(toy):
    assert toy["registered"]
    assert toy["own_loop"].startswith("avoa_simulator_")  # not the checked-in module
    assert toy["toy_acts_mv"] > 5.0


def test_a_fit_recovers_the_toys_parameter(toy):
    assert abs(toy["fitted_tilt_v"] - toy["true_tilt_v"]) <= 1e-4


def test_the_filter_steps_the_toy_as_simulate_does(toy):
    assert toy["filter_open_loop_max_v"] <= 1e-9
    assert toy["filter_final_soc_error"] <= 0.02  # the "within 2 %" after 5 min


def test_the_table_holds_the_toys_law(toy):
    assert toy["table_expresses_toy"]
    assert toy["table_ocv_vs_rest_max_v"] <= 1e-9


def test_pybamm_gives_the_toys_voltage(toy):
    assert toy["pybamm_rms_mv"] <= 0.1


def test_an_element_is_registered_before_the_model_library_or_not_at_all():
    """Here the model library is imported already: its columns would not hold the element."""
    import toy_element

    assert ecm.EFFECTS == elements.NAMES
    with pytest.raises(RuntimeError, match="register it before"):
        elements.register(toy_element.ELEMENT)
    assert "toy_tilt" not in elements.REGISTRY


def test_an_incomplete_element_is_refused(monkeypatch):
    import toy_element

    monkeypatch.delitem(sys.modules, "avoa_pipeline.model.ecm")
    broken = dataclasses.replace(toy_element.ELEMENT, kernel=None)
    with pytest.raises(ValueError, match="no physics for the compiled simulator"):
        elements.register(broken)
    assert "toy_tilt" not in elements.REGISTRY
