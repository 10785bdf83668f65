"""avoa_pipeline.notebook: the workflow's notebook command runs papermill's engine with the
parameters read as papermill's command line reads them, on a kernel whose sockets are files in a
folder of its own (never TCP ports two kernels started at once could both be handed)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import avoa_pipeline
from avoa_pipeline.notebook import value

CELL = ("from ipykernel.kernelapp import IPKernelApp\n"
        "app = IPKernelApp.instance()\n"
        "open(name + '.json', 'w').write(__import__('json').dumps(\n"
        "    [app.transport, app.ip, x, type(x).__name__, flag]))")  # fmt: skip


def test_values_are_read_as_papermills_command_line_reads_them():
    assert [value(v) for v in ("3", "-2.5", "True", "False", "None", "results/gap", "1e3")] == [
        3, -2.5, True, False, None, "results/gap", 1000.0]  # fmt: skip
    assert isinstance(value("3"), int)


def _notebook(path: Path) -> None:
    cells = [{"cell_type": "code", "metadata": {"tags": ["parameters"]}, "id": "p",
              "source": "x = 0\nname = 'n'\nflag = None", "outputs": [], "execution_count": None},
             {"cell_type": "code", "metadata": {}, "id": "c", "source": CELL, "outputs": [],
              "execution_count": None}]  # fmt: skip
    path.write_text(json.dumps({"cells": cells, "nbformat": 4, "nbformat_minor": 5, "metadata": {
        "kernelspec": {"name": "avoa-pipeline", "display_name": "avoa-pipeline",
                       "language": "python"}}}))  # fmt: skip


def test_two_notebooks_started_at_once_each_get_sockets_of_their_own(tmp_path):
    pytest.importorskip("papermill")
    nb = tmp_path / "nb.ipynb"
    _notebook(nb)
    src = str(Path(avoa_pipeline.__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [src, os.environ.get(
        "PYTHONPATH")])), "TMPDIR": str(tmp_path)}  # fmt: skip
    procs = [subprocess.Popen([sys.executable, "-m", "avoa_pipeline.notebook", str(nb),
                               str(tmp_path / f"out{j}.ipynb"), "-k", "avoa-pipeline",
                               "-p", "x", str(j + 1), "-p", "name", f"run{j}", "-p", "flag",
                               "True"], cwd=tmp_path, env=env, stderr=subprocess.PIPE, text=True)
             for j in range(2)]  # fmt: skip
    for p in procs:
        _, err = p.communicate(timeout=300)
        assert p.returncode == 0, err[-2000:]
    seen = [json.loads((tmp_path / f"run{j}.json").read_text()) for j in range(2)]
    assert [s[0] for s in seen] == ["ipc", "ipc"]
    assert seen[0][1] != seen[1][1]  # each kernel its own folder
    assert [s[2:] for s in seen] == [[1, "int", True], [2, "int", True]]
    # the sockets' folders are gone with their kernels
    assert not [d for d in tmp_path.iterdir() if d.name.startswith("avoa-kernel-")]
