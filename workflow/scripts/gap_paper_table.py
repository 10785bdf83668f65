"""Rule `gap_paper_table` (rules/gap.smk): what the paper's scenarios look like to a model
without load or fade."""

from functools import partial

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.gap.evaluate import paper_record
from avoa_pipeline.jobs.gap import table_job

inp = snakemake.input
table_job(
    partial(paper_record, threshold=snakemake.params.threshold),
    list(inp.data),
    list(inp.diag),
    snakemake.output[0],
    log,
)
