"""Rule `panasonic_cross_cycle` (rules/real.smk): the base circuit and the selected model, each
fitted to every drive cycle of a temperature in turn and run on all."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import cross_cycle_one

inp, p = snakemake.input, snakemake.params
cross_cycle_one(p.ambient_c, snakemake.wildcards.ptemp, inp.model, dict(p.cycles), inp.ocv,
                snakemake.output[0], log)  # fmt: skip
