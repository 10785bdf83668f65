# SOC estimation (issue 29; docs/real-data.md "SOC estimation (issue 29)"): at every Panasonic
# temperature of experiment 1, the model its diagnosis selected runs `estimate` on the unseen
# cycles, four runs each. On with real.panasonic.experiment.estimate (config/tiny.yaml: off).

if PAN_ESTIMATE_ON:

    rule panasonic_soc_estimation:
        """The protocol's runs (true start, ±20 %, a 1 % current bias) on every unseen cycle,
        one row each, and the figure; the same as `python -m
        avoa_pipeline.jobs.estimate` on these models."""
        input:
            models=[f"{PAN_OUT}/diagnosis/{t}/model.json" for t in PAN_EXP_TEMPS],
            tests=[p for t in PAN_EXP_TEMPS for p in pan_tests(t).values()],
        output:
            csv="results/real/soc_estimation.csv",
            png="results/real/figures/soc_estimation.png",
            pdf="results/real/figures/soc_estimation.pdf",
        log:
            "logs/real/soc_estimation.log",
        benchmark:
            "logs/real/soc_estimation.benchmark.tsv"
        params:
            models={t: f"{PAN_OUT}/diagnosis/{t}/model.json" for t in PAN_EXP_TEMPS},
            tests={t: pan_tests(t) for t in PAN_EXP_TEMPS},
        threads: 1
        script:
            "../scripts/panasonic_soc_estimation.py"
