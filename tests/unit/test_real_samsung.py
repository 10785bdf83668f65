"""Samsung 30Q HPPC import and experiment 2 (1-RC per pulse, Arrhenius fits)."""

import copy
import hashlib

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline import records
from avoa_pipeline.errors import ConfigError, DataError
from avoa_pipeline.importers import samsung
from avoa_pipeline.real.__main__ import main as real_main
from avoa_pipeline.real.experiments import arrhenius

KEY20 = "samsung_30q_hppc/DNN01_HPPC_1C_20amb_processed_scrubbed.csv"


@pytest.fixture(scope="module")
def real_cfg():
    from avoa_pipeline import config

    return config.load()


@pytest.fixture(scope="module")
def imported(real_cfg, tmp_path_factory):
    out = tmp_path_factory.mktemp("samsung") / "hppc_20degC.csv"
    samsung.import_hppc(real_cfg, "20degC", out)
    return out


def _copy_cfg(real_cfg, root, edits):
    """A config whose real.root is ``root``; ``edits`` maps source keys to new file bytes."""
    cfg = copy.deepcopy(real_cfg)
    cfg["real"]["root"] = str(root)
    for key, data in edits.items():
        path = root / key
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        cfg["real"]["sources"][key] = hashlib.sha256(data).hexdigest()
    return cfg


def _head(real_cfg, rows=5000) -> pd.DataFrame:
    return pd.read_csv(samsung.data_root(real_cfg) / KEY20, nrows=rows)


def test_import_builds_time_flips_sign_and_writes_sidecar(imported):
    rec = records.read(imported)
    frame, side = rec.frame, rec.meta
    assert tuple(frame.columns) == records.COLUMNS
    assert len(frame) == 92320  # every source row kept
    np.testing.assert_array_equal(frame["time_s"].to_numpy(), np.arange(len(frame), dtype=float))
    # the first 1C pulse is a discharge: positive current, voltage below the rest before it
    assert 2.9 < frame["current_a"].iloc[1] < 3.1
    assert frame["voltage_v"].iloc[1] < frame["voltage_v"].iloc[0] - 0.05
    assert (
        side["source_sha256"]
        == hashlib.sha256(
            (samsung.data_root({"real": {"root": "../shared/data/real"}}) / KEY20).read_bytes()
        ).hexdigest()
    )
    assert side["ambient_temperature_c"] == 20.0
    assert "no time column" in side["time_s"]
    assert "2.84" in side["dropped_columns"]["soc"]  # the soc column's own reference capacity


def test_flipped_current_sign_is_refused(real_cfg, tmp_path):
    raw = _head(real_cfg)
    raw["current"] = -raw["current"]
    cfg = _copy_cfg(real_cfg, tmp_path, {KEY20: raw.to_csv(index=False).encode()})
    out = tmp_path / "out" / "x.csv"
    with pytest.raises(DataError, match=r"DNN01_HPPC_1C_20amb.*column 'current': sign contradicts"):
        samsung.import_hppc(cfg, "20degC", out)
    assert not out.exists()
    assert not out.with_suffix(".json").exists()


def test_wrong_sampling_step_contradicts_soc_column(real_cfg, tmp_path):
    cfg = _copy_cfg(real_cfg, tmp_path, {KEY20: _head(real_cfg).to_csv(index=False).encode()})
    cfg["real"]["samsung"]["sample_s"] = 0.1
    with pytest.raises(
        DataError, match=r"column 'soc' implies a capacity of .* \(real\.samsung\.sample_s\)"
    ):
        samsung.import_hppc(cfg, "20degC", tmp_path / "x.csv")


def test_changed_source_fails_checksum(real_cfg, tmp_path):
    cfg = copy.deepcopy(real_cfg)
    cfg["real"]["root"] = str(tmp_path)
    (tmp_path / KEY20).parent.mkdir(parents=True)
    (tmp_path / KEY20).write_text("current,voltage,temperature,soc\n1,4,20,100\n")
    with pytest.raises(DataError, match=r"sha256 [0-9a-f]{64} does not match config real\.sources"):
        samsung.import_hppc(cfg, "20degC", tmp_path / "x.csv")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.drop(columns="voltage"), r"missing column 'voltage'"),
        (lambda d: d.assign(temperature=d["temperature"].where(d.index != 7)),
         r"column 'temperature' row 9: missing value \(NaN\)"),
        (lambda d: d.assign(current=d["current"].astype(str).where(d.index != 3, "abc")),
         r"column 'current' row 5: not a finite number"),
    ],
)  # fmt: skip
def test_bad_source_is_one_line_naming_file_and_field(real_cfg, tmp_path, edit, message):
    raw = edit(_head(real_cfg, 300))
    cfg = _copy_cfg(real_cfg, tmp_path, {KEY20: raw.to_csv(index=False).encode()})
    with pytest.raises(DataError, match=message) as err:
        samsung.import_hppc(cfg, "20degC", tmp_path / "x.csv")
    assert "\n" not in str(err.value)
    assert "DNN01_HPPC_1C_20amb" in str(err.value)


def test_unknown_temperature_is_a_config_error(real_cfg, tmp_path):
    with pytest.raises(ConfigError, match=r"real\.samsung\.hppc has no '25degC'"):
        samsung.import_hppc(real_cfg, "25degC", tmp_path / "x.csv")


def test_pulse_fit_recovers_known_rc_parameters():
    rng = np.random.default_rng(1)
    ts = 1.0
    current = np.r_[0.0, np.full(10, 3.0), np.zeros(180)]
    truth = (3.9, 0.030, 0.015, 22.0)
    q = np.r_[0.0, np.cumsum(current[:-1])] * ts / 3600  # charge out before each sample
    # eq. 3 written out: the RC input enters one sample late
    a = np.exp(-ts / truth[3])
    vtr = np.zeros(current.size)
    for k in range(1, current.size):
        vtr[k] = a * vtr[k - 1] + truth[2] * (1 - a) * current[k - 1]
    exact = truth[0] - 0.3 * q - truth[1] * current - vtr
    np.testing.assert_allclose(arrhenius.rc_voltage(truth, current, 0.3, ts), exact, atol=1e-12)
    v = exact + rng.normal(0, 2e-4, current.size)
    fit = arrhenius.fit_pulse(current, v, ts, 0.3, r0_guess=0.035)
    assert fit["r0_fit_ohm"] == pytest.approx(truth[1], rel=0.02)
    assert fit["rtr_ohm"] == pytest.approx(truth[2], rel=0.05)
    assert fit["tau_s"] == pytest.approx(truth[3], rel=0.05)
    assert fit["fit_rmse_mv"] < 0.3


def test_arrhenius_recovers_known_activation_energy():
    rng = np.random.default_rng(2)
    tk = np.repeat([293.15, 303.15, 313.15], 12)
    ea = 25.0  # kJ/mol
    r = (
        1e-6
        * np.exp(ea * 1e3 / (arrhenius.GAS_CONSTANT * tk))
        * np.exp(rng.normal(0, 0.01, tk.size))
    )
    fit = arrhenius.arrhenius(tk, r)
    assert fit["ea_kj_mol"] == pytest.approx(ea, abs=1.5)
    assert fit["ea_ci_low_kj_mol"] < ea < fit["ea_ci_high_kj_mol"]
    assert fit["prefactor"] == pytest.approx(1e-6, rel=0.5)
    # three points: one residual degree of freedom, t(0.975, 1) = 12.7 times the SE
    three = arrhenius.arrhenius(tk[::12], r[::12])
    assert three["dof"] == 1
    half = three["ea_ci_high_kj_mol"] - three["ea_kj_mol"]
    assert half == pytest.approx(12.706 * three["ea_se_kj_mol"], rel=1e-3)
    # pooled: one Ea, one prefactor per group
    groups = np.tile(np.arange(12), 3)
    scaled = r * (1 + groups)
    pooled = arrhenius.arrhenius_pooled(tk, scaled, groups)
    assert pooled["ea_kj_mol"] == pytest.approx(ea, abs=1.5)
    assert pooled["dof"] == 36 - 13


def test_arrhenius_rejects_bad_input():
    with pytest.raises(DataError, match="must be positive"):
        arrhenius.arrhenius([293.0, 303.0], [0.01, -0.01])
    with pytest.raises(DataError, match="matching"):
        arrhenius.arrhenius([293.0, 303.0, 313.0], [0.01, 0.02])


def test_pulse_table_on_the_real_record(real_cfg, imported):
    rec = records.read(imported)
    rc = arrhenius.pulse_table(rec.frame, rec.meta, real_cfg["real"]["samsung"], "20degC")
    assert list(rc["pulse"]) == list(range(1, 21))
    assert rc["soc_pct"].iloc[0] == pytest.approx(100, abs=0.1)
    assert rc["soc_pct"].iloc[-1] == pytest.approx(6.4, abs=1)
    ok = rc[rc["pooled"]]
    assert (ok["fit_rmse_mv"] < 2).all()
    assert ok["r0_step_ohm"].between(0.02, 0.05).all()
    assert ok["tau_s"].between(5, 60).all()


def test_cli_error_is_one_line_and_exit_2(capsys, tmp_path):
    code = real_main(["samsung-import", "--temperature", "99degC", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1
    assert "99degC" in err
    assert not list(tmp_path.iterdir())


def test_one_command_line_for_all_real_data(capsys, tmp_path):
    from avoa_pipeline.real.__main__ import build_parser, main

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert set(sub.choices) == {"list", "panasonic-import", "drive-cycles", "samsung-import",
                                "nasa-import", "arrhenius", "fade"}  # fmt: skip
    assert main(["fade", "--record", str(tmp_path / "none.csv"), "--out-states",
                 str(tmp_path / "s.csv"), "--out-fits", str(tmp_path / "f.csv")]) == 2  # fmt: skip
    assert main(["no-such-command"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2
    assert "none.csv" in err[0]
    assert "no-such-command" in err[1]
    assert not list(tmp_path.iterdir())
