# Fits in batches (docs/benchmarks.md, "Execution"): one job per scenario × case × block of
# seeds runs every configured algorithm on it and writes one record per algorithm × seed, and
# every record is still a target of its own. Block b holds the configured seeds in
# [b·n + 1, (b + 1)·n], n = fit_seeds_per_job. A job is a process of its own (start-up about
# 1 s: interpreter, imports, kernel cache), so one job per fit, or per algorithm, would pay it
# more often than a fit of the paper's budget costs (issue 20: 112 jobs → 16 on the paper grid).
# The records are `update()` outputs: Snakemake leaves them in place, and the job keeps every
# record whose job_key is current (jobs.identify.fit_algorithms), so seeds or algorithms added to a
# block compute only the new fits, while a changed budget, dataset or code recomputes them all.
FIT_SEEDS_PER_JOB = int(config.get("fit_seeds_per_job", 30))


def seed_blocks(seeds, size):
    """Block number (1-based) → the configured seeds in it."""
    blocks = {}
    for s in sorted(int(x) for x in seeds):
        blocks.setdefault((s - 1) // size + 1, []).append(s)
    return blocks


FIT_BLOCKS = seed_blocks(SEEDS, FIT_SEEDS_PER_JOB)

for _block, _seeds in FIT_BLOCKS.items():

    rule:
        name:
            f"fit_{_block}"
        input:
            data="results/data/s{scenario}/c{case}.csv",
        output:  # algorithm-major, as jobs.identify.fit_algorithms takes them
            [update(f"results/fits/s{{scenario}}/c{{case}}/{a}/seed{s}.json")
             for a in ALGOS for s in _seeds],
        log:
            f"logs/fits/s{{scenario}}/c{{case}}/block{_block}.log",
        params:  # what a fit reads beyond its data (plan.FIT_PARTS): a change reruns the block
            settings=config_part(*plan.FIT_PARTS),
            algorithms=ALGOS,
            seeds=_seeds,
        threads: 1
        resources:
            mem_mb=1000,  # measured: one fit process peaks at ~300 MB (numba, scipy, pandas)
            runtime=5 + len(_seeds),  # minutes; a fit takes 0.2-0.6 s at the paper's budget, so
            # 7 algorithms × 30 seeds about 2 min
            group_lane=1,  # profiles/slurm: a group's members run one after another
        group:
            "fits"  # used by cluster executors only (profiles/slurm); ignored locally
        script:
            "../scripts/fit.py"
