"""``simulate``: predict a record of the cell with a diagnosis's model."""

from __future__ import annotations

import sys

from .options import CURRENT_SIGN, CYCLER, number
from .registry import register


def arguments(s) -> None:
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
        type=number("soc0"),
        default=None,
        help="initial SOC (default: from the first voltage, the library's rule)",
    )
    s.add_argument(
        "--ambient-c",
        type=number("ambient-c"),
        default=None,
        metavar="T",
        help="the ambient (°C) from which the model's heat block predicts the cell temperature "
        "when the record has no temperature_c (or with --predict-temperature); default: the "
        "CSV's sidecar's ambient_temperature_c; for a model of per-temperature parameter sets "
        "(by_temperature) also the ambient whose parameters run (default: the sidecar's, else "
        "the record's first temperature sample)",
    )
    s.add_argument(
        "--predict-temperature",
        action="store_true",
        help="predict the cell temperature from the ambient even where the record measured it "
        "(to check the prediction against the thermocouple)",
    )


def expected_line(model) -> str:
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


def _warn(args, model, rec, pred, sets: bool = False) -> None:
    from .. import diagnosis, inputs
    from ..ambient import unused_ambient
    from ..model import heat

    inputs.warn(rec.warnings)
    inputs.warn(diagnosis.flag_lines(args.model, model.at_bounds(), model.intervals))
    if model.heat is not None:
        inputs.warn(f"{args.model}: {flag}" for flag in heat.flags(model.heat))
    if not sets:  # per-temperature sets: the ambient chose the set
        inputs.warn(unused_ambient(args.ambient_c, args.model, pred))
    if pred is not None and not pred.converged:
        inputs.warn([f"{args.model}: the temperature's fixed point moved "
                     f"{pred.last_change_k:.3g} K in its last of {pred.passes} passes "
                     f"(converged: below {heat.FIXED_POINT_TOL_K:g} K)"])  # fmt: skip


@register("simulate", "predict a record of the cell with a diagnosis's model",
          arguments=arguments, parents_after=(CURRENT_SIGN, CYCLER))  # fmt: skip
def run_simulate(args) -> None:
    import numpy as np

    from ..ambient import cell_temperature, heat_ambient, model_at_ambient
    from ..io import atomic_path, check_output
    from ..model_inputs import prediction_frame, read_model_and_record

    check_output(args.out, inputs=[args.model, args.data])
    model, rec = read_model_and_record(args.model, args.data, soc0=args.soc0, cycler=args.cycler,
                                       current_sign=args.current_sign, predicts=True)  # fmt: skip
    frame = rec.frame
    sets = model.by_temperature is not None
    ambient_c = heat_ambient(model, rec, args.ambient_c, args.predict_temperature)
    model, at_line = model_at_ambient(model, rec, model_name=args.model, data_name=args.data,
                                      ambient_c=args.ambient_c)  # fmt: skip
    temp_c, source, pred = cell_temperature(
        model, rec, model_name=args.model, data_name=args.data, ambient_c=ambient_c,
        predict=args.predict_temperature, soc0=args.soc0)  # fmt: skip
    run = frame if temp_c is None else frame.assign(temperature_c=temp_c)
    v = model.predict(run, soc0=args.soc0, source=args.model)
    out = prediction_frame(frame, v, temp_c, source)
    with atomic_path(args.out) as tmp:
        out.to_csv(tmp, index=False)
    rmse = float(np.sqrt(np.mean(out["error_mv"] ** 2)))
    _warn(args, model, rec, pred, sets)
    if at_line is not None:
        print(at_line, file=sys.stderr)
    print(f"{args.data}: temperature {source}", file=sys.stderr)
    line = f"{args.data}: RMSE {rmse:.2f} mV, max |error| {out['error_mv'].abs().max():.2f} mV"
    if pred is not None and "temperature_c" in frame.columns:
        dt = out["temperature_c_model"] - out["temperature_c"]
        line += (f"; temperature {float(np.sqrt(np.mean(dt**2))):.2f} K RMS, "
                 f"{float(dt.abs().max()):.2f} K at most against the measured one")  # fmt: skip
    print(f"{line}; {expected_line(model)}; wrote {args.out}")
