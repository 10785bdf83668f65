"""Cost of the model library's compiled simulator (``model.ecm.simulate_rows``) per sample and
parameter row, for configurations without and with the elements of issue 19 (R0/R1 by SOC,
a charge-dependent R0, an Arrhenius exchange current).

Run: .venv/bin/python benchmarks/bench_simulator.py [--samples 100000] [--rows 12] [--repeat 7]

Prints the ns per sample-row of each configuration (the minimum of ``--repeat`` timings of one call
each, in the thread's CPU time: the simulator runs in the calling thread, and on a shared machine
wall time also counts the spells the process waits for a core: at a load of 10 on 2 cores, the same
checkout's wall-time minima moved 1.5-2x between runs, its CPU-time ones 5 %); with ``--against
DIR`` it also runs the same on the package in DIR (another checkout, e.g. ``git worktree add
/tmp/before <commit>``) and prints the ratio now / before for the configurations both know: issue
19's goal was ≤ 1.2 for models without its elements, issue 39's (the loop generated from the
elements' statements) ≤ 1.05 for every mix. ``--every`` adds each element alone (with what it
requires; rational OCV) and all of them together. ``--interleave N``: the two checkouts measured N
times in turn, each ratio from the minima over all rounds (on a shared, noisy machine a slow spell
then hits both).
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
ACTIVE = {"second_rc": {"r2": 0.01}, "third_rc": {"r3": 0.005}, "soc_resistance": {"klow": 1.0},
          "diffusion": {"kd": 0.02}, "hysteresis": {"hm": 0.01}, "butler_volmer": {"bvg": 0.5},
          "thermal": {"th0": 3000.0, "th1": 3000.0}, "ocv_shape": {"u0": 0.01},
          "current_offset": {"ioff": 0.01}, "voltage_offset": {"voff": 0.003},
          "coulombic_efficiency": {"eta": 0.98}, "r0_soc": {"r0u0": 0.2}, "r1_soc": {"r1u0": 0.2},
          "r0_charge": {"rho": 0.2}, "bv_arrhenius": {"thbv": 2000.0},
          "thermal_tau": {"thtau": 1500.0}, "entropic": {"dudt": 3e-4},
          "capacity_temperature": {"kq": 0.01}}  # fmt: skip
"""A non-neutral value for each element (internal coordinates)."""


def every_mix() -> dict[str, tuple[tuple[str, ...], bool]]:
    """Each element alone (after the one it requires) and all of them, rational OCV."""
    from avoa_pipeline.model import ecm

    out = {}
    for e in ecm.EFFECTS:
        req = ecm.REQUIRES.get(e)
        out[f"{e} alone"] = ((req, e) if req else (e,), False)
    out["every element"] = (tuple(ecm.EFFECTS), False)
    return out


def measure(samples: int, rows: int, repeat: int, every: bool = False) -> dict[str, float]:
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
    out = {}
    for name, (effects, use_table) in {**CONFIGS, **(every_mix() if every else {})}.items():
        if any(e not in ecm.EFFECTS for e in effects):
            continue
        x = ecm.vector({"vnom_v": 4.1, "beta": 0.5, "capacity_ah": 20.0, "soc0": 0.9,
                        "r0_ohm": 0.03, "r1_ohm": 0.01, "tau1_s": 30.0})  # fmt: skip
        for e in effects:
            for k, v in ACTIVE[e].items():
                x[ecm.IDX[k]] = v
        X = np.repeat(x[None, :], rows, axis=0)
        X[:, ecm.IDX["r0"]] *= np.linspace(1.0, 1.01, rows)  # rows differ, as in a Jacobian
        tab = table if use_table else None
        ecm.simulate_rows(rec, X, ecm.Knots(0.0, 0.2), tab)  # compile / load the cache
        best = np.inf
        for _ in range(repeat):
            start = time.thread_time()
            ecm.simulate_rows(rec, X, ecm.Knots(0.0, 0.2), tab)
            best = min(best, time.thread_time() - start)
        out[name] = 1e9 * best / (samples * rows)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--rows", type=int, default=12)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--against", default=None, help="another checkout's folder (its src/)")
    ap.add_argument("--every", action="store_true", help="also each element alone, and all")
    ap.add_argument("--interleave", type=int, default=1, help="rounds of now and before in turn")
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.json:
        print(json.dumps(measure(args.samples, args.rows, args.repeat, args.every)))
        return 0

    def run(src: str) -> dict[str, float]:  # one round in a fresh process on checkout ``src``
        env = {**os.environ, "PYTHONPATH": src}
        cmd = [sys.executable, __file__, "--samples", str(args.samples), "--rows",
               str(args.rows), "--repeat", str(args.repeat), "--json",
               *(["--every"] if args.every else [])]  # fmt: skip
        res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
        return json.loads(res.stdout.strip().splitlines()[-1])

    here = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")
    now, before = {}, {}
    for _ in range(max(args.interleave, 1)):
        for into, src in ((now, here), (before, os.path.join(args.against or "", "src"))):
            if src == here or args.against:
                for name, ns in run(src).items():
                    into[name] = min(into.get(name, float("inf")), ns)
    rounds = f", {args.interleave} rounds interleaved" if args.interleave > 1 else ""
    print(f"{args.samples} samples x {args.rows} rows, best of {args.repeat}{rounds}; "
          "ns per sample-row")  # fmt: skip
    for name, ns in now.items():
        line = f"  {name:42s} {ns:7.2f}"
        if name in before:
            line += f"   before {before[name]:7.2f}   ratio {ns / before[name]:.3f}"
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
