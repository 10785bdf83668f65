"""Command line: ``python -m avoa_pipeline {fit,generate,recovery,diagnose} ...``.

Expected errors (bad arguments, config or data) print one line on stderr and exit 2 without a
traceback, and write no output file.
"""

from __future__ import annotations

import argparse
import os
import sys

os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")
# one BLAS thread (set before numpy loads): scipy's least_squares and L-BFGS-B call BLAS on small
# matrices, and spinning BLAS threads on a busy 2-core machine made a diagnosis up to 30x slower
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

from .errors import UserError
from .names import ALGORITHMS


class Parser(argparse.ArgumentParser):
    """argparse with usage errors as one-line :class:`UserError` (exit 2, no usage block)."""

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

    d = sub.add_parser("diagnose", help="sim-to-real gap diagnosis of a measured record")
    d.add_argument(
        "data", help="CSV: time_s, current_a (A, + discharge), voltage_v[, temperature_c]"
    )
    d.add_argument("--out", required=True, help="folder for diagnosis.json and diagnosis.png")
    d.add_argument("--capacity-ah", type=_float("capacity-ah"), default=None)
    d.add_argument("--soc0", type=_float("soc0"), default=None, help="initial SOC in [0, 1]")
    return p


def _float(name: str):
    def parse(text: str) -> float:
        try:
            return float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None

    return parse


def cmd_fit(args) -> None:
    import numba

    from . import config, fit, problem
    from .io import write_json

    cfg = config.load(args.config)
    budget = fit.budget_from(cfg, args.pop_size, args.iterations, args.max_nfe)
    if args.threads is not None:
        if args.threads < 1:
            raise UserError(f"--threads must be positive, got {args.threads}")
        numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))
    prob = problem.build(cfg, args.scenario, args.case, args.data, noise=not args.noise_free)
    record = fit.run(cfg, prob, args.algorithm, args.seed, budget)
    write_json(record, args.out)


def cmd_generate(args) -> None:
    from . import config, synthetic

    cfg = config.load(args.config)
    synthetic.write(
        synthetic.generate(cfg, args.scenario, args.case, noise=not args.noise_free), args.out
    )


def cmd_recovery(args) -> None:
    from pathlib import Path

    from . import config, fit, recovery
    from .io import atomic_path

    cfg = config.load(args.config)
    if args.seeds < 1:
        raise UserError(f"--seeds must be positive, got {args.seeds}")
    budget = fit.budget_from(cfg, iterations=args.iterations)
    runs = recovery.run(cfg, args.scenario, args.case, range(1, args.seeds + 1), budget)
    table = recovery.summary(runs)
    md = recovery.to_markdown(table)
    with atomic_path(args.out) as tmp:
        runs.to_csv(tmp, index=False)
    with atomic_path(Path(args.out).with_suffix(".md")) as tmp:
        tmp.write_text(md + "\n")
    print(md)


def cmd_diagnose(args) -> None:
    import json
    from pathlib import Path

    from .gap import diagnose, figure
    from .io import atomic_path

    frame = diagnose.read_record(args.data)
    report, arrays = diagnose.run(frame, args.capacity_ah, args.soc0, source=str(args.data))
    text = json.dumps(report, indent=1, allow_nan=False) + "\n"
    out = Path(args.out)
    # both files or neither: the figure is drawn into its temporary first; a failure there
    # leaves no JSON either
    with atomic_path(out / "diagnosis.png") as png, atomic_path(out / "diagnosis.json") as js:
        figure.render(report, arrays, png)
        js.write_text(text)
    v = report["verdict"]
    print(
        f"{args.data}: verdict {v['effect']}"
        + (f" (held-out shrink {v['shrink']:.1%})" if v["effect"] != "none" else "")
        + f"; wrote {out / 'diagnosis.json'}, {out / 'diagnosis.png'}"
    )


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(argv)
        commands = {
            "fit": cmd_fit,
            "generate": cmd_generate,
            "recovery": cmd_recovery,
            "diagnose": cmd_diagnose,
        }
        commands[args.command](args)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0
