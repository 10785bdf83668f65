rule dataset:
    """The synthetic "measured" record of one scenario × case (CSV + JSON sidecar)."""
    output:
        csv="results/data/s{scenario}/c{case}.csv",
        meta="results/data/s{scenario}/c{case}.json",
    log:
        "logs/data/s{scenario}/c{case}.log",
    params:  # what the dataset is made from (plan.DATASET_PARTS); its job reads no more
        settings=config_part(*plan.DATASET_PARTS),
    threads: 1
    priority: 10  # before any fit: the fits of a pair wait for its dataset
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    script:
        "../scripts/dataset.py"


rule effective_config:
    """The configuration of this run, as notebooks read it."""
    output:
        EFFECTIVE_CONFIG,
    params:
        cfg=config,
    log:
        "logs/config.log",
    threads: 1
    priority: 10  # every notebook reads it: run first, so reports need not wait for it
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    script:
        "../scripts/effective_config.py"
