"""notebooks/api_quickstart.ipynb runs on its own (papermill, the workflow's kernel): its
synthetic record's second RC branch is found, the model handed over is written and used."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

import avoa_pipeline
from avoa_pipeline.notebook import PrivateSocketKernelManager

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "api_quickstart.ipynb"


def test_the_api_notebook_runs_on_its_own(tmp_path, monkeypatch):
    papermill = pytest.importorskip("papermill")
    # the kernel is a process of its own: it imports the package these tests import
    src = str(Path(avoa_pipeline.__file__).resolve().parents[1])
    path = os.pathsep.join(filter(None, [src, os.environ.get("PYTHONPATH")]))
    monkeypatch.setenv("PYTHONPATH", path)
    out = tmp_path / "out"
    executed = tmp_path / "api_quickstart.ipynb"
    papermill.execute_notebook(str(NOTEBOOK), str(executed), parameters={"out_dir": str(out)},
                               kernel_name="avoa-pipeline", progress_bar=False,
                               cwd=str(tmp_path),
                               kernel_manager_class=PrivateSocketKernelManager)  # fmt: skip
    report = json.loads((out / "diagnosis" / "diagnosis.json").read_text())
    assert report["verdict"]["effect"] == "second_rc"  # the synthetic cell's known physics
    assert {p.name for p in (out / "diagnosis").iterdir()} == {
        "diagnosis.json", "diagnosis.png", "model.json"}  # fmt: skip
    text = executed.read_text()
    assert "simulated: " in text
    assert "estimated: final SOC" in text
    cells = json.loads(text)["cells"]
    (shown,) = [o for o in cells[-1]["outputs"] if o["output_type"] == "execute_result"]
    assert "soc" in "".join(shown["data"]["text/plain"])  # the table's head is shown
