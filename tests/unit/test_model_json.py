"""A hand-edited ``model.json`` (``FittedModel.load``, ``simulate``, ``export``): every field the
writer writes is checked before use, and every refusal is one line naming the file and the field,
exit 2, no traceback, no numpy warning, nothing written (issue 25, part 2).

The malformed files are generated from valid ones: each key removed in turn, each value (and
entries of every list) replaced by a boolean, a string, null, a list, a nested object, NaN,
±Infinity, a huge float and an integer no float holds.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from json_compare import assert_same_json
from test_ecm import ACTIVE, TRUTH

from avoa_pipeline import cli
from avoa_pipeline.errors import DataError
from avoa_pipeline.model import ecm, fitting, heat, intervals
from avoa_pipeline.model.fitted import PROBE_C_RATE, FittedModel, probe_record

CURRENT_SCALE_A = 2.0 * TRUTH["capacity_ah"]  # the 99th-percentile |I| of record() (its 2C legs)

SOC0 = 0.7
REPLACEMENTS = {
    "true": True,
    "false": False,
    "string": "text",
    "null": None,
    "list": [1.0, 2.0],
    "object": {"a": {"b": 1}},
    "nan": math.nan,
    "inf": math.inf,
    "-inf": -math.inf,
    "huge": 1e300,
    "-huge": -1e300,
    "bigint": 10**400,
}
FREE_TEXT = {
    ("package_version",),
    ("ocv_table", "source"),
    ("ocv_table", "how"),
    ("ocv_table", "offset_why"),
    ("intervals", "method"),
    ("heat", "method"),
    ("heat", "ambient_rule"),
    ("heat", "records", 0, "record"),
}
"""Strings written for readers: any other string is as valid."""
OPTIONAL = {("current_scale_a",), ("intervals",), ("heat",), ("ocv_table", "offset_sd_v"),
            ("ocv_table", "offset_why"), ("ocv_table", "capacity_sd_ah")}  # fmt: skip
"""Fields a file may lack (written before them; issue 37's table uncertainties among them)."""
NULLABLE = OPTIONAL - {("ocv_table", "offset_why")}
"""... and may hold null (not known: the named defaults stand in)."""

# the two models every variant is made from: a measured table with the elements that write
# values for readers (ocv_shape, r0_soc, r1_soc) and a temperature; the rational OCV with
# Butler-Volmer and its Arrhenius term
MODELS = {
    "table": ("table", ("second_rc", "thermal", "ocv_shape", "r0_soc", "r1_soc")),
    "rational": ("rational", ("butler_volmer", "bv_arrhenius")),
}


def ocv_table() -> ecm.OcvTable:
    """A measured OCV on 41 points (the library resamples a file's table onto 4,001; the
    loader takes any rising grid, and a short one keeps 2,000 variants quick), with a slow
    test's uncertainties (issue 37)."""
    soc = np.linspace(0.0, 1.0, 41)
    v = 3.3 + 0.8 * soc + 0.12 * np.tanh((soc - 0.1) / 0.05)
    return ecm.OcvTable(0.0, 0.025, v, source="ocv.csv", how="test table", offset_sd_v=0.01,
                        offset_why="test", capacity_sd_ah=0.03)  # fmt: skip


def make_model(kind: str, effects, extra=None) -> FittedModel:
    """A model as a fit leaves it: the library's bounds, values inside them."""
    config = ecm.Config(tuple(effects), ocv_table() if kind == "table" else None)
    names = config.names()
    values = {**TRUTH, **{k: v for e in effects for k, v in ACTIVE[e].items()}, **(extra or {})}
    if kind == "table":
        values["voltage_offset_v"] = -0.01
    x = ecm.vector({k: v for k, v in values.items() if ecm.BY_REPORT[k] in names})
    bounds = {n: fitting.internal_limits(n) for n in names if not ecm.PARAMS[n].per_record}
    model = FittedModel(config, x, ecm.Knots(0.2, 0.12), 300.15, bounds, {"by": "test"},
                        CURRENT_SCALE_A)  # fmt: skip
    model.intervals = model_intervals(model)
    if "thermal" in effects:
        model.heat = heat_block()
    return model


def heat_block() -> heat.Heat:
    """A heat block as ``heat.fit_heat`` writes one, with dU/dT admitted (every entry there)
    and the conductance's interval reaching its upper end's neighbourhood."""
    entry = {"value": 40.0, "low95": 30.0, "high95": 55.0, "at_bound": False}
    report = {
        "method": "test", "ambient_rule": heat.AMBIENT_RULE,
        "bounds": {"c_th_j_per_k": list(heat.C_TH_LIMITS_J_PER_K),
                   "ha_w_per_k": list(heat.HA_LIMITS_W_PER_K),
                   "dudt_v_per_k": list(heat.DUDT_LIMITS_V_PER_K)},
        "intervals": {"c_th_j_per_k": entry,
                      "ha_w_per_k": {**entry, "value": 0.1, "low95": 0.05, "high95": 0.2},
                      "dudt_v_per_k": {**entry, "value": -2e-4, "low95": -3e-4,
                                       "high95": -1e-4}},
        "entropic_candidate": {**entry, "value": -2e-4, "low95": -3e-4, "high95": -1e-4},
        "records": [{"record": "a.csv", "ambient_c": 25.0, "ambient_from": "sidecar",
                     "rmse_k": 0.5, "max_err_k": 1.5, "passes": 3}],
        "rmse_k": 0.5,
        "fixed_point": {"tolerance_k": heat.FIXED_POINT_TOL_K, "max_passes": heat.MAX_PASSES},
    }  # fmt: skip
    return heat.Heat(40.0, 0.1, -2e-4, True, report)


def model_intervals(model: FittedModel) -> dict:
    """Intervals as a fit reports them (``Intervals.report``), with every kind of entry: the
    capacity held (given), R1 at its upper bound, τ1 unconstrained, the others narrow, and
    R0 and R1 correlated beyond the limit."""
    x = model.x
    model.bounds["lq"] = (float(x[ecm.IDX["lq"]]),) * 2
    lo, hi = model.bounds["r1"]
    model.bounds["r1"] = (lo, float(x[ecm.IDX["r1"]]))
    free = tuple(n for n in model.names if n != "lq")
    k = {n: j for j, n in enumerate(free)}
    lo = np.array([model.bounds[n][0] for n in free])
    hi = np.array([model.bounds[n][1] for n in free])
    sd = 0.01 * (hi - lo)
    sd[k["ltau1"]] = np.inf
    sd[k["r1"]] = np.nan
    corr = np.eye(len(free))
    corr[k["r0"], k["ltau1"]] = corr[k["ltau1"], k["r0"]] = -0.995
    iv = intervals.Intervals(free, x[[ecm.IDX[n] for n in free]], lo, hi, sd, corr, 5000, 250.0,
                             1e-3, (("lq", float(x[ecm.IDX["lq"]])),))  # fmt: skip
    return iv.report()


def record(model: FittedModel) -> pd.DataFrame:
    """A record of the cell (its voltage the model's own from SOC0) with a moving temperature:
    rest, 2C discharge, rest, a 3C pulse, rest, 1C charge, rest."""
    c = TRUTH["capacity_ah"]
    cur = np.concatenate([np.zeros(20), np.full(300, 2 * c), np.zeros(60), np.full(5, 3 * c),
                          np.zeros(60), np.full(200, -c), np.zeros(40)])  # fmt: skip
    t = np.arange(cur.size, dtype=float)
    frame = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": 3.7,
                          "temperature_c": 25.0 + 4.0 * t / t[-1]})  # fmt: skip
    return frame.assign(voltage_v=model.simulate(frame, soc0=SOC0))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Per model kind: (its model.json text, a record CSV of it)."""
    root = tmp_path_factory.mktemp("models")
    out = {}
    for name, (kind, effects) in MODELS.items():
        model = make_model(kind, effects)
        path = root / f"{name}.json"
        model.save(path)
        data = root / f"{name}.csv"
        record(model).to_csv(data, index=False)
        out[name] = (path.read_text(), data)
    return out


def paths(d, at=()):
    """Every key of ``d`` (into lists: the first, a middle and the last entry), provenance's
    content left out (free, never read)."""
    if at == ("provenance",):
        return
    items = d.items() if isinstance(d, dict) else None
    if items is None and isinstance(d, list):
        picks = sorted({0, len(d) // 2, len(d) - 1}) if d else []
        items = [(j, d[j]) for j in picks]
    for key, value in items or ():
        yield (*at, key)
        if isinstance(value, dict | list):
            yield from paths(value, (*at, key))


def label(path) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out


def bound_refusal(d: dict, path, value) -> str | None:
    """The field that refuses bound ``path`` (a pair, or one end of it) set to ``value``, or
    None where it is still a bound of the value: inside the domain of its transform (a log
    needs a positive value, log10(1 − β) a β below 1) and around the value."""
    rep = path[1]
    pair = list(d["bounds"][rep])
    if len(path) == 3:
        pair[path[2]] = value
    else:
        pair = value
    transform = ecm.PARAMS[ecm.BY_REPORT[rep]].transform
    if not {"log10": min(pair) > 0, "log10_1m": max(pair) < 1, "lin": True}[transform]:
        return label(path)
    if pair[0] > pair[1]:
        return label(path[:2])
    return None if pair[0] <= d["parameters"][rep] <= pair[1] else f"parameters.{rep}"


def variants(text: str):
    """(name, malformed model.json, the field its refusal must name, or None where a removed
    list entry may be named by another field)."""
    d = json.loads(text)
    for path in paths(d):
        parent_path, key = path[:-1], path[-1]

        def edited(change, path=path, parent_path=parent_path, key=key):
            new = json.loads(text)
            parent = new
            for p in parent_path:
                parent = parent[p]
            change(parent, key)
            return new

        if isinstance(key, int):  # a list entry removed: another field may notice first
            yield f"{label(path)} removed", edited(lambda p, k: p.pop(k)), None
        elif path in OPTIONAL:
            pass  # may be absent (files written before them): test_a_file_without_current_scale
        else:
            yield f"{label(path)} missing", edited(lambda p, k: p.pop(k)), label(path)
        original = edited(lambda p, k: None)
        for p in parent_path:
            original = original[p]
        original = original[key]
        for name, value in REPLACEMENTS.items():
            if value is original or (path in FREE_TEXT and isinstance(value, str)):
                continue  # the same value, or text as good as the original's
            if path == ("provenance",) and isinstance(value, dict):
                continue  # any object: written for readers, never read
            if path in NULLABLE and value is None:
                continue  # null: not known (a model made in Python without it), probed at 1C
            want = label(path)
            pair_edit = (name, len(path)) in (("list", 2), ("huge", 3), ("-huge", 3))
            if path[0] == "bounds" and pair_edit:
                want = bound_refusal(d, path, value)
                if want is None:
                    continue  # a wider bound is still a bound of the value
            elif name == "list" and isinstance(original, list):  # judged with its neighbours
                want = label(parent_path)
            yield (f"{label(path)} = {name}",
                   edited(lambda p, k, v=value: p.__setitem__(k, v)), want)  # fmt: skip


def run(args, capsys):
    code = cli.main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def refused_in_one_line(code, err, source):
    assert code == 2, err
    assert err.count("\n") == 1, err
    assert err.startswith(f"error: {source}: "), err
    assert "Traceback" not in err


@pytest.mark.parametrize("name", list(MODELS))
def test_the_valid_files_load_and_predict_their_record(files, name, capsys, tmp_path):
    """The control: the files the variants come from pass, so each refusal is the edit's."""
    text, data = files[name]
    path = tmp_path / "model.json"
    path.write_text(text)
    model = FittedModel.load(path)
    assert_same_json(model.to_json(), json.loads(text))
    code, _, err = run(["simulate", path, data, "--out", tmp_path / "p.csv", "--soc0", SOC0],
                       capsys)  # fmt: skip
    assert code == 0, err
    got = pd.read_csv(tmp_path / "p.csv")
    assert np.abs(got["error_mv"]).max() < 1e-6
    model.check_cell(source=str(path))  # the export's probe passes a sound cell too


@pytest.mark.parametrize("name", list(MODELS))
def test_every_malformed_variant_is_one_line_naming_file_and_field(files, name, tmp_path):
    """Every key removed, every value replaced: FittedModel.load refuses each with a DataError
    that names the file and the field edited."""
    text, _ = files[name]
    path = tmp_path / "model.json"
    count = 0
    for what, d, field in variants(text):
        path.write_text(json.dumps(d))
        with pytest.raises(DataError) as exc:
            FittedModel.load(path)
        msg = str(exc.value)
        assert msg.startswith(f"{path}: field '"), (what, msg)
        assert "\n" not in msg, (what, msg)
        if field is not None:
            assert f"field '{field}" in msg, (what, msg)
        count += 1
    assert count > 400  # the generator reached every field (about 600-800 variants per model)


@pytest.mark.parametrize("name", list(MODELS))
def test_simulate_and_export_refuse_every_variant_alike_and_write_nothing(files, name, tmp_path,
                                                                          capsys):  # fmt: skip
    text, data = files[name]
    path = tmp_path / "model.json"
    pred, cell = tmp_path / "pred.csv", tmp_path / "cell.py"
    # every fifth variant (each field still met with several kinds of edit): the commands add
    # argument and output checks to FittedModel.load, which the test above runs on every one
    for what, d, _ in list(variants(text))[::5]:
        path.write_text(json.dumps(d))
        code_s, _, err_s = run(["simulate", path, data, "--out", pred], capsys)
        refused_in_one_line(code_s, err_s, path)
        code_e, _, err_e = run(["export", path, "--to", "pybamm", "--out", cell], capsys)
        refused_in_one_line(code_e, err_e, path)
        assert err_e == err_s, what
        assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json"], what


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ("[]", "a list of 0, not an object"),
        ("null", "null, not an object"),
        ('"model"', "a string ('model'), not an object"),
        ("3", "the number 3, not an object"),
        ("{", "not readable JSON"),
        ("[" * 100_000 + "]" * 100_000, "not readable JSON"),
        ("1" * 5000, "not readable JSON"),
    ],
    ids=["list", "null", "string", "number", "truncated", "nested", "long-integer"],
)
def test_a_file_that_is_no_model_object(tmp_path, capsys, content, needle):
    path = tmp_path / "model.json"
    path.write_text(content)
    for args in (["simulate", path, tmp_path / "d.csv", "--out", tmp_path / "p.csv"],
                 ["export", path, "--to", "pybamm", "--out", tmp_path / "c.py"]):  # fmt: skip
        code, _, err = run(args, capsys)
        refused_in_one_line(code, err, path)
        assert needle in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json"]


def test_a_folder_as_the_model(tmp_path, capsys):
    folder = tmp_path / "model"
    folder.mkdir()
    code, _, err = run(["export", folder, "--to", "pybamm", "--out", tmp_path / "c.py"], capsys)
    refused_in_one_line(code, err, folder)
    assert "a folder" in err


def _set(*keys_and_value):
    *keys, value = keys_and_value

    def edit(d):
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value

    return edit


TESTERS_FILES = {
    "bool": (_set("parameters", "r0_ohm", True), "'parameters.r0_ohm': a boolean (true)"),
    "effects-string": (_set("effects", "thermal"), "'effects': a string ('thermal'), not a list"),
    "no-knots": (lambda d: d.pop("knots"), "'knots': missing"),
    "no-tref": (lambda d: d.pop("tref_k"), "'tref_k': missing"),
    "bound-scalar": (_set("bounds", "r0_ohm", 0.05), "'bounds.r0_ohm': the number 0.05, not a"),
    "bound-three": (_set("bounds", "r0_ohm", [0, 1, 2]), "'bounds.r0_ohm': a list of 3, need 2"),
    "tref-string": (_set("tref_k", "300"), "'tref_k': a string ('300'), not a number"),
    "tref-nan": (_set("tref_k", math.nan), "'tref_k': NaN, not a finite number"),
    "tref-celsius": (_set("tref_k", 25.0), "'tref_k': 25 outside"),
    "step-0": (_set("knots", "step", 0), "'knots.step': 0 outside the knots' SOC step (0,"),
    "bounds-reversed": (_set("bounds", "r0_ohm", [0.1, 0.01]), "lower 0.1 above upper"),
    "r0-range": (_set("parameters", "r0_ohm", 2.5), "'parameters.r0_ohm': 2.5 outside the lib"),
    "table-falls": (_set("ocv_table", "ocv_v", 3, 3.0), "'ocv_table.ocv_v[3]': 3 V, not above"),
    "derived": (_set("parameters", "r0_knot0_factor", 2.0), "'parameters.r0_knot0_factor': 2,"),
    "capacity": (_set("capacity_ah", 3.0), "'capacity_ah': 3, but the parameters give 2.57"),
    "foreign": (_set("parameters", "hysteresis_m_v", 0.01), "'parameters.hysteresis_m_v': not a"),
}


@pytest.mark.parametrize("case", list(TESTERS_FILES))
def test_the_testers_files_get_their_own_words(files, tmp_path, capsys, case):
    """The hand-edited files of issue 25 (each a traceback, a bare exception text or a silent
    run before): the refusal says what is wrong in the user's words, for both commands."""
    edit, needle = TESTERS_FILES[case]
    text, data = files["table"]
    d = json.loads(text)
    edit(d)
    path = tmp_path / "model.json"
    path.write_text(json.dumps(d))
    for args in (["simulate", path, data, "--out", tmp_path / "p.csv"],
                 ["export", path, "--to", "pybamm", "--out", tmp_path / "c.py"]):  # fmt: skip
        code, _, err = run(args, capsys)
        refused_in_one_line(code, err, path)
        assert needle in err, err


def test_nan_tref_in_a_fresh_process_prints_one_line_and_no_warning(files, tmp_path):
    """NaN printed two numpy warnings first (and never named tref_k): a real process, so that
    nothing but the command's own stderr is seen."""
    text, _ = files["table"]
    d = json.loads(text)
    d["tref_k"] = math.nan
    path = tmp_path / "model.json"
    path.write_text(json.dumps(d))  # json writes NaN, as a hand edit may
    res = subprocess.run([sys.executable, "-m", "avoa_pipeline", "export", str(path), "--to",
                          "pybamm", "--out", str(tmp_path / "c.py")],
                         capture_output=True, text=True, timeout=300, check=False)  # fmt: skip
    assert res.returncode == 2
    assert res.stderr == f"error: {path}: field 'tref_k': NaN, not a finite number\n"
    assert not (tmp_path / "c.py").exists()


@pytest.mark.parametrize("with_record", [True, False], ids=["record", "probe"])
def test_export_refuses_what_simulate_refuses(files, tmp_path, capsys, with_record):
    """R0 = 1.9 Ω in a 2.57 Ah cell, inside the library's range and its (edited) bound: no cell.
    On a record, export refuses with simulate's own words; without one, on the 1C probe."""
    _, data = files["table"]
    model = make_model(*MODELS["table"], extra={"r0_ohm": 1.9})
    path = tmp_path / "model.json"
    model.save(path)
    code_s, _, err_s = run(["simulate", path, data, "--out", tmp_path / "p.csv"], capsys)
    refused_in_one_line(code_s, err_s, path)
    assert "outside one cell's 0.5..6 V" in err_s
    args = ["export", path, "--to", "pybamm", "--out", tmp_path / "c.py"]
    code_e, _, err_e = run([*args, "--record", data] if with_record else args, capsys)
    refused_in_one_line(code_e, err_e, path)
    if with_record:
        assert err_e == err_s
    else:
        assert "under a discharge and charge at its training current (5.14 A)" in err_e
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json"]


@pytest.mark.parametrize("known", [True, False], ids=["training-current", "1C"])
def test_the_probe_crosses_the_fitted_soc_range_and_back(known):
    model = make_model(*MODELS["table"])
    if not known:
        model.current_scale_a = None
    frame, start, what = probe_record(model)
    grid = model.knots.grid()
    assert start == pytest.approx(grid[-1])
    cur, dt = frame["current_a"].to_numpy()[:-1], np.diff(frame["time_s"])
    assert np.sum(cur * dt) == pytest.approx(0.0, abs=1e-9)  # down and back
    q = TRUTH["capacity_ah"]
    amps = CURRENT_SCALE_A if known else PROBE_C_RATE * q
    assert frame["current_a"].max() == pytest.approx(amps)
    assert ("training current" in what) == known
    down = cur > 0
    assert np.sum(cur[down] * dt[down]) / 3600.0 / q == pytest.approx(grid[-1] - grid[0])


def test_a_file_without_current_scale_is_probed_at_1c(files, tmp_path, capsys):
    """model.json files written before current_scale_a load; export probes them at 1C of their
    capacity, so removing the field does not bypass the probe (R0 = 1.9 Ω is still refused)."""
    text, _ = files["table"]
    d = json.loads(text)
    del d["current_scale_a"], d["intervals"]  # written before either existed
    path = tmp_path / "model.json"
    path.write_text(json.dumps(d))
    assert FittedModel.load(path).current_scale_a is None
    d["parameters"]["r0_ohm"] = 1.9
    d["bounds"]["r0_ohm"] = [0.0, 2.0]
    path.write_text(json.dumps(d))
    code, _, err = run(["export", path, "--to", "pybamm", "--out", tmp_path / "c.py"], capsys)
    refused_in_one_line(code, err, path)
    assert f"at {PROBE_C_RATE:g}C (model.json has no current_scale_a)" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json"]


def test_an_extreme_model_is_refused_by_its_voltage_without_numpy_warnings(files, tmp_path):
    """Parameters at the ends of the library's ranges that overflow on the way are refused by
    the voltage they predict (pytest turns any numpy warning into an error here)."""
    _, data = files["rational"]
    extreme = make_model("rational", ("butler_volmer", "bv_arrhenius"),
                         extra={"bv_inv_i0_per_a": 1e5, "bv_theta_i0_k": 12000.0,
                                "r0_ohm": 2.0})  # fmt: skip
    frame = pd.read_csv(data)
    with pytest.raises(DataError, match="do not describe a cell"):
        extreme.predict(frame.assign(temperature_c=-40.0), source="m.json")


def _holes(node, at=""):
    """Where the schema file left a number to the library and none was filled in."""
    if isinstance(node, dict):
        for key, value in node.items():
            if value is None and key in ("minimum", "maximum", "const"):
                yield f"{at}/{key}"
            yield from _holes(value, f"{at}/{key}")
    elif isinstance(node, list):
        for j, value in enumerate(node):
            yield from _holes(value, f"{at}/{j}")


@pytest.mark.parametrize("effects", [(), *[(e,) for e in ecm.EFFECTS], ("second_rc", "third_rc")])
def test_schema_file_filled_for_every_element(effects):
    """schemas/model.schema.yaml leaves the library's numbers as null; model_schema fills every
    one, for each element (its parameters, their bounds and intervals named and ranged), and the
    file is a valid Draft 2020-12 schema."""
    import jsonschema

    from avoa_pipeline.model import fitted
    from avoa_pipeline.records import VOLTAGE_RANGE_V

    try:
        config = ecm.Config(effects, fitted._STAND_IN_TABLE)
    except ValueError:  # an element that needs another (third_rc needs second_rc)
        pytest.skip(f"{effects} is no configuration alone")
    schema = fitted.model_schema(config)
    jsonschema.Draft202012Validator.check_schema(schema)
    assert list(_holes(schema)) == []
    top = schema["properties"]
    reports = [ecm.PARAMS[n].report for n in config.names() if not ecm.PARAMS[n].per_record]
    assert list(top["bounds"]["properties"]) == reports
    assert set(reports) <= set(top["parameters"]["required"])
    # the load's floor is the records' highest voltage over the largest current of a cell
    floor = VOLTAGE_RANGE_V[1] / top["current_scale_a"]["maximum"]
    assert top["load_ohm"]["minimum"] == floor
