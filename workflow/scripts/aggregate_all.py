"""Rule `aggregate_all` (rules/aggregate.smk): every scenario × case in one pair of tables."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.aggregate import concat_aggregates

inp, out = snakemake.input, snakemake.output
concat_aggregates(list(inp.runs), list(inp.histories), out.runs, out.histories, log)
