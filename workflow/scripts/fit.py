"""Rules `fit_<block>` (rules/identify.smk): one block of seeds of a scenario × case, every
configured algorithm, each algorithm's seeds stepped together, one record per algorithm × seed."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.identify import fit_algorithms

w, p = snakemake.wildcards, snakemake.params
fit_algorithms(p.settings, snakemake.input.data, w.scenario, w.case, p.algorithms, p.seeds,
               list(snakemake.output), log)  # fmt: skip
