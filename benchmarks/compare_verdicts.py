"""Two sets of diagnoses compared decision by decision, not number by number.

    .venv/bin/python benchmarks/compare_verdicts.py THIS/results/gap OTHER/results/gap
    .venv/bin/python benchmarks/compare_verdicts.py OUT/this OUT/other  # compare_diagnoses --out

For a change that rounds otherwise (issue 42: rests merged in a thinned simulation), the
numbers of every diagnosis move a little and ``compare_diagnoses.py`` (exact) reports them all;
what must hold is each decision. For every diagnosis JSON under THIS (a ``results/gap`` tree's
``diagnoses/**.json``, or ``compare_diagnoses.py``'s ``*/diagnosis.json``) with a counterpart
under OTHER, :func:`decisions` takes the selected model, the ladder, pruning, the undecided
elements, the bounds hit, the model handed over, each hand-over candidate's eligibility (and,
apart, the reasons an ineligible one gives) and which candidates pay; it prints each diagnosis
whose decisions differ, then the count, the hand-over's held-out RMSE against OTHER's, and,
for ``results/gap`` trees, whether the check's tables (``confusion.csv`` ...) are equal and
which ``records.csv`` rows changed verdict, ladder or rightness. Exits 1 if any decision
differs.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pandas as pd

TABLES = ("confusion.csv", "target.csv", "detection_limit.csv", "accuracy.csv", "pairs.csv")
REASONS = "why_not (reasons only)"


def decisions(d: dict) -> dict:
    """What a diagnosis decided (names and flags; no number that rounding moves)."""
    h = d["handed_over"]
    return {
        "verdict": (d.get("verdict") or {}).get("effect"),
        "selected": d["selected"]["name"],
        "undecided": [u.get("effect") for u in d.get("undecided") or []],
        "pruned": [p.get("effect") for p in d.get("pruned") or []],
        "at_bounds": [(b.get("parameter"), b.get("bound")) for b in d.get("at_bounds") or []],
        "handed": (h["name"], h["candidate"], h["effects"]),
        "eligible": [(c["name"], c["eligible"]) for c in h["candidates"]],
        REASONS: [_heads(c["why_not"]) for c in h["candidates"]],
        "elements": [(e["effect"], e["handed_over"]) for e in h.get("verdict_elements", [])],
        "ladder": [r["effect"] for r in d.get("ladder", [])],
        "candidates": [(c.get("effect"), c.get("pays")) for c in d.get("candidates", [])],
    }


def _heads(reasons: list[str]) -> list[str]:
    """Each reason's element and kind, without its numbers ("second_rc: r2_ohm")."""
    return [":".join(w.split(":")[:2]).split(" = ")[0] for w in reasons]


def pairs(this: Path, other: Path) -> list[tuple[str, dict, dict]]:
    """(name, this diagnosis, other diagnosis) for every diagnosis found under both."""
    out = []
    for fa in sorted(this.rglob("*.json")):
        fb = other / fa.relative_to(this)
        if fa.name == "model.json" or not fb.exists():
            continue
        da = json.loads(fa.read_text())
        if isinstance(da, dict) and "handed_over" in da:
            out.append((str(fa.relative_to(this)), da, json.loads(fb.read_text())))
    return out


def tables(this: Path, other: Path) -> None:
    for name in TABLES:
        if (this / name).exists() and (other / name).exists():
            equal = pd.read_csv(this / name).equals(pd.read_csv(other / name))
            print(f"{name}: {'equal' if equal else 'differs'}")
    if (this / "records.csv").exists() and (other / "records.csv").exists():
        cols = ["name", "profile", "replicate", "verdict", "ladder", "right"]
        a, b = (pd.read_csv(d / "records.csv")[cols] for d in (this, other))
        m = a.merge(b, on=cols[:3], suffixes=("", "_other")).fillna("")
        moved = m[(m.verdict != m.verdict_other) | (m.ladder != m.ladder_other)
                  | (m.right != m.right_other)]  # fmt: skip
        print(f"records.csv: {len(m)} rows, {len(moved)} with another verdict, ladder or rightness")
        if len(moved):
            print(moved.to_string(index=False))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("this", type=Path)
    p.add_argument("other", type=Path)
    a = p.parse_args(argv)
    same = reasons = 0
    rmse = {"within 1 %": 0, "lower here": 0, "higher here": 0}
    found = pairs(a.this, a.other)
    for name, da, db in found:
        sa, sb = decisions(da), decisions(db)
        keys = [k for k in sa if sa[k] != sb[k]]
        ra, rb = (d["handed_over"]["heldout_rmse_mv"] for d in (da, db))
        rmse["within 1 %" if abs(ra - rb) <= 0.01 * rb else
             "lower here" if ra < rb else "higher here"] += 1  # fmt: skip
        if keys in ([], [REASONS]):
            same += 1
            reasons += bool(keys)
            continue
        print(f"{name}: {', '.join(keys)}; hand-over {ra:.3f} mV here, {rb:.3f} there")
        for k in keys:
            print(f"    here : {json.dumps(sa[k])[:300]}\n    there: {json.dumps(sb[k])[:300]}")
    print(
        f"{len(found)} diagnoses: {same} with the same decisions ({reasons} of them with another "
        f"reason for an ineligible hand-over candidate), {len(found) - same} differ; the "
        f"hand-over's held-out RMSE: " + ", ".join(f"{k} {v}" for k, v in rmse.items())
    )
    tables(a.this, a.other)
    return 0 if same == len(found) else 1


if __name__ == "__main__":
    sys.exit(main())
