"""What the Panasonic rules of ``workflow/rules/real.smk`` call: one function per rule.

Each writes its outputs atomically and a one-line log. The light ones run in the Snakemake
process (``run:``); the rules hand the fits (``*_one``) to the workflow's worker-process pool
(``avoa_pipeline.workflow.run_in_pool``), and ``python -m avoa_pipeline.real`` calls them directly.
"""

from __future__ import annotations

from pathlib import Path

from .. import config as config_mod
from ..io import write_log


def canonical_name(name: str) -> str:
    """``25degC/us06`` → the file stem ``panasonic_25degC_us06`` under results/real/canonical."""
    return "panasonic_" + name.replace("/", "_")


def panasonic_import(cfg, name: str, out_csv, log=None) -> None:
    from . import panasonic

    cfg = dict(cfg)
    config_mod.validate(cfg, source="snakemake config")
    side = panasonic.import_named(cfg, name, out_csv)
    write_log(
        log,
        f"wrote {out_csv}: {side['n_samples']} samples, {side['discharged_ah']:.4f} Ah out "
        f"(tester: {side['discharged_ah_tester_counter']:.4f} Ah) from {side['source_file']}",
    )


# --- experiment 1 ------------------------------------------------------------------------------


def _frames(paths: dict) -> dict:
    from . import canonical

    frames = {}
    for name, path in paths.items():
        frames[name] = canonical.read(path)[0]
        frames[name].attrs["source"] = str(path)  # for error messages that name the file
    return frames


def panasonic_ocv(canonical_csv, out_csv, log=None) -> None:
    """The C/20 discharge curve as an SOC → OCV table (CSV + JSON with its capacity)."""
    from ..io import atomic_path, write_json
    from . import canonical, drive_cycles

    frame, side = canonical.read(canonical_csv)
    ocv = drive_cycles.c20_ocv(frame, source=str(canonical_csv))
    with atomic_path(out_csv) as tmp:
        ocv.to_csv(tmp, index=False)
    meta = {**ocv.attrs, "source": str(canonical_csv), "source_file": side["source_file"]}
    write_json(meta, Path(out_csv).with_suffix(".json"))
    write_log(log, f"wrote {out_csv}: C/20 discharge {meta['capacity_ah']:.4f} Ah at "
                   f"{meta['current_a']:.4f} A")  # fmt: skip


def paper_fit_one(cfg, temp, model, algorithm, train_csv, tests, out_json, log=None) -> None:
    import numba

    from ..io import write_json
    from . import drive_cycles

    numba.set_num_threads(1)
    train = _frames({"train": train_csv})["train"]
    rec = drive_cycles.paper_fit(cfg, temp, model, algorithm, train, _frames(tests))
    rec["train_record"] = str(train_csv)
    write_json(rec, out_json)
    med = drive_cycles.median_run(rec["runs"])
    write_log(log, f"{model} {algorithm} {temp}: median-seed train RMSE "
                   f"{med['train_rmse_mv']:.1f} mV; "
                   + ", ".join(f"{c} {e['rmse_mv']:.1f}" for c, e in med["cycles"].items())
                   + f" mV; {sum(r['wall_s'] for r in rec['runs']):.1f} s")  # fmt: skip


def c20_fit_one(cfg, temp, train_csv, tests, ocv_csv, out_json, log=None) -> None:
    import pandas as pd

    from ..io import write_json
    from . import drive_cycles

    train = _frames({"train": train_csv})["train"]
    rec = drive_cycles.c20_fits(cfg, temp, train, _frames(tests), pd.read_csv(ocv_csv))
    rec["train_record"] = str(train_csv)
    write_json(rec, out_json)
    write_log(log, "; ".join(
        f"{m} train {r['train_rmse_mv']:.1f} mV, "
        + ", ".join(f"{c} {e['rmse_mv']:.1f}" for c, e in r["cycles"].items())
        for m, r in rec["models"].items()))  # fmt: skip


def gap_fit_one(temp, train_csv, tests, out_json, out_parquet, log=None) -> None:
    import pandas as pd

    from ..io import atomic_path, write_json
    from . import drive_cycles

    train = _frames({"train": train_csv})["train"]
    rec = drive_cycles.diagnosis_fits(temp, {str(train_csv): train}, _frames(tests),
                                      prefix="gap")  # fmt: skip
    preds = rec.pop("predictions")
    rows = [
        pd.DataFrame({"temperature": temp, "cycle": cycle, "model": model, "model_v": v})
        for model, per_cycle in preds.items()
        for cycle, v in per_cycle.items()
    ]
    rec["train_record"] = str(train_csv)
    with atomic_path(out_parquet) as tmp:
        pd.concat(rows, ignore_index=True).to_parquet(tmp, index=False)
    write_json(rec, out_json)
    per_model = "; ".join(
        f"{m} " + ", ".join(f"{c} {e['rmse_mv']:.1f}" for c, e in r["cycles"].items())
        for m, r in rec["models"].items()
    )
    write_log(log, f"{temp}: selected {rec['selected']}; {per_model} mV; "
                   f"diagnosis {rec['diagnose_wall_s']:.0f} s")  # fmt: skip


def drive_cycle_table(cfg, fit_jsons, gap_parquets, tests: dict, ocv_csv, out_csv, out_runs,
                      out_predictions, log=None, out_cv=None) -> None:  # fmt: skip
    """``drive_cycle_rmse.csv``, the per-seed rows, and the figure cycles' predicted voltages."""
    import json

    import pandas as pd

    from ..io import atomic_path
    from . import drive_cycles as dc

    cfg = dict(cfg)
    records = [json.loads(Path(p).read_text()) for p in fit_jsons]
    temps = cfg["real"]["panasonic"]["temperatures"]
    ambient = {t: float(s["ambient_c"]) for t, s in temps.items()}
    summary, runs = dc.table(records, ambient)
    exp = dc.experiment(cfg)
    qdis = float(exp["qdis_ah"])
    ocv = pd.read_csv(ocv_csv)
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
            if rec["temperature"] != temp:
                continue
            if "runs" in rec:
                run = dc.median_run(rec["runs"])
                v = dc.paper_simulate(run["params"], frame, dc.PAPER_MODELS[rec["model"]], qdis)
                traces.append(pd.DataFrame({**base, "model": f"{rec['model']}_{rec['algorithm']}",
                                            "model_v": v}))  # fmt: skip
            elif "selected" in rec:  # only the CV-selected circuit is drawn
                from . import circuits

                m = rec["models"][rec["selected"]]
                table = circuits.model_table(m, read_ocv(ocv_csv))
                v = circuits.simulate(m["params"], frame, table, m["effects"])
                traces.append(pd.DataFrame({**base, "model": "c20_cv_selected", "model_v": v}))
            elif "prefix" not in rec:
                for name, m in rec["models"].items():
                    v = dc.c20_simulate(m["params"], frame, ocv)
                    traces.append(pd.DataFrame({**base, "model": name, "model_v": v}))
        for path in gap_parquets:
            g = pd.read_parquet(path)
            g = g[(g["temperature"] == temp) & (g["cycle"] == cycle)]
            for name, part in g.groupby("model", sort=False):
                traces.append(pd.DataFrame({**base, "model": name,
                                            "model_v": part["model_v"].to_numpy()}))  # fmt: skip
    cv_rows = [
        {"temperature_c": ambient[rec["temperature"]], "model": name,
         "effects": "+".join(m["effects"]), "folds": rec["folds"],
         "cv_rmse_mv": m["cv_rmse_mv"], "train_rmse_mv": m["train_rmse_mv"],
         "fold_rmse_mv": " ".join(f"{x:.2f}" for x in m["fold_rmse_mv"]),
         "selected": name == rec["selected"]}
        for rec in records if "selected" in rec for name, m in rec["models"].items()
    ]  # fmt: skip
    outs = [(summary, out_csv), (runs, out_runs)]
    if out_cv:
        outs.append((pd.DataFrame(cv_rows), out_cv))
    for df, path in outs:
        with atomic_path(path) as tmp:
            df.to_csv(tmp, index=False)
    cols = ["temperature", "cycle", "time_s", "current_a", "measured_v", "model", "model_v"]
    pred = pd.concat(traces, ignore_index=True)[cols] if traces else pd.DataFrame(columns=cols)
    with atomic_path(out_predictions) as tmp:
        pred.to_parquet(tmp, index=False)
    write_log(log, f"wrote {out_csv}: {len(summary)} rows from {len(records)} fit records")


def read_ocv(ocv_csv):
    """The C/20 table with its capacity and current (from the JSON beside it) as attrs."""
    import json

    import pandas as pd

    ocv = pd.read_csv(ocv_csv)
    meta = Path(ocv_csv).with_suffix(".json")
    if meta.exists():
        ocv.attrs.update(json.loads(meta.read_text()))
    return ocv


def circuit_fit_one(cfg, temp, train_csv, tests, ocv_csv, hppc_csv, out_json, log=None) -> None:
    from ..io import write_json
    from . import circuits, drive_cycles

    settings = drive_cycles.experiment(cfg)["circuits"]
    frames = _frames({"train": train_csv, **({"hppc": hppc_csv} if hppc_csv else {})})
    rec = circuits.choose(temp, frames["train"], _frames(tests), read_ocv(ocv_csv), settings,
                          hppc=frames.get("hppc"))  # fmt: skip
    rec["train_record"] = str(train_csv)
    write_json(rec, out_json)
    write_log(log, f"{temp}: selected {rec['selected']}; " + "; ".join(
        f"{m} CV {r['cv_rmse_mv']:.1f} mV" for m, r in rec["models"].items()))  # fmt: skip


def cross_cycle_one(cfg, temp, circuits_json, cycles, ocv_csv, hppc_csv, out_csv, log=None):
    """The base circuit and the CV-selected one of ``circuits_json``, each fitted to every drive
    cycle of the temperature and run on all (``circuits.cross_cycle``)."""
    import json

    import pandas as pd

    from ..io import atomic_path
    from . import circuits

    rec = json.loads(Path(circuits_json).read_text())
    models = {"c20_2rc_lowsoc": ()}
    models[rec["selected"]] = tuple(rec["models"][rec["selected"]]["effects"])
    hppc = _frames({"hppc": hppc_csv})["hppc"] if hppc_csv else None
    rows = circuits.cross_cycle(temp, _frames(cycles), read_ocv(ocv_csv), models, hppc=hppc)
    df = pd.DataFrame(rows)
    ambient = cfg["real"]["panasonic"]["temperatures"][temp]["ambient_c"]
    df.insert(0, "temperature_c", float(ambient))
    with atomic_path(out_csv) as tmp:
        df.to_csv(tmp, index=False)
    diag = df[df["in_sample"]].groupby("model")["rmse_mv"].median()
    write_log(log, f"wrote {out_csv}: {len(df)} rows; median in-sample RMSE " + "; ".join(
        f"{m} {v:.1f} mV" for m, v in diag.items()))  # fmt: skip
