"""Rule `real_nasa_import` (rules/real.smk): the NASA B0005 discharges in one canonical record."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import nasa_import

nasa_import(snakemake.params.cfg, snakemake.output.csv, log)
