"""Rule `gap_pybamm_table` (rules/gap.smk): verdicts on the PyBaMM records."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.gap.evaluate import pybamm_record
from avoa_pipeline.jobs.gap import table_job

inp = snakemake.input
table_job(pybamm_record, list(inp.data), list(inp.diag), snakemake.output[0], log)
