"""The jobs of ``workflow/rules/estimate.smk``: SOC estimation with the selected models on the
unseen Panasonic cycles (issue 29; docs/real-data.md "SOC estimation (issue 29)")."""

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
    write_log(log, f"wrote {out_csv}, {figure_stem}.png: {len(table)} runs; largest RMSE after "
                   f"5 min: {by_temp}")  # fmt: skip
