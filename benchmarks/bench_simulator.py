"""Cost of the model library's compiled simulator (``model.ecm.simulate_rows``) per sample and
parameter row, for configurations without and with the elements of issue 19 (R0/R1 by SOC,
a charge-dependent R0, an Arrhenius exchange current).

Run: .venv/bin/python benchmarks/bench_simulator.py [--samples 100000] [--rows 12] [--repeat 7]

Prints the median ns per sample-row of each configuration (the minimum of ``--repeat`` timings
of one call each); with ``--against DIR`` it also runs the same on the package in DIR (another
checkout, e.g. ``git worktree add /tmp/before <commit>``) and prints the ratio now / before for
the configurations both know: the issue's goal is ≤ 1.2 for models without the new elements.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

CONFIGS = {
    "base (rational)": ((), False),
    "base (table)": ((), True),
    "second_rc+soc_resistance (table)": (("second_rc", "soc_resistance"), True),
    "hysteresis+thermal+butler_volmer": (("hysteresis", "thermal", "butler_volmer"), False),
    "r0_soc+r1_soc (table)": (("r0_soc", "r1_soc"), True),
    "r0_charge+butler_volmer+bv_arrhenius": (("r0_charge", "butler_volmer", "bv_arrhenius"),
                                             False),
}  # fmt: skip


def measure(samples: int, rows: int, repeat: int) -> dict[str, float]:
    import numpy as np
    import pandas as pd

    from avoa_pipeline.model import ecm

    rng = np.random.default_rng(0)
    t = np.arange(samples, dtype=float)
    cur = np.repeat(rng.choice([0.0, 1.0, 2.0, -1.0], samples // 20 + 1), 20)[:samples]
    frame = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": 3.7,
                          "temperature_c": 25.0 + 3.0 * np.sin(t / 3000.0)})  # fmt: skip
    rec = ecm.Record.from_frame(frame)
    table = ecm.OcvTable.from_points(np.linspace(0, 1, 11), 3.2 + 0.9 * np.linspace(0, 1, 11))
    active = {"second_rc": {"r2": 0.01}, "soc_resistance": {"klow": 1.0},
              "hysteresis": {"hm": 0.01}, "thermal": {"th0": 3000.0, "th1": 3000.0},
              "butler_volmer": {"bvg": 0.5}, "r0_soc": {"r0u0": 0.2}, "r1_soc": {"r1u0": 0.2},
              "r0_charge": {"rho": 0.2}, "bv_arrhenius": {"thbv": 2000.0}}  # fmt: skip
    out = {}
    for name, (effects, use_table) in CONFIGS.items():
        if any(e not in ecm.EFFECTS for e in effects):
            continue
        x = ecm.vector({"vnom_v": 4.1, "beta": 0.5, "capacity_ah": 20.0, "soc0": 0.9,
                        "r0_ohm": 0.03, "r1_ohm": 0.01, "tau1_s": 30.0})  # fmt: skip
        for e in effects:
            for k, v in active[e].items():
                x[ecm.IDX[k]] = v
        X = np.repeat(x[None, :], rows, axis=0)
        X[:, ecm.IDX["r0"]] *= np.linspace(1.0, 1.01, rows)  # rows differ, as in a Jacobian
        tab = table if use_table else None
        ecm.simulate_rows(rec, X, ecm.Knots(0.0, 0.2), tab)  # compile / load the cache
        best = np.inf
        for _ in range(repeat):
            start = time.perf_counter()
            ecm.simulate_rows(rec, X, ecm.Knots(0.0, 0.2), tab)
            best = min(best, time.perf_counter() - start)
        out[name] = 1e9 * best / (samples * rows)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--rows", type=int, default=12)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--against", default=None, help="another checkout's folder (its src/)")
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    now = measure(args.samples, args.rows, args.repeat)
    if args.json:
        print(json.dumps(now))
        return 0
    before = {}
    if args.against:
        env = {**os.environ, "PYTHONPATH": os.path.join(args.against, "src")}
        cmd = [sys.executable, __file__, "--samples", str(args.samples), "--rows",
               str(args.rows), "--repeat", str(args.repeat), "--json"]  # fmt: skip
        res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
        before = json.loads(res.stdout.strip().splitlines()[-1])
    print(f"{args.samples} samples x {args.rows} rows, best of {args.repeat}; ns per sample-row")
    for name, ns in now.items():
        line = f"  {name:42s} {ns:7.2f}"
        if name in before:
            line += f"   before {before[name]:7.2f}   ratio {ns / before[name]:.3f}"
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
