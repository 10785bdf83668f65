"""Rule `aggregate_case` (rules/aggregate.smk): a scenario × case's records → runs, histories."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.aggregate import aggregate_runs

out = snakemake.output
aggregate_runs(list(snakemake.input), out.runs, out.histories, log)
