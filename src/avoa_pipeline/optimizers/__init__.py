"""Optimizers, keyed by the one name used everywhere (config, CLI, file names).

Importing this package registers all seven algorithms of the paper in ``REGISTRY``.
"""

from ..names import ALGORITHMS
from . import avoa, ga, gto, gwo, nelder_mead, quasi_newton, run  # noqa: F401 - registers each
from .base import (
    REGISTRY,
    Budget,
    OptimResult,
    Runs,
    drive,
    minimize,
    minimize_together,
    register,
)

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

__all__ = [
    "ALGORITHMS",
    "PAPER_LABELS",
    "REGISTRY",
    "Budget",
    "OptimResult",
    "Runs",
    "drive",
    "minimize",
    "minimize_together",
    "register",
]
