"""Rule `dataset` (rules/data.smk): one scenario × case → its synthetic record."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.data import dataset

w = snakemake.wildcards
dataset(snakemake.params.settings, w.scenario, w.case, snakemake.output.csv, log)
