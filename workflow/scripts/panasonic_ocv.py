"""Rule `panasonic_ocv` (rules/real.smk): the C/20 test as an SOC → OCV table."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import panasonic_ocv

panasonic_ocv(snakemake.input[0], snakemake.output.csv, log)
