# Real data (issue "Real data"; docs/real-data.md). Active when the config has `real:` and its data
# root exists (relative to the working directory); `snakemake -j2 real` builds every real-data
# output, and `all` includes them then. Sources are read in place and never copied.
from avoa_pipeline.real import jobs as real_jobs
from avoa_pipeline.real import panasonic as real_panasonic

REAL = config.get("real") or {}
REAL_ROOT = Path(REAL["root"]) if REAL else None
REAL_PRESENT = bool(REAL) and REAL_ROOT.is_dir()
REAL_TARGETS = []  # every section below adds its outputs; `real` and `all` build them


def real_outputs():
    """The real-data outputs for `all`: none without the data."""
    return REAL_TARGETS if REAL_PRESENT else []


# ------------------------------------------------------------------------------------------------
# Panasonic NCR18650PF (Kollmeyer): import, experiment 1 (drive cycles)
# ------------------------------------------------------------------------------------------------
PANASONIC = real_panasonic.records(config)
PAN_CANON = "results/real/canonical"


def pan_sources(w):
    return [str(REAL_ROOT / k) for k in PANASONIC[f"{w.ptemp}/{w.ptest}"]["keys"]]


PAN_TEMPS = sorted({n.split("/")[0] for n in PANASONIC})
PAN_TESTS = sorted({n.split("/")[1] for n in PANASONIC})
REAL_TARGETS += [f"{PAN_CANON}/{real_jobs.canonical_name(n)}.csv" for n in PANASONIC]


rule panasonic_import:
    """One Panasonic test (an HPPC pulse file with its SOC-step file, a drive cycle, the C/20
    test) → canonical CSV + JSON sidecar."""
    input:
        pan_sources,
    output:
        csv=f"{PAN_CANON}/panasonic_{{ptemp}}_{{ptest}}.csv",
        meta=f"{PAN_CANON}/panasonic_{{ptemp}}_{{ptest}}.json",
    log:
        "logs/real/canonical/panasonic_{ptemp}_{ptest}.log",
    wildcard_constraints:
        ptemp="|".join(PAN_TEMPS) or "none",
        ptest="|".join(PAN_TESTS) or "none",
    params:
        sources=lambda w: {k: REAL["sources"][k] for k in PANASONIC[f"{w.ptemp}/{w.ptest}"]["keys"]},
    run:
        real_jobs.panasonic_import(config, f"{wildcards.ptemp}/{wildcards.ptest}", output.csv,
                                   log[0])


# ------------------------------------------------------------------------------------------------
# Samsung 30Q and NASA B0005: their rules go below this line (they add to REAL_TARGETS).
# ------------------------------------------------------------------------------------------------


# ------------------------------------------------------------------------------------------------
# Target: every real-data output. Kept last so every section above has added its outputs.
# ------------------------------------------------------------------------------------------------
rule real:
    """Every real-data output (`snakemake -j2 real`)."""
    input:
        lambda w: REAL_TARGETS,
