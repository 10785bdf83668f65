"""Rule `panasonic_drive_cycle_table` (rules/real.smk): experiment 1's table, per-seed rows and
the figure cycles' predicted voltages."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import drive_cycle_table

p, out = snakemake.params, snakemake.output
drive_cycle_table(p.cfg, list(snakemake.input.fits), dict(p.diagnoses), dict(p.tests), out.csv,
                  out.runs, out.pred, log)  # fmt: skip
