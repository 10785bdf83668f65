"""The element registry (model/elements/): every element declares every part, and the parts
the package keeps elsewhere (the compiled loop, the docs table) are there for each."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline import gap
from avoa_pipeline.model import ecm, elements, fitting, loopgen
from avoa_pipeline.model.elements.element import KNOTS, Piece, Signature, View, missing_parts

DOCS = Path(__file__).resolve().parents[2] / "docs" / "gap-diagnosis.md"


@pytest.mark.parametrize("name", elements.NAMES)
def test_every_part_declared(name):
    assert missing_parts(elements.get(name)) == []


def test_a_missing_part_is_found():
    e = elements.get("second_rc")
    broken = dataclasses.replace(e, signature=" ", would_decide="", compiled="fast", kernel=None)
    assert len(missing_parts(broken)) == 4
    p = e.params["r2"]
    bad = dataclasses.replace(e, params={"r2": dataclasses.replace(p, limits=(0.1, 2.0), why="")})
    assert any("outside its limits" in m for m in missing_parts(bad))
    assert any("no reason" in m for m in missing_parts(bad))


def test_names_unique_and_requirements_earlier():
    reports = [p.report for p in ecm.PARAMS.values()]
    assert len(set(reports)) == len(reports)
    for k, e in enumerate(elements.REGISTRY.values()):
        if e.requires:  # the ladder offers it only after what it needs
            assert e.requires in elements.NAMES[:k]
    assert set(gap.EFFECTS) <= set(elements.NAMES)


@pytest.mark.parametrize("name", elements.NAMES)
def test_starts_set_only_own_parameters(name):
    e = elements.get(name)
    row = dict(zip(ecm.NAMES, ecm.NEUTRAL, strict=True)) | {"r1": 0.02, "ltau1": 1.5, "ltau2": 2.5}
    starts = e.starts(row, 3.0)
    assert starts
    assert all(set(s) <= set(e.params) for s in starts)


@pytest.mark.parametrize("name", elements.NAMES)
def test_kernel_reads_each_column(name):
    """The element's statement copies every physical column it owns, the loop generated for its
    version reads them (its code is there), and a core element's is in both versions."""
    e = elements.get(name)
    core, extras = loopgen.source().split("def simulate_extras")
    cols = ecm.columns(e)
    if e.vector is not None:
        reads = {f"P[:, {int(cols[0])} : {int(cols[0])} + nk]"}
        assert list(e.kernel.columns.values()) == [KNOTS]
    else:
        reads = {f"P[:, {int(c)}]" for c in cols}
        assert set(e.kernel.columns.values()) == set(e.params)
    for r in reads:
        assert r in extras, r
        assert (r in core) == (e.compiled == "core"), r
    assert e.compiled == "core" or bool(set(cols) <= set(ecm.EXTRAS_COLUMNS))


def test_docs_table_has_one_row_per_element():
    rows = re.findall(r"^\| `([a-z0-9_]+)`", DOCS.read_text(), flags=re.M)
    table = rows[: rows.index(elements.NAMES[-1]) + 1]  # the registry's last ends the table
    assert sorted(table) == sorted(elements.NAMES)


@pytest.mark.parametrize("name", elements.NAMES)
def test_export_piece_or_reason(name):
    e = elements.get(name)
    if e.pybamm.exported:
        x = ecm.NEUTRAL.copy()
        assert isinstance(e.pybamm.piece(ecm.physical(x, ecm.Knots(0.0, 0.2))), Piece)


def test_signatures_read_a_record():
    t = np.arange(0.0, 4000.0)
    i = np.where((t // 400) % 3 == 0, 0.0, np.where((t // 400) % 3 == 1, 2.0, -1.0))
    frame = pd.DataFrame({"time_s": t, "current_a": i, "voltage_v": 3.7 - 0.05 * i,
                          "temperature_c": 25.0 + t / 1000.0})  # fmt: skip
    rec = ecm.Record.from_frame(frame)
    v = View(rec, np.sin(t / 300) * 1e-3, np.linspace(0.9, 0.2, t.size), t % 400, np.sign(i),
             np.sign(i), rec.imax(), lambda r: 0.0)  # fmt: skip
    for e in elements.REGISTRY.values():
        if isinstance(e.signature, Signature):
            got = e.signature.read(v)
            assert got, e.name
            assert "acts" not in got, e.name
    assert fitting.priors_for([rec])["kd"][1] == pytest.approx(0.1 / rec.imax())
