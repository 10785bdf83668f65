"""``diagnose``: the sim-to-real gap diagnosis of a cell's measured records (docs/gap-diagnosis.md),
through the one diagnose pipeline (``diagnosis.diagnose``, ``Diagnosis.write``)."""

from __future__ import annotations

from ..names import CURRENT_SIGNS
from .options import CYCLER, THREADS, number, use_threads
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
        action="append",
        default=None,
        help="the cell's OCV: a slow test (≤ C/10, canonical columns) or a table soc,ocv_v; "
        "given once per temperature (slow tests, each with its ambient), also its ∂U/∂T "
        "over SOC, which the entropic term then scales (docs/temperature-rule.md part 5)",
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
    from .. import diagnosis, inputs

    ocvs = args.ocv or []
    given = [*args.data, *args.validate, *ocvs]
    # every input and output is checked before any fit, so bad input costs no time
    diagnosis.check_outputs(args.out, given)
    use_threads(args)
    # one --ocv is passed as one path, as before; several as the list (one per temperature)
    ocv = None if not ocvs else ocvs[0] if len(ocvs) == 1 else ocvs
    d = diagnosis.diagnose(args.data, args.validate, ocv, capacity_ah=args.capacity_ah,
                           soc0=args.soc0, current_accuracy_a=args.current_accuracy_a,
                           cycler=args.cycler, current_sign=args.current_sign)  # fmt: skip
    d.write(args.out)
    inputs.warn(d.warning_lines(args.out))  # once the command succeeded: an error stays one line
    print(d.summary_line(args.out))


def _folder(args) -> tuple[str, bool]:
    return args.out, True  # --out is a folder (diagnosis.json, diagnosis.png, model.json)


register("diagnose", "sim-to-real gap diagnosis of a cell's measured records", arguments=arguments,
         parents_after=(CYCLER, THREADS), output=_folder)(cmd_diagnose)  # fmt: skip
