"""NASA B0005 import and experiment 3 (capacity and resistance per state, fade-law fits)."""

import copy
import hashlib

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline import records
from avoa_pipeline.errors import ConfigError, DataError
from avoa_pipeline.importers import nasa
from avoa_pipeline.real.experiments import fade

NASA_CFG = {
    "cutoff_v": 2.7,
    "load_current_a": 1.0,
    "resistance_delay_s": 20.0,
    "long_rest_h": 8.0,
}


@pytest.fixture(scope="module")
def real_cfg():
    from avoa_pipeline import config

    return config.load()


@pytest.fixture(scope="module")
def imported(real_cfg, tmp_path_factory):
    out = tmp_path_factory.mktemp("nasa") / "b0005.csv"
    nasa.import_b0005(real_cfg, out)
    return out


def _small_root(real_cfg, root, k_max=3, edit=None):
    """A data root with discharges 1..k_max and the index's first k_max rows; ``edit(k, df)``
    may change a discharge. Returns a config pointing at it with the new sha256s."""
    cfg = copy.deepcopy(real_cfg)
    src = nasa.data_root(real_cfg)
    n = cfg["real"]["nasa"]
    keep = {}
    lines = (src / n["index"]).read_text().splitlines(keepends=True)
    keep[n["index"]] = "".join(lines[: k_max + 1]).encode()
    for k, key, _ in nasa.discharge_keys(real_cfg)[:k_max]:
        df = pd.read_csv(src / key)
        if edit is not None:
            df = edit(k, df)
        keep[key] = df.to_csv(index=False).encode()
    cfg["real"]["root"] = str(root)
    cfg["real"]["sources"] = {}
    for key, data in keep.items():
        (root / key).parent.mkdir(parents=True, exist_ok=True)
        (root / key).write_bytes(data)
        cfg["real"]["sources"][key] = hashlib.sha256(data).hexdigest()
    return cfg


def test_import_all_168_discharges_on_one_time_axis(imported):
    rec = records.read(imported)
    frame, side = rec.frame, rec.meta
    d = side["discharges"]
    assert [e["discharge"] for e in d] == list(range(1, 169))
    assert sum(e["n_rows"] for e in d) == len(frame)
    assert d[-1]["start"] == "2008-05-27T20:45:42"
    assert d[0]["start_s"] == 0.0
    assert (np.diff(frame["time_s"]) > 0).all()
    # uneven sampling kept: about 18.7 s early, 9.4 s late
    first = frame.iloc[: d[0]["n_rows"]]
    last = frame.iloc[d[-1]["first_row"] :]
    assert np.median(np.diff(first["time_s"])) == pytest.approx(18.7, abs=0.2)
    assert np.median(np.diff(last["time_s"])) == pytest.approx(9.4, abs=0.1)
    assert first["current_a"].max() == pytest.approx(2.01, abs=0.01)  # discharge is positive


def test_flipped_sign_in_one_discharge_is_refused(real_cfg, tmp_path):
    def flip(k, df):
        return df.assign(current=-df["current"]) if k == 2 else df

    cfg = _small_root(real_cfg, tmp_path, edit=flip)
    out = tmp_path / "out.csv"
    with pytest.raises(DataError, match=r"dis_2_cap_.*column 'current': sign contradicts"):
        nasa.import_b0005(cfg, out)
    assert not out.exists()
    assert not out.with_suffix(".json").exists()


def test_small_root_imports(real_cfg, tmp_path):
    _frame, side = nasa.import_b0005(_small_root(real_cfg, tmp_path), tmp_path / "out.csv")
    assert len(side["discharges"]) == 3


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda k, d: d.drop(columns="time"), r"dis_1_cap_.*missing column 'time'"),
        (lambda k, d: d.assign(time=d["time"].where(d.index != 5, d["time"].iloc[4])),
         r"dis_1_cap_.*column 'time_s' row 7: duplicate time"),
        (lambda k, d: d.assign(voltage=d["voltage"].where(d.index != 9)),
         r"dis_1_cap_.*column 'voltage' row 11: missing value"),
        (lambda k, d: d.iloc[:-3] if k == 3 else d,
         r"B0005_discharge\.csv: row 4 field 'time' .* is not the last time of dis_3"),
    ],
)  # fmt: skip
def test_bad_discharge_is_one_line(real_cfg, tmp_path, edit, message):
    cfg = _small_root(real_cfg, tmp_path, edit=edit)
    with pytest.raises(DataError, match=message) as err:
        nasa.import_b0005(cfg, tmp_path / "out.csv")
    assert "\n" not in str(err.value)


def test_gap_in_discharge_numbers_is_a_config_error(real_cfg, tmp_path):
    cfg = _small_root(real_cfg, tmp_path)
    key2 = next(k for k in cfg["real"]["sources"] if "/dis_2_" in k)
    del cfg["real"]["sources"][key2]
    with pytest.raises(
        ConfigError, match=r"discharges must be 1\.\.K without gaps \(missing \[2\]"
    ):
        nasa.import_b0005(cfg, tmp_path / "out.csv")


def _synthetic_discharge(r_ohm=0.1, slope_v_per_s=-2e-4, dt=10.0, t_on=15.0, i=2.0):
    """Rest samples, then a constant-current discharge whose voltage falls linearly."""
    t = np.arange(0.0, 8000.0, dt) + 0.5
    on = t > t_on
    v = np.where(on, 4.0 - i * r_ohm + slope_v_per_s * (t - t_on), 4.19)
    cur = np.where(on, i, 0.0)
    cut = np.flatnonzero(v < 2.5)[0]
    t, v, cur = t[: cut + 3], v[: cut + 3], cur[: cut + 3]
    cur[-2:] = 0.0
    v[-2:] = 3.0
    return pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": v, "temperature_c": 24.0})


def test_capacity_and_resistance_of_a_known_discharge():
    sub = _synthetic_discharge()
    st = fade.discharge_state(sub, {"discharge": 1}, NASA_CFG, "synthetic")
    # the load is taken on at the last rest sample (t = 10.5 s); V reaches 2.7 V at t_on + (4.0 -
    # 0.2 - 2.7)/2e-4 s after the true switch at 15 s
    t_rest = 10.5
    t_cut = 15.0 + (4.0 - 0.2 - 2.7) / 2e-4
    assert st["capacity_ah"] == pytest.approx(2.0 * (t_cut - t_rest) / 3600, rel=1e-6)
    # V_rest - V(t_rest + 20 s) over the current
    expected = (4.19 - (4.0 - 0.2 - 2e-4 * (t_rest + 20 - 15.0))) / 2.0
    assert st["resistance_ohm"] == pytest.approx(expected, rel=1e-9)


def test_discharge_that_never_reaches_cutoff_is_refused():
    sub = _synthetic_discharge()
    sub = sub[sub["voltage_v"] > 2.8]
    with pytest.raises(
        DataError, match=r"synthetic: discharge 1: column 'voltage_v' never crosses"
    ):
        fade.discharge_state(sub, {"discharge": 1}, NASA_CFG, "synthetic")


@pytest.mark.parametrize(("law", "params"), [("sqrt", (1.9, -30.0)), ("power", (2.0, 25.0, 1.4))])
def test_fade_law_fit_recovers_known_parameters(law, params):
    rng = np.random.default_rng(3)
    n = np.arange(168.0)
    y = fade.law_values(law, params, n, 167.0) + rng.normal(0, 0.002, n.size)
    f = fade.fit_law(n, y, law)
    assert f["y0"] == pytest.approx(params[0], rel=0.01)
    assert f["delta_pct"] == pytest.approx(params[1], abs=1.0)
    if law == "power":
        assert f["z"] == pytest.approx(params[2], abs=0.1)
    assert f["rmse"] == pytest.approx(0.002, rel=0.2)
    # the other laws fit such data worse
    worse = fade.fit_law(n, y, "linear" if law == "sqrt" else "sqrt")
    assert worse["aic"] > f["aic"] + 10


def test_fade_law_rejects_bad_input():
    with pytest.raises(DataError, match="matching n and y"):
        fade.fit_law(np.arange(5.0), np.ones(4), "sqrt")
    with pytest.raises(DataError, match="unknown fade law 'cubic'"):
        fade.fit_law(np.arange(5.0), np.ones(5), "cubic")


def test_fade_experiment_on_the_real_record(real_cfg, imported, tmp_path):
    table, fits = fade.experiment(
        imported, real_cfg["real"]["nasa"], tmp_path / "f.csv", tmp_path / "g.csv"
    )
    assert len(table) == 168
    assert len(fits) == 3 * 3
    # our coulomb count against NASA's own capacity field (PROVENANCE: within 0.006 Ah)
    assert (table["capacity_ah"] - table["capacity_nasa_ah"]).abs().max() < 0.006
    assert table["resistance_ohm"].between(0.08, 0.15).all()
    assert table["after_long_rest"].sum() >= 5  # the breaks the capacity recovers in
    assert {"capacity_ah_sqrt", "resistance_ohm_power"} <= set(table.columns)
    assert pd.read_csv(tmp_path / "g.csv").shape == fits.shape
