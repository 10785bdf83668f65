"""Transfer benchmark (gap/transfer.py, benchmarks/bench_transfer.py): the quick records, logged as
a cycler logs them, the drive-cycle currents, the fixed circuits and the table. The diagnosis
end to end (the quick benchmark, about two minutes on busy cores) is marked slow."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline import inputs, records
from avoa_pipeline.errors import ConfigError
from avoa_pipeline.gap import transfer as T

pytest.importorskip("pybamm", reason="pybamm is not installed (pip install avoa-pipeline[pybamm])")

ROOT = T.default_panasonic_root()
needs_panasonic = pytest.mark.skipif(
    not (ROOT / T.PANASONIC_DRIVE["la92"]).exists(), reason="Panasonic 18650PF data not here"
)
BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_transfer.py"


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    """The quick benchmark's records (one cell, 25 °C, HPPC, LA92 and the C/20 test)."""
    if not (ROOT / T.PANASONIC_DRIVE["la92"]).exists():
        pytest.skip("Panasonic 18650PF data not here")
    data = tmp_path_factory.mktemp("transfer")
    q = T.QUICK
    paths = T.build(data, q["cells"], q["ambients"], q["profiles"], T.QUICK_SCALE, 0, ROOT,
                    log=lambda m: None)  # fmt: skip
    return paths


def test_records_are_logged_as_a_cycler_logs_them(quick):
    frame = pd.read_csv(quick["nmc_hppc_25C"])
    meta = json.loads(quick["nmc_hppc_25C"].with_suffix(".json").read_text())
    checked = records.check(frame, "hppc")  # the records layer accepts it as it stands
    t, i = frame["time_s"].to_numpy(), frame["current_a"].to_numpy()
    dt = np.diff(t)
    assert (dt > 0).all()
    load = np.abs(i[:-1]) > records.REST_FRACTION * np.abs(i).max()
    assert np.allclose(dt[load], 1.0)  # 1-s logging under load
    assert set(np.round(dt[~load], 6)) <= {1.0, float(T.REST_LOG_S)}
    assert (dt[~load] == T.REST_LOG_S).mean() > 0.5  # rests mostly coarse
    assert i.max() == pytest.approx(meta["capacity_ah"], abs=0.01)  # the 1C pulse, 5 Ah
    assert meta["noise_rmse_mv"] == pytest.approx(T.NOISE_MV, rel=0.3)
    assert frame["temperature_c"].max() > 25.5  # self-heating in the lumped thermal model
    assert checked.n >= 2000  # the diagnosis's minimum (diagnose.MIN_SAMPLES)


def test_slow_test_gives_an_ocv_table_of_the_cell(quick):
    table = inputs.read_ocv(quick["nmc_ocv_25C"])
    assert "mean of the discharge" in table.how  # both C/20 branches span the cell
    assert table.capacity_ah == pytest.approx(5.0, rel=0.05)  # Chen2020's nominal 5 Ah


@needs_panasonic
def test_drive_currents_keep_the_panasonic_charge():
    from avoa_pipeline.importers import panasonic

    seconds = 600
    c = T.drive_c_rate("la92", ROOT, seconds)
    df = panasonic.read_mat(ROOT / T.PANASONIC_DRIVE["la92"])
    t, ah = df["Time"].to_numpy(), df["Ah"].to_numpy()
    start = t[np.flatnonzero(np.abs(df["Current"].to_numpy()) > panasonic.REST_A)[0]]
    # the tester's own Ah counter (discharge counts down) over the same window
    logged_ah = -(np.interp(start + seconds, t, ah) - np.interp(start, t, ah))
    assert c.size == seconds
    assert c.sum() * T.PANASONIC_AH / 3600 == pytest.approx(logged_ah, rel=0.02)
    assert c.max() > 1.0  # driving
    assert c.min() < -0.3  # regenerative braking


def test_fixed_circuits_fit_the_training_records_and_predict_a_drive(quick):
    read = inputs.read_inputs([quick["nmc_hppc_25C"]], [quick["nmc_la92_25C"]])
    table = inputs.read_ocv(quick["nmc_ocv_25C"])
    fits = T.fit_fixed([c.frame for c in read.train], table)
    # the 2RC circuit holds the 1RC one (started from its fit): it fits the training no worse
    assert fits["2rc"].train_rmse_mv <= fits["1rc"].train_rmse_mv + 0.05
    assert fits["1rc"].train_rmse_mv < 30.0
    frame = read.validate[0].frame
    for fit in fits.values():
        rmse = 1e3 * np.sqrt(np.mean((fit.model.simulate(frame) - frame["voltage_v"]) ** 2))
        assert 1.0 < rmse < 100.0  # above the 1-mV noise, a usable prediction


def test_summary_takes_medians_and_ratios():
    # the "selected" model is the handed-over one (docs/handover-rule.md); the verdict's beside it
    pairs = [(4.0, 8.0), (6.0, 2.0), (30.0, 4.0)]  # (handed over, 2RC) per unseen record
    rows = [{"cell": "c", "split": "s", "record": f"r{k}", "handed_over_model": "m",
             "handed_over_mv": sel, "verdict_model": "v", "verdict_mv": 2 * sel,
             "base_mv": 10.0, "fixed_1rc_mv": 10.0, "fixed_2rc_mv": two,
             "floor_mv": 1.0} for k, (sel, two) in enumerate(pairs)]  # fmt: skip
    s = T.summarize(rows).iloc[0]
    assert s["handed_over_mv"] == 6.0
    assert s["verdict_mv"] == 12.0
    assert s["fixed_2rc_mv"] == 4.0
    assert s["n_unseen"] == 3
    assert s["handed_over_over_2rc"] == pytest.approx(1.5)
    assert s["handed_over_over_base"] == pytest.approx(0.6)
    assert s["verdict_over_2rc"] == pytest.approx(3.0)
    assert "| c | s | m | 3 | 6.00 | v | 12.00 |" in T.markdown(T.summarize(rows))


def test_unknown_profile_is_refused():
    with pytest.raises(ConfigError, match="unknown profile"):
        T.experiment_steps("wltp", 5.0, 2.5, 4.2)


@pytest.mark.slow
@needs_panasonic
def test_quick_benchmark_end_to_end(tmp_path):
    spec = importlib.util.spec_from_file_location("bench_transfer", BENCH)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert bench.main(["--quick", "--data", str(tmp_path)]) == 0
    out = tmp_path / "quick"
    rows = pd.read_csv(out / "transfer.csv")
    assert list(rows["record"]) == ["nmc_la92_25C"]
    r = rows.iloc[0]
    # the floor is the handed-over configuration fitted to the unseen record itself
    assert r["floor_mv"] <= r["handed_over_mv"] + 1e-6
    summary = pd.read_csv(out / "summary.csv").iloc[0]
    assert summary["handed_over_over_2rc"] == pytest.approx(
        r["handed_over_mv"] / r["fixed_2rc_mv"], rel=1e-3)  # fmt: skip
    diagnosis = json.loads((out / "nmc" / "hppc" / "diagnosis.json").read_text())
    assert diagnosis["handed_over"]["name"] == r["handed_over_model"]
    assert diagnosis["selected"]["name"] == r["verdict_model"]
    assert (out / "summary.md").read_text().startswith("| cell |")
