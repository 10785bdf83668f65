"""What the Panasonic rules of ``workflow/rules/real.smk`` call: one function per rule.

Each runs in the Snakemake process (``run:``), writes its outputs atomically and a one-line log.
"""

from __future__ import annotations

from pathlib import Path

from .. import config as config_mod


def _log(path, text: str) -> None:
    if path:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(text.rstrip() + "\n")


def canonical_name(name: str) -> str:
    """``25degC/us06`` → the file stem ``panasonic_25degC_us06`` under results/real/canonical."""
    return "panasonic_" + name.replace("/", "_")


def panasonic_import(cfg, name: str, out_csv, log=None) -> None:
    from . import panasonic

    cfg = dict(cfg)
    config_mod.validate(cfg, source="snakemake config")
    side = panasonic.import_named(cfg, name, out_csv)
    _log(
        log,
        f"wrote {out_csv}: {side['n_samples']} samples, {side['discharged_ah']:.4f} Ah out "
        f"(tester: {side['discharged_ah_tester_counter']:.4f} Ah) from {side['source_file']}",
    )
