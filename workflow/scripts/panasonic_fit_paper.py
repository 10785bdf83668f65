"""Rule `panasonic_fit_paper` (rules/real.smk): the paper's model, one optimizer, all seeds,
fitted to the training cycle and run on the unseen ones."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import paper_fit_one

w, p = snakemake.wildcards, snakemake.params
paper_fit_one(p.exp, p.base_seed, w.ptemp, w.pmodel, w.algorithm, snakemake.input.train,
              dict(p.tests), snakemake.output[0], log)  # fmt: skip
