"""Rule `panasonic_fit_c20` (rules/real.smk): the C/20 circuits fitted to the training cycle."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import c20_fit_one

inp = snakemake.input
c20_fit_one(snakemake.wildcards.ptemp, inp.train, dict(snakemake.params.tests), inp.ocv,
            snakemake.output[0], log)  # fmt: skip
