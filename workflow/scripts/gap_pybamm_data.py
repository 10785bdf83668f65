"""Rule `gap_pybamm_data` (rules/gap.smk): one PyBaMM record."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.gap import pybamm

pybamm(snakemake.params.base_seed, snakemake.wildcards.name, snakemake.output.csv, log)
