"""The jobs of ``workflow/rules/data.smk``: the run's checked config and the synthetic records
of the paper grid. Each writes its outputs atomically and a one-line log."""

from __future__ import annotations

import copy

import yaml

from .. import config, synthetic
from ..io import atomic_path, write_log


def effective_config(cfg, out_yaml: str) -> None:
    """The configuration this run used, for notebooks and for the record (checked again here:
    it is the one job that receives the whole config)."""
    cfg = copy.deepcopy(dict(cfg))
    config.validate(cfg, source="snakemake config")
    with atomic_path(out_yaml) as tmp:
        tmp.write_text(yaml.safe_dump(cfg, sort_keys=False))


def dataset(cfg, scenario, case, out_csv: str, log: str | None = None) -> None:
    """One scenario × case's synthetic record. ``cfg`` needs only the parts the ``dataset`` rule
    passes (``plan.DATASET_PARTS``); the whole config was checked once, when the workflow
    started."""
    ds = synthetic.generate(cfg, int(scenario), int(case))
    synthetic.write(ds, out_csv)
    write_log(log, f"wrote {out_csv}: {ds.time_s.size} samples, truth {ds.meta['true_params']}")
