"""Rule `real_samsung_import` (rules/real.smk): one Samsung 30Q HPPC file, canonical."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import samsung_import

samsung_import(snakemake.params.cfg, snakemake.wildcards.stemp, snakemake.output.csv, log)
