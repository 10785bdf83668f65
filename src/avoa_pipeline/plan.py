"""What the workflow builds for a config, for ``workflow/rules/common.smk``: the parts of the
config each rule passes its job, the gap check's records and outputs, the real-data files and
targets. It runs in the Snakemake process, so it computes nothing and never imports :mod:`.jobs`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from .errors import ConfigError

DATASET_PARTS = ("base_seed", "data", "true_params", "profile", "constants", "temperatures_c")
"""The parts of the config a synthetic dataset is made from (:func:`.config.part`)."""
FIT_PARTS = ("budget", "bounds_used", "constants", "base_seed", "true_params")
"""The parts of the config a fit of the paper grid reads beyond its dataset."""


def regex(values) -> str:
    """A wildcard constraint for exactly ``values`` (never matching when there are none)."""
    return "|".join(map(str, values)) if values else "(?!x)x"


# --- the gap check (workflow/rules/gap.smk) ----------------------------------------------------

GAP_TABLES = ("records", "confusion", "accuracy", "detection_limit", "shrink", "target")
GAP_FIGURES = ("confusion", "accuracy", "shrink", "detection_limit")


def gap(gcfg: dict | None, real_present: bool = False) -> dict:
    """Every record and output of the gap rules for the config's ``gap:`` section."""
    from .gap import withheld

    if not gcfg:
        return {"outputs": []}
    full = sorted(gcfg["replicates"])
    control_only = sorted(set(gcfg["control_replicates"]) - set(full))
    full_names = withheld.names(gcfg, full[0]) if full else []
    control_names = withheld.names({**gcfg, "replicates": []}, -1)
    records_ = [f"{profile}/r{rep}/{name}" for profile in gcfg["profiles"]
                for rep in withheld.all_replicates(gcfg)
                for name in (full_names if rep in full else control_names)]  # fmt: skip
    pair_names = withheld.pair_names(gcfg, full[0]) if full else []
    pair_records = [f"{profile}/r{rep}/{name}" for profile in gcfg["profiles"] for rep in full
                    for name in pair_names]  # fmt: skip
    real = list(gcfg.get("real", [])) if real_present else []
    outputs = [
        *(f"results/gap/{t}.csv" for t in GAP_TABLES),
        "results/gap/paper_scenarios.csv",
        "results/gap/pybamm.csv",
        *(f"results/gap/figures/{f}.png" for f in GAP_FIGURES),
        *(["results/gap/real.csv"] if real else []),
        *(["results/gap/pairs.csv"] if pair_records else []),
    ]
    return {
        "full_replicates": full,
        "control_only": control_only,
        "full_names": full_names,
        "control_names": control_names,
        "records": records_,
        "pair_names": pair_names,
        "pair_records": pair_records,
        "paper": [f"paper/s{s}c{c}" for s in gcfg["paper_scenarios"] for c in gcfg["paper_cases"]],
        "pybamm": [f"pybamm/{n}" for n in gcfg["pybamm"]],
        "real": real,
        "outputs": outputs,
    }


# --- real data (workflow/rules/real.smk) -------------------------------------------------------


def canonical_name(name: str) -> str:
    """``25degC/us06`` → the file stem ``panasonic_25degC_us06`` under results/real/canonical."""
    return "panasonic_" + name.replace("/", "_")


def real_section(cfg: Mapping, section: str) -> Mapping:
    """The config's ``real.<section>``; a missing one is a ConfigError naming the field."""
    real = cfg.get("real") or {}
    if section not in real or not real[section]:
        raise ConfigError(f"config: field real.{section} missing (docs/real-data.md)")
    return real[section]


CELL_OUTPUTS = {
    "samsung": ("results/real/samsung_rc_vs_temperature.csv", "results/real/samsung_arrhenius.csv"),
    "nasa": ("results/real/nasa_fade.csv", "results/real/nasa_fade_fit.csv"),
    "report": ("results/notebooks/real_cells.ipynb",),
}


def source_path(cfg: Mapping, key: str) -> str:
    """A source file as the rules name it: under real.root, relative to the working directory."""
    return str(Path(cfg["real"]["root"]) / key)


def nasa_source_sha256(cfg: Mapping) -> dict[str, str]:
    """The NASA index and every discharge file listed in real.sources, with their sha256."""
    nasa = real_section(cfg, "nasa")
    folder = Path(nasa["discharge_dir"])
    sources = cfg["real"]["sources"]
    keys = [nasa["index"]] + [k for k in sources if Path(k).parent == folder]
    return {k: sources.get(k, "") for k in keys}


SAMSUNG_JOINT_TABLE = "results/real/samsung_joint_temperature.csv"
"""Issue 28 on the Samsung 30Q: the joint model and each training temperature's own on the
unseen temperature (rules ``real_samsung_diagnose``, ``real_samsung_joint_table``)."""


def samsung_joint_fits(cfg: Mapping) -> dict[str, list[str]]:
    """Issue 28 on the Samsung 30Q: each diagnosis's training temperatures, the joint fit of
    ``real.samsung.joint.train`` and each of them alone (empty without that section)."""
    joint = ((cfg.get("real") or {}).get("samsung") or {}).get("joint") or {}
    train = list(joint.get("train") or [])
    return {"joint": train, **{t: [t] for t in train}} if train else {}


def cell_targets(cfg: Mapping) -> list[str]:
    """The final outputs of experiments 2 and 3 for the sections the config has."""
    real = cfg.get("real") or {}
    out = []
    for section in ("samsung", "nasa"):
        if real.get(section):
            out += CELL_OUTPUTS[section]
    if (real.get("samsung") or {}).get("joint"):  # one model over temperature (issue 28)
        out.append(SAMSUNG_JOINT_TABLE)
    if real.get("samsung") and real.get("nasa"):
        out += CELL_OUTPUTS["report"]
    return out
