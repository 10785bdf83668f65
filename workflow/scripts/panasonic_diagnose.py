"""Rule `panasonic_diagnose` (rules/real.smk): experiment 1 through the diagnosis, the training
cycle and the same temperature's HPPC test fitted together, the C/20 test as --ocv, the unseen
cycles as validation records only."""

from pathlib import Path

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import diagnose_one

inp = snakemake.input
diagnose_one([inp.train, inp.hppc], dict(snakemake.params.tests),
             str(Path(snakemake.output.json).parent), inp.ocv, log)  # fmt: skip
