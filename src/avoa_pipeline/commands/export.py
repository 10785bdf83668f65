"""``export``: a diagnosis's model for PyBaMM, or as a BMS lookup table (docs/pybamm.md); the
files are ``interop.export_files``'s, the lines printed are this module's."""

from __future__ import annotations

from ..errors import UserError
from .options import CURRENT_SIGN, CYCLER, number
from .registry import register

EXPORT_TARGETS = ("pybamm", "table")
"""What ``export --to`` writes: PyBaMM's parameter module, or a BMS-style lookup table."""


def arguments(x) -> None:
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
        type=number("soc0"),
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


def _table(args) -> None:
    from .. import diagnosis, inputs
    from ..interop.export_files import write_table

    if args.record is not None or args.soc0 is not None or args.drop_unsupported:
        raise UserError("--record, --soc0 and --drop-unsupported apply to --to pybamm")
    res = write_table(args.model, args.out, args.soc_grid, args.temperatures)
    model, side = res.model, res.side
    col, worst = max(side["interpolation_error"].items(), key=lambda kv: kv[1]["max_rel"])
    inputs.warn(diagnosis.flag_lines(args.model, model.at_bounds(), model.intervals))
    strays = ("linear interpolation gives the model's laws at the middle of every grid cell"
              if worst["at_soc"] is None else
              f"linear interpolation strays at most {100 * worst['max_rel']:.2g} % ({col}; "
              f"{worst['max_abs']:.3g} {side['columns'][col]['unit']} at SOC "
              f"{worst['at_soc']:.3g}, {worst['at_temperature_c']:g} °C) from the model between "
              "grid points")  # fmt: skip
    print(f"{args.model}: wrote {res.csv} ({len(side['grid']['temperature_c'])} temperatures × "
          f"{len(side['grid']['soc'])} SOC values, {model.config.name}) and {res.sidecar}; "
          f"{strays}")  # fmt: skip


def _check_notes(args, res, line: str, notes: list[str]) -> str:
    """The line and notes on PyBaMM's run of the module on ``--record`` against ours."""
    from ..interop import pybamm as to_pybamm

    check, out, ambient = res.check, res.module, res.ambient
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
    return line


def _pybamm(args) -> None:
    from .. import diagnosis, inputs
    from ..interop.export_files import write_pybamm

    res = write_pybamm(args.model, args.out, record=args.record, soc0=args.soc0,
                       drop_unsupported=args.drop_unsupported,
                       predict_temperature=args.predict_temperature, cycler=args.cycler,
                       current_sign=args.current_sign)  # fmt: skip
    ex, model = res.export, res.model
    line = (
        f"{args.model}: wrote {res.module} (PyBaMM Thevenin, {ex.model.config.name}, "
        f"{res.options['number of rc elements']} RC element(s); initial SOC "
        f"{ex.initial_soc:.4g}, {ex.soc0_note})"
    )
    if ex.summary is not None:
        line += (
            f"; dropped {', '.join(ex.dropped)}: {ex.summary['rms_mv']:.3g} mV RMS, "
            f"{ex.summary['max_abs_mv']:.3g} mV at most on {args.record}; wrote {res.cost}"
        )
    notes = diagnosis.flag_lines(args.model, model.at_bounds(), model.intervals)
    line = _check_notes(args, res, line, notes)
    inputs.warn(notes)
    print(line)


@register("export", "a diagnosis's model for PyBaMM, or as a BMS lookup table (CSV)",
          arguments=arguments, parents_after=(CURRENT_SIGN, CYCLER))  # fmt: skip
def run_export(args) -> None:
    if args.to == "table" and args.predict_temperature:
        raise UserError("--predict-temperature applies to --to pybamm")
    if args.to == "table":
        return _table(args)
    if args.soc_grid is not None or args.temperatures is not None:
        raise UserError("--soc-grid and --temperatures apply to --to table")
    return _pybamm(args)
