rule fit:
    """One identification run: scenario × case × algorithm × seed → one JSON record.

    No ``benchmark:``: the record holds the optimizer's own wall time per iteration, and a
    benchmark thread per job (3,360 of them) costs the scheduler more than it tells.
    """
    input:
        data="results/data/s{scenario}/c{case}.csv",
    output:
        "results/fits/s{scenario}/c{case}/{algorithm}/seed{seed}.json",
    log:
        "logs/fits/s{scenario}/c{case}/{algorithm}/seed{seed}.log",
    params:  # what a fit depends on beyond its data: changing any of it reruns the fits
        budget=config["budget"],
        bounds=config["bounds_used"],
        constants=config["constants"],
        base_seed=config["base_seed"],
    # The fit runs in the worker-process pool (one worker per core, `wf.fit_job`), not in this
    # job's thread, so the job claims no core; `fit_slots` (profile: 6) caps the fits in flight.
    # With one core per fit only two were in flight, and each finished fit left its worker idle
    # while Snakemake started the next (measured: 1.2 fits/s, workers ~40 % busy).
    threads: 0
    resources:
        fit_slots=1,
    run:
        wf.fit_job(config, input.data, wildcards.scenario, wildcards.case,
                   wildcards.algorithm, wildcards.seed, output[0], log[0],
                   workers=workflow.cores)
