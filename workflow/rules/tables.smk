rule tables_config:
    """Tables 1-3 from the configuration that ran."""
    input:
        nb="notebooks/tables_config.ipynb",
        cfg=EFFECTIVE_CONFIG,
    output:
        report([f"results/tables/table{n:02d}.{e}" for n in (1, 2, 3) for e in TABLE_EXT],
               category="Tables", subcategory="Tables 1-3: configuration"),
        nb="results/notebooks/tables_config.ipynb",
    log:
        "logs/notebooks/tables_config.log",
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    shell:
        papermill("{input.nb}", "{output.nb}", "{log}", config_path="{input.cfg}",
                  tables_dir="results/tables")


rule case_report:
    """Table NN (parameters) and Figure NN (convergence) of one scenario × case, NN = 04..19."""
    input:
        nb="notebooks/case_report.ipynb",
        cfg=EFFECTIVE_CONFIG,
        paper=f"{PAPER}/params.csv",
        agg=case_inputs,
    output:
        report(ext("results/tables/table{nn}", TABLE_EXT), category="Tables",
               subcategory="Tables 4-19: parameters"),
        report(ext("results/figures/fig{nn}", FIG_EXT), category="Figures",
               subcategory="Figures 4-19: convergence"),
        nb="results/notebooks/case_report_{nn}.ipynb",
    wildcard_constraints:
        nn="0[4-9]|1[0-9]",
    log:
        "logs/notebooks/case_report_{nn}.log",
    params:
        sc=lambda w: scenario_case(w.nn),
        runs=lambda w, input: input.agg[0] if input.agg else "",
        hist=lambda w, input: input.agg[1] if input.agg else "",
        not_run=lambda w: not ran(*scenario_case(w.nn)),
    priority: 5
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    shell:
        papermill("{input.nb}", "{output.nb}", "{log}", config_path="{input.cfg}",
                  tables_dir="results/tables", figures_dir="results/figures",
                  scenario="{params.sc[0]}", case="{params.sc[1]}", runs="{params.runs}",
                  histories="{params.hist}", not_run="{params.not_run}")


rule table_objective:
    """Tables 20-23: objective values, ranks and tests for one scenario; beside each, the share of
    seeds that found every parameter within 1 % / 5 % (named by table number: every output of a
    rule needs the same wildcards)."""
    input:
        nb="notebooks/table_objective.ipynb",
        cfg=EFFECTIVE_CONFIG,
        paper=f"{PAPER}/objective.csv",
        runs=scenario_runs,
    output:
        report(ext("results/tables/table{nn}", TABLE_EXT), category="Tables",
               subcategory="Tables 20-23: objective values and ranks"),
        report(ext("results/tables/table{nn}_accuracy", TABLE_EXT), category="Tables",
               subcategory="Parameter accuracy (beside Tables 20-23)"),
        nb="results/notebooks/table_objective_{nn}.ipynb",
    wildcard_constraints:
        nn="2[0-3]",
    log:
        "logs/notebooks/table_objective_{nn}.log",
    params:
        scenario=lambda w: int(w.nn) - 19,
        runs=lambda w, input: ",".join(input.runs),
        not_run=lambda w, input: not input.runs,
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    shell:
        papermill("{input.nb}", "{output.nb}", "{log}", config_path="{input.cfg}",
                  tables_dir="results/tables", scenario="{params.scenario}",
                  runs="{params.runs}", not_run="{params.not_run}")


rule table_time:
    """Table 24: time per iteration and per evaluation, scenario 4 case 4."""
    input:
        nb="notebooks/table_time.ipynb",
        cfg=EFFECTIVE_CONFIG,
        paper=f"{PAPER}/time_per_iteration.csv",
        runs=sc_aggregate(4, 4),
    output:
        report(ext("results/tables/table24", TABLE_EXT), category="Tables",
               subcategory="Table 24: time"),
        nb="results/notebooks/table_time.ipynb",
    log:
        "logs/notebooks/table_time.log",
    params:
        not_run=not ran(4, 4),
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    shell:
        papermill("{input.nb}", "{output.nb}", "{log}", config_path="{input.cfg}",
                  tables_dir="results/tables", runs="{input.runs}", not_run="{params.not_run}")


rule claims:
    """Each claim of the paper, decided by our statistics under both protocols."""
    input:
        nb="notebooks/claims.ipynb",
        cfg=EFFECTIVE_CONFIG,
        objective=f"{PAPER}/objective.csv",
        time=f"{PAPER}/time_per_iteration.csv",
        runs="results/aggregate/runs.parquet",
        histories="results/aggregate/histories.parquet",
    output:
        report("results/tables/claims.csv", category="Claims"),
        nb="results/notebooks/claims.ipynb",
    log:
        "logs/notebooks/claims.log",
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    shell:
        papermill("{input.nb}", "{output.nb}", "{log}", config_path="{input.cfg}",
                  tables_dir="results/tables", runs="{input.runs}",
                  histories="{input.histories}")
