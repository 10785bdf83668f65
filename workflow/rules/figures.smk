rule fig_static:
    """Figure 1 (equivalent circuit) and Figure 3 (AVOA flowchart), drawn from code."""
    input:
        nb="notebooks/fig_static.ipynb",
        cfg=EFFECTIVE_CONFIG,
    output:
        report(ext("results/figures/fig01", FIG_EXT), category="Figures", subcategory="Model"),
        report(ext("results/figures/fig03", FIG_EXT), category="Figures", subcategory="Model"),
        nb="results/notebooks/fig_static.ipynb",
    log:
        "logs/notebooks/fig_static.log",
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    shell:
        papermill("{input.nb}", "{output.nb}", "{log}", config_path="{input.cfg}",
                  out_dir="results/figures")


rule fig_profile:
    """Figure 2: the test profile and the cell's voltage, intervals i0-i4 marked."""
    input:
        nb="notebooks/fig_profile.ipynb",
        cfg=EFFECTIVE_CONFIG,
        data=f"results/data/s{SCENARIOS[0]}/c{CASE_LIST[0]}.csv",
    output:
        report(ext("results/figures/fig02", FIG_EXT), category="Figures", subcategory="Model"),
        nb="results/notebooks/fig_profile.ipynb",
    log:
        "logs/notebooks/fig_profile.log",
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    shell:
        papermill("{input.nb}", "{output.nb}", "{log}", config_path="{input.cfg}",
                  dataset_csv="{input.data}", scenario=SCENARIOS[0], case=CASE_LIST[0],
                  out_dir="results/figures")


rule fig_fit:
    """Figures 20-21: voltage before/after identification, scenario 4 case 4."""
    input:
        nb="notebooks/fig_fit.ipynb",
        cfg=EFFECTIVE_CONFIG,
        data="results/data/s4/c4.csv" if ran(4, 4) else [],
        runs=sc_aggregate(4, 4),
    output:
        report(ext("results/figures/fig20", FIG_EXT), category="Figures", subcategory="Fit"),
        report(ext("results/figures/fig21", FIG_EXT), category="Figures", subcategory="Fit"),
        nb="results/notebooks/fig_fit.ipynb",
    log:
        "logs/notebooks/fig_fit.log",
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    shell:
        papermill("{input.nb}", "{output.nb}", "{log}", config_path="{input.cfg}",
                  dataset_csv="{input.data}", runs="{input.runs}", out_dir="results/figures")


rule fig_budget:
    """Beyond the paper: fixed-budget curves of one scenario (ECDFs of the evaluations to reach
    10 %, 1 %, 0.1 % excess over the truth; mean per-seed rank against evaluations; E8)."""
    input:
        nb="notebooks/fig_budget.ipynb",
        cfg=EFFECTIVE_CONFIG,
        runs="results/aggregate/runs.parquet",
        histories="results/aggregate/histories.parquet",
    output:
        report(ext("results/figures/budget_s{scenario}", FIG_EXT), category="Figures",
               subcategory="Fixed-budget curves (beyond the paper)"),
        ecdf="results/figures/budget_s{scenario}_ecdf.csv",
        rank="results/figures/budget_s{scenario}_rank.csv",
        nb="results/notebooks/fig_budget_s{scenario}.ipynb",
    log:
        "logs/notebooks/fig_budget_s{scenario}.log",
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    shell:
        papermill("{input.nb}", "{output.nb}", "{log}", config_path="{input.cfg}",
                  runs="{input.runs}", histories="{input.histories}",
                  scenario="{wildcards.scenario}", figures_dir="results/figures")
