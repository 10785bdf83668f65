"""Rule `gap_pairs_table` (rules/gap.smk): one judged row per two-effect dataset."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.gap import pair_table_job

inp = snakemake.input
pair_table_job(list(inp.data), list(inp.diag), snakemake.output[0], snakemake.params.threshold,
               log)  # fmt: skip
