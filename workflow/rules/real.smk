# Real data (issue "Real data"; docs/real-data.md). Active when the config has `real:` and its data
# root exists (relative to the working directory); `snakemake -j2 real` builds every real-data
# output, and `all` includes them then. Sources are read in place and never copied.
# Helpers, constants and the targets (REAL, real_targets, PANASONIC, pan_*) live in common.smk.


# ------------------------------------------------------------------------------------------------
# Panasonic NCR18650PF (Kollmeyer): import, experiment 1 (drive cycles)
# ------------------------------------------------------------------------------------------------
rule panasonic_import:
    """One Panasonic test (an HPPC pulse file with its SOC-step file, a drive cycle, the C/20
    test) → canonical CSV + JSON sidecar."""
    input:
        pan_sources,
    output:
        csv=f"{REAL_CANON}/panasonic_{{ptemp}}_{{ptest}}.csv",
        meta=f"{REAL_CANON}/panasonic_{{ptemp}}_{{ptest}}.json",
    log:
        "logs/real/canonical/panasonic_{ptemp}_{ptest}.log",
    wildcard_constraints:
        ptemp=plan.regex(PAN_TEMPS),
        ptest=plan.regex(PAN_TESTS),
    params:  # real.panasonic without its experiment: a change there reruns no import
        cfg=config_part("real.root", "real.sources",
                        *(f"real.panasonic.{k}" for k in REAL["panasonic"] if k != "experiment"))
            if PANASONIC else {},
    threads: 1
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    script:
        "../scripts/panasonic_import.py"


rule panasonic_ocv:
    """The C/20 test as an SOC → OCV table (the library's slow-test rule, model/ocv.py)."""
    input:
        PAN_OCV_RECORD,
    output:
        csv=f"{PAN_OUT}/ocv_c20.csv",
        meta=f"{PAN_OUT}/ocv_c20.json",
    log:
        "logs/real/panasonic/ocv_c20.log",
    threads: 1
    script:
        "../scripts/panasonic_ocv.py"


rule panasonic_fit_paper:
    """The paper's model (with or without the RC branch), one optimizer, all seeds, fitted to
    the training drive cycle and run on the unseen ones."""
    input:
        train=pan_train,
        tests=pan_test_csvs,
    output:
        f"{PAN_OUT}/fits/{{ptemp}}/{{pmodel}}/{{algorithm}}.json",
    log:
        "logs/real/panasonic/fits/{ptemp}/{pmodel}/{algorithm}.log",
    wildcard_constraints:
        ptemp=PAN_EXP_TEMP_RE,
        pmodel="|".join(real_dc.PAPER_MODELS),
        algorithm=plan.regex(PAN_EXP.get("algorithms", [])),
    params:
        exp=lambda w: real_dc.fit_settings(config, w.ptemp),
        base_seed=config["base_seed"],
        tests=lambda w: pan_tests(w.ptemp),
    group:
        "fits"  # cluster executors only (profiles/slurm)
    threads: 1
    resources:
        group_lane=1,  # profiles/slurm: a group's members run one after another
    script:
        "../scripts/panasonic_fit_paper.py"


rule panasonic_fit_c20:
    """The C/20 circuits (library configurations on the C/20 table), fitted to the training
    cycle, run on the others."""
    input:
        train=pan_train,
        tests=pan_test_csvs,
        ocv=f"{PAN_OUT}/ocv_c20.csv",
        meta=f"{PAN_OUT}/ocv_c20.json",
    output:
        f"{PAN_OUT}/fits/{{ptemp}}/c20.json",
    log:
        "logs/real/panasonic/fits/{ptemp}/c20.log",
    wildcard_constraints:
        ptemp=PAN_EXP_TEMP_RE,
    params:
        train=lambda w: PAN_EXP["train"][w.ptemp],
        tests=lambda w: pan_tests(w.ptemp),
    threads: 1
    script:
        "../scripts/panasonic_fit_c20.py"


rule panasonic_diagnose:
    """Experiment 1 through the diagnosis (docs/real-data.md, the rule written before any test
    number): the training cycle and the same temperature's HPPC test fitted together, the C/20
    test as --ocv, the unseen cycles as validation records only. The same as
    `python -m avoa_pipeline diagnose TRAIN HPPC --ocv C20 --validate TESTS --out DIR` without
    its figure."""
    input:
        train=pan_train,
        hppc=pan_hppc,
        ocv=PAN_OCV_RECORD,
        tests=pan_test_csvs,
    output:
        json=f"{PAN_OUT}/diagnosis/{{ptemp}}/diagnosis.json",
        model=f"{PAN_OUT}/diagnosis/{{ptemp}}/model.json",
    log:
        "logs/real/panasonic/diagnosis/{ptemp}.log",
    benchmark:
        "logs/real/panasonic/diagnosis/{ptemp}.benchmark.tsv"
    wildcard_constraints:
        ptemp=PAN_EXP_TEMP_RE,
    params:
        tests=lambda w: pan_tests(w.ptemp),
    threads: LONG_DIAGNOSIS_THREADS
    script:
        "../scripts/panasonic_diagnose.py"


rule panasonic_fit_gap:
    """Comparison rows gap_*: the diagnosis of the training cycle alone, without --ocv (what a
    user without a slow test gets); the unseen cycles as validation records only."""
    input:
        train=pan_train,
        tests=pan_test_csvs,
    output:
        json=f"{PAN_OUT}/gap/{{ptemp}}/diagnosis.json",
        model=f"{PAN_OUT}/gap/{{ptemp}}/model.json",
    log:
        "logs/real/panasonic/gap/{ptemp}.log",
    wildcard_constraints:
        ptemp=PAN_EXP_TEMP_RE,
    params:
        tests=lambda w: pan_tests(w.ptemp),
    threads: 1
    script:
        "../scripts/panasonic_fit_gap.py"


rule panasonic_cross_cycle:
    """Diagnostic: the base circuit c20_2rc_lowsoc and the configuration the diagnosis selected,
    each fitted to every drive cycle of the temperature in turn and run on all; the in-sample
    errors bound what transfer can reach."""
    input:
        model=f"{PAN_OUT}/diagnosis/{{ptemp}}/model.json",
        cycles=lambda w: [pan_train(w)] + pan_test_csvs(w),
        ocv=f"{PAN_OUT}/ocv_c20.csv",
        meta=f"{PAN_OUT}/ocv_c20.json",
    output:
        f"{PAN_OUT}/cross_cycle/{{ptemp}}.csv",
    log:
        "logs/real/panasonic/cross_cycle/{ptemp}.log",
    wildcard_constraints:
        ptemp=PAN_EXP_TEMP_RE,
    params:
        cycles=lambda w: {PAN_EXP["train"][w.ptemp]: pan_train(w), **pan_tests(w.ptemp)},
        ambient_c=lambda w: REAL["panasonic"]["temperatures"][w.ptemp]["ambient_c"],
    threads: 1
    script:
        "../scripts/panasonic_cross_cycle.py"


rule panasonic_drive_cycle_table:
    """Experiment 1's table: RMSE and maximum error per temperature × unseen cycle × model."""
    input:
        fits=pan_fit_records(),
        diagnoses=[f"{d}/{f}" for per_temp in pan_diagnoses().values()
                   for d in per_temp.values() for f in ("diagnosis.json", "model.json")],
        tests=[pan_canon(f"{t}/{c}") for t in PAN_EXP_TEMPS for c in real_dc.unseen_cycles(config, t)],
    output:
        csv="results/real/drive_cycle_rmse.csv",
        runs=f"{PAN_OUT}/drive_cycle_runs.csv",
        pred=f"{PAN_OUT}/figure_predictions.parquet",
    log:
        "logs/real/panasonic/drive_cycle_table.log",
    params:
        cfg=config_part("real.panasonic.temperatures", "real.panasonic.experiment") if PAN_EXP else {},
        diagnoses=pan_diagnoses(),
        tests={f"{t}/{c}": pan_canon(f"{t}/{c}") for t in PAN_EXP_TEMPS
               for c in real_dc.unseen_cycles(config, t)},
    threads: 1
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    script:
        "../scripts/panasonic_drive_cycle_table.py"


rule panasonic_drive_cycles_notebook:
    """Figure (measured against predicted voltage on an unseen cycle) and table of experiment 1."""
    input:
        nb="notebooks/real_drive_cycles.ipynb",
        csv="results/real/drive_cycle_rmse.csv",
        runs=f"{PAN_OUT}/drive_cycle_runs.csv",
        pred=f"{PAN_OUT}/figure_predictions.parquet",
    output:
        report(ext("results/real/figures/panasonic_drive_cycles", FIG_EXT),
               category="Real data", subcategory="Panasonic drive cycles"),
        report(ext("results/real/tables/panasonic_drive_cycle_rmse", TABLE_EXT),
               category="Real data", subcategory="Panasonic drive cycles"),
        nb="results/notebooks/real_drive_cycles.ipynb",
    log:
        "logs/notebooks/real_drive_cycles.log",
    localrule: True  # cheap: run by the submitting Snakemake on a cluster
    resources:
        local_job=1,  # profiles/slurm: how many run at once
    shell:
        papermill("{input.nb}", "{output.nb}", "{log}", rmse_csv="{input.csv}",
                  runs_csv="{input.runs}", predictions="{input.pred}",
                  figures_dir="results/real/figures", tables_dir="results/real/tables")


# ------------------------------------------------------------------------------------------------
# One model over temperature (issue 28; docs/real-data.md, "One model over temperature"): every
# temperature's training records diagnosed together, beside each temperature's own diagnosis
# ------------------------------------------------------------------------------------------------
PAN_JOINT = "results/real/joint"
PAN_JOINT_TESTS = {f"{t}/{c}": pan_canon(f"{t}/{c}") for t in PAN_EXP_TEMPS
                   for c in real_dc.unseen_cycles(config, t)}  # every temperature's unseen cycles


if PAN_JOINT_ON:

    rule panasonic_joint:
        """The diagnosis of every temperature's training cycle and HPPC test together (one
        reference temperature, the mean of all; the thermal elements are candidates where the
        measured temperature moves), the 25 degC C/20 test as --ocv, every temperature's unseen
        cycles as validation records only: `python -m avoa_pipeline diagnose TRAIN... --ocv C20
        --validate TESTS... --out DIR` without its figure; model.json carries the heat block
        the command fits where a training record's temperature moves (model/heat.py)."""
        input:
            train=[pan_canon(f"{t}/{r}") for t in PAN_EXP_TEMPS for r in (PAN_EXP["train"][t], "hppc")],
            ocv=PAN_OCV_RECORD,
            tests=list(PAN_JOINT_TESTS.values()),
        output:
            json=f"{PAN_JOINT}/diagnosis.json",
            model=f"{PAN_JOINT}/model.json",
        log:
            "logs/real/joint/diagnosis.log",
        benchmark:
            "logs/real/joint/diagnosis.benchmark.tsv"
        params:
            tests=PAN_JOINT_TESTS,
        threads: LONG_DIAGNOSIS_THREADS
        script:
            "../scripts/panasonic_joint.py"

    rule panasonic_joint_table:
        """Per temperature and unseen cycle, the joint model's RMSE and largest error beside
        the temperature's own diagnosis (the `diagnosis_selected` rows of drive_cycle_rmse.csv,
        read from the same diagnosis.json, so the table waits for no paper-model fit); and the
        cell temperature predicted from the ambient alone by the joint model.json's heat block
        against the thermocouple, with the voltage on it (issue 28 item 2; traces and figure)."""
        input:
            joint=f"{PAN_JOINT}/diagnosis.json",
            model=f"{PAN_JOINT}/model.json",
            own=[f"{d}/diagnosis.json" for d in pan_diagnoses()["diagnosis"].values()],
            tests=list(PAN_JOINT_TESTS.values()),
        output:
            csv="results/real/joint_temperature.csv",
            png="results/real/figures/joint_temperature.png",
            pdf="results/real/figures/joint_temperature.pdf",
            traces="results/real/joint_temperature_heat.csv",
            heat_png="results/real/figures/joint_temperature_heat.png",
            heat_pdf="results/real/figures/joint_temperature_heat.pdf",
        log:
            "logs/real/joint/table.log",
        params:
            ambient={t: REAL["panasonic"]["temperatures"][t]["ambient_c"] for t in PAN_EXP_TEMPS},
            own_dirs=pan_diagnoses()["diagnosis"],
            tests=PAN_JOINT_TESTS,
        threads: 1
        localrule: True  # cheap: run by the submitting Snakemake on a cluster
        resources:
            local_job=1,  # profiles/slurm: how many run at once
        script:
            "../scripts/panasonic_joint_table.py"


# ------------------------------------------------------------------------------------------------
# Samsung 30Q and NASA B0005 (jobs in avoa_pipeline.jobs.real, one script per rule). A config
# without real.samsung or real.nasa leaves that dataset's rules out. docs/real-data.md, sections
# "Samsung INR18650-30Q", "NASA B0005".
# ------------------------------------------------------------------------------------------------
REAL_REPORT = "results/real/report"


if SAMSUNG_CFG:

    rule real_samsung_import:
        """One Samsung 30Q HPPC file in the canonical form (time built from the 1 s rows, current
        sign flipped and checked against the voltage, sha256 checked)."""
        input:
            lambda w: plan.source_path(config, SAMSUNG_CFG["hppc"][w.stemp]["file"]),
        output:
            csv=f"{REAL_CANON}/samsung_hppc_{{stemp}}.csv",
            meta=f"{REAL_CANON}/samsung_hppc_{{stemp}}.json",
        wildcard_constraints:
            stemp="|".join(SAMSUNG_TEMPS),
        log:
            "logs/real/canonical/samsung_hppc_{stemp}.log",
        params:  # the Samsung settings, the root and this file's sha256
            cfg=lambda w: config_part("real.root", "real.samsung",
                                      ("real", "sources", SAMSUNG_CFG["hppc"][w.stemp]["file"])),
        threads: 1
        localrule: True  # cheap: run by the submitting Snakemake on a cluster
        resources:
            local_job=1,  # profiles/slurm: how many run at once
        script:
            "../scripts/real_samsung_import.py"

    rule real_samsung_arrhenius:
        """Experiment 2: R0, Rtr, tau per 1C HPPC pulse at each temperature; Arrhenius fits."""
        input:
            expand(f"{REAL_CANON}/samsung_hppc_{{stemp}}.csv", stemp=SAMSUNG_TEMPS),
        output:
            rc=plan.CELL_OUTPUTS["samsung"][0],
            arrhenius=plan.CELL_OUTPUTS["samsung"][1],
        log:
            "logs/real/samsung_arrhenius.log",
        params:
            cfg=config_part("real.samsung"),
            temperatures=SAMSUNG_TEMPS,
        threads: 1
        script:
            "../scripts/real_samsung_arrhenius.py"


if SAMSUNG_FITS:

    rule real_samsung_diagnose:
        """Issue 28 on the Samsung 30Q (docs/real-data.md, its rule): the diagnosis of the training
        temperatures' HPPC tests together (sfit=joint) or of one alone, the unseen temperature's
        test as a validation record only: `python -m avoa_pipeline diagnose TRAIN... --validate
        UNSEEN --out DIR` without its figure."""
        input:
            train=lambda w: [samsung_canon(t) for t in SAMSUNG_FITS[w.sfit]],
            unseen=samsung_canon(SAMSUNG_JOINT["unseen"]),
        output:
            json="results/real/samsung/diagnosis/{sfit}/diagnosis.json",
            model="results/real/samsung/diagnosis/{sfit}/model.json",
        wildcard_constraints:
            sfit=plan.regex(SAMSUNG_FITS),
        log:
            "logs/real/samsung/diagnosis_{sfit}.log",
        benchmark:
            "logs/real/samsung/diagnosis_{sfit}.benchmark.tsv"
        params:
            tests=lambda w: {SAMSUNG_JOINT["unseen"]: samsung_canon(SAMSUNG_JOINT["unseen"])},
        threads: LONG_DIAGNOSIS_THREADS
        script:
            "../scripts/real_samsung_diagnose.py"

    rule real_samsung_joint_table:
        """The unseen temperature's RMSE and largest error, the joint model beside each training
        temperature's own."""
        input:
            expand("results/real/samsung/diagnosis/{sfit}/diagnosis.json", sfit=SAMSUNG_FITS),
        output:
            plan.SAMSUNG_JOINT_TABLE,
        log:
            "logs/real/samsung/joint_table.log",
        params:
            fits=list(SAMSUNG_FITS),
            unseen=samsung_canon(SAMSUNG_JOINT["unseen"]),
        threads: 1
        localrule: True  # cheap: run by the submitting Snakemake on a cluster
        resources:
            local_job=1,  # profiles/slurm: how many run at once
        script:
            "../scripts/real_samsung_joint_table.py"


if NASA_CFG:

    rule real_nasa_import:
        """The 168 NASA B0005 discharges in one canonical record on one time axis (samples where
        measured), each source's sha256 and current sign checked."""
        input:
            [plan.source_path(config, k) for k in plan.nasa_source_sha256(config)],
        output:
            csv=f"{REAL_CANON}/nasa_b0005.csv",
            meta=f"{REAL_CANON}/nasa_b0005.json",
        log:
            "logs/real/canonical/nasa_b0005.log",
        params:  # the NASA settings, the root and the sha256 of the index and every discharge
            cfg=config_part("real.root", "real.nasa",
                            *(("real", "sources", k) for k in plan.nasa_source_sha256(config))),
        threads: 1
        localrule: True  # cheap: run by the submitting Snakemake on a cluster
        resources:
            local_job=1,  # profiles/slurm: how many run at once
        script:
            "../scripts/real_nasa_import.py"

    rule real_nasa_fade:
        """Experiment 3: capacity and 20-s resistance per ageing state; fade laws (eqs. 7-9)."""
        input:
            f"{REAL_CANON}/nasa_b0005.csv",
        output:
            states=plan.CELL_OUTPUTS["nasa"][0],
            fits=plan.CELL_OUTPUTS["nasa"][1],
        log:
            "logs/real/nasa_fade.log",
        params:
            cfg=config_part("real.nasa"),
        threads: 1
        script:
            "../scripts/real_nasa_fade.py"


if SAMSUNG_CFG and NASA_CFG:

    rule real_cells_report:
        """Figures and summary tables of experiments 2 and 3 (notebook; all in the report)."""
        input:
            nb="notebooks/real_cells.ipynb",
            rc=plan.CELL_OUTPUTS["samsung"][0],
            arrhenius=plan.CELL_OUTPUTS["samsung"][1],
            fade=plan.CELL_OUTPUTS["nasa"][0],
            fade_fit=plan.CELL_OUTPUTS["nasa"][1],
        output:
            report(ext(f"{REAL_REPORT}/samsung_rc_temperature", FIG_EXT), category="Real data",
                   subcategory="Samsung 30Q: R0, Rtr, tau against temperature"),
            report(ext(f"{REAL_REPORT}/samsung_arrhenius_summary", TABLE_EXT),
                   category="Real data",
                   subcategory="Samsung 30Q: R0, Rtr, tau against temperature"),
            report(ext(f"{REAL_REPORT}/nasa_fade", FIG_EXT), category="Real data",
                   subcategory="NASA B0005: fade law"),
            report(ext(f"{REAL_REPORT}/nasa_fade_summary", TABLE_EXT), category="Real data",
                   subcategory="NASA B0005: fade law"),
            nb=plan.CELL_OUTPUTS["report"][0],
        log:
            "logs/notebooks/real_cells.log",
        localrule: True  # cheap: run by the submitting Snakemake on a cluster
        resources:
            local_job=1,  # profiles/slurm: how many run at once
        shell:
            papermill("{input.nb}", "{output.nb}", "{log}", rc_csv="{input.rc}",
                      arrhenius_csv="{input.arrhenius}", fade_csv="{input.fade}",
                      fade_fit_csv="{input.fade_fit}", out_dir=REAL_REPORT)


rule real:
    """Every real-data output (`snakemake -j2 real`)."""
    input:
        real_targets(),
