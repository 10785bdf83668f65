# Reproduces Fahmy et al. 2023 (Mathematics 11, 2215): datasets → fits → aggregates → tables,
# figures, claims. Wiring only; every rule calls into src/avoa_pipeline.
from snakemake.utils import min_version, validate

min_version("9.27.1")  # as environment.txt pins it; avoa_pipeline.snakemake_compat was written for it


configfile: "config/config.yaml"


validate(config, schema="workflow/schemas/config.schema.yaml")


include: "workflow/rules/common.smk"
include: "workflow/rules/data.smk"
include: "workflow/rules/identify.smk"
include: "workflow/rules/aggregate.smk"
include: "workflow/rules/tables.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/real.smk"
include: "workflow/rules/gap.smk"
include: "workflow/rules/estimate.smk"


rule all:
    default_target: True
    input:
        all_tables(),
        all_figures(),
        budget_figures(),
        "results/tables/claims.csv",
        real_outputs(),
        GAP_OUTPUTS,


rule paper:
    """The reproduction alone: Tables 1-24, Figures 1-21, the claims and the fixed-budget curves
    (`snakemake -j2 paper`)."""
    input:
        all_tables(),
        all_figures(),
        budget_figures(),
        "results/tables/claims.csv",
