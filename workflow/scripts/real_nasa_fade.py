"""Rule `real_nasa_fade` (rules/real.smk): experiment 3, capacity and resistance per ageing
state and the fade laws."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import fade

out = snakemake.output
fade(snakemake.params.cfg, snakemake.input[0], out.states, out.fits, log)
