"""The compiled simulator's source is written from the elements' statements (model/loopgen.py):
the checked-in model/_simulator.py is what the generator writes now, and the generator refuses
what it cannot place."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from avoa_pipeline.model import _simulator, ecm, elements, loopgen
from avoa_pipeline.model.elements.element import Kernel


def test_checked_in_source_is_what_the_generator_writes(capsys):
    assert loopgen.main(["--check"]) == 0, capsys.readouterr().err


def test_one_compiled_function_per_version_and_the_filters_step():
    src = loopgen.source()
    assert src.count("@nb.njit") == 3
    assert set(ecm.COMPILED.SIMULATE) == {False, True}
    assert ecm.COMPILED is _simulator  # the package's registry: the checked-in module


def _with(name: str, kernel: Kernel) -> dict:
    reg = dict(elements.REGISTRY)
    reg[name] = dataclasses.replace(reg[name], kernel=kernel)
    return reg


def test_a_snippet_in_an_unknown_slot_is_refused():
    reg = _with("voltage_offset", Kernel(columns={"voff": "voff"}, code={"ocv_end": "e += 1"}))
    with pytest.raises(ValueError, match="unknown slots"):
        loopgen.source(reg)


def test_a_snippets_position_orders_the_slot():
    """Hysteresis's OCV term comes after voltage_offset's although it is registered earlier:
    its position says so (float sums are not associative)."""
    src = loopgen.source().split("def simulate_extras")[1]
    assert (
        src.index("e += voff[c]")
        < src.index("e += dudt[c] * pf * dtemp")
        < src.index("e += hm[c] * h[c]")
    )
    hyst = elements.get("hysteresis").kernel
    code = dict(hyst.code) | {"ocv": hyst.code["ocv"][1]}  # position 0: registry order
    src = loopgen.source(_with("hysteresis", dataclasses.replace(hyst, code=code)))
    assert src.index("e += hm[c] * h[c]") < src.index("e += voff[c]")


def test_a_registrys_own_loop_is_written_into_the_environment(monkeypatch, tmp_path):
    """$NUMBA_CACHE_DIR when set, else the environment's folder, else (read-only environment)
    the temporary folder (issue 42: per environment, not per machine)."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert loopgen.generated_folder() == tmp_path / "avoa-simulators"
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setattr(loopgen.sys, "prefix", str(tmp_path / "venv"))
    monkeypatch.setattr(loopgen.os, "access", lambda path, mode: True)
    assert loopgen.generated_folder() == tmp_path / "venv" / "var" / "avoa-pipeline" / "simulators"
    monkeypatch.setattr(loopgen.os, "access", lambda path, mode: False)
    assert loopgen.generated_folder().parent == Path(loopgen.tempfile.gettempdir())
