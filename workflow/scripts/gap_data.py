"""Rules `gap_data` and `gap_controls` (rules/gap.smk): every withheld-effect dataset (or only
the controls) of one base cell."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.gap import generate

w, p = snakemake.wildcards, snakemake.params
generate(p.base_seed, p.grid, w.profile, w.replicate, p.out_dir, log)
