"""The jobs of ``workflow/rules/estimate.smk``: SOC estimation with the selected models on the
unseen Panasonic cycles (issue 29; docs/real-data.md "SOC estimation (issue 29)").

``python -m avoa_pipeline.jobs.estimate --models DIR --canonical DIR --out CSV`` runs the same
job without Snakemake (DIR/<temperature>/model.json, the cycles of ``soc_estimation.UNSEEN``;
``--one-model M`` instead runs one model at every temperature, issue 28's joint model;
``--records 30degC/hppc=CSV ...`` runs other records, another cell's). It lives
here, not in the experiment, because it draws: experiments never import ``report``."""

from __future__ import annotations

from ..io import write_log


def soc_estimation(models: dict, tests: dict, out_csv, figure_stem, log=None) -> None:
    """``soc_estimation.csv`` and its figure: at each temperature (``models``: temperature →
    model.json), the four runs of the protocol on its unseen cycles (``tests``: temperature →
    cycle → canonical CSV)."""
    from ..io import atomic_path
    from ..real.experiments import soc_estimation as se
    from ..report import estimate_figures

    table = se.soc_estimation_table(dict(models), {t: dict(c) for t, c in tests.items()})
    with atomic_path(out_csv) as tmp:
        table.to_csv(tmp, index=False)
    estimate_figures.soc_estimation_figure(table, figure_stem, se.GOALS)
    worst = table.groupby("temperature")["rmse_after_window"].max()
    by_temp = ", ".join(f"{t} {100 * v:.2f} %" for t, v in worst.items())
    text = (f"wrote {out_csv}, {figure_stem}.png: {len(table)} runs; largest RMSE after 5 min: "
            f"{by_temp}\n{se.rule_summary(table).to_string(index=False)}")  # fmt: skip
    write_log(log, text)
    if not log:  # run from the command line: the summary on stdout
        print(text)


def main(argv=None) -> None:
    import argparse
    from pathlib import Path

    from ..real.experiments import soc_estimation as se

    p = argparse.ArgumentParser(description=se.__doc__.splitlines()[0])
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--models", help="DIR/<temperature>/model.json")
    which.add_argument("--one-model", help="one model.json for every temperature (issue 28's)")
    records = p.add_mutually_exclusive_group(required=True)
    records.add_argument("--canonical", help="the canonical Panasonic records' folder")
    records.add_argument("--records", nargs="+", metavar="TEMPERATURE/CYCLE=CSV",
                         help="another cell's records (with --one-model or --models)")  # fmt: skip
    p.add_argument("--temperatures", nargs="+", default=list(se.UNSEEN))
    p.add_argument("--out", required=True, help="CSV; the figure goes beside it (.png, .pdf)")
    args = p.parse_args(argv)
    if args.records:
        tests = _named_records(p, args.records)
    else:
        tests = {t: {c: str(Path(args.canonical) / f"panasonic_{t}_{c}.csv")
                     for c in se.UNSEEN[t]} for t in args.temperatures}  # fmt: skip
    if args.one_model:
        models = dict.fromkeys(tests, args.one_model)
    else:
        models = {t: str(Path(args.models) / t / "model.json") for t in tests}
    soc_estimation(models, tests, args.out, str(Path(args.out).with_suffix("")))


def _named_records(parser, given: list[str]) -> dict[str, dict[str, str]]:
    """``TEMPERATURE/CYCLE=CSV`` pairs as the experiment's temperature → cycle → record."""
    tests: dict[str, dict[str, str]] = {}
    for item in given:
        name, sep, path = item.partition("=")
        temp, slash, cycle = name.partition("/")
        if not (sep and slash and temp and cycle and path):
            parser.error(f"--records: {item!r} is not TEMPERATURE/CYCLE=CSV")
        tests.setdefault(temp, {})[cycle] = path
    return tests


if __name__ == "__main__":
    main()
