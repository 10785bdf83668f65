"""Rule `panasonic_joint` (rules/real.smk): one model over temperature (issue 28), every
temperature's training cycle and HPPC test diagnosed together, the 25 °C C/20 test as --ocv, every
temperature's unseen cycles as validation records only."""

from pathlib import Path

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import diagnose_one

inp = snakemake.input
diagnose_one(list(inp.train), dict(snakemake.params.tests),
             str(Path(snakemake.output.json).parent), inp.ocv, log)  # fmt: skip
