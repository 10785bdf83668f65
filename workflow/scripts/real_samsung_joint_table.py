"""Rule `real_samsung_joint_table` (rules/real.smk): the unseen temperature's errors, the joint
Samsung model beside each training temperature's own."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import selected_on

p = snakemake.params
selected_on(dict(zip(p.fits, snakemake.input, strict=True)), p.unseen, snakemake.output[0], log)
