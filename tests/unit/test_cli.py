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


# ------------------------------------------------------------------------------------------------
# simulate's cell temperature: measured, or predicted from the ambient by the heat block


@pytest.fixture(scope="module")
def heat_files(tmp_path_factory):
    """A thermal model with a heat block fitted on two synthetic records (test_heat's cell),
    and a third record of the cell: with its temperature, without it (a sidecar naming the
    ambient), and without either."""
    from test_heat import TRUE, cell, checked, drive, measured, write_records

    from avoa_pipeline.model import heat

    root = tmp_path_factory.mktemp("heat")
    model = cell()
    recs = [checked(measured(model, TRUE, drive(30 + k), 40 + k), k) for k in range(2)]
    model.heat, _ = heat.fit_heat(model, recs)
    model.save(root / "model.json")
    bare = cell()
    bare.save(root / "bare.json")
    write_records(root, measured(model, TRUE, drive(50), 60))
    return root


def _simulate(root, data, capsys, *extra, model="model.json"):
    out = root / "out" / f"{model}-{data}{''.join(extra)}.csv"  # one per call
    out.parent.mkdir(exist_ok=True)
    code = main(["simulate", str(root / model), str(root / data), "--out", str(out),
                 "--soc0", "0.95", *extra])  # fmt: skip
    got = capsys.readouterr()
    return code, got.out, got.err, out


def test_simulate_uses_the_measured_temperature_where_the_record_has_one(heat_files, capsys):
    import pandas as pd

    code, _out, err, path = _simulate(heat_files, "with_t.csv", capsys)
    assert code == 0, err
    assert "temperature measured (the record's temperature_c)" in err
    df = pd.read_csv(path)
    assert (df["temperature_c_model"] == df["temperature_c"]).all()
    assert set(df["temperature_source"]) == {"measured (the record's temperature_c)"}


def test_simulate_predicts_the_temperature_from_the_sidecars_ambient(heat_files, capsys):
    import numpy as np
    import pandas as pd

    code, out, err, path = _simulate(heat_files, "no_t.csv", capsys)
    assert code == 0, err
    assert "temperature predicted from ambient 10 °C (the sidecar)" in err
    df = pd.read_csv(path)
    truth = pd.read_csv(heat_files / "with_t.csv")["temperature_c"]
    assert np.sqrt(np.mean((df["temperature_c_model"] - truth) ** 2)) < 0.2  # the 0.05 K noise
    assert df["temperature_source"].iloc[0].startswith("predicted from ambient 10 °C")
    assert np.sqrt(np.mean(df["error_mv"] ** 2)) < 1.0
    # --ambient-c overrides the sidecar; --predict-temperature predicts beside the thermocouple
    code, _, err, path = _simulate(heat_files, "no_t.csv", capsys, "--ambient-c", "12")
    assert code == 0
    assert "ambient 12 °C (--ambient-c)" in err
    assert pd.read_csv(path)["temperature_c_model"].iloc[0] == pytest.approx(12.0)
    code, out, err, path = _simulate(heat_files, "with_t.csv", capsys, "--predict-temperature",
                                     "--ambient-c", "10")  # fmt: skip
    assert code == 0, err
    assert "K RMS" in out
    assert "against the measured one" in out
    assert {"temperature_c", "temperature_c_model"} <= set(pd.read_csv(path).columns)


@pytest.mark.parametrize(
    ("data", "model", "extra", "needle"),
    [
        ("no_t.csv", "bare.json", (), "bare.json: field 'heat': missing"),
        ("with_t.csv", "bare.json", ("--predict-temperature",), "field 'heat': missing"),
        ("alone.csv", "model.json", (), "no ambient to predict the cell temperature from (no "
                                        "sidecar"),
        ("no_t.csv", "model.json", ("--ambient-c", "400"), "--ambient-c must lie in"),
        ("no_t.csv", "model.json", ("--ambient-c", "nan"), "--ambient-c must lie in"),
        ("with_t.csv", "model.json", ("--ambient-c", "10"), "add --predict-temperature"),
        ("with_t.csv", "model.json", ("--predict-temperature",), "with_t.json"),
    ],
    ids=["no-block", "no-block-forced", "no-ambient", "hot", "nan", "ambient-unused",
         "forced-no-ambient"],
)  # fmt: skip
def test_simulate_refuses_in_one_line_when_it_has_no_temperature(heat_files, capsys, data, model,
                                                                 extra, needle):  # fmt: skip
    code, _out, err, path = _simulate(heat_files, data, capsys, *extra, model=model)
    assert code == 2, err
    assert err.count("\n") == 1, err
    assert err.startswith("error: "), err
    assert needle in err, err
    assert not path.exists()


def test_simulate_refuses_a_sidecar_ambient_that_is_no_temperature(heat_files, capsys, tmp_path):
    import shutil

    shutil.copy(heat_files / "no_t.csv", tmp_path / "r.csv")
    (tmp_path / "r.json").write_text(json.dumps({"ambient_temperature_c": "warm"}))
    shutil.copy(heat_files / "model.json", tmp_path / "model.json")
    code, _, err, path = _simulate(tmp_path, "r.csv", capsys)
    assert code == 2
    assert err.count("\n") == 1, err
    assert "r.json: field 'ambient_temperature_c': 'warm'" in err, err
    assert not path.exists()


# ------------------------------------------------------------------------------------------------
# commands as registered modules (issue 39, item 4): main knows none by name


def test_a_registered_command_runs_through_main_with_the_lock_it_declares(
    tmp_path, capsys, monkeypatch
):
    """A command added from outside the package (its arguments, its run, the output it locks)
    runs through ``main`` like the package's own: nothing in ``main`` names a command."""
    from pathlib import Path

    from avoa_pipeline.commands import registry
    from avoa_pipeline.errors import UserError
    from avoa_pipeline.io import LOCK_SUFFIX

    monkeypatch.setattr(registry, "REGISTRY", dict(registry.REGISTRY))
    held = []

    def arguments(p):
        p.add_argument("--out", required=True)
        p.add_argument("--times", type=int, default=1)

    @registry.register("toy", "a toy command", arguments=arguments)
    def run_toy(args):
        held.extend(p.name for p in tmp_path.iterdir())  # the lock, while the run runs
        if args.times < 1:
            raise UserError(f"--times must be positive, got {args.times}")
        Path(args.out).write_text("x" * args.times)
        print("toy ran")

    out = tmp_path / "t.txt"
    assert main(["toy", "--out", str(out), "--times", "3"]) == 0
    assert out.read_text() == "xxx"
    assert held == [f".t.txt{LOCK_SUFFIX}"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.txt"]  # the lock released
    assert capsys.readouterr().out == "toy ran\n"
    assert main(["toy", "--out", str(tmp_path / "u.txt"), "--times", "0"]) == 2
    assert capsys.readouterr().err == "error: --times must be positive, got 0\n"

    # a command that declares no output takes no lock (and needs no --out)
    registry.register("quiet", "no output", arguments=lambda p: None,
                      output=None)(lambda args: print("quiet ran"))  # fmt: skip
    assert main(["quiet"]) == 0
    assert capsys.readouterr().out == "quiet ran\n"


def test_the_cli_module_names_no_command():
    """``main`` and ``build_parser`` read the registry; the code of cli.py (its docstring
    aside) names no registered command."""
    from pathlib import Path

    from avoa_pipeline import cli, commands

    code = Path(cli.__file__).read_text().split('"""', 2)[2]
    names = {name for _, name in commands.REGISTRY}
    assert {"fit", "diagnose", "real", "fade"} <= names
    assert [n for n in sorted(names) if f'"{n}"' in code or f"'{n}'" in code] == []


def _subparsers(parser):
    return next(a for a in parser._actions if a.dest == "command").choices


def test_shared_options_are_defined_once_and_listed_where_they_were():
    """The options several commands take come from one parent parser each (the same argparse
    action in every command), and each --help still lists them in the order it did: the
    scenario and case first, the current sign and the cycler last (then the threads, where a
    command takes them)."""
    from avoa_pipeline import cli

    sub = _subparsers(cli.build_parser())

    def action(command, option):
        return next(a for a in sub[command]._actions if option in a.option_strings)

    readers = ("diagnose", "simulate", "export", "estimate")
    assert len({id(action(c, "--cycler")) for c in readers}) == 1
    assert len({id(action(c, "--current-sign")) for c in readers[1:]}) == 1
    grid = ("fit", "generate", "recovery")
    assert len({id(action(c, "--scenario")) for c in grid}) == 1
    assert len({id(action(c, "--threads")) for c in ("fit", "diagnose")}) == 1
    for c in readers:
        options = [a.option_strings for a in sub[c]._actions if a.option_strings != ["--threads"]]
        assert options[-1] == ["--cycler"]
        assert options[-2] == ["--current-sign"]
    for c in grid:
        assert [a.option_strings for a in sub[c]._actions[1:3]] == [["--scenario"], ["--case"]]


def test_real_data_commands_join_the_cli_and_keep_their_alias(tmp_path, capsys):
    """``python -m avoa_pipeline real ...`` and ``python -m avoa_pipeline.real ...`` are one
    parser and one run; each names itself in a usage error."""
    from avoa_pipeline import cli
    from avoa_pipeline.real import __main__ as alias

    assert set(_subparsers(alias.build_parser())) == set(
        _subparsers(_subparsers(cli.build_parser())["real"])
    )
    args = ["fade", "--record", str(tmp_path / "none.csv"), "--out-states",
            str(tmp_path / "s.csv"), "--out-fits", str(tmp_path / "f.csv")]  # fmt: skip
    assert main(["real", *args]) == 2
    assert alias.main(args) == 2
    first, second = capsys.readouterr().err.splitlines()
    assert first == second
    assert "none.csv" in first
    assert main(["real", "nope"]) == 2
    assert capsys.readouterr().err.startswith("error: avoa_pipeline real: argument command: ")
    assert alias.main(["nope"]) == 2
    assert capsys.readouterr().err.startswith(
        "error: python -m avoa_pipeline.real: argument command: "
    )
    assert not list(tmp_path.iterdir())


def test_cli_py_is_short():
    """Issue 39's goal for the command line: cli.py under 300 lines (it names no command; the
    commands are modules of commands/). Function lengths: test_layers.py, package-wide."""
    from pathlib import Path

    import avoa_pipeline

    assert len((Path(avoa_pipeline.__file__).parent / "cli.py").read_text().splitlines()) < 300
