"""Rule `panasonic_import` (rules/real.smk): one Panasonic test → canonical CSV + sidecar."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import panasonic_import

w = snakemake.wildcards
panasonic_import(snakemake.params.cfg, f"{w.ptemp}/{w.ptest}", snakemake.output.csv, log)
