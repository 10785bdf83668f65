"""Experiment 1's cross-cycle diagnostic: how far a model can get on these drive cycles at all.

A diagnostic, used for no choice (docs/real-data.md, "How far the circuit itself can go"). Each
model (a configuration of the library, ``model/ecm.py``) is fitted (``model.fitted.fit_model``)
to every drive cycle of one temperature in turn and run on all of them, starting each record by
the library's one initial-SOC rule. The diagonal (fitted and scored on the same cycle) is what
the model reaches on that cycle when it may see that very cycle; an unseen cycle's prediction
error above its diagonal is what the transfer from the training cycle costs.
"""

from __future__ import annotations

import pandas as pd

from ...model.ecm import Config
from .drive_cycles import fit_and_predict


def fit_each_predict_all(temp: str, cycles: dict[str, pd.DataFrame],
                         models: dict[str, Config]) -> list[dict]:  # fmt: skip
    """One row per (model, cycle fitted on, cycle predicted): RMSE and maximum error, and
    ``in_sample`` where the two cycles are the same."""
    rows = []
    for name, config in models.items():
        for fit_on, frame in cycles.items():
            rec = fit_and_predict(frame, config, cycles)
            for predict, err in rec["cycles"].items():
                rows.append({"temperature": temp, "model": name,
                             "effects": "+".join(config.effects), "fit_on": fit_on,
                             "predict": predict, "in_sample": fit_on == predict,
                             "train_rmse_mv": rec["train_rmse_mv"], **err})  # fmt: skip
    return rows
