"""What a screen before a candidate's refinement or fit check would save, and what it would miss.

    .venv/bin/python benchmarks/bench_screen.py --out DIR RECORD.csv [RECORD.csv ...]
    .venv/bin/python benchmarks/bench_screen.py --out DIR            # the table of DIR only

Each record (a canonical CSV, as the withheld-effect check diagnoses it: ``gap.diagnose`` of the
CSV alone) is diagnosed once with every full-data fit of the selection logged by stage, into
``DIR/<record>.jsonl`` (a record already there is not run again). A fit is made by the same
functions in the same order as ``fitting.best_of``: the multi-start trials on the thinned
samples (``fitting.best_start``), the refinement on the fitted samples, the fit check; logged
are the cost on the fitted samples after each stage (the trials' best evaluated there) and each
stage's thread CPU time. Run it with one core per process (``taskset``), so that a fit's CPU
time is its own.

Then it prints, over every logged record: the candidates (a fit adding one element to the fit
logged before it with the other elements), how many fail the BIC criterion after the check
(``selection.BIC_MAX``: not held out, so their refinement and check decide nothing unless they
take the candidate below it), each stage's time for failing and passing candidates, and for
each screen rule the candidates it would stop, those of them that the later stages took below
``BIC_MAX`` (misses: a decision it would change), and the time it would save. Nothing is
asserted; the rules are the ones docs/benchmarks.md ("A screen before the refinement or the
check") measured.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from avoa_pipeline.model import fitting
from avoa_pipeline.selection import BIC_MAX, bic


def _logged_best_of(out):
    """``fitting.best_of`` stage by stage, each full-data checked fit logged to ``out``."""
    best_of = fitting.best_of

    def logged(recs, st, starts, masks=None, max_nfev_coarse=60, max_nfev=200, check=True,
               taus=None):  # fmt: skip
        if masks is not None or not check:  # held-out refits and unchecked fits: as they are
            return best_of(recs, st, starts, masks, max_nfev_coarse, max_nfev, check, taus)
        idx = fitting.indices(recs, None, fitting.MAX_FIT_POINTS)
        t0 = time.thread_time()
        c_trial = None
        x0 = starts[0]
        if len(starts) > 1:
            x0 = fitting.best_start(recs, st, starts, None, max_nfev_coarse).X
            r = fitting.Problem(recs, st, x0, idx).residuals(st.z_of(x0))
            c_trial = 0.5 * float(r @ r)
        t1 = time.thread_time()
        fit = fitting.fit_structure(recs, st, x0, idx, max_nfev=max_nfev)
        t2 = time.thread_time()
        res = fitting.check_fit(recs, st, fit, None, max_nfev_coarse, max_nfev, taus)
        t3 = time.thread_time()
        out.write(json.dumps({
            "effects": list(st.effects), "k": int(st.k), "n": int(sum(i.size for i in idx)),
            "c_trial": c_trial, "c_refined": fit.cost_fit, "c_checked": res.cost_fit,
            "t_trials": t1 - t0, "t_refine": t2 - t1, "t_check": t3 - t2,
        }) + "\n")  # fmt: skip
        out.flush()
        return res

    return logged


def run(csv: Path, path: Path) -> None:
    from avoa_pipeline.gap.diagnose import diagnose
    from avoa_pipeline.inputs import read_record

    best_of = fitting.best_of
    t = time.perf_counter()
    with path.open("w") as out:
        fitting.best_of = _logged_best_of(out)
        try:
            result = diagnose(read_record(str(csv)))
        finally:
            fitting.best_of = best_of
        out.write(json.dumps({"done": True, "wall_s": time.perf_counter() - t,
                              "verdict": result["verdict"]["effect"]}) + "\n")  # fmt: skip


def candidates(path: Path) -> tuple[list[dict], float | None]:
    """The logged candidates of one record (each with ΔBIC after every stage against its
    reference's checked fit) and the diagnosis's wall time (None if it did not finish)."""
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    done = [x for x in lines if x.get("done")]
    fits = [x for x in lines if "effects" in x]
    rows = []
    for j, e in enumerate(fits):
        mine = set(e["effects"])
        refs = [p for p in fits[:j]
                if set(p["effects"]) < mine and len(p["effects"]) == len(mine) - 1]  # fmt: skip
        if not mine or not refs:
            continue
        ref, n = refs[-1], e["n"]

        def dbic(cost, e=e, ref=ref, n=n):
            return bic(2 * cost, n, e["k"]) - bic(2 * ref["c_checked"], n, ref["k"])

        rows.append({
            "record": path.stem, "effects": "+".join(e["effects"]),
            "multi": e["c_trial"] is not None,
            "trial_le_ref": e["c_trial"] is not None and e["c_trial"] <= ref["c_checked"],
            "refined_le_ref": e["c_refined"] <= ref["c_checked"],
            "d_trial": None if e["c_trial"] is None else dbic(e["c_trial"]),
            "d_refined": dbic(e["c_refined"]), "d_checked": dbic(e["c_checked"]),
            "t_trials": e["t_trials"], "t_refine": e["t_refine"], "t_check": e["t_check"],
        })  # fmt: skip
    return rows, (done[0]["wall_s"] if done else None)


# the screens measured: (name, the stage it stops before, which candidates it stops)
RULES = (
    (
        "trials fail ΔBIC and fit no worse than the reference",
        "refinement",
        lambda r: r["multi"] and r["trial_le_ref"] and r["d_trial"] >= BIC_MAX,
    ),
    ("trials fail ΔBIC", "refinement", lambda r: r["multi"] and r["d_trial"] >= BIC_MAX),
    (
        "refined fit fails ΔBIC, several starts, no worse than the reference",
        "check",
        lambda r: r["multi"] and r["refined_le_ref"] and r["d_refined"] >= BIC_MAX,
    ),
    (
        "refined fit fails ΔBIC, several starts",
        "check",
        lambda r: r["multi"] and r["d_refined"] >= BIC_MAX,
    ),
    ("refined fit fails ΔBIC", "check", lambda r: r["d_refined"] >= BIC_MAX),
)


def report(out_dir: Path) -> None:
    rows, walls = [], []
    for path in sorted(out_dir.glob("*.jsonl")):
        mine, wall = candidates(path)
        if wall is not None:
            rows += mine
            walls.append(wall)
    if not rows:
        print(f"no finished record in {out_dir}")
        return
    fail = [r for r in rows if r["d_checked"] >= BIC_MAX]
    total = sum(walls)
    print(f"{len(walls)} diagnoses, {total:.0f} s wall in all; {len(rows)} candidates, "
          f"{len(fail)} fail ΔBIC < {BIC_MAX:g} after the check")  # fmt: skip
    passing = [r for r in rows if r["d_checked"] < BIC_MAX]
    for name, sel in (("failing", fail), ("passing", passing)):
        t = {k: sum(r[k] for r in sel) for k in ("t_trials", "t_refine", "t_check")}
        share = sum(t.values()) / total
        print(f"  {name}: trials {t['t_trials']:.0f} s, refinement {t['t_refine']:.0f} s, "
              f"check {t['t_check']:.0f} s ({share:.0%} of the wall)")  # fmt: skip
    for name, stage, rule in RULES:
        hit = [r for r in rows if rule(r)]
        miss = [r for r in hit if r["d_checked"] < BIC_MAX]
        keys = ("t_refine", "t_check") if stage == "refinement" else ("t_check",)
        saved = sum(r[k] for r in hit for k in keys)
        print(f"screen before the {stage}: {name}: stops {len(hit)}, misses {len(miss)}, "
              f"saves {saved:.0f} s ({saved / total:.0%} of the wall)")  # fmt: skip
        for r in miss:
            trial = "-" if r["d_trial"] is None else f"{r['d_trial']:.1f}"
            print(f"  miss: {r['record']} {r['effects']}: ΔBIC trials {trial}, refined "
                  f"{r['d_refined']:.1f}, checked {r['d_checked']:.1f}")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("records", nargs="*", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    for csv in a.records:
        path = a.out / ("-".join(csv.parts[-3:-1]) + f"-{csv.stem}.jsonl")
        if path.is_file() and '"done"' in path.read_text():
            continue
        run(csv, path)
    report(a.out)


if __name__ == "__main__":
    main()
