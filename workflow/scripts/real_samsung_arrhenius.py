"""Rule `real_samsung_arrhenius` (rules/real.smk): experiment 2, R0, Rtr and tau per pulse and
their Arrhenius fits."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import arrhenius

p, out = snakemake.params, snakemake.output
hppc = dict(zip(p.temperatures, snakemake.input, strict=True))
arrhenius(p.cfg, hppc, out.rc, out.arrhenius, log)
