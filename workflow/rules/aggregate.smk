rule aggregate_case:
    """All fits of one scenario × case → runs and histories tables."""
    input:
        lambda w: fits_of(w.scenario, w.case),
    output:
        runs="results/aggregate/s{scenario}/c{case}/runs.parquet",
        histories="results/aggregate/s{scenario}/c{case}/histories.parquet",
    log:
        "logs/aggregate/s{scenario}/c{case}.log",
    threads: 1
    priority: 5  # a finished pair's aggregate and report run between fits, not after the last
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    script:
        "../scripts/aggregate_case.py"


rule aggregate_all:
    """Every scenario × case of this config in one pair of tables."""
    input:
        runs=expand("results/aggregate/s{s}/c{c}/runs.parquet", s=SCENARIOS, c=CASE_LIST),
        histories=expand("results/aggregate/s{s}/c{c}/histories.parquet", s=SCENARIOS, c=CASE_LIST),
    output:
        runs="results/aggregate/runs.parquet",
        histories="results/aggregate/histories.parquet",
    log:
        "logs/aggregate/all.log",
    threads: 1
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    script:
        "../scripts/aggregate_all.py"
