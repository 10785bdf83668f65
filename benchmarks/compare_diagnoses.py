"""The five reference diagnoses, run by two checkouts and compared, timings aside.

    .venv/bin/python benchmarks/compare_diagnoses.py --against OTHER_CHECKOUT \
        --gap-data results/gap/data --panasonic results/real/canonical [--out DIR] [--only NAME]

A refactor of the model library, the fits or the diagnosis must leave every diagnosis as it was.
This runs ``python -m avoa_pipeline diagnose`` on the same five inputs with this checkout's
``src`` and with OTHER_CHECKOUT's ``src`` (the same interpreter), then compares ``diagnosis.json``
(every key but the clocks: ``wall_s`` and any key ending in ``_s`` under ``timing``) and
``model.json`` exactly (JSON floats round-trip, so equal numbers are equal bits), or with
``--rtol`` floats within a relative difference (a change that rounds otherwise: every string,
flag and count still exactly, so a verdict that flips shows). The five: four
withheld-effect records (a workflow run's ``results/gap/data``: pulse hysteresis, pulse second RC,
drive thermal, drive nothing withheld) and Panasonic 25 °C (the training cycle and HPPC with the
C/20 test as ``--ocv`` and the unseen cycles as ``--validate``, as ``rules/real.smk`` runs it).
Prints one line per diagnosis; exits 1 if any differs or fails.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
WITHHELD = ("pulse/r1/hysteresis_m0_n0", "pulse/r1/second_rc_m0_n0", "drive/r1/thermal_m0_n0",
            "drive/r1/none_m0_n0")  # fmt: skip
PANASONIC_25 = ("la92", "hppc")  # the training cycle (config.yaml) and the HPPC test
PANASONIC_UNSEEN = ("cycle_1", "hwfet", "us06")


def cases(gap: Path, pan: Path) -> dict[str, list[str]]:
    """Each reference diagnosis's arguments (before ``--out``)."""
    out = {name.replace("/", "_"): [str(gap / f"{name}.csv")] for name in WITHHELD}
    p = lambda c: str(pan / f"panasonic_25degC_{c}.csv")  # noqa: E731
    out["panasonic_25degC"] = [*(p(c) for c in PANASONIC_25), "--ocv", p("ocv_c20"),
                               "--validate", *(p(c) for c in PANASONIC_UNSEEN)]  # fmt: skip
    return out


def run(src: Path, args: list[str], out: Path) -> float:
    env = dict(os.environ, PYTHONPATH=str(src), PYBAMM_DISABLE_TELEMETRY="true")
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "avoa_pipeline", "diagnose", *args, "--out",
                           str(out)], env=env, capture_output=True, text=True)  # fmt: skip
    if proc.returncode:
        raise RuntimeError(f"{src}: exit {proc.returncode}: {proc.stderr.strip()[-400:]}")
    return time.perf_counter() - t


def _clockless(obj, key: str = ""):
    if isinstance(obj, dict):
        return {k: _clockless(v, k) for k, v in obj.items()
                if k != "wall_s" and not (key == "timing" and k.endswith("_s"))}  # fmt: skip
    if isinstance(obj, list):
        return [_clockless(v) for v in obj]
    return obj


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def differences(a, b, path: str = "", rtol: float = 0.0, worst: list | None = None) -> list[str]:
    """Paths (JSON pointers) where ``a`` and ``b`` differ (the first 20); with ``rtol``, two
    floats within that relative difference count as equal, and ``worst`` (a one-element list)
    keeps the largest relative difference met."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = [f"{path}/{k}: only in one" for k in sorted(set(a) ^ set(b))]
        for k in sorted(set(a) & set(b)):
            out += differences(a[k], b[k], f"{path}/{k}", rtol, worst)
        return out[:20]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        pairs = enumerate(zip(a, b, strict=True))
        return [d for j, (x, y) in pairs
                for d in differences(x, y, f"{path}/{j}", rtol, worst)][:20]  # fmt: skip
    if rtol and _number(a) and _number(b) and (isinstance(a, float) or isinstance(b, float)):
        rel = abs(a - b) / max(abs(a), abs(b), 1e-300)
        if worst is not None and a != b:
            worst[0] = max(worst[0], (rel, path))
        return [] if rel <= rtol else [path or "/"]
    return [] if a == b else [path or "/"]


def compare(out_a: Path, out_b: Path, rtol: float = 0.0) -> tuple[list[str], tuple]:
    """Paths that differ in the two outputs, and the largest relative difference of floats
    (with ``rtol``; else (0, ""))."""
    diffs, worst = [], [(0.0, "")]
    for name in ("diagnosis.json", "model.json"):
        a, b = (_clockless(json.loads((d / name).read_text())) for d in (out_a, out_b))
        diffs += [f"{name}{p}" for p in differences(a, b, "", rtol, worst)]
    return diffs, worst[0]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--against", type=Path, required=True, help="the other checkout")
    p.add_argument("--gap-data", type=Path, required=True)
    p.add_argument("--panasonic", type=Path, required=True)
    p.add_argument("--out", type=Path, default=Path("/tmp/compare_diagnoses"))
    p.add_argument("--only", nargs="*", help="these reference diagnoses only")
    p.add_argument("--rtol", type=float, default=0.0,
                   help="floats within this relative difference count as equal (default 0: "
                        "every number bit for bit); the largest one met is printed")  # fmt: skip
    p.add_argument(
        "--keep-other",
        action="store_true",
        help="reuse the other checkout's outputs where --out holds them",
    )
    a = p.parse_args(argv)
    bad = 0
    for name, args in cases(a.gap_data, a.panasonic).items():
        if a.only and name not in a.only:
            continue
        outs = {side: a.out / side / name for side in ("this", "other")}
        try:
            secs = {side: (0.0 if side == "other" and a.keep_other
                           and (outs[side] / "model.json").exists()
                           else run(src / "src", args, outs[side]))
                    for side, src in (("this", HERE), ("other", a.against))}  # fmt: skip
            diffs, worst = compare(outs["this"], outs["other"], a.rtol)
        except (RuntimeError, OSError, ValueError) as e:
            print(f"{name}: failed: {e}")
            bad += 1
            continue
        bad += bool(diffs)
        near = f", floats within {worst[0]:.1e} ({worst[1]})" if a.rtol and worst[0] else ""
        print(f"{name}: {'same' if not diffs else 'differs: ' + '; '.join(diffs)}{near} "
              f"({secs['this']:.0f} s here, {secs['other']:.0f} s there)")  # fmt: skip
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
