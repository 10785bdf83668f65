"""PyBaMM test data: short profiles, so the whole file runs in a few seconds."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline.errors import ConfigError
from avoa_pipeline.gap import EFFECTS
from avoa_pipeline.gap import pybamm_data as P

pytest.importorskip("pybamm", reason="pybamm is not installed (pip install avoa-pipeline[pybamm])")

# 10 min of the pulse profile's start: rest, a 1C discharge pulse, a charge pulse, C/2
SHORT = np.concatenate([np.zeros(60), np.full(10, 1.0), np.zeros(40), np.full(10, -0.75),
                        np.zeros(40), np.full(440, 0.5), [0.0]])  # fmt: skip


@pytest.fixture(scope="module")
def hysteresis_pair():
    return P.make(3, "spme_hysteresis_pulse", SHORT), P.make(3, "spme_hysteresis_pulse", SHORT)


def test_record_has_the_csv_columns_and_a_varying_temperature(hysteresis_pair):
    ds, _ = hysteresis_pair
    frame = ds.frame()
    assert list(frame.columns) == ["time_s", "current_a", "voltage_v", "temperature_c"]
    assert len(frame) == SHORT.size
    assert np.isfinite(frame.to_numpy()).all()
    assert frame["voltage_v"].min() > 3.0
    assert frame["voltage_v"].max() < 4.4
    assert frame["temperature_c"].max() - frame["temperature_c"].min() > 1.0
    # 1C of the 5 Ah cell, with 1 mA sensor noise and quantisation
    assert frame["current_a"].max() == pytest.approx(5.0, abs=0.01)
    assert ds.meta["noise_rmse_mv"] == pytest.approx(1.0, rel=0.3)
    assert set(ds.meta["effects_present"]) <= set(EFFECTS)
    assert "hysteresis" in ds.meta["effects_present"]


def test_same_seed_same_record(hysteresis_pair):
    a, b = hysteresis_pair
    pd.testing.assert_frame_equal(a.frame(), b.frame(), check_exact=True)


def test_the_models_differ_and_the_pulse_shows_an_ohmic_drop():
    dfn = P.solve("dfn_thermal", SHORT)
    spme = P.solve("spme_hysteresis", SHORT)
    assert np.sqrt(np.mean((dfn["voltage_v"] - spme["voltage_v"]) ** 2)) > 1e-3
    drop = dfn["voltage_v"][59] - dfn["voltage_v"][60]
    assert drop > 5.0 * P.CONTACT_OHM  # at least the contact resistance's share at 5 A


def test_unknown_dataset_name_is_a_config_error():
    with pytest.raises(ConfigError, match="unknown PyBaMM dataset"):
        P.make(3, "spm_pulse", SHORT)
    assert len(P.dataset_names()) == len(P.MODELS) * 2
