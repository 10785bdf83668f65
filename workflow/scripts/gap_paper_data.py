"""Rule `gap_paper_data` (rules/gap.smk): a paper scenario × case, to be diagnosed."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.gap import paper_job

w = snakemake.wildcards
paper_job(snakemake.params.settings, w.scenario, w.case, snakemake.output.csv, log)
