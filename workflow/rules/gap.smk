# Issue 5, "Checked on withheld effects": datasets with one hidden effect, with two at once
# (`gap.pairs`), PyBaMM records and the paper's scenarios; one diagnosis job per record, tables
# and figures. Optional: without a
# `gap:` section in the config no rule here runs. The plan (GAP_PLAN: records and outputs) is made in
# common.smk.


if GAP:

    rule gap_data:
        """Every effect × magnitude × noise dataset (and the controls) of one base cell."""
        output:
            expand("results/gap/data/{{profile}}/r{{replicate}}/{name}.{ext}",
                   name=GAP_PLAN["full_names"], ext=("csv", "json")),
        wildcard_constraints:
            profile=plan.regex(GAP["profiles"]),
            replicate=plan.regex(GAP_PLAN["full_replicates"]),
        log:
            "logs/gap/data/{profile}/r{replicate}.log",
        params:
            grid=lambda w: gap_grid(w, "noise_mv", "magnitudes"),
            base_seed=config["base_seed"],
            out_dir=gap_dir,
        threads: 1
        script:
            "../scripts/gap_data.py"

    rule gap_controls:
        """The `none` controls of a base cell that carries no effect datasets."""
        output:
            expand("results/gap/data/{{profile}}/r{{replicate}}/{name}.{ext}",
                   name=GAP_PLAN["control_names"], ext=("csv", "json")),
        wildcard_constraints:
            profile=plan.regex(GAP["profiles"]),
            replicate=plan.regex(GAP_PLAN["control_only"]),
        log:
            "logs/gap/data/{profile}/r{replicate}.log",
        params:
            grid=lambda w: gap_grid(w, "noise_mv"),
            base_seed=config["base_seed"],
            out_dir=gap_dir,
        threads: 1
        script:
            "../scripts/gap_data.py"

    if GAP_PLAN["pair_names"]:

        rule gap_pair_data:
            """Every pair of effects (gap.pairs) × its noise levels on one effect-carrying cell."""
            output:
                expand("results/gap/data/{{profile}}/r{{replicate}}/{name}.{ext}",
                       name=GAP_PLAN["pair_names"], ext=("csv", "json")),
            wildcard_constraints:
                profile=plan.regex(GAP["profiles"]),
                replicate=plan.regex(GAP_PLAN["full_replicates"]),
            log:
                "logs/gap/data/{profile}/r{replicate}.pairs.log",
            params:
                grid=lambda w: gap_grid(w, "noise_mv", "magnitudes", "pairs"),
                base_seed=config["base_seed"],
                out_dir=gap_dir,
            threads: 1
            script:
                "../scripts/gap_pair_data.py"

        rule gap_pairs_table:
            """Two effects at once: per record, both named? anything extra? (pairs.csv)."""
            input:
                data=[f"results/gap/data/{r}.json" for r in GAP_PLAN["pair_records"]],
                diag=[f"results/gap/diagnoses/{r}.json" for r in GAP_PLAN["pair_records"]],
            output:
                report("results/gap/pairs.csv", category="Gap diagnosis",
                       subcategory="Two effects at once"),
            params:
                threshold=GAP["threshold"],
            log:
                "logs/gap/pairs.log",
            threads: 1
            localrule: True  # cheap: run by the submitting Snakemake on a cluster
            resources:
                local_job=1,  # profiles/slurm: how many run at once
            script:
                "../scripts/gap_pairs_table.py"

    rule gap_paper_data:
        """A paper scenario × case as the main workflow simulates it, to be diagnosed."""
        output:
            csv="results/gap/data/paper/s{scenario}c{case}.csv",
            meta="results/gap/data/paper/s{scenario}c{case}.json",
        wildcard_constraints:
            scenario="[1-4]",
            case="[1-4]",
        log:
            "logs/gap/data/paper/s{scenario}c{case}.log",
        params:  # what the dataset is made from (plan.DATASET_PARTS)
            settings=config_part(*plan.DATASET_PARTS),
        threads: 1
        script:
            "../scripts/gap_paper_data.py"

    rule gap_pybamm_data:
        """A PyBaMM record (DFN or SPMe, lumped thermal, ...): made once, then a cached file."""
        output:
            csv="results/gap/data/pybamm/{name}.csv",
            meta="results/gap/data/pybamm/{name}.json",
        wildcard_constraints:
            name=plan.regex(GAP["pybamm"]),
        log:
            "logs/gap/data/pybamm/{name}.log",
        params:
            base_seed=config["base_seed"],
        threads: 1
        script:
            "../scripts/gap_pybamm_data.py"

    rule gap_diagnose:
        """One diagnosis (the CSV only, as a user runs it) of one record."""
        input:
            "results/gap/data/{record}.csv",
        output:
            "results/gap/diagnoses/{record}.json",
        wildcard_constraints:
            record=r"(?!real/)[\w/.-]+",
        log:
            "logs/gap/diagnoses/{record}.log",
        group:
            "diagnoses"  # cluster executors only (profiles/slurm)
        threads: 1
        resources:
            group_lane=1,  # profiles/slurm: a group's members run one after another
        script:
            "../scripts/gap_diagnose.py"

    rule gap_diagnose_real:
        """One diagnosis of a canonical real record (CSV only; its sidecar is not read)."""
        input:
            f"{REAL_CANON}/{{name}}.csv",
        output:
            "results/gap/diagnoses/real/{name}.json",
        wildcard_constraints:
            name=plan.regex(GAP_PLAN["real"]),
        log:
            "logs/gap/diagnoses/real/{name}.log",
        group:
            "diagnoses"  # cluster executors only (profiles/slurm)
        threads: 1
        resources:
            group_lane=1,  # profiles/slurm: a group's members run one after another
        script:
            "../scripts/gap_diagnose.py"

    rule gap_real_table:
        """Verdicts on real records: what the paper's model misses on measured cells."""
        input:
            data=[f"{REAL_CANON}/{n}.csv" for n in GAP_PLAN["real"]],
            diag=[f"results/gap/diagnoses/real/{n}.json" for n in GAP_PLAN["real"]],
        output:
            report("results/gap/real.csv", category="Gap diagnosis", subcategory="Real records"),
        log:
            "logs/gap/real.log",
        threads: 1
        localrule: True  # cheap: run by the submitting Snakemake on a cluster
        resources:
            local_job=1,  # profiles/slurm: how many run at once
        script:
            "../scripts/gap_real_table.py"

    rule gap_evaluate:
        """Confusion matrix, accuracy, detection limit, shrink, target check (with the pairs')."""
        input:
            data=[f"results/gap/data/{r}.json" for r in GAP_PLAN["records"]],
            diag=[f"results/gap/diagnoses/{r}.json" for r in GAP_PLAN["records"]],
            pairs=["results/gap/pairs.csv"] if GAP_PLAN["pair_records"] else [],
        output:
            **{t: report(f"results/gap/{t}.csv", category="Gap diagnosis",
                         subcategory="Withheld effects") for t in plan.GAP_TABLES},
        params:
            threshold=GAP["threshold"],
        log:
            "logs/gap/evaluate.log",
        threads: 1
        localrule: True  # cheap: run by the submitting Snakemake on a cluster
        resources:
            local_job=1,  # profiles/slurm: how many run at once
        script:
            "../scripts/gap_evaluate.py"

    rule gap_paper_table:
        """What the paper's scenarios look like to a model without load or fade."""
        input:
            data=[f"results/gap/data/{r}.json" for r in GAP_PLAN["paper"]],
            diag=[f"results/gap/diagnoses/{r}.json" for r in GAP_PLAN["paper"]],
        output:
            report("results/gap/paper_scenarios.csv", category="Gap diagnosis",
                   subcategory="Paper scenarios"),
        params:
            threshold=GAP["threshold"],
        log:
            "logs/gap/paper_scenarios.log",
        threads: 1
        localrule: True  # cheap: run by the submitting Snakemake on a cluster
        resources:
            local_job=1,  # profiles/slurm: how many run at once
        script:
            "../scripts/gap_paper_table.py"

    rule gap_pybamm_table:
        """Verdicts on the PyBaMM records against the effects each holds."""
        input:
            data=[f"results/gap/data/{r}.json" for r in GAP_PLAN["pybamm"]],
            diag=[f"results/gap/diagnoses/{r}.json" for r in GAP_PLAN["pybamm"]],
        output:
            report("results/gap/pybamm.csv", category="Gap diagnosis", subcategory="PyBaMM"),
        log:
            "logs/gap/pybamm.log",
        threads: 1
        localrule: True  # cheap: run by the submitting Snakemake on a cluster
        resources:
            local_job=1,  # profiles/slurm: how many run at once
        script:
            "../scripts/gap_pybamm_table.py"

    rule gap_notebook:
        """Figures: confusion matrix, accuracy, shrink, detection limit."""
        input:
            nb="notebooks/gap_validation.ipynb",
            tables=[f"results/gap/{t}.csv" for t in plan.GAP_TABLES],
            paper="results/gap/paper_scenarios.csv",
            pybamm="results/gap/pybamm.csv",
            real=["results/gap/real.csv"] if GAP_PLAN["real"] else [],
            pairs=["results/gap/pairs.csv"] if GAP_PLAN["pair_records"] else [],
        output:
            *(report(f"results/gap/figures/{f}.png", category="Gap diagnosis",
                     subcategory="Withheld effects") for f in plan.GAP_FIGURES),
            nb="results/notebooks/gap_validation.ipynb",
        log:
            "logs/notebooks/gap_validation.log",
        localrule: True  # cheap: run by the submitting Snakemake on a cluster
        resources:
            local_job=1,  # profiles/slurm: how many run at once
        shell:
            papermill("{input.nb}", "{output.nb}", "{log}", tables_dir="results/gap",
                      out_dir="results/gap/figures")

    rule gap:
        """The withheld-effect check: every table and figure of this file."""
        input:
            GAP_OUTPUTS,

