"""The jobs of ``workflow/rules/real.smk``: the Panasonic import and experiment 1 (drive
cycles), the Samsung 30Q and NASA B0005 imports and experiments 2-3. Each writes its outputs
atomically and a one-line log; ``python -m avoa_pipeline.real`` calls them too.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from ..io import write_log
from ..plan import real_section


def panasonic_import(cfg, name: str, out_csv, log=None) -> None:
    from ..importers import panasonic

    side = panasonic.import_named(cfg, name, out_csv)
    write_log(log, f"wrote {out_csv}: {side['n_samples']} samples, {side['discharged_ah']:.4f} Ah "
                   f"out (tester: {side['discharged_ah_tester_counter']:.4f} Ah) from "
                   f"{side['source_file']}")  # fmt: skip


# --- experiment 1 (Panasonic), then the Samsung and NASA imports and experiments 2-3 ---------


def _frames(paths: dict) -> dict:
    from .. import records

    frames = {}
    for name, path in paths.items():
        frames[name] = records.read(path).frame
        frames[name].attrs["source"] = str(path)  # for error messages that name the file
    return frames


def panasonic_ocv(canonical_csv, out_csv, log=None) -> None:
    """The C/20 test as an SOC → OCV table by the library's slow-test rule
    (``model.ocv.from_slow_test``): ``soc,ocv_v`` CSV (what ``--ocv`` reads) and a JSON beside
    it with the table's capacity, how it was made and its source."""
    import pandas as pd

    from .. import records
    from ..io import atomic_path, write_json
    from ..model import ocv as ocv_mod

    record = records.read(canonical_csv)
    table = ocv_mod.from_slow_test(record.frame, str(canonical_csv))
    with atomic_path(out_csv) as tmp:
        pd.DataFrame({"soc": table.grid(), "ocv_v": table.values}).to_csv(tmp, index=False)
    meta = {"capacity_ah": table.capacity_ah, "how": table.how, "source": table.source,
            "source_file": record.meta["source_file"]}  # fmt: skip
    write_json(meta, Path(out_csv).with_suffix(".json"))
    write_log(log, f"wrote {out_csv}: {table.how}")


def read_ocv(ocv_csv):
    """The C/20 table written by :func:`panasonic_ocv`, read back as an ``ecm.OcvTable``
    (``inputs.read_ocv``) with its capacity, how and source from the JSON beside it."""
    import dataclasses
    import json

    from ..errors import DataError
    from ..inputs import read_ocv as read_table

    table = read_table(ocv_csv)
    meta_path = Path(ocv_csv).with_suffix(".json")
    try:
        meta = json.loads(meta_path.read_text())
        return dataclasses.replace(table, capacity_ah=float(meta["capacity_ah"]),
                                   how=str(meta["how"]), source=str(meta["source"]))  # fmt: skip
    except FileNotFoundError:
        raise DataError(f"{meta_path}: no such file (written with {ocv_csv})") from None
    except KeyError as exc:
        raise DataError(f"{meta_path}: field {exc.args[0]!r}: missing") from None


def paper_fit_one(exp, base_seed, temp, model, algorithm, train_csv, tests, out_json,
                  log=None) -> None:  # fmt: skip
    """``exp``: ``drive_cycles.fit_settings(cfg, temp)``."""
    from ..io import write_json
    from ..real.experiments import drive_cycles

    train = _frames({"train": train_csv})["train"]
    rec = drive_cycles.paper_fit(exp, base_seed, temp, model, algorithm, train,
                                 _frames(tests))  # fmt: skip
    rec["train_record"] = str(train_csv)
    write_json(rec, out_json)
    med = drive_cycles.median_run(rec["runs"])
    write_log(log, f"{model} {algorithm} {temp}: median-seed train RMSE "
                   f"{med['train_rmse_mv']:.1f} mV; "
                   + ", ".join(f"{c} {e['rmse_mv']:.1f}" for c, e in med["cycles"].items())
                   + f" mV; {sum(r['wall_s'] for r in rec['runs']):.1f} s")  # fmt: skip


def c20_fit_one(temp, train_csv, tests, ocv_csv, out_json, log=None) -> None:
    """The C/20 circuits (library configurations on the C/20 table) fitted to the training cycle
    and run on the unseen ones."""
    from ..io import write_json
    from ..real.experiments import drive_cycles

    train = _frames({"train": train_csv})["train"]
    rec = drive_cycles.c20_fits(temp, train, _frames(tests), read_ocv(ocv_csv))
    rec["train_record"] = str(train_csv)
    write_json(rec, out_json)
    write_log(log, "; ".join(
        f"{m} train {r['train_rmse_mv']:.1f} mV, "
        + ", ".join(f"{c} {e['rmse_mv']:.1f}" for c, e in r["cycles"].items())
        for m, r in rec["models"].items()))  # fmt: skip


def diagnose_one(train_csvs, tests, out_dir, ocv=None, log=None) -> None:
    """The diagnosis (``gap.diagnose``) of the training records (fitted together), with ``ocv``
    (a slow test or a table, as ``--ocv``) and the unseen cycles as validation records:
    ``out_dir``/diagnosis.json and model.json (the handed-over model, docs/handover-rule.md), as
    ``python -m avoa_pipeline diagnose`` writes them (``diagnosis.diagnose``, the one pipeline;
    its figure left out, docs/real-data.md says why). An unseen cycle the diagnosis's checks
    refuse is left out, and said (``diagnosis.json``'s ``refused_validation``, a line of the
    log each): one refused record does not stop the experiment."""
    from .. import diagnosis, handover

    d = diagnosis.diagnose(list(train_csvs), list(tests.values()), ocv,
                           skip_refused_validation=True)  # fmt: skip
    out = Path(out_dir)
    d.write(out, figure=False)
    report = d.report
    refused = "".join(f"\nrefused, left out of the validation: {r['refusal']}"
                      for r in report.get("refused_validation", ()))  # fmt: skip
    write_log(log, f"{', '.join(map(str, train_csvs))}: verdict's model "
                   f"{report['selected']['name']}; "
                   f"{handover.summary_line(report['handed_over'])} (model.json); {d.heat_line}; "
                   f"wrote {out / 'diagnosis.json'}, {out / 'model.json'}; "
                   f"{report['wall_s']:.0f} s{refused}")  # fmt: skip


def attach_heat(model_json, train_csvs, out_json, log=None) -> None:
    """A model.json written by a diagnosis before the heat block existed, with the block the
    diagnosis now writes (``heat.attach`` on the same training records, the electrical model
    held, so the block is what :func:`diagnose_one` would add); written to ``out_json``."""
    from .. import inputs
    from ..model import heat
    from ..model.fitted import FittedModel

    model = FittedModel.load(model_json)
    read = inputs.read_inputs(list(train_csvs), [], None)
    line = heat.attach(model, read.train)
    model.save(out_json)
    write_log(log, f"{model_json}: {line}; wrote {out_json}")


def diagnosis_record(temp, prefix, out_dir, tests: dict) -> dict:
    """The table's record (``drive_cycles.diagnosis_record``) of the diagnosis in ``out_dir``,
    its validation records named by their unseen cycle (``tests``: cycle → CSV)."""
    import json

    from ..real.experiments import drive_cycles

    path = Path(out_dir) / "diagnosis.json"
    report = json.loads(path.read_text())
    where = {Path(p).resolve(): c for c, p in tests.items()}
    cycle_of = {r["record"]: where.get(Path(r["record"]).resolve())
                for r in report.get("validation") or []}  # fmt: skip
    return drive_cycles.diagnosis_record(temp, report, prefix, cycle_of, source=str(path))


def joint_temperature_table(ambient, joint_dir, own_dirs, tests: dict, out_csv, figure_stem,
                            log=None, traces_csv=None, heat_stem=None) -> None:  # fmt: skip
    """``joint_temperature.csv``: the joint diagnosis in ``joint_dir`` (every temperature's
    training records) beside each temperature's own (``own_dirs``: temperature → folder), on
    the unseen cycles ``tests`` (``<temperature>/<cycle>`` → CSV); ``ambient``: temperature →
    °C. With ``traces_csv`` and ``heat_stem``, also the self-heating predicted from the ambient
    alone by the joint model.json's heat block (``joint_temperature.heat_rows``: its columns,
    the traces and their figure); empty columns, and the log says why, where it has none."""
    from ..io import atomic_path
    from ..real.experiments import joint_temperature as jt
    from ..report import real_figures

    joint = diagnosis_record("all", "joint", joint_dir, tests)
    own = {}
    for temp, out_dir in own_dirs.items():
        here = {k.split("/", 1)[1]: p for k, p in tests.items() if k.split("/")[0] == temp}
        own[temp] = diagnosis_record(temp, "diagnosis", out_dir, here)
    ambient = {t: float(a) for t, a in ambient.items()}
    df = jt.table(joint, own, ambient)
    heat_df, traces, heat_note = None, None, ""
    if traces_csv is not None:  # not on a cycle the joint diagnosis refused (its warnings)
        kept = {k: p for k, p in tests.items() if not _refused_in(joint, p)}
        heat_df, traces, heat_note = _joint_heat(Path(joint_dir) / "model.json", kept)
    df = jt.with_heat(df, heat_df, ambient)
    with atomic_path(out_csv) as tmp:
        df.to_csv(tmp, index=False)
    real_figures.joint_temperature_figure(df, figure_stem)
    if traces_csv is not None:
        with atomic_path(traces_csv) as tmp:
            traces.to_csv(tmp, index=False)
        real_figures.joint_heat_figure(traces, df, heat_stem)
    medians = ", ".join(
        f"{r.temperature_c:g} °C {r.joint_rmse_mv:.1f} / {r.per_temperature_rmse_mv:.1f}"
        for r in jt.medians(df).itertuples()
    )
    heat_line = f"\nself-heating from the ambient: {heat_note}" if heat_note else ""
    refused = "".join(f"\nrefused ({r['prefix']} {r['temperature']}), not predicted: "
                      f"{x['refusal']}"
                      for r in (joint, *own.values()) for x in r["refused"])  # fmt: skip
    write_log(log, f"wrote {out_csv}, {figure_stem}.png: joint {joint['selected']}; median unseen "
                   f"RMSE joint / own [mV]: {medians}{heat_line}{refused}")  # fmt: skip


def _refused_in(record: dict, csv) -> bool:
    """Whether a diagnosis's table record (``drive_cycles.diagnosis_record``) refused ``csv``
    as a validation record."""
    return any(Path(x["record"]).resolve() == Path(csv).resolve() for x in record["refused"])


def _joint_heat(model_json: Path, tests: dict):
    """(heat rows, traces, one line) of the joint model's heat block on the unseen cycles
    (``joint_temperature.heat_rows``), or (None, empty traces, why not)."""
    import pandas as pd

    from .. import inputs
    from ..model.fitted import FittedModel
    from ..real.experiments import joint_temperature as jt

    empty = pd.DataFrame(columns=["key", "time_s", "temperature_c", "temperature_c_predicted"])
    if not model_json.is_file():
        return None, empty, f"no {model_json}: temperature columns left empty"
    model = FittedModel.load(model_json)
    if model.heat is None:
        return None, empty, f"{model_json} has no heat block: temperature columns left empty"
    recs = {k: inputs.read_record(p) for k, p in tests.items()}
    heat_df, traces = jt.heat_rows(model, recs)
    h = model.heat
    line = (f"C_th {h.c_th:.4g} J/K, hA {h.ha:.4g} W/K, dU/dT {1e3 * h.dudt:.3g} mV/K "
            f"(entropic {'admitted' if h.entropic else 'not admitted'}); per unseen cycle "
            "temperature RMSE, voltage RMSE on the predicted / measured temperature: ")  # fmt: skip
    each = "; ".join(f"{r.key} {r.temperature_rmse_k:.2f} K, {r.joint_rmse_predicted_t_mv:.1f} "
                     f"/ {r.joint_rmse_measured_t_mv:.1f} mV"
                     for r in heat_df.itertuples())  # fmt: skip
    return heat_df, traces, line + each


def drive_cycle_table(cfg, fit_jsons, diagnoses: dict, tests: dict, out_csv, out_runs,
                      out_predictions, log=None) -> None:  # fmt: skip
    """``drive_cycle_rmse.csv``, the per-seed rows, and the figure cycles' predicted voltages.

    ``cfg``: ``real.panasonic.temperatures`` and ``real.panasonic.experiment`` (the rule passes
    no more); ``fit_jsons``: the paper-model and C/20 records; ``diagnoses``: prefix →
    temperature → the folder of a diagnosis (diagnosis.json, model.json); ``tests``:
    ``<temp>/<cycle>`` → CSV."""
    import json

    import pandas as pd

    from ..io import atomic_path
    from ..model.fitted import FittedModel
    from ..real.experiments import drive_cycles as dc

    cfg = dict(cfg)
    records = [json.loads(Path(p).read_text()) for p in fit_jsons]
    drawn = {}  # (temperature, model name) → the fitted library model drawn in the figure
    for rec, path in zip(records, fit_jsons, strict=True):
        for name, m in rec.get("models", {}).items():
            drawn[rec["temperature"], name] = (m["model"], f"{path}: models.{name}.model")
    refused_by = {}  # (temperature, model name) → the diagnosis's record (its refusals)
    for prefix, per_temp in diagnoses.items():
        for temp, out_dir in per_temp.items():
            here = {k.split("/", 1)[1]: p for k, p in tests.items() if k.split("/")[0] == temp}
            records.append(diagnosis_record(temp, prefix, out_dir, here))
            drawn[temp, f"{prefix}_selected"] = Path(out_dir) / "model.json"
            refused_by[temp, f"{prefix}_selected"] = records[-1]
    temps = cfg["real"]["panasonic"]["temperatures"]
    ambient = {t: float(s["ambient_c"]) for t, s in temps.items()}
    summary, runs = dc.table(records, ambient)
    refused = "".join(f"\nrefused ({r['prefix']} {r['temperature']}), no rows: {x['refusal']}"
                      for r in records for x in r.get("refused", ()))  # fmt: skip
    exp = dc.experiment(cfg)
    qdis = float(exp["qdis_ah"])
    # the measured and predicted voltage of each temperature's figure cycle, one row per sample
    traces = []
    for temp, cycle in (exp.get("figure_cycle") or {}).items():
        key = f"{temp}/{cycle}"
        if key not in tests:
            continue
        frame = _frames({key: tests[key]})[key]
        base = {"temperature": temp, "cycle": cycle, "time_s": frame["time_s"].to_numpy(),
                "current_a": frame["current_a"].to_numpy(),
                "measured_v": frame["voltage_v"].to_numpy()}  # fmt: skip
        for rec in records:
            if rec["temperature"] == temp and "runs" in rec:
                run = dc.median_run(rec["runs"])
                v = dc.paper_simulate(run["params"], frame, dc.PAPER_MODELS[rec["model"]], qdis)
                traces.append(pd.DataFrame({**base, "model": f"{rec['model']}_{rec['algorithm']}",
                                            "model_v": v}))  # fmt: skip
        for (t, name), model in drawn.items():
            if t == temp and not (
                (t, name) in refused_by and _refused_in(refused_by[t, name], tests[key])
            ):  # a diagnosis's model is not drawn on a cycle that diagnosis refused
                fm = (FittedModel.load(model) if isinstance(model, Path)
                      else FittedModel.from_json(*model))  # fmt: skip
                traces.append(pd.DataFrame({**base, "model": name, "model_v": fm.simulate(frame)}))
    for df, path in ((summary, out_csv), (runs, out_runs)):
        with atomic_path(path) as tmp:
            df.to_csv(tmp, index=False)
    cols = ["temperature", "cycle", "time_s", "current_a", "measured_v", "model", "model_v"]
    pred = pd.concat(traces, ignore_index=True)[cols] if traces else pd.DataFrame(columns=cols)
    with atomic_path(out_predictions) as tmp:
        pred.to_parquet(tmp, index=False)
    write_log(log, f"wrote {out_csv}: {len(summary)} rows from {len(records)} records{refused}")


def cross_cycle_one(ambient_c, temp, model_json, cycles, ocv_csv, out_csv, log=None) -> None:
    """The cross-cycle diagnostic (``cross_cycle.fit_each_predict_all``) of the base circuit
    ``c20_2rc_lowsoc`` and of the configuration the diagnosis handed over (its elements and
    OCV table, from its ``model_json``), each fitted to every drive cycle of ``cycles`` in turn."""
    import pandas as pd

    from ..io import atomic_path
    from ..model.ecm import Config
    from ..model.fitted import FittedModel
    from ..real.experiments import cross_cycle
    from ..real.experiments.drive_cycles import C20_MODELS

    models = {
        "c20_2rc_lowsoc": Config(C20_MODELS["c20_2rc_lowsoc"], read_ocv(ocv_csv)),
        "diagnosis_selected": FittedModel.load(model_json).config,
    }
    df = pd.DataFrame(cross_cycle.fit_each_predict_all(temp, _frames(cycles), models))
    df.insert(0, "temperature_c", float(ambient_c))
    with atomic_path(out_csv) as tmp:
        df.to_csv(tmp, index=False)
    diag = df[df["in_sample"]].groupby("model")["rmse_mv"].median()
    write_log(log, f"wrote {out_csv}: {len(df)} rows; median in-sample RMSE " + "; ".join(
        f"{m} {v:.1f} mV" for m, v in diag.items()))  # fmt: skip


def samsung_import(cfg, temperature: str, out_csv, log=None) -> None:
    from ..importers import samsung

    real_section(cfg, "samsung")
    frame, side = samsung.import_hppc(cfg, temperature, out_csv)
    write_log(log, f"wrote {out_csv}: {len(frame)} samples from {side['source_file']}")


def selected_on(diagnoses: Mapping[str, str], unseen_csv, out_csv, log=None) -> None:
    """``out_csv``: per diagnosis (label → its diagnosis.json), the selected model's RMSE and
    largest error on the unseen record ``unseen_csv`` (its validation entry), with what trained
    it and its temperature laws' parameters (issue 28 on the Samsung 30Q). The selected model is
    the one handed over (model.json, docs/handover-rule.md; its validation rows ``handed_over``),
    the verdict's beside it (``verdict_model``); a report written before the hand-over rule gave
    the verdict's model as model.json, and it is the selected one there."""
    import json

    import pandas as pd

    from ..io import atomic_path
    from ..model import ecm, elements

    # the temperature laws: every parameter of an element that needs a temperature
    laws_of = {e.name for e in elements.REGISTRY.values() if e.needs_temperature}
    law_names = {p.report for p in ecm.PARAMS.values() if p.element in laws_of}
    target, rows = Path(unseen_csv).resolve(), []
    for label, path in diagnoses.items():
        report = json.loads(Path(path).read_text())
        chosen = report.get("handed_over") or report["selected"]
        name = chosen["name"]
        row_name = "handed_over" if "handed_over" in report else name
        hit = [v for v in report.get("validation") or []
               if v["model"] == row_name and Path(v["record"]).resolve() == target]  # fmt: skip
        if len(hit) != 1:
            raise ValueError(f"{path}: no one validation entry of {name} on {unseen_csv}")
        laws = {k: v for k, v in chosen["parameters"].items() if k in law_names}
        trained = "+".join(Path(r["source"]).stem for r in report["records"])
        rows.append({"fit": label, "trained_on": trained, "selected": name,
                     "verdict_model": report["selected"]["name"],
                     "rmse_mv": hit[0]["rmse_mv"], "max_err_mv": hit[0]["max_err_mv"],
                     "floor_rmse_mv": hit[0].get("floor_rmse_mv"),
                     "laws": json.dumps(laws, sort_keys=True)})  # fmt: skip
    df = pd.DataFrame(rows)
    Path(out_csv).parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out_csv) as tmp:
        df.to_csv(tmp, index=False)
    write_log(log, f"wrote {out_csv}: " + "; ".join(
        f"{r.fit} {r.selected} {r.rmse_mv:.1f} mV" for r in df.itertuples()))  # fmt: skip


def nasa_import(cfg, out_csv, log=None) -> None:
    from ..importers import nasa

    real_section(cfg, "nasa")
    frame, side = nasa.import_b0005(cfg, out_csv)
    write_log(log, f"wrote {out_csv}: {len(frame)} samples, {len(side['discharges'])} discharges")


def arrhenius(cfg, hppc: Mapping[str, str], out_rc, out_arrhenius, log=None) -> None:
    from ..real.experiments import arrhenius as arr

    rc, table = arr.experiment(hppc, real_section(cfg, "samsung"), out_rc, out_arrhenius)
    pooled = table[(table["scope"] == "pooled_pulses")].set_index("quantity")
    write_log(
        log,
        f"wrote {out_rc} ({len(rc)} pulses) and {out_arrhenius}; pooled Ea [kJ/mol]: "
        + ", ".join(f"{q} {r['ea_kj_mol']:.2f}" for q, r in pooled.iterrows()),
    )


def fade(cfg, record, out_states, out_fits, log=None) -> None:
    from ..real.experiments import fade as fade_mod

    table, fits = fade_mod.experiment(record, real_section(cfg, "nasa"), out_states, out_fits)
    write_log(
        log,
        f"wrote {out_states} ({len(table)} states) and {out_fits}; RMSE: "
        + ", ".join(f"{r.quantity}/{r.law} {r.rmse:.4g}" for r in fits.itertuples()),
    )


def experiments(cfg, workdir) -> dict:
    """Experiments 2 and 3 from the configured sources, files in ``workdir`` (for
    notebooks/real_cells.ipynb on its own); returns the four output tables by name."""
    from ..real.experiments import arrhenius as arr
    from ..real.experiments import fade as fade_mod

    work = Path(workdir)
    hppc = {}
    for temperature in real_section(cfg, "samsung")["hppc"]:
        hppc[temperature] = work / f"samsung_hppc_{temperature}.csv"
        samsung_import(cfg, temperature, hppc[temperature])
    rc, table = arr.experiment(hppc, real_section(cfg, "samsung"), work / "rc.csv",
                               work / "arrhenius.csv")  # fmt: skip
    nasa_import(cfg, work / "nasa_b0005.csv")
    states, fits = fade_mod.experiment(
        work / "nasa_b0005.csv", real_section(cfg, "nasa"), work / "fade.csv", work / "fade_fit.csv"
    )
    return {"rc": rc, "arrhenius": table, "fade": states, "fade_fit": fits}


def drive_cycle_demo(cfg: dict, out_dir=None) -> dict:
    """The demo run of notebooks/real_drive_cycles.ipynb, its inputs when the workflow's are not
    given: a reduced experiment 1 (25 °C, LA92 → US06, Nelder–Mead seed 1 at 10 × 30, the C/20
    circuits) written to ``out_dir``. It drives this module's jobs, so it sits here, above the
    experiments (which never import ``jobs``)."""
    import copy
    import tempfile

    from .. import plan
    from ..importers import panasonic
    from ..real.experiments import drive_cycles as dc

    out = Path(out_dir or tempfile.mkdtemp(prefix="real_drive_cycles_"))
    cfg = copy.deepcopy(cfg)
    pan = cfg["real"]["panasonic"]
    exp = pan["experiment"]
    exp.update(
        train={"25degC": "la92"},
        algorithms=["nelder_mead"],
        seeds=[1],
        budget={"pop_size": 10, "iterations": 30},
        figure_cycle={"25degC": "us06"},
    )
    t25 = pan["temperatures"]["25degC"]
    t25["drive_cycles"] = {c: t25["drive_cycles"][c] for c in ("la92", "us06")}
    pan["temperatures"] = {"25degC": t25}
    paths = {}
    for name in ("25degC/la92", "25degC/us06", "25degC/ocv_c20"):
        paths[name] = out / f"{plan.canonical_name(name)}.csv"
        panasonic.import_named(cfg, name, paths[name])
    ocv = out / "ocv_c20.csv"
    panasonic_ocv(paths["25degC/ocv_c20"], ocv)
    tests = {"us06": paths["25degC/us06"]}
    fits = [out / "paper_rc.json", out / "c20.json"]
    paper_fit_one(dc.fit_settings(cfg, "25degC"), cfg["base_seed"], "25degC", "paper_rc",
                       "nelder_mead", paths["25degC/la92"], tests, fits[0])  # fmt: skip
    c20_fit_one("25degC", paths["25degC/la92"], tests, ocv, fits[1])
    res = {"rmse_csv": out / "drive_cycle_rmse.csv", "runs_csv": out / "drive_cycle_runs.csv",
           "predictions": out / "figure_predictions.parquet", "train": exp["train"]}  # fmt: skip
    drive_cycle_table(cfg, fits, {}, {"25degC/us06": paths["25degC/us06"]}, res["rmse_csv"],
                           res["runs_csv"], res["predictions"])  # fmt: skip
    return res
