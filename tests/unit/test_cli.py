"""The fit command: its record, its determinism, and its one-line errors."""

import json
import subprocess
import sys

import pytest
import yaml

from avoa_pipeline.cli import main

FAST = ["--iterations", "5", "--pop-size", "6"]


def fit_args(out, *extra, algorithm="avoa", scenario="1", case="2"):
    return [
        "fit",
        "--scenario",
        scenario,
        "--case",
        case,
        "--algorithm",
        algorithm,
        "--seed",
        "3",
        "--out",
        str(out),
        *FAST,
        *extra,
    ]


REQUIRED_KEYS = {
    "scenario",
    "case",
    "algorithm",
    "seed",
    "best_params",
    "best_ise",
    "true_params",
    "nfe",
    "n_samples",
    "wall_s",
    "history",
    "versions",
}


@pytest.mark.parametrize(
    "algorithm", ["nelder_mead", "quasi_newton", "ga", "gwo", "run", "avoa", "gto"]
)
def test_fit_record_is_complete_and_repeatable(tmp_path, algorithm):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    assert main(fit_args(a, algorithm=algorithm, scenario="4", case="4")) == 0
    assert main(fit_args(b, algorithm=algorithm, scenario="4", case="4")) == 0
    ra, rb = json.loads(a.read_text()), json.loads(b.read_text())
    assert ra.keys() >= REQUIRED_KEYS
    assert ra["best_params"] == rb["best_params"]
    assert ra["best_ise"] == rb["best_ise"]
    assert list(ra["best_params"]) == ["vnom", "r0", "vdis", "rtr", "tau"]
    assert ra["n_samples"] == 5701
    hist = ra["history"]
    assert len(hist["best_ise"]) == len(hist["nfe"]) == len(hist["wall_s"])
    assert hist["nfe"][-1] == ra["nfe"]
    assert hist["best_ise"][-1] == ra["best_ise"]
    assert {"numpy", "scipy", "numba", "avoa_pipeline"} <= ra["versions"].keys()


def test_fit_on_written_dataset_equals_in_memory(tmp_path):
    data = tmp_path / "d.csv"
    assert main(["generate", "--scenario", "3", "--case", "1", "--out", str(data)]) == 0
    assert data.with_suffix(".json").exists()
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    assert main(fit_args(a, scenario="3", case="1")) == 0
    assert main(fit_args(b, "--data", str(data), scenario="3", case="1")) == 0
    assert json.loads(a.read_text())["best_ise"] == json.loads(b.read_text())["best_ise"]


def _bad_config(tmp_path, cfg, mutate):
    bad = json.loads(json.dumps(cfg))
    mutate(bad)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(bad))
    return path


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--algorithm", "pso"], "unknown algorithm 'pso'"),
        (["--scenario", "5"], "unknown scenario 5"),
        (["--case", "0"], "unknown case 0"),
        (["--iterations", "0"], "iterations"),
        (["--pop-size", "-3"], "pop_size"),
        (["--max-nfe", "0"], "max_nfe"),
        (["--data", "/nonexistent/x.csv"], "/nonexistent/x.csv"),
    ],
)
def test_bad_arguments_one_line_exit_2_no_output(tmp_path, capsys, extra, needle):
    out = tmp_path / "r.json"
    assert main([*fit_args(out), *extra]) == 2
    err = capsys.readouterr().err
    assert needle in err
    assert err.count("\n") == 1
    assert "Traceback" not in err
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_impossible_config_names_file_and_field(tmp_path, capsys, cfg):
    def swap(c):
        c["bounds_used"]["T1"]["r0"] = [0.06, 0.05]

    path = _bad_config(tmp_path, cfg, swap)
    out = tmp_path / "r.json"
    assert main([*fit_args(out), "--config", str(path)]) == 2
    err = capsys.readouterr().err
    assert str(path) in err
    assert "bounds_used.T1.r0" in err
    assert err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ("time_s,current_a\n0,1\n1,1\n2,1\n", "missing column 'voltage_v'"),
        ("time_s,current_a,voltage_v\n0,1,3.7\n1,1,\n2,1,3.7\n", "'voltage_v' row 3"),
        ("time_s,current_a,voltage_v\n0,1,3.7\n0,1,3.7\n1,1,3.7\n", "duplicate time"),
        ("time_s,current_a,voltage_v\n0,1,3.7\n2,1,3.7\n1,1,3.7\n", "backwards"),
        ("time_s,current_a,voltage_v\n0,1,3.7\n1,x,3.7\n2,1,3.7\n", "'current_a' row 3"),
    ],
)
def test_malformed_csv(tmp_path, capsys, content, needle):
    data = tmp_path / "m.csv"
    data.write_text(content)
    out = tmp_path / "r.json"
    assert main([*fit_args(out), "--data", str(data)]) == 2
    err = capsys.readouterr().err
    assert needle in err
    assert str(data) in err
    assert err.count("\n") == 1
    assert not out.exists()


def test_module_entry_point_has_no_traceback(tmp_path):
    out = tmp_path / "r.json"
    proc = subprocess.run(
        [sys.executable, "-m", "avoa_pipeline", *fit_args(out, algorithm="bogus")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: ")
    assert "Traceback" not in proc.stderr
    assert not out.exists()


def test_recovery_reports_every_algorithm(tmp_path, capsys):
    out = tmp_path / "rec.csv"
    assert (
        main(
            [
                "recovery",
                "--scenario",
                "1",
                "--case",
                "3",
                "--seeds",
                "2",
                "--iterations",
                "3",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    import pandas as pd

    runs = pd.read_csv(out)
    assert len(runs) == 7 * 2
    assert {"err_vnom_pct", "err_r0_pct", "err_vdis_pct"} <= set(runs.columns)
    assert out.with_suffix(".md").read_text().count("\n") == 2 + 7
