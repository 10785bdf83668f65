"""Rule `panasonic_soc_estimation` (rules/estimate.smk): the selected models estimate SOC on
the unseen cycles (issue 29)."""

from pathlib import Path

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.estimate import soc_estimation

p = snakemake.params
soc_estimation(dict(p.models), dict(p.tests), snakemake.output.csv,
               str(Path(snakemake.output.png).with_suffix("")), log)  # fmt: skip
