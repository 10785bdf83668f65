"""Issue 41's development records (docs/temperature-rule.md part 7): the NMC and LFP cells at
several ambients, read back through the records layer, logged as cyclers log, and holding the
temperature dependence the laws must find. Each PyBaMM run here takes about a second."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline import records
from avoa_pipeline.gap import temperature_cells as T
from avoa_pipeline.gap import withheld
from avoa_pipeline.model import heat

pytest.importorskip("pybamm", reason="pybamm is not installed (pip install avoa-pipeline[pybamm])")

# a short record of the same shape: a rest, a 5-min 1C fast cycle, then one HPPC pulse pair; its
# edges (125, 425, ... s) fall off the 60-s rest grid, so a kept edge row is not kept by the grid
SHORT = np.concatenate([np.zeros(125), np.full(300, 1.0), np.zeros(300), np.full(300, -1.0),
                        np.zeros(300), np.full(10, 1.0), np.zeros(40), np.full(10, -0.75),
                        np.zeros(121)])  # fmt: skip
SENSOR_K = withheld.TEMPERATURE_NOISE_K
NOISE_V = 1e-3 * T.NOISE_MV


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    out = tmp_path_factory.mktemp("devtemp")
    return out, T.write_set(out, chemistries=("lfp",), ambients=(25.0,), base_seed=4, log=None)


@pytest.fixture(scope="module")
def short():
    """(chemistry, ambient) → the short record at 0 and 40 °C of both cells."""
    return {(c, a): T.make(c, a, "hppc", 1, SHORT) for c in T.CHEMISTRIES for a in (0.0, 40.0)}


def _read(csv):
    return records.read(csv, capacity_ah=lambda m: m["nominal_capacity_ah"])


def test_the_set_is_written_as_named_and_reads_through_the_records_layer(written):
    out, paths = written
    assert sorted(p.name for p in paths) == sorted(
        f"lfp_25degC_{p}.{ext}" for p in T.PROFILES for ext in ("csv", "json"))  # fmt: skip
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]  # no staging left
    for csv in (p for p in paths if p.suffix == ".csv"):
        checked = _read(csv)
        assert heat.ambient_of(checked) == (25.0, "sidecar")
        side = json.loads(csv.with_suffix(".json").read_text())
        assert side["chemistry"] == "lfp"
        assert side["parameter_set"] == "Prada2013"
        assert side["profile"] in T.PROFILES
        assert side["seed"] == 4
        assert side["pybamm_version"]
        assert checked.warnings == ()


def test_the_lfp_drive_tells_its_sign_despite_the_late_current(written):
    """The flat LFP drive leaves the first look nothing after the jump (the current a sample
    late); the records layer's second look, the current a row earlier, tells."""
    out, _ = written
    checked = _read(out / "lfp_25degC_drive.csv")
    assert checked.warnings == ()
    assert (checked.sign.verdict, checked.sign.current_lag_samples) == ("discharge-positive", 1)


def test_the_set_is_all_or_none(tmp_path, monkeypatch):
    real = T.make

    def fails_at_the_last(chemistry, ambient_c, profile, base_seed=0, rate=None):
        if profile == list(T.PROFILES)[-1]:
            raise RuntimeError("solver failed")
        return real(chemistry, ambient_c, profile, base_seed, SHORT)

    monkeypatch.setattr(T, "make", fails_at_the_last)
    with pytest.raises(RuntimeError, match="solver failed"):
        T.write_set(tmp_path / "set", chemistries=("lfp",), ambients=(25.0,), log=None)
    assert not (tmp_path / "set").exists() or not list((tmp_path / "set").iterdir())


def test_the_cell_starts_at_the_ambient_and_warms_under_load(short):
    for (chem, amb), ds in short.items():
        temp = ds.temperature_c
        assert abs(temp[0] - amb) < 4 * SENSOR_K, (chem, amb)  # soaked: only the sensor's noise
        # the fast cycle's 1C discharge heats it, by far more than the sensor's noise
        assert temp.max() - amb > 10 * SENSOR_K, (chem, amb)


def test_the_drive_record_warms_enough_to_train_the_heat_block(written):
    out, _ = written
    frame = records.read(out / "lfp_25degC_drive.csv").frame
    assert np.ptp(frame["temperature_c"]) >= heat.MIN_RANGE_C


def test_rests_are_logged_coarsely_and_the_current_a_sample_late(short):
    ds = short[("nmc", 40.0)]
    frame, q = ds.frame(), ds.meta["nominal_capacity_ah"]
    t, i = frame["time_s"].to_numpy(), frame["current_a"].to_numpy()
    # a row at rest between rows at rest (a rest's inside, not a row at an edge, which the late
    # current shows at rest) is one of the coarse ones, on the REST_LOG_S grid
    rest = np.abs(i) < 0.01 * q
    inside = np.flatnonzero(rest[1:-1] & rest[:-2] & rest[2:]) + 1
    assert inside.size > 10
    assert np.all(np.mod(t[inside], T.REST_LOG_S) == 0.0)
    assert np.all(np.diff(t)[~rest[1:]] == 1.0)  # under load, every second
    # in the long rests only every REST_LOG_S is kept: far fewer rows than seconds
    assert len(frame) < 0.6 * SHORT.size
    # true current rises at 125 s; the row at 125 s is logged at rest while its voltage has
    # already dropped by the 1C ohmic jump (tens of mV, far above the noise)
    row = np.flatnonzero(t == 125.0)[0]
    assert abs(i[row]) < 0.01 * q
    assert i[row + 1] > 0.9 * q
    assert frame["voltage_v"].iloc[row - 1] - frame["voltage_v"].iloc[row] > 10 * NOISE_V


def test_cycler_log_on_a_known_frame():
    cur = np.r_[np.zeros(130), np.full(5, 2.0), np.zeros(70)]
    frame = pd.DataFrame({"time_s": np.arange(cur.size, dtype=float), "current_a": cur})
    logged = T.cycler_log(frame, rest_log_s=60.0)
    assert logged["time_s"].tolist() == [0, 60, 120, 130, 131, 132, 133, 134, 135, 180, 204]
    assert logged["current_a"].tolist() == [0, 0, 0, 0, 2, 2, 2, 2, 2, 0, 0]


@pytest.mark.parametrize("chemistry", T.CHEMISTRIES)
def test_the_cold_cell_drops_more_under_the_same_pulse(short, chemistry):
    cold, warm = short[(chemistry, 0.0)], short[(chemistry, 40.0)]
    q = cold.meta["nominal_capacity_ah"]
    d_cold, d_warm = (T.pulse_drop_v(ds.frame(), q) for ds in (cold, warm))
    # each drop is a difference of two noisy samples (σ√2); the cold one must exceed the warm
    # one by far more than their difference's noise (2σ), the property issue 41's laws must find
    assert d_warm > 0
    assert d_cold - d_warm > 10 * 2 * NOISE_V
