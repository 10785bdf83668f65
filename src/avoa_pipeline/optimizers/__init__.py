"""Optimizers, keyed by the one name used everywhere (config, CLI, file names).

Importing this package registers all seven algorithms of the paper in ``REGISTRY``.
"""

import importlib

from .base import REGISTRY, Budget, OptimResult, Tracker, minimize, register

ALGORITHMS = ("nelder_mead", "quasi_newton", "ga", "gwo", "run", "avoa", "gto")
"""The paper's seven algorithms, in the column order of its Tables 4-24."""

PAPER_LABELS = {
    "nelder_mead": "Nelder–Mead",
    "quasi_newton": "Quasi-Newton",
    "ga": "GA",
    "gwo": "GWO",
    "run": "RK",
    "avoa": "AVOA",
    "gto": "GTO",
}
"""The paper's column headings (it calls the Runge-Kutta optimizer RUN "RK")."""

for _name in ALGORITHMS:
    try:
        importlib.import_module(f"{__name__}.{_name}")
    except ModuleNotFoundError as exc:  # DEV-ONLY: remove once all seven modules exist
        if exc.name != f"{__name__}.{_name}":
            raise

__all__ = [
    "ALGORITHMS",
    "PAPER_LABELS",
    "REGISTRY",
    "Budget",
    "OptimResult",
    "Tracker",
    "minimize",
    "register",
]
