"""Rule `gap_real_table` (rules/gap.smk): verdicts on real records."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.gap.evaluate import real_record
from avoa_pipeline.jobs.gap import table_job

inp = snakemake.input
table_job(real_record, list(inp.data), list(inp.diag), snakemake.output[0], log)
