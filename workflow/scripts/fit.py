"""Rules `fit_<block>` (rules/identify.smk): one block of seeds of a scenario × case ×
algorithm, stepped together, one record per seed."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.workflow import fit_batch

w, p = snakemake.wildcards, snakemake.params
fit_batch(p.settings, snakemake.input.data, w.scenario, w.case, w.algorithm, p.seeds,
          list(snakemake.output), log)  # fmt: skip
