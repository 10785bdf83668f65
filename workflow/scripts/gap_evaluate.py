"""Rule `gap_evaluate` (rules/gap.smk): the withheld-effect tables (confusion, accuracy,
detection limit, shrink, the target check with the pairs')."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.gap import evaluate_job

inp = snakemake.input
evaluate_job(list(inp.data), list(inp.diag), dict(snakemake.output), snakemake.params.threshold,
             log, pairs_csv=list(inp.pairs))  # fmt: skip
