"""``estimate``: the SOC of a record by a Kalman filter over a model's states (``estimate.py``,
issue 29)."""

from __future__ import annotations

import sys

from ..errors import UserError
from .options import CURRENT_SIGN, CYCLER, csv_and_sidecar, number
from .registry import register

SOC0_GUESS_RANGE = (-0.5, 1.5)
"""``estimate --soc0``: a guess may be wrong, even outside the cell's range (issue 29's +20 %
start from a full cell is 1.2), but one beyond half the range past either end is not a guess."""


def arguments(e) -> None:
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
        type=number("soc0"),
        default=None,
        help="the start's guess (default: from the opening voltage, the library's rule); "
        "may lie outside [0, 1] (a wrong guess)",
    )
    e.add_argument(
        "--current-bias-a",
        type=number("current-bias-a"),
        default=0.0,
        metavar="B",
        help="add B amperes to the current the filter reads (a sensor off by B; default 0)",
    )
    e.add_argument(
        "--reference-soc0",
        type=number("reference-soc0"),
        default=None,
        metavar="S",
        help="the known start: adds soc_reference (coulomb counting from S with the record's "
        "current) and soc_error, and scores the filter against it",
    )
    e.add_argument(
        "--reference-full",
        action="store_true",
        help="adds soc_reference counted from SOC = 1 at every end of a CC-CV charge in the "
        "record (coulomb counting between, the model's capacity) and soc_error, and scores the "
        "filter against it (docs/soc-filter.md part 5)",
    )
    e.add_argument(
        "--bms-events",
        action="store_true",
        help="use the ends of CC-CV charges (SOC = 1) and the lower cut-off under load (a "
        "lower bound) as pseudo-measurements; SOC.json's bms_events says which fired and when "
        "(docs/soc-filter.md part 5)",
    )
    e.add_argument(
        "--noise",
        choices=("expected-error", "training-residual"),  # estimate.NOISE_RULES
        default="expected-error",
        help="the model's voltage error: model.json's expected_error on other profiles, by "
        "operating point (default; a model without it runs training-residual and says so), or "
        "its training residual (issue 29's rule); docs/soc-filter.md",
    )
    e.add_argument(
        "--no-adapt",
        dest="adapt",
        action="store_false",
        help="do not scale the voltage error's variance from what the filter attributes to it "
        "(docs/soc-filter.md)",
    )


def _check_options(args) -> None:
    import numpy as np

    lo, hi = SOC0_GUESS_RANGE
    if args.soc0 is not None and not (np.isfinite(args.soc0) and lo <= args.soc0 <= hi):
        raise UserError(f"--soc0 must lie in [{lo:g}, {hi:g}] (a guess), got {args.soc0}")
    ref = args.reference_soc0
    if ref is not None and not (np.isfinite(ref) and 0.0 <= ref <= 1.0):
        raise UserError(f"--reference-soc0 must lie in [0, 1], got {ref}")
    if ref is not None and args.reference_full:
        raise UserError("--reference-soc0 and --reference-full are two references: give one")
    if not np.isfinite(args.current_bias_a):
        raise UserError(f"--current-bias-a must be finite, got {args.current_bias_a}")


def _warn(args, model, rec, result) -> None:
    from .. import diagnosis, inputs

    summary = result.summary
    inputs.warn(rec.warnings)
    inputs.warn(list(result.warnings))
    inputs.warn(diagnosis.flag_lines(args.model, model.at_bounds(), model.intervals))
    out_of = summary["outside_range"]
    if out_of is not None:
        lo, hi = out_of["range"]
        inputs.warn([f"{args.data}: the estimated SOC reaches {out_of['soc']:.4f} ± "
                     f"{out_of['soc_sd']:.2g} at t = {out_of['time_s']:g} s, outside "
                     f"{args.model}'s SOC range {lo:g}-{hi:g} by more than "
                     f"{out_of['sd_beyond']:g} sd: no SOC of the cell; the record's voltage "
                     "leaves what the model describes (another cell, or model?)"])  # fmt: skip


@register("estimate", "SOC of a record by a Kalman filter over a model's states",
          arguments=arguments, parents_after=(CURRENT_SIGN, CYCLER))  # fmt: skip
def run_estimate(args) -> None:
    import json

    from .. import estimate
    from ..ambient import model_at_ambient
    from ..io import atomic_paths, check_output
    from ..model import heat
    from ..model_inputs import read_model_and_record
    from ..report import estimate_figures

    out, summary_path = csv_and_sidecar(args.out, [args.model, args.data])
    png = out.with_suffix(".png")
    check_output(png, inputs=[args.model, args.data], what="--out's figure")
    _check_options(args)
    ref = args.reference_soc0
    # the model and record as simulate reads them (its --soc0 rule is for a start, not a guess);
    # a record that only rests is read too: its SOC is the OCV's
    model, rec = read_model_and_record(args.model, args.data, cycler=args.cycler,
                                       current_sign=args.current_sign, rest_ok=True)  # fmt: skip
    model, at_line = model_at_ambient(model, rec, model_name=args.model, data_name=args.data)
    limit = estimate.bias_limit_a(model, rec.frame["current_a"].to_numpy())
    if abs(args.current_bias_a) > limit:
        raise UserError(f"--current-bias-a {args.current_bias_a:g} A: beyond the currents of "
                        f"{args.data} (|I| at most {limit:.4g} A); a sensor's offset is a "
                        "fraction of the range it reads")  # fmt: skip
    result = estimate.estimate_record(model, rec.frame, args.soc0, args.current_bias_a, ref,
                                      source=args.model, noise=args.noise,
                                      adapt=args.adapt, bms_events=args.bms_events,
                                      reference_full=args.reference_full,
                                      ambient=heat.ambient_if_any(rec))  # fmt: skip
    summary = {"model": str(args.model), "record": str(args.data), **result.summary}
    with atomic_paths(out, summary_path, png) as (csv_tmp, js_tmp, png_tmp):
        result.frame.to_csv(csv_tmp, index=False)
        js_tmp.write_text(json.dumps(summary, indent=1, allow_nan=False) + "\n")
        estimate_figures.render(result.frame, summary, png_tmp, title=str(args.data))
    _warn(args, model, rec, result)
    if at_line is not None:
        print(at_line, file=sys.stderr)
    line = (f"{args.data}: final SOC {summary['final_soc']:.4f} ± {summary['final_soc_sd']:.4f}"
            + (" (the record only rests: the SOC of its OCV)" if summary["rest_only"] else "")
            + f" ({summary['times_real_time']:.0f}× real time)")  # fmt: skip
    if "filter" in summary:
        f = summary["filter"]
        line += (f"; after 5 min RMSE {100 * f['rmse_after_window']:.2f} %, max "
                 f"{100 * f['max_error_after_window']:.2f} %, ±2σ coverage "
                 f"{100 * f['coverage_2sd']:.0f} %")  # fmt: skip
    print(f"{line}; wrote {out}, {summary_path}, {png}")
