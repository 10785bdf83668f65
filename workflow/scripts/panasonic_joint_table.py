"""Rule `panasonic_joint_table` (rules/real.smk): the joint model's unseen errors beside each
temperature's own model's."""

from pathlib import Path

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import joint_temperature_table

p = snakemake.params
joint_temperature_table(dict(p.ambient), Path(snakemake.input.joint).parent, dict(p.own_dirs),
                        dict(p.tests), snakemake.output.csv,
                        str(Path(snakemake.output.png).with_suffix("")), log)  # fmt: skip
