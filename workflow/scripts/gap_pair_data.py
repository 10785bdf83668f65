"""Rule `gap_pair_data` (rules/gap.smk): every two-effect dataset of one base cell."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.gap import generate_pairs

w, p = snakemake.wildcards, snakemake.params
generate_pairs(p.base_seed, p.grid, w.profile, w.replicate, p.out_dir, log)
