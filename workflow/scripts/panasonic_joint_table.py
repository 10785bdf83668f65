"""Rule `panasonic_joint_table` (rules/real.smk): the joint model's unseen errors beside each
temperature's own model's, and the cell temperature predicted from the ambient by the joint
model's heat block."""

from pathlib import Path

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import joint_temperature_table

p = snakemake.params
out = snakemake.output
joint_temperature_table(dict(p.ambient), Path(snakemake.input.joint).parent, dict(p.own_dirs),
                        dict(p.tests), out.csv, str(Path(out.png).with_suffix("")), log,
                        out.traces, str(Path(out.heat_png).with_suffix("")))  # fmt: skip
