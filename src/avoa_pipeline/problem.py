"""One identification problem: a dataset, the model of a scenario × case, the searched box.

The objective maps a population of *free* parameter vectors (the case's identified parameters,
in the paper's table order) to ISE values (eq. 13); parameters a case does not identify are held
at the cell's known values.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from . import config as config_mod
from . import records, synthetic
from .errors import DataError
from .io import sidecar_of, uniform_step
from .model import kernel
from .model.battery import (
    CASES,
    PARAM_NAMES,
    ModelSpec,
    first_sample_soc0,
    ise,
    simulate,
    vector,
)


@dataclass
class Problem:
    scenario: int
    case: int
    names: tuple[str, ...]
    lb: np.ndarray
    ub: np.ndarray
    fixed: np.ndarray  # full vector; free entries are overwritten by candidates
    truth: np.ndarray | None  # full fresh-cell truth, when known
    spec: ModelSpec
    time_s: np.ndarray
    current_a: np.ndarray
    voltage_v: np.ndarray
    notes: tuple[str, ...] = ()  # what the data could not tell (records.check_scale's warnings)
    soc0_rule: str = "given"  # or "first_sample": each candidate's own (battery.first_sample_soc0)

    @property
    def ts(self) -> float:
        return float(self.time_s[1] - self.time_s[0])

    @property
    def free_index(self) -> list[int]:
        return [PARAM_NAMES.index(n) for n in self.names]

    def full(self, X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        P = np.tile(self.fixed, (X.shape[0], 1))
        P[:, self.free_index] = X
        return P

    def objective(self, X: np.ndarray) -> np.ndarray:
        P = self.full(X)
        if self.soc0_rule == "given":
            return ise(P, self.current_a, self.voltage_v, self.ts, self.spec)
        return np.array([ise(P[r : r + 1], self.current_a, self.voltage_v, self.ts,
                             spec)[0] for r, spec in enumerate(self.specs(P))])  # fmt: skip

    def specs(self, P: np.ndarray) -> list[ModelSpec]:
        """Per row of full vectors ``P``, the simulation's spec with the start the rule gives
        (``soc0_rule``: the spec's own, or each row's from the record's first sample)."""
        if self.soc0_rule == "given":
            return [self.spec] * P.shape[0]
        s0 = first_sample_soc0(P * self.spec.fade_factors, self.voltage_v[0], self.current_a[0],
                               self.spec.qdis_ah)  # fmt: skip
        return [replace(self.spec, soc0=float(s)) for s in s0]

    @cached_property
    def _one_args(self) -> tuple:
        # built once: argument assembly would cost more than the simulation itself otherwise
        spec = self.spec
        return (
            np.asarray(self.free_index, dtype=np.int64),
            np.ascontiguousarray(self.fixed, dtype=float),
            np.ascontiguousarray(spec.fade_factors, dtype=float),
            np.ascontiguousarray(self.current_a, dtype=float),
            np.ascontiguousarray(self.voltage_v, dtype=float),
            self.ts,
            spec.soc0,
            spec.qdis_ah,
            spec.g_load,
            spec.dynamics,
        )

    def objective_one(self, x: np.ndarray) -> float:
        """:meth:`objective` of one candidate, as a float (the same compiled steps, bit for bit)."""
        if self.soc0_rule != "given":
            return float(self.objective(np.asarray(x)[None, :])[0])
        return kernel.ise_one(np.ascontiguousarray(x, dtype=float), *self._one_args)

    def simulate(self, x_free) -> dict:
        P = self.full(x_free)
        return simulate(P[0], self.current_a, self.ts, self.specs(P)[0])

    def true_free(self) -> np.ndarray | None:
        return None if self.truth is None else self.truth[self.free_index]


def build(
    cfg: dict, scenario: int, case: int, data: str | Path | None = None, noise: bool = True
) -> Problem:
    """The problem of ``scenario`` × ``case`` on ``data`` (default: generated in memory)."""
    c = CASES[case]
    names, lb, ub = config_mod.bounds(cfg, case)
    truth_cfg = cfg["true_params"][c.temperature]

    def fixed_of(meta: dict) -> np.ndarray:
        return vector(meta.get("true_params", truth_cfg))

    def q_max(meta: dict) -> float:  # the largest capacity the fit may find
        q = PARAM_NAMES.index("q")
        return float(ub[names.index("q")] if "q" in names else fixed_of(meta)[q])

    notes = ()
    if data is None:
        ds = synthetic.generate(cfg, scenario, case, noise=noise)
        t, i, v, meta = ds.time_s, ds.current_a, ds.voltage_v, ds.meta
    else:  # ms, mA, mV, minutes, a sign or a sidecar that does not fit: refused before any fit
        # (records.read: a known capacity tells the units)
        rec = records.read(data, keys=(), required=records.REQUIRED, min_samples=3,
                           capacity_ah=q_max)  # fmt: skip
        t, i, v = (rec.frame[k].to_numpy() for k in ("time_s", "current_a", "voltage_v"))
        uniform_step(data, t)
        meta, notes = rec.meta, rec.warnings
        if meta and (meta.get("scenario"), meta.get("case")) != (scenario, case):
            raise DataError(
                f"{sidecar_of(data)}: field scenario/case: is {meta.get('scenario')}/"
                f"{meta.get('case')}, the fit asked for {scenario}/{case}"
            )
    truth = vector(meta["true_params"]) if "true_params" in meta else None
    fixed = fixed_of(meta)
    spec = ModelSpec.for_scenario_case(cfg["constants"], scenario, case)
    return Problem(
        scenario,
        case,
        names,
        np.array(lb),
        np.array(ub),
        fixed,
        truth,
        spec,
        np.asarray(t),
        np.asarray(i),
        np.asarray(v),
        notes,
    )


def on_record(names, lb, ub, current_a, voltage_v, ts: float, dynamics: bool,
              qdis_ah: float) -> Problem:  # fmt: skip
    """The paper's model (no load, no fade) on a measured record: ``names`` free in [lb, ub], the
    others at 0 (τ at 1 s: unused without dynamics, but finite), each candidate started by the
    record's first sample (``soc0_rule="first_sample"``); no scenario, case or truth."""
    fixed = np.zeros(len(PARAM_NAMES))
    fixed[PARAM_NAMES.index("tau")] = 1.0
    spec = ModelSpec(dynamics=dynamics, fade_factors=np.ones(6), load_ohm=None, soc0=0.0,
                     qdis_ah=qdis_ah)  # fmt: skip
    current_a, voltage_v = (np.ascontiguousarray(a, dtype=float) for a in (current_a, voltage_v))
    time_s = np.arange(current_a.size) * ts  # t[1] − t[0] is ts exactly
    return Problem(None, None, tuple(names), np.asarray(lb, dtype=float),
                   np.asarray(ub, dtype=float), fixed, None, spec, time_s, current_a, voltage_v,
                   soc0_rule="first_sample")  # fmt: skip
