"""Writes tests/data/kernel_golden.npz: the compiled simulator's voltages for two small records x
every element alone and all of them together, with the rational OCV and a table (where the
element allows it) and under the paper's load, whole, thinned (the held-current shortcut) and
traced, with the traced pass's traces; all stored as numbers (about 640 kB), so a failure shows by
how much, and with the machine they were made on (``machine``). ``tests/unit/test_kernel_golden.py``
holds the generated loop to them: bit for bit on that machine, to a relative 1e-12 elsewhere.

Run it on the checkout whose voltages are the reference (issue 39: the hand-written loop, as at
a81259e; bda8ec0 has that simulator and this script's cases):

    git worktree add /tmp/ref39 bda8ec0
    PYTHONPATH=/tmp/ref39/src python tests/data/make_kernel_golden.py tests/data/kernel_golden.npz

The file was first recorded on a81259e's machine with the thinned and traced passes as digests;
it was recorded again on a znver3 machine (glibc 2.36, numba 0.68.1) when the digests failed on
that CPU in 30 of 336 cases and the whole pass differed by 1 ULP in 14 of 112 (last bits from
the C library's exp, log and pow; the generated loop gave the hand-written loop's values bit for
bit there too).
"""

from __future__ import annotations

import hashlib
import sys

import numpy as np
import pandas as pd

from avoa_pipeline.model import ecm, elements

N = 96
ACTIVE = {  # one non-neutral value per parameter, inside its limits (internal coordinates)
    "r2": 0.012, "ltau2": 2.3, "r3": 0.006, "ltau3": 3.1, "klow": 1.5, "lsig": -1.1,
    "kd": 0.02, "ltaud": 1.9, "hm": 0.02, "lgamma": 1.7, "h0": 0.3, "bvg": 0.4, "th0": 3000.0,
    "th1": 2500.0, "u0": 0.01, "u1": -0.02, "u2": 0.015, "u3": -0.01, "ioff": 0.05,
    "voff": 0.004, "eta": 0.97, "r0u0": 0.2, "r0u1": -0.3, "r0u2": 0.1, "r0u3": 0.05,
    "r0u4": -0.1, "r1u0": -0.2, "r1u1": 0.25, "r1u2": -0.1, "r1u3": 0.05, "r1u4": 0.1,
    "rho": 0.3, "thbv": 2000.0, "thtau": 1500.0, "dudt": 3e-4, "kq": 0.01,
}  # fmt: skip
BASE = {"vnom_v": 4.1, "beta": 0.5, "capacity_ah": 0.05, "soc0": 0.8, "r0_ohm": 0.03,
        "r1_ohm": 0.01, "tau1_s": 12.0}  # fmt: skip


def records() -> dict[str, ecm.Record]:
    """A uniform 1 s record of held steps and rests (temperature moving), and an uneven one."""
    rng = np.random.default_rng(39)
    cur = np.repeat(rng.choice([0.0, 0.0, 1.0, 2.0, -1.0, -0.5], N // 8), 8)
    t = np.arange(N, dtype=float)
    temp = 25.0 + 4.0 * np.sin(t / 17.0)
    temp[cur == 0.0] = np.round(temp[cur == 0.0], 1)
    uniform = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": 3.7,
                            "temperature_c": temp})  # fmt: skip
    t2 = np.cumsum(rng.uniform(0.5, 3.0, N))
    uneven = pd.DataFrame({"time_s": t2, "current_a": cur[::-1].copy(), "voltage_v": 3.7,
                           "temperature_c": 20.0 + 0.05 * t2})  # fmt: skip
    return {"uniform": ecm.Record.from_frame(uniform), "uneven": ecm.Record.from_frame(uneven)}


def mixes() -> dict[str, tuple[str, ...]]:
    out = {}
    for e in ecm.EFFECTS:
        req = elements.get(e).requires
        out[e] = (req, e) if req else (e,)
    core = tuple(e for e in ecm.EFFECTS if elements.get(e).compiled == "core")
    out["all_core"] = core
    out["all"] = tuple(ecm.EFFECTS)
    return {"base": (), **out}


def cases():
    """(name, record, rows X, table or None, load_ohm or None)."""
    soc = np.linspace(0, 1, 11)
    table = ecm.OcvTable.from_points(soc, 3.2 + 0.9 * soc**0.8)
    for rname, rec in records().items():
        for mname, effects in mixes().items():
            x = ecm.vector(BASE)
            for e in effects:
                for n in elements.get(e).params:
                    x[ecm.IDX[n]] = ACTIVE[n]
            X = np.repeat(x[None, :], 2, axis=0)
            X[1, ecm.IDX["r0"]] *= 1.3  # rows differ, as in a Jacobian
            X[1, ecm.IDX["soc0"]] = 0.35
            for ocv, tab in (("rational", None), ("table", table)):
                if any(elements.get(e).conflict(tab is not None, False) for e in effects):
                    continue
                yield f"{rname}/{mname}/{ocv}", rec, X, tab, None
            if not any(elements.get(e).conflict(False, True) for e in effects):
                yield f"{rname}/{mname}/load", rec, X, None, 8.0


def machine() -> str:
    """What decides a compiled loop's last bits on this machine: the CPU numba compiles for and
    its features (the instructions LLVM may pick), the C library (glibc picks its exp, log and
    pow by the CPU's features at run time) and numba's version."""
    import platform

    import llvmlite.binding as llvm
    import numba

    features = hashlib.sha256(llvm.get_host_cpu_features().flatten().encode()).hexdigest()[:16]
    return (f"{llvm.get_host_cpu_name()} features {features}, "
            f"{'-'.join(platform.libc_ver())}, numba {numba.__version__}")  # fmt: skip


def simulate_all() -> dict[str, np.ndarray]:
    """By case: the whole pass's voltages, the thinned pass's (the held-current shortcut), the
    traced pass's and its traces."""
    knots = ecm.Knots(0.1, 0.15)
    idx = np.arange(7, N, 13)
    out = {}
    for name, rec, X, tab, load in cases():
        out[f"{name}/whole"] = ecm.simulate_rows(rec, X, knots, tab, load)
        out[f"{name}/thinned"] = ecm.simulate_rows(rec, X, knots, tab, load, idx=idx)
        v, tr = ecm.simulate_rows(rec, X, knots, tab, load, traces=True)
        out[f"{name}/traced"], out[f"{name}/traces"] = v, tr
    return out


if __name__ == "__main__":
    np.savez_compressed(sys.argv[1], **simulate_all(), machine=np.array(machine()))
