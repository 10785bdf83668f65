"""``real drive-cycles``: experiment 1 (the Panasonic drive cycles) into a folder, in one process
from the workflow's jobs (``jobs.real``)."""

from __future__ import annotations

from ...errors import UserError
from ..registry import register
from . import load_config


def arguments(d) -> None:
    d.add_argument("--out-dir", required=True)
    d.add_argument(
        "--temperature",
        action="append",
        help="only this one (repeatable; a negative one as --temperature=-10degC)",
    )


def run_experiment(cfg: dict, out_dir, temps: list[str] | None):
    """What the workflow's real rules run, job by job, in one process and no pool: it imports
    what it needs into ``out_dir/canonical`` and runs, per temperature, the paper models, the
    C/20 circuits, the diagnosis (training cycle + HPPC, the C/20 test as OCV, the unseen cycles
    as validation), the gap comparison and the cross-cycle diagnostic, then the table."""
    from ... import plan
    from ...importers import panasonic
    from ...jobs import real as jobs
    from ...real.experiments import drive_cycles as dc

    exp = dc.experiment(cfg)
    temps = temps or dc.temperatures(cfg)
    canon = out_dir / "canonical"

    def record(name):
        path = canon / f"{plan.canonical_name(name)}.csv"
        if not path.is_file():
            panasonic.import_named(cfg, name, path)
        return path

    ocv_record = record("25degC/ocv_c20")
    ocv = out_dir / "ocv_c20.csv"
    jobs.panasonic_ocv(ocv_record, ocv)
    fits, all_tests = [], {}
    diagnoses = {"diagnosis": {}, **({"gap": {}} if exp.get("gap", True) else {})}
    for temp in temps:
        if temp not in exp["train"]:
            raise UserError(f"--temperature {temp}: not in real.panasonic.experiment.train")
        train = record(f"{temp}/{exp['train'][temp]}")
        tests = {c: record(f"{temp}/{c}") for c in dc.unseen_cycles(cfg, temp)}
        all_tests.update({f"{temp}/{c}": p for c, p in tests.items()})
        for model in dc.PAPER_MODELS:
            for alg in exp["algorithms"]:
                fits.append(out_dir / "fits" / temp / model / f"{alg}.json")
                jobs.paper_fit_one(dc.fit_settings(cfg, temp), cfg["base_seed"], temp, model,
                                   alg, train, tests, fits[-1])  # fmt: skip
        fits.append(out_dir / "fits" / temp / "c20.json")
        jobs.c20_fit_one(temp, train, tests, ocv, fits[-1])
        diagnoses["diagnosis"][temp] = out_dir / "diagnosis" / temp
        jobs.diagnose_one([train, record(f"{temp}/hppc")], tests, diagnoses["diagnosis"][temp],
                          ocv_record)  # fmt: skip
        if "gap" in diagnoses:
            diagnoses["gap"][temp] = out_dir / "gap" / temp
            jobs.diagnose_one([train], tests, diagnoses["gap"][temp])
        ambient = cfg["real"]["panasonic"]["temperatures"][temp]["ambient_c"]
        jobs.cross_cycle_one(ambient, temp, diagnoses["diagnosis"][temp] / "model.json",
                             {exp["train"][temp]: train, **tests}, ocv,
                             out_dir / "cross_cycle" / f"{temp}.csv")  # fmt: skip
    out = out_dir / "drive_cycle_rmse.csv"
    jobs.drive_cycle_table(cfg, fits, diagnoses, all_tests, out, out_dir / "drive_cycle_runs.csv",
                           out_dir / "figure_predictions.parquet")  # fmt: skip
    return out


@register("drive-cycles", "experiment 1 into a folder", arguments=arguments, group="real",
          output=None)  # fmt: skip
def run_drive_cycles(args) -> None:
    from pathlib import Path  # here, not above: --help stays without pathlib's imports

    print(f"wrote {run_experiment(load_config(args), Path(args.out_dir), args.temperature)}")
