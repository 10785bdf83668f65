rule fit:
    """One identification run: scenario × case × algorithm × seed → one JSON record."""
    input:
        data="results/data/s{scenario}/c{case}.csv",
    output:
        "results/fits/s{scenario}/c{case}/{algorithm}/seed{seed}.json",
    log:
        "logs/fits/s{scenario}/c{case}/{algorithm}/seed{seed}.log",
    benchmark:
        "results/benchmarks/fits/s{scenario}/c{case}/{algorithm}/seed{seed}.tsv"
    params:  # what a fit depends on beyond its data: changing any of it reruns the fits
        budget=config["budget"],
        bounds=config["bounds_used"],
        constants=config["constants"],
        base_seed=config["base_seed"],
    threads: 1
    run:
        wf.fit_one(config, input.data, wildcards.scenario, wildcards.case,
                   wildcards.algorithm, wildcards.seed, output[0], log[0])
