"""`snakemake real` on a small real-data config, in a fresh directory: the Panasonic import and
experiment 1 end to end (25 degC only, LA92 -> US06, two optimizers, one seed, small budget;
Samsung and NASA sections removed, the gap model off). Skipped without the data.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml

from avoa_pipeline.real import canonical

REPO = Path(__file__).resolve().parents[2]
COPY = ("Snakefile", "workflow", "config", "notebooks", "profiles")


def _small_config(root: Path) -> dict:
    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    real = cfg["real"]
    pan = real["panasonic"]
    t25 = pan["temperatures"]["25degC"]
    t25["drive_cycles"] = {c: t25["drive_cycles"][c] for c in ("la92", "us06")}
    pan["temperatures"] = {"25degC": t25}
    pan["experiment"].update(
        train={"25degC": "la92"},
        algorithms=["nelder_mead", "avoa"],
        seeds=[1],
        budget={"pop_size": 8, "iterations": 15},
        figure_cycle={"25degC": "us06"},
        gap=False,
        circuits={"folds": 2, "min_gain": 0.0, "candidates": ["q_c20", "hppc"]},
    )
    used = {t25["hppc"], t25["hppc_steps"], *t25["drive_cycles"].values(), pan["ocv_c20"]}
    real["sources"] = {k: v for k, v in real["sources"].items() if k in used}
    real["root"] = str(root)
    for other in ("samsung", "nasa"):
        real.pop(other, None)
    return cfg


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    root = Path(yaml.safe_load((REPO / "config" / "config.yaml").read_text())["real"]["root"])
    root = root if root.is_absolute() else (REPO / root).resolve()
    if not (root / "panasonic_18650pf").is_dir():
        pytest.skip(f"Panasonic data not found under {root}")
    wd = tmp_path_factory.mktemp("real")
    for name in COPY:
        src = REPO / name
        if src.is_dir():
            shutil.copytree(src, wd / name)
        else:
            shutil.copy2(src, wd / name)
    (wd / "config" / "config.yaml").write_text(yaml.safe_dump(_small_config(root)))
    env = {**os.environ, "XDG_CACHE_HOME": str(wd / ".cache")}
    proc = subprocess.run(
        [sys.executable, "-m", "snakemake", "-j2", "real"],
        cwd=wd, env=env, capture_output=True, text=True, check=False, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-4000:]
    return wd


def test_real_target_builds_experiment_one(workdir):
    rmse = pd.read_csv(workdir / "results/real/drive_cycle_rmse.csv")
    assert list(rmse.columns) == ["temperature_c", "cycle", "model", "rmse_mv", "max_err_mv"]
    assert set(rmse["cycle"]) == {"us06"}  # la92 was the training cycle
    assert set(rmse["model"]) == {
        "paper_rc_nelder_mead", "paper_rc_avoa", "paper_norc_nelder_mead", "paper_norc_avoa",
        "c20_rc", "c20_2rc_lowsoc", "c20_2rc_lowsoc+q_c20", "c20_2rc_lowsoc+hppc",
        "c20_cv_selected",
    } | ({"c20_2rc_lowsoc+q_c20+hppc"} & set(rmse["model"]))  # fmt: skip
    assert (rmse["temperature_c"] == 25.0).all()
    assert (rmse["rmse_mv"] > 0).all()
    assert (rmse["max_err_mv"] >= rmse["rmse_mv"]).all()
    cv = pd.read_csv(workdir / "results/real/panasonic/circuit_cv.csv")
    assert cv["selected"].sum() == 1
    sel = cv.loc[cv["selected"], "model"].iloc[0]
    assert cv.loc[cv["selected"], "cv_rmse_mv"].iloc[0] == cv["cv_rmse_mv"].min()
    assert "c20_2rc_lowsoc" in set(cv["model"])
    chosen = rmse.set_index("model")["rmse_mv"]
    if sel != "c20_2rc_lowsoc":
        assert chosen["c20_cv_selected"] == chosen[sel]
    for stem in ("results/real/figures/panasonic_drive_cycles.png",
                 "results/real/figures/panasonic_drive_cycles.pdf",
                 "results/real/tables/panasonic_drive_cycle_rmse.md"):  # fmt: skip
        assert (workdir / stem).stat().st_size > 0, stem


def test_canonical_records_and_sidecars(workdir):
    for test in ("hppc", "la92", "us06", "ocv_c20"):
        path = workdir / f"results/real/canonical/panasonic_25degC_{test}.csv"
        frame, side = canonical.read(path)
        assert tuple(frame.columns) == canonical.COLUMNS
        assert side["ambient_temperature_c"] == 25.0
        assert len(side["source_sha256"]) == 64


def test_nothing_to_do_after_a_run(workdir):
    env = {**os.environ, "XDG_CACHE_HOME": str(workdir / ".cache")}
    proc = subprocess.run(
        [sys.executable, "-m", "snakemake", "-n", "real"],
        cwd=workdir, env=env, capture_output=True, text=True, check=False, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Nothing to be done" in proc.stdout + proc.stderr
