"""``diagnose``: the sim-to-real gap diagnosis of a cell's measured records (docs/gap-diagnosis.md).

``cmd_diagnose`` is the body the CLI had before commands were modules, unchanged but for its
imports (one level up), so that one diagnose pipeline can replace it in one place (issue 39)."""

from __future__ import annotations

from ..names import CURRENT_SIGNS
from .options import CYCLER, number
from .options import flag_lines as _flag_lines
from .registry import register


def arguments(d) -> None:
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
    d.add_argument("--capacity-ah", type=number("capacity-ah"), default=None)
    d.add_argument("--soc0", type=number("soc0"), default=None, help="initial SOC in [0, 1]")
    d.add_argument(
        "--current-accuracy-a",
        type=number("current-accuracy-a"),
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


def cmd_diagnose(args) -> None:
    import json
    from pathlib import Path

    from .. import handover, inputs
    from ..gap import diagnose
    from ..io import atomic_paths, check_output
    from ..model import heat
    from ..report import gap_figures as figure

    out = Path(args.out)
    given = [*args.data, *args.validate, *([args.ocv] if args.ocv else [])]
    # every input and output is checked before any fit, so bad input costs no time
    check_output(out, inputs=given, folder=True)
    for name in ("diagnosis.json", "diagnosis.png", "model.json"):
        check_output(out / name, inputs=given)
    read = inputs.read_inputs(args.data, args.validate, args.ocv, cycler=args.cycler,
                              current_sign=args.current_sign)  # fmt: skip
    heat.training_ambients(read.train)  # a bad sidecar ambient is refused before any fit
    report, arrays, model = diagnose.diagnose_records(
        read.train, args.capacity_ah, args.soc0, ocv_table=read.ocv, validate=read.validate,
        warnings=read.warnings, current_accuracy_a=args.current_accuracy_a)  # fmt: skip
    text = json.dumps(report, indent=1, allow_nan=False) + "\n"
    # all three files or none: the figure is drawn into its temporary first; a failure there
    # leaves no JSON either, and a failed rename puts back the files renamed before it
    names = ("diagnosis.png", "diagnosis.json", "model.json")
    with atomic_paths(*(out / n for n in names)) as (png, js, mj):
        figure.render(report, arrays, png)
        heat_line = heat.attach(model, read.train)  # the thermal state, where the records allow
        js.write_text(text)
        mj.write_text(json.dumps(model.to_json(), indent=1, allow_nan=False) + "\n")
    inputs.warn(read.warnings)  # once the command succeeded: an error stays one line
    inputs.warn(_flag_lines(out / "model.json", report.get("at_bounds", ()),
                            report.get("intervals")))  # fmt: skip
    if model.heat is not None:
        inputs.warn(f"{out / 'model.json'}: {flag}" for flag in heat.flags(model.heat))
    inputs.warn(
        f"{out / 'diagnosis.json'}: {u['effect']} selected, but {u['why']}: these records may "
        f"not identify it; would decide it: {u['would_decide']}"
        for u in report.get("undecided", ())
    )
    inputs.warn(f"{out / 'diagnosis.json'}: {w}" for w in report["handed_over"]["warnings"])
    v = report["verdict"]
    print(
        f"{', '.join(args.data)}: verdict {v['effect']}"
        + (f" (held-out shrink {v['shrink']:.1%})" if v["effect"] != "none" else "")
        + f"; selected {report['selected']['name']}; "
        f"{handover.summary_line(report['handed_over'])}; {heat_line}; wrote "
        f"{out / 'diagnosis.json'}, {out / 'diagnosis.png'}, {out / 'model.json'}"
    )


def _folder(args) -> tuple[str, bool]:
    return args.out, True  # --out is a folder (diagnosis.json, diagnosis.png, model.json)


register("diagnose", "sim-to-real gap diagnosis of a cell's measured records", arguments=arguments,
         parents_after=(CYCLER,), output=_folder)(cmd_diagnose)  # fmt: skip
