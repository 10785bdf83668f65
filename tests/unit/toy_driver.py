"""Runs the toy element (toy_element.py) through the package in a process of its own, the
registry line first: ``python toy_driver.py`` prints JSON of what tests/unit/test_toy_element.py
asserts. A process of its own because the model library lays out its columns and compiles its
simulator for the registry it finds when imported (``elements.register``)."""

from __future__ import annotations

import dataclasses
import json

import toy_element

from avoa_pipeline.model import elements

elements.register(toy_element.ELEMENT)  # the one registry line

import numpy as np  # noqa: E402 - after the registry line, as the model library must be
import test_ecm  # noqa: E402
import test_estimate as te  # noqa: E402

from avoa_pipeline import estimate as E  # noqa: E402
from avoa_pipeline.interop import pybamm as X  # noqa: E402
from avoa_pipeline.interop import table as T  # noqa: E402
from avoa_pipeline.model import ecm, fitting  # noqa: E402

TOY = toy_element.ELEMENT.name
test_ecm.ACTIVE[TOY] = {"ocv_tilt_v": toy_element.TILT_V}


def main() -> dict:
    out = {"registered": TOY in ecm.EFFECTS, "own_loop": ecm.COMPILED.__name__}
    model = te.fitted("table", ("second_rc", TOY))
    frame = te.drive(seconds=1200)
    v = model.simulate(frame, soc0=te.SOC0)
    bare = te.fitted("table", ("second_rc",)).simulate(frame, soc0=te.SOC0)
    out["toy_acts_mv"] = 1e3 * float(np.max(np.abs(v - bare)))

    # a fit of the toy's parameter from its own starts, the cell's others known (on 20 min a
    # tilt of the OCV and a slow RC branch trade: with all free the fit may end in that valley)
    rec = model.record(frame.assign(voltage_v=v))
    st = fitting.structure([rec], model.config, model.knots, fix_capacity=True, fix_soc0=True)
    own = [st.shared.index(n) for n in toy_element.ELEMENT.params]
    st = dataclasses.replace(st, shared=tuple(toy_element.ELEMENT.params), lo=st.lo[own],
                             hi=st.hi[own], prior=st.prior[own])  # fmt: skip
    X0 = model.x.copy()[None, :]
    X0[0, ecm.IDX["tilt"]] = 0.0
    X0[0, ecm.IDX["soc0"]] = te.SOC0  # given: the rest rule's formula has today's OCV terms only
    fit = fitting.best_of([rec], st, fitting.effect_starts([rec], X0, TOY))
    out["fitted_tilt_v"] = float(ecm.report(fit.X[0], ("tilt",))["ocv_tilt_v"])
    out["true_tilt_v"] = toy_element.TILT_V

    # the filter: its open loop against simulate
    got = E.open_loop(E.filter_model(model), E.Inputs.of(model.record(frame)), te.SOC0)
    out["filter_open_loop_max_v"] = float(np.max(np.abs(got - v)))
    est = E.estimate_record(model, frame.assign(voltage_v=v), 0.7, 0.0, te.SOC0)
    out["filter_final_soc_error"] = float(est.summary["filter"]["max_error_after_window"])

    # the table: its ocv_v is the simulator's voltage at rest at each SOC
    table, _ = T.export_table(model, "m.json", soc=np.linspace(0.05, 0.95, 7))
    rest = frame.iloc[:2].assign(current_a=0.0)
    at_rest = [float(model.simulate(rest, soc0=float(s))[0]) for s in table["soc"]]
    out["table_ocv_vs_rest_max_v"] = float(np.max(np.abs(table["ocv_v"] - at_rest)))
    out["table_expresses_toy"] = TOY in T.EXPRESSED

    # PyBaMM: the written module against simulate
    cell = X.load_source(X.export(model, "model.json", soc0=te.SOC0).text)
    theirs = cell.simulate(frame["time_s"], frame["current_a"], frame["temperature_c"])
    out["pybamm_rms_mv"] = 1e3 * float(np.sqrt(np.mean((np.asarray(theirs) - v) ** 2)))
    return out


if __name__ == "__main__":
    print(json.dumps(main()))
