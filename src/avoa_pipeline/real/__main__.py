"""``python -m avoa_pipeline.real``: every real-data import and experiment without Snakemake.

    python -m avoa_pipeline.real list
    python -m avoa_pipeline.real panasonic-import 25degC/us06 --out us06.csv
    python -m avoa_pipeline.real panasonic-import --out us06.csv -- -10degC/us06
    python -m avoa_pipeline.real drive-cycles --out-dir DIR [--temperature 25degC]
    python -m avoa_pipeline.real samsung-import --temperature 20degC --out s20.csv
    python -m avoa_pipeline.real arrhenius --hppc 20degC=s20.csv ... --out-rc R --out-arrhenius A
    python -m avoa_pipeline.real nasa-import --out b0005.csv
    python -m avoa_pipeline.real fade --record b0005.csv --out-states S --out-fits F

``drive-cycles`` imports what it needs into ``DIR`` and runs experiment 1 as the workflow does
(one process, no pool): paper models, C/20 circuits, the diagnosis (training cycle + HPPC, the
C/20 test as OCV, the unseen cycles as validation), the gap comparison, the cross-cycle
diagnostic and the table. Expected errors print one line on stderr and exit 2;
nothing is half-written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# first: importing the CLI module sets one BLAS thread before numpy loads (cli.py says why; the
# diagnosis took 6 min instead of 1 with the default threads on this 2-core machine)
from ..cli import Parser

# isort: split
from .. import config as config_mod
from ..errors import UserError


def _drive_cycles(cfg: dict, out_dir: Path, temps: list[str] | None) -> Path:
    from .. import plan
    from ..importers import panasonic
    from ..jobs import real as jobs
    from .experiments import drive_cycles as dc

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


def _pair(text: str) -> tuple[str, str]:
    key, sep, value = text.partition("=")
    if not sep or not key or not value:
        raise argparse.ArgumentTypeError(f"expected TEMPERATURE=CSV (e.g. 20degC=a.csv): {text!r}")
    return key, value


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(prog="python -m avoa_pipeline.real", description=__doc__,
                          formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    ap.add_argument("--config", default=None, help="config file (default: config/config.yaml)")
    sub = ap.add_subparsers(dest="command", required=True, parser_class=Parser)
    sub.add_parser("list", help="the Panasonic records the config names")
    p = sub.add_parser("panasonic-import", help="one Panasonic test → canonical CSV + JSON")
    p.add_argument(
        "name",
        help="<temperature>/<test>, e.g. 25degC/us06 (see `list`); a "
        "negative temperature after `--`, as argparse reads -10degC as an option: "
        "`--out X.csv -- -10degC/us06`",
    )
    p.add_argument("--out", required=True, type=Path)
    d = sub.add_parser("drive-cycles", help="experiment 1 into a folder")
    d.add_argument("--out-dir", required=True, type=Path)
    d.add_argument(
        "--temperature",
        action="append",
        help="only this one (repeatable; a negative one as --temperature=-10degC)",
    )
    s = sub.add_parser("samsung-import", help="one Samsung HPPC file into the canonical form")
    s.add_argument("--temperature", required=True, help="key of real.samsung.hppc, e.g. 20degC")
    s.add_argument("--out", required=True, help="canonical CSV (sidecar .json beside it)")
    n = sub.add_parser("nasa-import", help="the 168 B0005 discharges into one canonical record")
    n.add_argument("--out", required=True)
    a = sub.add_parser("arrhenius", help="experiment 2: R0, Rtr, tau per pulse and Arrhenius fits")
    a.add_argument("--hppc", type=_pair, nargs="+", required=True, metavar="TEMP=CSV")
    a.add_argument("--out-rc", required=True)
    a.add_argument("--out-arrhenius", required=True)
    f = sub.add_parser("fade", help="experiment 3: capacity/resistance per state and fade laws")
    f.add_argument("--record", required=True, help="canonical B0005 record (nasa-import)")
    f.add_argument("--out-states", required=True)
    f.add_argument("--out-fits", required=True)
    return ap


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(argv)
        from ..importers import panasonic
        from ..jobs import real as jobs

        cfg = config_mod.load(args.config)
        if args.command == "list":
            for name, rec in panasonic.records(cfg).items():
                print(f"{name}\t{rec['test_type']}\t{'; '.join(rec['keys'])}")
        elif args.command == "panasonic-import":
            side = panasonic.import_named(cfg, args.name, args.out)
            print(f"wrote {args.out}: {side['n_samples']} samples")
        elif args.command == "drive-cycles":
            print(f"wrote {_drive_cycles(cfg, args.out_dir, args.temperature)}")
        elif args.command == "samsung-import":
            jobs.samsung_import(cfg, args.temperature, args.out)
        elif args.command == "nasa-import":
            jobs.nasa_import(cfg, args.out)
        elif args.command == "arrhenius":
            jobs.arrhenius(cfg, dict(args.hppc), args.out_rc, args.out_arrhenius)
        else:
            jobs.fade(cfg, args.record, args.out_states, args.out_fits)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
