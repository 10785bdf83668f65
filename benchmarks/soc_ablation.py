"""Which part of the SOC filter's rule (docs/soc-filter.md) moves a run's error: the rule as
written, without its adaptation (``--no-adapt``), and without the SOC's variance floor (no option:
the floor is switched off here, in this process only), from the true start of one record.

A diagnostic: it chooses nothing. Run on unseen records it explains a result after the fact (the
addendum to parts 6-7); a rule chosen from what it prints must be judged on other records.

Run: PYTHONPATH=src .venv/bin/python benchmarks/soc_ablation.py MODEL.json RECORD.csv [...]
(MODEL.json RECORD.csv pairs; the record as the workflow's canonical CSV, with its sidecar)
"""

from __future__ import annotations

import sys
from contextlib import contextmanager

from avoa_pipeline import estimate as E
from avoa_pipeline import records
from avoa_pipeline.model import heat
from avoa_pipeline.model.fitted import FittedModel


@contextmanager
def without_floor():
    keep = E._hold_soc_floor
    E._hold_soc_floor = lambda *args, **kw: None
    try:
        yield
    finally:
        E._hold_soc_floor = keep


def run(model_path: str, record_path: str) -> None:
    model = FittedModel.load(model_path)
    checked = records.read(record_path)
    soc0 = model.initial_soc(model.record(checked.frame))
    ambient = heat.ambient_if_any(checked)
    variants = {"the rule": ({}, False), "no adaptation": ({"adapt": False}, False),
                "no SOC floor": ({}, True)}  # fmt: skip
    for name, (kw, drop_floor) in variants.items():
        if drop_floor:
            with without_floor():
                res = E.estimate_record(model, checked.frame, soc0, 0.0, soc0, ambient=ambient)
        else:
            res = E.estimate_record(model, checked.frame, soc0, 0.0, soc0, ambient=ambient, **kw)
        f = res.summary["filter"]
        print(f"{record_path}: {name:14s} RMSE after 5 min {100 * f['rmse_after_window']:.2f} %, "
              f"±2σ coverage {100 * f['coverage_2sd']:.1f} %, end "
              f"{100 * f['error_at_end']:+.2f} %")  # fmt: skip


if __name__ == "__main__":
    args = sys.argv[1:]
    if not args or len(args) % 2:
        sys.exit("usage: soc_ablation.py MODEL.json RECORD.csv [MODEL.json RECORD.csv ...]")
    for m, r in zip(args[::2], args[1::2], strict=True):
        run(m, r)
