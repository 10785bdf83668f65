"""Command line: ``python -m avoa_pipeline COMMAND ...``, one function ``cmd_<command>`` each.

Commands: fit, generate, recovery, convert, diagnose, simulate, export, estimate (``--help`` says
more).

Expected errors (bad arguments, config or data) print one line on stderr and exit 2 without a
traceback, and write no output file.
"""

from __future__ import annotations

import argparse
import os
import re
import sys

os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")
# one BLAS thread (set before numpy loads): scipy's least_squares and L-BFGS-B call BLAS on small
# matrices, and spinning BLAS threads on a busy 2-core machine made a diagnosis up to 30x slower
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

from .errors import UserError
from .names import ALGORITHMS, CURRENT_FROM, CURRENT_SIGNS, CYCLERS

CYCLER_HELP = (
    "the data files (and --ocv, --validate) are this cycler's raw exports; a file already in the "
    "canonical columns is read as it is"
)


NUMBERS = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?(,\s*[-+]?(\d+\.?\d*|\.\d+)"
                     r"([eE][-+]?\d+)?)*,?$")  # fmt: skip
"""An argument that starts with a minus and is a number or a comma-separated list of them
(``-10,0,10``, ``-1e-3``): a value, not an option (argparse's own rule takes only ``-10`` and
``-.5``, so ``--temperatures -10,0,10`` was "expected one argument")."""


class Parser(argparse.ArgumentParser):
    """argparse with usage errors as one-line :class:`UserError` (exit 2, no usage block), and
    negative numbers and lists of numbers taken as values (:data:`NUMBERS`)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NUMBERS  # argparse's hook for what looks like a number

    def error(self, message):  # one line, exit 2 (argparse prints the usage block otherwise)
        raise UserError(f"{self.prog}: {message}")


def _int_in(name: str, allowed):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if allowed is not None and value not in allowed:
            raise argparse.ArgumentTypeError(
                f"unknown {name} {value}; choose from {', '.join(map(str, allowed))}"
            )
        return value

    return parse


def _algorithm(text: str) -> str:
    if text not in ALGORITHMS:
        raise argparse.ArgumentTypeError(
            f"unknown algorithm {text!r}; choose from {', '.join(ALGORITHMS)}"
        )
    return text


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="avoa_pipeline", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True, parser_class=Parser)

    f = sub.add_parser("fit", help="identify the parameters of one scenario × case")
    f.add_argument("--scenario", type=_int_in("scenario", (1, 2, 3, 4)), required=True)
    f.add_argument("--case", type=_int_in("case", (1, 2, 3, 4)), required=True)
    f.add_argument("--algorithm", type=_algorithm, required=True)
    f.add_argument("--seed", type=_int_in("seed", None), required=True)
    f.add_argument("--out", required=True, help="record file (JSON)")
    f.add_argument("--config", default=None, help="config file (default config/config.yaml)")
    f.add_argument("--data", default=None, help="dataset CSV (default: generated in memory)")
    f.add_argument("--pop-size", type=_int_in("pop-size", None), default=None)
    f.add_argument("--iterations", type=_int_in("iterations", None), default=None)
    f.add_argument("--max-nfe", type=_int_in("max-nfe", None), default=None)
    f.add_argument("--noise-free", action="store_true", help="generated data without noise")
    f.add_argument("--threads", type=_int_in("threads", None), default=None)

    g = sub.add_parser("generate", help="write the synthetic dataset of one scenario × case")
    g.add_argument("--scenario", type=_int_in("scenario", (1, 2, 3, 4)), required=True)
    g.add_argument("--case", type=_int_in("case", (1, 2, 3, 4)), required=True)
    g.add_argument("--out", required=True, help="CSV path; the JSON sidecar goes beside it")
    g.add_argument("--config", default=None)
    g.add_argument("--noise-free", action="store_true")
    r = sub.add_parser("recovery", help="every algorithm on noise-free data: parameter errors")
    r.add_argument("--scenario", type=_int_in("scenario", (1, 2, 3, 4)), required=True)
    r.add_argument("--case", type=_int_in("case", (1, 2, 3, 4)), required=True)
    r.add_argument("--seeds", type=_int_in("seeds", None), default=5, help="seeds 1..N")
    r.add_argument("--iterations", type=_int_in("iterations", None), default=None)
    r.add_argument("--out", required=True, help="CSV of runs; a .md summary goes beside it")
    r.add_argument("--config", default=None)

    c = sub.add_parser("convert", help="a raw cycler export → the canonical CSV + JSON sidecar")
    c.add_argument("raw", help="the cycler's export (docs/cyclers.md says which columns)")
    c.add_argument("--cycler", choices=CYCLERS, required=True)
    c.add_argument("--out", required=True, help="CSV path; the JSON sidecar goes beside it")
    c.add_argument(
        "--steps",
        default=None,
        metavar="A-B",
        help="keep one contiguous range of the cycler's step numbers (default: all)",
    )
    c.add_argument(
        "--rest-dt",
        type=_float("rest-dt"),
        default=None,
        metavar="SECONDS",
        help="thin long rests: 10 samples per decade of rest time, at most this far "
        "apart (default: every sample)",
    )
    c.add_argument(
        "--current-from",
        choices=CURRENT_FROM,
        default=CURRENT_FROM[0],
        help="interval means from the charge counters (default, where the export has "
        "them) or the held current channel",
    )
    which = c.add_mutually_exclusive_group()
    which.add_argument(
        "--sheet",
        default=None,
        metavar="NAME",
        help="a workbook's data sheet to convert (needed when it has several)",
    )
    which.add_argument(
        "--sheets",
        choices=("each", "concat"),  # cycler.convert's two ways to read every data sheet
        default=None,
        help="every data sheet of a workbook: each to its own CSV (OUT's stem + '-' + the "
        "sheet's name), or concat into one record in sheet order, time continued",
    )

    d = sub.add_parser("diagnose", help="sim-to-real gap diagnosis of a cell's measured records")
    d.add_argument(
        "data",
        nargs="+",
        help="training CSV(s) of one cell: time_s, current_a (A, + discharge), "
        "voltage_v[, temperature_c]; several are fitted together (shared cell parameters)",
    )
    d.add_argument(
        "--out", required=True, help="folder for diagnosis.json, diagnosis.png and model.json"
    )
    d.add_argument(
        "--ocv",
        default=None,
        help="the cell's OCV: a slow test (≤ C/10, canonical columns) or a table soc,ocv_v",
    )
    d.add_argument(
        "--validate",
        nargs="+",
        default=[],
        metavar="TEST.csv",
        help="records of the same cell never used for any choice; predicted by every "
        "model of the ladder",
    )
    d.add_argument("--capacity-ah", type=_float("capacity-ah"), default=None)
    d.add_argument("--soc0", type=_float("soc0"), default=None, help="initial SOC in [0, 1]")
    d.add_argument(
        "--current-accuracy-a",
        type=_float("current-accuracy-a"),
        default=None,
        help="the cycler channel's current accuracy (A) a fitted current offset is judged by "
        "(default: 0.1 %% of the largest current; docs/handover-rule.md)",
    )
    d.add_argument(
        "--current-sign",
        choices=CURRENT_SIGNS,
        default=CURRENT_SIGNS[0],
        help="the canonical CSVs' convention, for every one of them (training, --validate, a "
        "slow test as --ocv; default: positive current = discharge)",
    )
    d.add_argument("--cycler", choices=CYCLERS, default=None, help=CYCLER_HELP)

    s = sub.add_parser("simulate", help="predict a record of the cell with a diagnosis's model")
    s.add_argument("model", help="model.json written by diagnose")
    s.add_argument("data", help="CSV: time_s, current_a, voltage_v[, temperature_c]")
    s.add_argument(
        "--out",
        required=True,
        help="CSV: time_s, voltage_v, model_v, error_mv, temperature_c_model (the cell "
        "temperature the model ran on), temperature_source[, temperature_c: the measured one]",
    )
    s.add_argument(
        "--soc0",
        type=_float("soc0"),
        default=None,
        help="initial SOC (default: from the first voltage, the library's rule)",
    )
    s.add_argument(
        "--ambient-c",
        type=_float("ambient-c"),
        default=None,
        metavar="T",
        help="the ambient (°C) from which the model's heat block predicts the cell temperature "
        "when the record has no temperature_c (or with --predict-temperature); default: the "
        "CSV's sidecar's ambient_temperature_c",
    )
    s.add_argument(
        "--predict-temperature",
        action="store_true",
        help="predict the cell temperature from the ambient even where the record measured it "
        "(to check the prediction against the thermocouple)",
    )
    s.add_argument("--current-sign", choices=CURRENT_SIGNS, default=CURRENT_SIGNS[0])
    s.add_argument("--cycler", choices=CYCLERS, default=None, help=CYCLER_HELP)

    x = sub.add_parser(
        "export", help="a diagnosis's model for PyBaMM, or as a BMS lookup table (CSV)"
    )
    x.add_argument("model", help="model.json written by diagnose")
    x.add_argument(
        "--to",
        choices=EXPORT_TARGETS,
        required=True,
        help="pybamm: a PyBaMM parameter module (.py); table: R0, RC branches and OCV on an "
        "SOC × temperature grid (.csv, with a .json sidecar; docs/pybamm.md)",
    )
    x.add_argument(
        "--out",
        required=True,
        help="the parameter module (.py) that PyBaMM loads without this package, or the "
        "table (.csv; its sidecar .json beside it)",
    )
    x.add_argument(
        "--soc-grid",
        default=None,
        metavar="S1,S2,...",
        help="--to table: the SOC values, increasing, in [0, 1] (default: 0-1 in 0.01 steps "
        "plus the model's SOC knots)",
    )
    x.add_argument(
        "--temperatures",
        default=None,
        metavar="T1,T2,...",
        help="--to table: the temperatures in °C, increasing (default: the model's reference "
        "temperature, ±10 K in 2 K steps where the model depends on temperature)",
    )
    x.add_argument(
        "--soc0",
        type=_float("soc0"),
        default=None,
        help="initial SOC written (default: --record's, by the library's rule; else 1)",
    )
    x.add_argument(
        "--record",
        default=None,
        metavar="DATA.csv",
        help="a record of the cell: its initial SOC, where PyBaMM runs the module against our "
        "simulator before it is written, and where --drop-unsupported measures what dropping costs",
    )
    x.add_argument(
        "--drop-unsupported",
        action="store_true",
        help="export without the elements PyBaMM's Thevenin model lacks, and write what that "
        "costs on --record (OUT with .dropped.csv)",
    )
    x.add_argument(
        "--predict-temperature",
        action="store_true",
        help="--to pybamm: compare on --record from its ambient alone (the model's heat block "
        "predicts the cell temperature, in ours and in the module) even where it has "
        "temperature_c; without it, so only where the record has none",
    )
    x.add_argument("--current-sign", choices=CURRENT_SIGNS, default=CURRENT_SIGNS[0])
    x.add_argument("--cycler", choices=CYCLERS, default=None, help=CYCLER_HELP)

    e = sub.add_parser("estimate", help="SOC of a record by a Kalman filter over a model's states")
    e.add_argument("model", help="model.json written by diagnose")
    e.add_argument("data", help="CSV: time_s, current_a, voltage_v[, temperature_c]")
    e.add_argument(
        "--out",
        required=True,
        help="CSV: time_s, soc, soc_sd, model_v, innovation_v[, soc_reference, soc_error]; "
        "its summary (.json) and figure (.png) go beside it",
    )
    e.add_argument(
        "--soc0",
        type=_float("soc0"),
        default=None,
        help="the start's guess (default: from the opening voltage, the library's rule); "
        "may lie outside [0, 1] (a wrong guess)",
    )
    e.add_argument(
        "--current-bias-a",
        type=_float("current-bias-a"),
        default=0.0,
        metavar="B",
        help="add B amperes to the current the filter reads (a sensor off by B; default 0)",
    )
    e.add_argument(
        "--reference-soc0",
        type=_float("reference-soc0"),
        default=None,
        metavar="S",
        help="the known start: adds soc_reference (coulomb counting from S with the record's "
        "current) and soc_error, and scores the filter against it",
    )
    e.add_argument("--current-sign", choices=CURRENT_SIGNS, default=CURRENT_SIGNS[0])
    e.add_argument("--cycler", choices=CYCLERS, default=None, help=CYCLER_HELP)
    return p


def _float(name: str):
    def parse(text: str) -> float:
        try:
            return float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None

    return parse


def _config_path(args):
    """The config file a command reads (an input: no output may replace it)."""
    from . import config

    return args.config if args.config is not None else config.DEFAULT_CONFIG


def _csv_and_sidecar(out, inputs):
    """A command writing a CSV and its JSON sidecar: ``--out`` ends .csv, and neither file is an
    input (nor an input's sidecar) or unwritable. Both paths, checked before any work."""
    from pathlib import Path

    from .io import check_output, sidecar_of

    out = Path(out)
    if out.suffix.lower() != ".csv":
        raise UserError(
            f"--out {out}: must end .csv (its JSON sidecar {out.stem}.json goes beside it)"
        )
    check_output(out, inputs=inputs)
    check_output(sidecar_of(out), inputs=inputs, what="--out's sidecar")
    return out, sidecar_of(out)


def cmd_fit(args) -> None:
    import numba

    from . import config, fit, problem
    from .io import check_output, write_json

    if args.seed < 0:
        raise UserError(f"--seed must be 0 or more, got {args.seed}")
    check_output(args.out, inputs=[args.data, _config_path(args)])
    cfg = config.load(args.config)
    budget = fit.budget_from(cfg, args.pop_size, args.iterations, args.max_nfe)
    if args.threads is not None:
        if args.threads < 1:
            raise UserError(f"--threads must be positive, got {args.threads}")
        numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))
    prob = problem.build(cfg, args.scenario, args.case, args.data, noise=not args.noise_free)
    record = fit.run(cfg, prob, args.algorithm, args.seed, budget)
    write_json(record, args.out)
    for note in prob.notes:
        print(f"warning: {note}", file=sys.stderr)


def cmd_generate(args) -> None:
    from . import config, synthetic

    out, _ = _csv_and_sidecar(args.out, [_config_path(args)])
    cfg = config.load(args.config)
    synthetic.write(
        synthetic.generate(cfg, args.scenario, args.case, noise=not args.noise_free), out
    )


def cmd_recovery(args) -> None:
    from pathlib import Path

    from . import config, fit, recovery
    from .io import atomic_paths, check_output

    out = Path(args.out)
    if out.suffix.lower() != ".csv":
        raise UserError(f"--out {out}: must end .csv (its summary {out.stem}.md goes beside it)")
    check_output(out, inputs=[_config_path(args)])
    check_output(out.with_suffix(".md"), inputs=[_config_path(args)], what="--out's summary")
    cfg = config.load(args.config)
    if args.seeds < 1:
        raise UserError(f"--seeds must be positive, got {args.seeds}")
    budget = fit.budget_from(cfg, iterations=args.iterations)
    runs = recovery.recover(cfg, args.scenario, args.case, range(1, args.seeds + 1), budget)
    table = recovery.summary(runs)
    md = recovery.to_markdown(table)
    with atomic_paths(out, out.with_suffix(".md")) as (csv_tmp, md_tmp):
        runs.to_csv(csv_tmp, index=False)
        md_tmp.write_text(md + "\n")
    print(md)


def cmd_convert(args) -> None:
    from pathlib import Path

    from .importers import cycler
    from .io import unchanged_while_read

    out = Path(args.out)
    if out.suffix.lower() != ".csv":
        raise UserError(f"--out must be a .csv path, got {str(out)!r}")
    options = {
        "steps": cycler.parse_steps(args.steps),
        "rest_dt": args.rest_dt,
        "current_from": args.current_from,
    }
    if args.sheets == "each":  # one record per data sheet, each named after its sheet
        if not Path(args.raw).is_file():
            raise UserError(f"{args.raw}: no such file")
        names = cycler.data_sheets(args.raw, args.cycler)
        if not names:
            raise UserError(f"{args.raw}: --sheets each: not a workbook (.xlsx); it has no sheets")
        jobs = [(cycler.sheet_path(out, n), {"sheet": n}) for n in names]
        if len({p for p, _ in jobs}) < len(jobs):
            raise UserError(f"{args.raw}: sheets {', '.join(map(repr, names))} give the same "
                            "file name; convert them one at a time with --sheet NAME")  # fmt: skip
    else:
        jobs = [(out, {"sheet": args.sheet, "concat": args.sheets == "concat"})]
    for path, _ in jobs:
        _csv_and_sidecar(path, [args.raw])
    # every sheet converted before any is written: a bad sheet leaves no file; an export that
    # changes meanwhile (a cycler still writing it) is refused
    with unchanged_while_read(args.raw):
        done = [(path, *cycler.convert(args.raw, args.cycler, **options, **which))
                for path, which in jobs]  # fmt: skip
    for path, frame, info in done:
        side = cycler.write(frame, info, path)
        charge = info["charge"]["discharged_ah_output"]
        check = info["sign"]["voltage_check"]
        sheets = info.get("sheets", {}).get("read")
        print(
            f"{args.raw}" + (f" (sheet {', '.join(map(repr, sheets))})" if sheets else "")
            + f": {len(frame)} samples over {frame['time_s'].iloc[-1]:.0f} s, current from "
            f"the {info['current']['source']}, net discharge {charge:.4f} Ah, sign "
            + ("confirmed" if check["confirmed"] else "not confirmable (see the warning)")
            + f"; wrote {path}, {side}"
        )  # fmt: skip
        for note in info["warnings"]:
            print(f"warning: {note}", file=sys.stderr)


def cmd_diagnose(args) -> None:
    from . import diagnosis, inputs

    given = [*args.data, *args.validate, *([args.ocv] if args.ocv else [])]
    # every input and output is checked before any fit, so bad input costs no time
    diagnosis.check_outputs(args.out, given)
    d = diagnosis.diagnose(args.data, args.validate, args.ocv, capacity_ah=args.capacity_ah,
                           soc0=args.soc0, current_accuracy_a=args.current_accuracy_a,
                           cycler=args.cycler, current_sign=args.current_sign)  # fmt: skip
    d.write(args.out)
    inputs.warn(d.warning_lines(args.out))  # once the command succeeded: an error stays one line
    print(d.summary_line(args.out))


def _flag_lines(source, at_bounds, intervals: dict | None) -> list[str]:
    """``diagnosis.flag_lines`` (its words), for ``simulate``, ``estimate`` and ``export``."""
    from .diagnosis import flag_lines

    return flag_lines(source, at_bounds, intervals)


def _model_and_record(args, data, predicts: bool = False, rest_ok: bool = False):
    """``simulate`` and ``export``: the model (``FittedModel.load``, its one refusal) and the
    record it runs on (or None), checked together: ``--soc0`` in [0, 1], a temperature for a
    thermal model (unless the caller ``predicts`` one: ``simulate``, :func:`_temperature`);
    ``rest_ok``: a record that only rests is read (``estimate``)."""
    import numpy as np

    from . import inputs
    from .model.fitted import FittedModel

    if args.soc0 is not None and not (np.isfinite(args.soc0) and 0.0 <= args.soc0 <= 1.0):
        raise UserError(f"--soc0 must lie in [0, 1], got {args.soc0}")
    model = FittedModel.load(args.model)
    if data is None:
        return model, None
    rec = inputs.read_record(data, cycler=args.cycler, current_sign=args.current_sign,
                             rest_ok=rest_ok)  # fmt: skip
    from . import records
    from .model import elements
    from .model.ecm import IDX

    # the model's capacity tells the units the record alone cannot (minutes, mA)
    records.check_scale(rec.frame, rec.source, float(10.0 ** model.x[IDX["lq"]]),
                        rest_ok=rest_ok)  # fmt: skip
    needs_t = {e for e in model.config.effects if elements.get(e).needs_temperature}
    if needs_t and "temperature_c" not in rec.frame.columns and not predicts:
        raise UserError(f"{data}: missing column 'temperature_c' (the model has "
                        f"{', '.join(sorted(needs_t))})")  # fmt: skip
    return model, rec


def _ambient(args, rec) -> tuple[float, str]:
    """(ambient °C, where from) for ``simulate``'s prediction: ``--ambient-c``, else the CSV's
    sidecar's ``ambient_temperature_c``; else a one-line refusal naming the missing field."""
    from .io import read_sidecar, sidecar_of
    from .model import heat

    if args.ambient_c is not None:
        lo, hi = heat.AMBIENT_RANGE_C
        if not lo <= args.ambient_c <= hi:  # NaN fails too
            raise UserError(f"--ambient-c must lie in {lo:g}..{hi:g} °C, got {args.ambient_c}")
        return float(args.ambient_c), "--ambient-c"
    meta = read_sidecar(args.data) if rec.origin.get("read_as") == "canonical CSV" else {}
    side = sidecar_of(args.data)
    if "ambient_temperature_c" not in meta:
        what = f"{side}: field 'ambient_temperature_c': missing" if meta else f"no sidecar {side}"
        raise UserError(f"{args.data}: no ambient to predict the cell temperature from ({what}); "
                        "give --ambient-c")  # fmt: skip
    where = f"{side}: field 'ambient_temperature_c'"
    return heat.check_ambient(meta["ambient_temperature_c"], where), "the sidecar"


def _unused_ambient(args, pred) -> list[str]:
    """``simulate --ambient-c`` where nothing predicted a temperature from it (the model has no
    temperature law, so the record's run needs none): one warning line, as the option changed
    nothing (a record with temperature_c is refused in :func:`_temperature`)."""
    if args.ambient_c is None or pred is not None:
        return []
    return [f"--ambient-c {args.ambient_c:g}: ignored: {args.model} has no temperature law, so "
            "no cell temperature is predicted from the ambient"]  # fmt: skip


def _temperature(args, model, rec):
    """``simulate``'s cell temperature: (°C per sample or None, what it is, the prediction or
    None). The record's measured ``temperature_c`` where it has one; predicted from the ambient
    by the model's heat block (``model/heat.py``) where it has none and the model needs one, or
    with ``--predict-temperature``; refused where neither is possible."""
    from .model import elements, heat
    from .model.ecm import T_DEFAULT_K

    has_t = "temperature_c" in rec.frame.columns
    needs_t = sorted(e for e in model.config.effects if elements.get(e).needs_temperature)
    if has_t and not args.predict_temperature:
        if args.ambient_c is not None:
            raise UserError(
                "--ambient-c: the record has temperature_c, which simulate uses; add "
                "--predict-temperature to predict from the ambient instead"
            )
        return rec.frame["temperature_c"].to_numpy(), "measured (the record's temperature_c)", None
    if not args.predict_temperature and not needs_t:
        return (None, f"none (no temperature_c; the model has no temperature law: "
                      f"{T_DEFAULT_K - heat.KELVIN:g} °C in its 2RT/F)", None)  # fmt: skip
    if model.heat is None:
        why = (
            "--predict-temperature"
            if args.predict_temperature
            else f"{args.data} has no temperature_c and the model has {', '.join(needs_t)}"
        )
        raise UserError(f"{args.model}: field 'heat': missing ({why}; diagnose writes it when "
                        "the model has thermal and its training records a moving measured "
                        "temperature)")  # fmt: skip
    ambient, where = _ambient(args, rec)
    pred = heat.predict(model, model.heat, rec.frame, ambient, soc0=args.soc0)
    what = (f"predicted from ambient {ambient:g} °C ({where}) by {args.model}'s heat block, "
            f"{pred.passes} fixed-point passes")  # fmt: skip
    return pred.temp_k - heat.KELVIN, what, pred


def cmd_simulate(args) -> None:
    import numpy as np
    import pandas as pd

    from . import inputs
    from .io import atomic_path, check_output
    from .model import heat

    check_output(args.out, inputs=[args.model, args.data])
    model, rec = _model_and_record(args, args.data, predicts=True)
    frame = rec.frame
    temp_c, source, pred = _temperature(args, model, rec)
    run = frame if temp_c is None else frame.assign(temperature_c=temp_c)
    v = model.predict(run, soc0=args.soc0, source=args.model)
    out = pd.DataFrame(
        {
            "time_s": frame["time_s"],
            "voltage_v": frame["voltage_v"],
            "model_v": v,
            "error_mv": 1e3 * (v - frame["voltage_v"].to_numpy()),
            "temperature_c_model": np.nan if temp_c is None else temp_c,
            "temperature_source": source,
        }
    )
    if "temperature_c" in frame.columns:
        out["temperature_c"] = frame["temperature_c"]
    with atomic_path(args.out) as tmp:
        out.to_csv(tmp, index=False)
    rmse = float(np.sqrt(np.mean(out["error_mv"] ** 2)))
    inputs.warn(rec.warnings)
    inputs.warn(_flag_lines(args.model, model.at_bounds(), model.intervals))
    if model.heat is not None:
        inputs.warn(f"{args.model}: {flag}" for flag in heat.flags(model.heat))
    inputs.warn(_unused_ambient(args, pred))
    if pred is not None and not pred.converged:
        inputs.warn([f"{args.model}: the temperature's fixed point moved "
                     f"{pred.last_change_k:.3g} K in its last of {pred.passes} passes "
                     f"(converged: below {heat.FIXED_POINT_TOL_K:g} K)"])  # fmt: skip
    print(f"{args.data}: temperature {source}", file=sys.stderr)
    line = f"{args.data}: RMSE {rmse:.2f} mV, max |error| {out['error_mv'].abs().max():.2f} mV"
    if pred is not None and "temperature_c" in frame.columns:
        dt = out["temperature_c_model"] - out["temperature_c"]
        line += (f"; temperature {float(np.sqrt(np.mean(dt**2))):.2f} K RMS, "
                 f"{float(dt.abs().max()):.2f} K at most against the measured one")  # fmt: skip
    print(f"{line}; {_expected_line(model)}; wrote {args.out}")


def _expected_line(model) -> str:
    """``simulate``'s words on the error to expect (model.json's ``expected_error``), beside its
    own error on the record."""
    ee = model.expected_error
    if ee is None:
        return "no expected error in the model (written before it, or not by diagnose)"
    return (
        f"expected {ee['rms_mv']:.2f} mV RMS on a profile unlike the training records "
        f"(its held-out training data, {ee['held_out']}; error correlated over "
        f"{ee['correlation_time_s']:.3g} s)"
    )


EXPORT_TARGETS = ("pybamm", "table")
"""What ``export --to`` writes: PyBaMM's parameter module, or a BMS-style lookup table."""


def cmd_export(args) -> None:
    if args.to == "table" and args.predict_temperature:
        raise UserError("--predict-temperature applies to --to pybamm")
    if args.to == "table":
        return _export_table(args)
    if args.soc_grid is not None or args.temperatures is not None:
        raise UserError("--soc-grid and --temperatures apply to --to table")
    return _export_pybamm(args)


def _export_ambient(args, model, rec) -> float | None:
    """``export --to pybamm --record``'s temperature mode: the record's ambient (°C,
    ``heat.ambient_of``) where the module's thermal state is compared (``--predict-temperature``,
    or a record without temperature_c and a model with a heat block), else None (the measured
    temperature, as ``simulate`` uses it); refused where a model needs a temperature and
    neither is possible."""
    from .model import elements, heat

    if args.predict_temperature and rec is None:
        raise UserError("--predict-temperature needs --record (where the comparison runs)")
    if rec is None:
        return None
    has_t = "temperature_c" in rec.frame.columns
    if has_t and not args.predict_temperature:
        return None
    if model.heat is None:
        needs_t = sorted(e for e in model.config.effects if elements.get(e).needs_temperature)
        if not args.predict_temperature and not needs_t:
            return None
        why = (
            "--predict-temperature"
            if args.predict_temperature
            else (f"{args.record} has no temperature_c and the model has {', '.join(needs_t)}")
        )
        raise UserError(f"{args.model}: field 'heat': missing ({why})")
    return heat.ambient_of(rec)[0]


def _export_table(args) -> None:
    import json
    from pathlib import Path

    from . import inputs, records
    from .interop import table
    from .io import atomic_paths, check_output, sidecar_of

    if args.record is not None or args.soc0 is not None or args.drop_unsupported:
        raise UserError("--record, --soc0 and --drop-unsupported apply to --to pybamm")
    out = Path(args.out)
    if out.suffix != ".csv":
        raise UserError(f"--out {args.out}: the table is a CSV; end it .csv")
    check_output(out, inputs=[args.model])
    check_output(sidecar_of(out), inputs=[args.model], what="--out's sidecar")
    soc = temps = None
    if args.soc_grid is not None:
        soc = table.parse_grid(args.soc_grid, "--soc-grid", table.SOC_RANGE, "")
    if args.temperatures is not None:
        temps = table.parse_grid(args.temperatures, "--temperatures",
                                 records.TEMPERATURE_RANGE_C, "°C")  # fmt: skip
    model, _ = _model_and_record(args, None)
    model.check_cell(None, None, args.model)  # what simulate and export --to pybamm refuse
    frame, side = table.export_table(model, args.model, soc, temps)
    with atomic_paths(out, sidecar_of(out)) as (tmp, tmp_side):
        frame.to_csv(tmp, index=False, float_format="%.10g")
        tmp_side.write_text(json.dumps(side, indent=1, ensure_ascii=False) + "\n")
    col, worst = max(side["interpolation_error"].items(), key=lambda kv: kv[1]["max_rel"])
    inputs.warn(_flag_lines(args.model, model.at_bounds(), model.intervals))
    strays = ("linear interpolation gives the model's laws at the middle of every grid cell"
              if worst["at_soc"] is None else
              f"linear interpolation strays at most {100 * worst['max_rel']:.2g} % ({col}; "
              f"{worst['max_abs']:.3g} {side['columns'][col]['unit']} at SOC "
              f"{worst['at_soc']:.3g}, {worst['at_temperature_c']:g} °C) from the model between "
              "grid points")  # fmt: skip
    print(f"{args.model}: wrote {out} ({len(side['grid']['temperature_c'])} temperatures × "
          f"{len(side['grid']['soc'])} SOC values, {model.config.name}) and {sidecar_of(out)}; "
          f"{strays}")  # fmt: skip


def _export_pybamm(args) -> None:
    import contextlib
    from pathlib import Path

    from .interop import pybamm as to_pybamm
    from .io import atomic_path, check_output

    out = Path(args.out)
    if out.suffix != ".py":
        raise UserError(f"--out {args.out}: the PyBaMM parameters are a Python module; end it .py")
    check_output(out, inputs=[args.model, args.record])
    check_output(out.with_suffix(".dropped.csv"), inputs=[args.model, args.record],
                 what="--out's cost file")  # fmt: skip
    model, rec = _model_and_record(args, args.record, predicts=True)
    ambient = _export_ambient(args, model, rec)
    to_pybamm.check_exportable(model, args.model, args.drop_unsupported)
    frame = None if rec is None else rec.frame
    to_pybamm.require_pybamm()
    ex = to_pybamm.export(
        model, args.model, args.soc0, frame, args.record, args.drop_unsupported, out.name
    )
    module = to_pybamm.load_source(ex.text)
    options, _ = to_pybamm.build(module)  # it loads before it is written
    # on a record, PyBaMM runs the module before it is written: its voltage against ours
    check = None
    if ambient is not None:  # the thermal state, from the record's ambient, against heat.py's
        check = to_pybamm.thermal_agreement(module, ex.model, frame, ex.initial_soc, ambient)
    elif frame is not None:
        check = to_pybamm.agreement(module, ex.model, frame, ex.initial_soc)
    cost_path = out.with_suffix(".dropped.csv")
    with (
        atomic_path(out) as tmp,
        atomic_path(cost_path) if ex.cost is not None else contextlib.nullcontext() as cost_tmp,
    ):
        tmp.write_text(ex.text)
        if ex.cost is not None:
            ex.cost.to_csv(cost_tmp, index=False)
    line = (
        f"{args.model}: wrote {out} (PyBaMM Thevenin, {ex.model.config.name}, "
        f"{options['number of rc elements']} RC element(s); initial SOC {ex.initial_soc:.4g}, "
        f"{ex.soc0_note})"
    )
    if ex.summary is not None:
        line += (
            f"; dropped {', '.join(ex.dropped)}: {ex.summary['rms_mv']:.3g} mV RMS, "
            f"{ex.summary['max_abs_mv']:.3g} mV at most on {args.record}; wrote {cost_path}"
        )
    from . import inputs

    notes = _flag_lines(args.model, model.at_bounds(), model.intervals)
    if check is not None and "error" in check:
        notes.append(f"{out}: PyBaMM could not run {args.record}: {check['error']}")
    elif check is not None:
        line += (f"; PyBaMM from {out.name} on {args.record}: {check['rms_mv']:.3g} mV RMS, "
                 f"{check['max_abs_mv']:.3g} mV at most from our simulator "
                 f"({check['seconds']:.1f} s)")  # fmt: skip
        if "rms_k" in check:
            line += (f"; temperature predicted from ambient {ambient:g} °C: "
                     f"{check['rms_k']:.3g} K RMS, {check['max_abs_k']:.3g} K at most")  # fmt: skip
        if check["rms_mv"] > to_pybamm.AGREEMENT_RMS_MV:
            notes.append(f"{out}: PyBaMM differs from our simulator by {check['rms_mv']:.3g} mV "
                         f"RMS on {args.record}, above {to_pybamm.AGREEMENT_RMS_MV:g} mV "
                         + ("(docs/pybamm.md: the thermal state, the temperature's hold)"
                            if ambient is not None
                            else "(docs/pybamm.md: the step and soc_resistance)"))  # fmt: skip
    inputs.warn(notes)
    print(line)


SOC0_GUESS_RANGE = (-0.5, 1.5)
"""``estimate --soc0``: a guess may be wrong, even outside the cell's range (issue 29's +20 %
start from a full cell is 1.2), but one beyond half the range past either end is not a guess."""


def cmd_estimate(args) -> None:
    import json

    import numpy as np

    from . import estimate, inputs
    from .io import atomic_paths, check_output
    from .report import estimate_figures

    out, summary_path = _csv_and_sidecar(args.out, [args.model, args.data])
    png = out.with_suffix(".png")
    check_output(png, inputs=[args.model, args.data], what="--out's figure")
    lo, hi = SOC0_GUESS_RANGE
    if args.soc0 is not None and not (np.isfinite(args.soc0) and lo <= args.soc0 <= hi):
        raise UserError(f"--soc0 must lie in [{lo:g}, {hi:g}] (a guess), got {args.soc0}")
    ref = args.reference_soc0
    if ref is not None and not (np.isfinite(ref) and 0.0 <= ref <= 1.0):
        raise UserError(f"--reference-soc0 must lie in [0, 1], got {ref}")
    if not np.isfinite(args.current_bias_a):
        raise UserError(f"--current-bias-a must be finite, got {args.current_bias_a}")
    # the model and record as simulate reads them (its --soc0 rule is for a start, not a guess);
    # a record that only rests is read too: its SOC is the OCV's
    model, rec = _model_and_record(argparse.Namespace(**{**vars(args), "soc0": None}), args.data,
                                   rest_ok=True)  # fmt: skip
    limit = estimate.bias_limit_a(model, rec.frame["current_a"].to_numpy())
    if abs(args.current_bias_a) > limit:
        raise UserError(f"--current-bias-a {args.current_bias_a:g} A: beyond the currents of "
                        f"{args.data} (|I| at most {limit:.4g} A); a sensor's offset is a "
                        "fraction of the range it reads")  # fmt: skip
    result = estimate.estimate_record(model, rec.frame, args.soc0, args.current_bias_a, ref,
                                      source=args.model)  # fmt: skip
    summary = {"model": str(args.model), "record": str(args.data), **result.summary}
    with atomic_paths(out, summary_path, png) as (csv_tmp, js_tmp, png_tmp):
        result.frame.to_csv(csv_tmp, index=False)
        js_tmp.write_text(json.dumps(summary, indent=1, allow_nan=False) + "\n")
        estimate_figures.render(result.frame, summary, png_tmp, title=str(args.data))
    inputs.warn(rec.warnings)
    inputs.warn(_flag_lines(args.model, model.at_bounds(), model.intervals))
    out_of = summary["outside_range"]
    if out_of is not None:
        lo, hi = out_of["range"]
        inputs.warn([f"{args.data}: the estimated SOC reaches {out_of['soc']:.4f} ± "
                     f"{out_of['soc_sd']:.2g} at t = {out_of['time_s']:g} s, outside "
                     f"{args.model}'s SOC range {lo:g}-{hi:g} by more than "
                     f"{out_of['sd_beyond']:g} sd: no SOC of the cell; the record's voltage "
                     "leaves what the model describes (another cell, or model?)"])  # fmt: skip
    line = (f"{args.data}: final SOC {summary['final_soc']:.4f} ± {summary['final_soc_sd']:.4f}"
            + (" (the record only rests: the SOC of its OCV)" if summary["rest_only"] else "")
            + f" ({summary['times_real_time']:.0f}× real time)")  # fmt: skip
    if ref is not None:
        f = summary["filter"]
        line += (f"; after 5 min RMSE {100 * f['rmse_after_window']:.2f} %, max "
                 f"{100 * f['max_error_after_window']:.2f} %, ±2σ coverage "
                 f"{100 * f['coverage_2sd']:.0f} %")  # fmt: skip
    print(f"{line}; wrote {out}, {summary_path}, {png}")


def main(argv=None) -> int:
    from .io import output_lock

    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args = build_parser().parse_args(argv)
        commands = {
            "fit": cmd_fit,
            "generate": cmd_generate,
            "recovery": cmd_recovery,
            "convert": cmd_convert,
            "diagnose": cmd_diagnose,
            "simulate": cmd_simulate,
            "export": cmd_export,
            "estimate": cmd_estimate,
        }
        # one run at a time per output: the lock is held from before the first check to the
        # last rename (io.output_lock); diagnose's --out is a folder, every other one a file
        command = " ".join(["avoa_pipeline", *argv])
        with output_lock(args.out, folder=args.command == "diagnose", command=command):
            commands[args.command](args)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        # a file the user named that the system refuses (a name too long, a symlink loop) where
        # no reader checked it first: still one line naming it; an OSError naming no file is a
        # bug and keeps its traceback
        if exc.filename is None:
            raise
        print(f"error: {exc.filename}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    return 0
