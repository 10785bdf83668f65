# Issue 5, "Checked on withheld effects": datasets with one hidden effect (and PyBaMM records and
# the paper's scenarios), one diagnosis job per record, tables and figures. Optional: without a
# `gap:` section in the config no rule here runs.
import avoa_pipeline.gap.evaluate as gap_eval
from avoa_pipeline.gap import EFFECTS
from avoa_pipeline.gap import withheld as gap_withheld

GAP = config.get("gap")
GAP_TABLES = ("records", "confusion", "accuracy", "detection_limit", "shrink", "target")
GAP_FIGURES = ("confusion", "accuracy", "shrink", "detection_limit")


def _regex(values):
    # a never-matching pattern for an empty list (the rule then makes nothing)
    return "|".join(map(str, values)) if values else "(?!x)x"


if GAP:
    GAP_FULL = sorted(GAP["replicates"])
    GAP_CONTROL_ONLY = sorted(set(GAP["control_replicates"]) - set(GAP["replicates"]))
    GAP_FULL_NAMES = gap_withheld.names(GAP, GAP_FULL[0]) if GAP_FULL else []
    GAP_CONTROL_NAMES = gap_withheld.names({**GAP, "replicates": []}, -1)

    def gap_records():
        """Every withheld-effect dataset as profile/rN/name (no extension)."""
        out = []
        for profile in GAP["profiles"]:
            for rep in gap_withheld.all_replicates(GAP):
                names = GAP_FULL_NAMES if rep in GAP["replicates"] else GAP_CONTROL_NAMES
                out += [f"{profile}/r{rep}/{n}" for n in names]
        return out

    def gap_paper_records():
        return [f"paper/s{s}c{c}" for s in GAP["paper_scenarios"] for c in GAP["paper_cases"]]

    def gap_pybamm_records():
        return [f"pybamm/{n}" for n in GAP["pybamm"]]

    # canonical real records (workflow/rules/real.smk) to diagnose, when the data are there
    GAP_REAL = list(GAP.get("real", [])) if REAL_PRESENT else []

    def gap_outputs():
        return [
            *(f"results/gap/{t}.csv" for t in GAP_TABLES),
            "results/gap/paper_scenarios.csv",
            "results/gap/pybamm.csv",
            *(f"results/gap/figures/{f}.png" for f in GAP_FIGURES),
            *(["results/gap/real.csv"] if GAP_REAL else []),
        ]

    rule gap_data:
        """Every effect × magnitude × noise dataset (and the controls) of one base cell."""
        output:
            expand("results/gap/data/{{profile}}/r{{replicate}}/{name}.{ext}",
                   name=GAP_FULL_NAMES, ext=("csv", "json")),
        wildcard_constraints:
            profile=_regex(GAP["profiles"]),
            replicate=_regex(GAP_FULL),
        log:
            "logs/gap/data/{profile}/r{replicate}.log",
        params:
            grid={k: GAP[k] for k in ("noise_mv", "magnitudes")},
            base_seed=config["base_seed"],
        run:
            gap_eval.generate_job(config["base_seed"], GAP, wildcards.profile,
                                  wildcards.replicate, log[0], workers=workflow.cores)

    rule gap_controls:
        """The `none` controls of a base cell that carries no effect datasets."""
        output:
            expand("results/gap/data/{{profile}}/r{{replicate}}/{name}.{ext}",
                   name=GAP_CONTROL_NAMES, ext=("csv", "json")),
        wildcard_constraints:
            profile=_regex(GAP["profiles"]),
            replicate=_regex(GAP_CONTROL_ONLY),
        log:
            "logs/gap/data/{profile}/r{replicate}.log",
        params:
            noise=GAP["noise_mv"],
            base_seed=config["base_seed"],
        run:
            gap_eval.generate_job(config["base_seed"], GAP, wildcards.profile,
                                  wildcards.replicate, log[0], workers=workflow.cores)

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
        params:
            data=config["data"],
            truth=config["true_params"],
            profile=config["profile"],
        run:
            gap_eval.paper_job(config, wildcards.scenario, wildcards.case, output.csv, log[0])

    rule gap_pybamm_data:
        """A PyBaMM record (DFN or SPMe, lumped thermal, ...): made once, then a cached file."""
        output:
            csv="results/gap/data/pybamm/{name}.csv",
            meta="results/gap/data/pybamm/{name}.json",
        wildcard_constraints:
            name=_regex(GAP["pybamm"]),
        log:
            "logs/gap/data/pybamm/{name}.log",
        params:
            base_seed=config["base_seed"],
        run:
            gap_eval.pybamm_job(config["base_seed"], wildcards.name, output.csv, log[0],
                                workers=workflow.cores)

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
        threads: 1
        run:
            gap_eval.diagnose_job(input[0], output[0], log[0], workers=workflow.cores)

    rule gap_diagnose_real:
        """One diagnosis of a canonical real record (CSV only; its sidecar is not read)."""
        input:
            f"{PAN_CANON}/{{name}}.csv",
        output:
            "results/gap/diagnoses/real/{name}.json",
        wildcard_constraints:
            name=_regex(GAP_REAL),
        log:
            "logs/gap/diagnoses/real/{name}.log",
        threads: 1
        run:
            gap_eval.diagnose_job(input[0], output[0], log[0], workers=workflow.cores)

    rule gap_real_table:
        """Verdicts on real records: what the paper's model misses on measured cells."""
        input:
            data=[f"{PAN_CANON}/{n}.csv" for n in GAP_REAL],
            diag=[f"results/gap/diagnoses/real/{n}.json" for n in GAP_REAL],
        output:
            report("results/gap/real.csv", category="Gap diagnosis", subcategory="Real records"),
        log:
            "logs/gap/real.log",
        run:
            gap_eval.table_job(gap_eval.real_record, input.data, input.diag, output[0], log[0])

    rule gap_evaluate:
        """Confusion matrix, accuracy, detection limit, shrink, target check."""
        input:
            data=[f"results/gap/data/{r}.json" for r in gap_records()],
            diag=[f"results/gap/diagnoses/{r}.json" for r in gap_records()],
        output:
            **{t: report(f"results/gap/{t}.csv", category="Gap diagnosis",
                         subcategory="Withheld effects") for t in GAP_TABLES},
        params:
            threshold=GAP["threshold"],
        log:
            "logs/gap/evaluate.log",
        run:
            gap_eval.evaluate_job(input.data, input.diag, dict(output), GAP["threshold"], log[0])

    rule gap_paper_table:
        """What the paper's scenarios look like to a model without load or fade."""
        input:
            data=[f"results/gap/data/{r}.json" for r in gap_paper_records()],
            diag=[f"results/gap/diagnoses/{r}.json" for r in gap_paper_records()],
        output:
            report("results/gap/paper_scenarios.csv", category="Gap diagnosis",
                   subcategory="Paper scenarios"),
        log:
            "logs/gap/paper_scenarios.log",
        run:
            gap_eval.table_job(gap_eval.paper_record, input.data, input.diag, output[0], log[0])

    rule gap_pybamm_table:
        """Verdicts on the PyBaMM records against the effects each holds."""
        input:
            data=[f"results/gap/data/{r}.json" for r in gap_pybamm_records()],
            diag=[f"results/gap/diagnoses/{r}.json" for r in gap_pybamm_records()],
        output:
            report("results/gap/pybamm.csv", category="Gap diagnosis", subcategory="PyBaMM"),
        log:
            "logs/gap/pybamm.log",
        run:
            gap_eval.table_job(gap_eval.pybamm_record, input.data, input.diag, output[0], log[0])

    rule gap_notebook:
        """Figures: confusion matrix, accuracy, shrink, detection limit."""
        input:
            nb="notebooks/gap_validation.ipynb",
            tables=[f"results/gap/{t}.csv" for t in GAP_TABLES],
            paper="results/gap/paper_scenarios.csv",
            pybamm="results/gap/pybamm.csv",
            real=["results/gap/real.csv"] if GAP_REAL else [],
        output:
            *(report(f"results/gap/figures/{f}.png", category="Gap diagnosis",
                     subcategory="Withheld effects") for f in GAP_FIGURES),
            nb="results/notebooks/gap_validation.ipynb",
        log:
            "logs/notebooks/gap_validation.log",
        shell:
            papermill("{input.nb}", "{output.nb}", "{log}", tables_dir="results/gap",
                      out_dir="results/gap/figures")

    rule gap:
        """The withheld-effect check: every table and figure of this file."""
        input:
            gap_outputs(),

else:

    def gap_outputs():
        return []
