"""Rule `effective_config` (rules/data.smk): the whole config this run used, checked."""

from avoa_pipeline import jobs

jobs.start(snakemake)

from avoa_pipeline.jobs.data import effective_config

effective_config(snakemake.params.cfg, snakemake.output[0])
