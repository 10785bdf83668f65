"""A fitted model (``model.json``) as PyBaMM's Thevenin equivalent-circuit model.

``python -m avoa_pipeline export DIR/model.json --to pybamm --out cell.py`` writes a Python module
in PyBaMM's own parameter-set convention (the form of PyBaMM's bundled sets, e.g.
``pybamm/input/parameters/ecm/example_set.py``): ``get_parameter_values()`` returns the dict for
``pybamm.ParameterValues``, ``OPTIONS`` the options of ``pybamm.equivalent_circuit.Thevenin``, and
``drive``/``simulate`` run it on a record as this package's records define the current (row k's
current held over [t_k, t_k+1)). It imports only PyBaMM and NumPy. Why a module and not a JSON:
the SOC, temperature and current dependences are functions, which a module states as readable
formulas through PyBaMM's long-stable public API (``Interpolant``, ``exp``), while PyBaMM's own
JSON (``ParameterValues.to_json``) stores them in its internal expression-tree format
(docs/pybamm.md).

Every element of the model library declares how it maps onto Thevenin's parameters, or why it
cannot (``Element.pybamm``, ``model/elements/``). An element that maps contributes a ``Piece``
(constants, helper functions, terms of the OCV, RC branches, factors and terms of the
resistances; issue 28: submodels for states beyond Thevenin's, their parameters and states, a
term of drive()'s current); the module text is assembled here from the pieces, and
:func:`parameter_values` / :func:`pybamm_model` execute that same text, so the file and the
in-process model cannot differ. Since issue 28 every element maps: diffusion and hysteresis are
states of their own (submodels written in the module; their ODEs are our zero-order-hold
updates exactly for a held current), and SOC-dependent resistances read the SoC at the start of
each interval of a record (``soc_at_interval_start``), as our simulator holds them.
``export --record`` runs the module on the record (:func:`agreement`) before it is written.

A model.json's ``heat`` block (``model/heat.py``) becomes the module's thermal state (issue 28
item 4, :func:`thermal_block`): a submodel of its own, ``LumpedHeat``, not PyBaMM's cell-jig
``ThermalSubModel``, because q = I·(OCV − V) − I·T·dU/dT read from the model's own variables
counts every overpotential (hysteresis, Butler–Volmer's I·η) as heat.py does, where PyBaMM's
sums its elements' I²R-type heats and the diffusion overpotential only. It holds the
temperature and the heat over each interval as our simulator and heat.py do (gated states).
The module's ``simulate(..., ambient_c=...)`` predicts the temperature from the ambient;
``export --record`` compares it with heat.py's prediction (:func:`thermal_agreement`).

Hand-written: PyBaMM has no importer for a foreign equivalent-circuit model; the mapping is the
point of this module. PyBaMM is imported only by the functions that need it (optional extra).
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import textwrap
import types
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .. import __version__
from ..errors import UserError
from ..model import ecm, elements, fitting
from ..model.elements.coulombic_efficiency import counted_piece
from ..model.elements.element import Physical, Piece, flat_ends
from ..model.elements.second_rc import rc_piece
from ..model.fitted import FittedModel

INSTALL = "pip install 'avoa-pipeline[pybamm]'"
DEFAULT_SOC0 = 1.0
"""model.json holds the cell, not a record's initial state: without --soc0 or --record the
export starts full (PyBaMM's ``sim.solve(initial_soc=...)`` overrides it)."""
VOLTAGE_CUTOFFS_V = (0.0, 6.0)
"""The model knows no cut-off voltages; these are wide (the package accepts cell voltages in
0.5-6 V) so that they never stop a simulation of a record. Set the cell's own."""
SOLVER_TOL = 1e-6
"""rtol = atol of the IDAKLU solver in the generated ``simulate``: 0.012-0.017 mV RMS (0.06 mV at
worst) from our simulator on records of 2,222 and 15,000 samples, where IDAKLU's defaults give
up to 0.094 mV RMS and 0.33 mV at worst (``benchmarks/bench_pybamm_export.py``, docs/pybamm.md)."""
AGREEMENT_RMS_MV = 0.1
"""What the export promises: PyBaMM's voltage from the module within 0.1 mV RMS of our
simulator's on a record (the unit tests' bound, docs/pybamm.md); ``export --record`` measures it
on the record and warns above it."""
CHUNK_SAMPLES = 500
"""The generated ``simulate`` solves a record in pieces of this many intervals: PyBaMM's time per
step grows with the length of the held current. 15,000 samples: 68 s in one piece, 12-17 s in
pieces of 250-2,000 (``benchmarks/bench_pybamm_export.py --sizes 15000 --chunks ...``)."""


def require_pybamm():
    """PyBaMM, or a one-line UserError saying how to install it (telemetry off before import)."""
    os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")
    try:
        import pybamm
    except ImportError:
        raise UserError(
            f"export --to pybamm needs PyBaMM, which is not installed: {INSTALL}"
        ) from None
    return pybamm


# ----------------------------------------------------------------------------------------------
# the mapping table


BASE_HOW = (
    "the OCV as a function of SoC (a measured table: a linear interpolant through its points, "
    "flat beyond them, plus the fitted offset; the paper's rational curve, eq. 5: its closed "
    "form, SOC clipped to [0, 1.2]); R0 [Ohm]; RC branch 1 as R1 [Ohm], C1 [F] = τ1/R1; "
    "Cell capacity [A.h]; Initial SoC"
)


def unsupported(model: FittedModel) -> list[str]:
    """The model's elements that PyBaMM's Thevenin model cannot hold."""
    return [e for e in model.config.effects if not elements.get(e).pybamm.exported]


def check_one_set(model: FittedModel, source: str) -> None:
    """A model of per-temperature parameter sets (``by_temperature``) is refused in one line:
    PyBaMM's Thevenin parameters may be functions of the cell temperature, but the sets are
    chosen by a record's ambient, and the capacity and time constants per set would need
    interpolants of their own over the ambient (docs/temperature-rule.md, part 3's check)."""
    if model.by_temperature is not None:
        temps = ", ".join(f"{a:g}" for a, _ in model.by_temperature)
        raise UserError(f"{source}: field 'by_temperature': per-temperature parameter sets "
                        f"({temps} °C) cannot be exported to PyBaMM's Thevenin model (the sets "
                        "are chosen by a record's ambient, not the cell temperature its "
                        "parameters read); export --to table writes them over "
                        "temperature")  # fmt: skip


def check_no_profile(model: FittedModel, source: str) -> None:
    """An ``entropic`` element that scales the slow tests' ∂U/∂T profile over SOC
    (docs/temperature-rule.md part 5) is refused in one line: PyBaMM's "Entropic change [V/K]"
    is a function of the OCV and the cell temperature (``EcmParameters.dUdT``), not of SOC, and
    the model's OCV (table, offset, ocv_shape) maps to SOC only through the whole model; a
    model without the element exports as before (its table is the OCV at its reference
    temperature)."""
    table = model.config.table
    if "entropic" in model.config.effects and table is not None and table.dudt_shape().size:
        raise UserError(f"{source}: field 'ocv_table.dudt_v_per_k': the entropic term scales "
                        "the slow tests' ∂U/∂T profile over SOC, and PyBaMM's Thevenin model "
                        "reads its entropic change as a function of the OCV and temperature, "
                        "not of SOC; export --to table writes it over SOC and "
                        "temperature")  # fmt: skip


def check_exportable(model: FittedModel, source: str, drop_unsupported: bool) -> list[str]:
    """The elements to drop (with ``drop_unsupported``), or a one-line UserError naming them (or
    the model's per-temperature sets, :func:`check_one_set`, or its ∂U/∂T profile,
    :func:`check_no_profile`)."""
    check_one_set(model, source)
    check_no_profile(model, source)
    if model.config.load_ohm is not None:
        raise UserError(f"{source}: field 'load_ohm': the paper's load resistor is part of its "
                        "test rig, not of the cell; PyBaMM's Thevenin model has none")  # fmt: skip
    bad = unsupported(model)
    if bad and not drop_unsupported:
        why = "; ".join(f"{e}: {elements.get(e).pybamm.how}" for e in bad)
        raise UserError(f"{source}: element{'s' if len(bad) > 1 else ''} {', '.join(bad)} "
                        f"cannot be exported to PyBaMM's Thevenin model ({why}); "
                        "--drop-unsupported exports the rest")  # fmt: skip
    return bad


def without(model: FittedModel, elements) -> FittedModel:
    """The model with ``elements`` removed: their parameters back to neutral, nothing refitted
    (what the export holds when they are dropped)."""
    if not elements:
        return model
    effects = tuple(e for e in model.config.effects if e not in elements)
    config = ecm.Config(effects, model.config.table, model.config.load_ohm)
    x = fitting.neutralise(model.x[None, :], elements)[0]
    names = set(config.names())
    bounds = {n: b for n, b in model.bounds.items() if n in names}
    return dataclasses.replace(model, config=config, x=x, bounds=bounds)


# ----------------------------------------------------------------------------------------------
# the module text


def _plain(text: str) -> str:
    """``text`` safe inside the generated docstring and comments (file names are the user's)."""
    return str(text).replace("\\", "/").replace('"', "'").replace("\n", " ").replace("\r", " ")


def _literal(value) -> str:
    if isinstance(value, dict) and value:
        return "{\n" + "".join(f"    {k!r}: {v!r},\n" for k, v in value.items()) + "}"
    if isinstance(value, str | dict):
        return repr(value)
    if isinstance(value, list | tuple | np.ndarray):
        body = ", ".join(repr(float(v)) for v in value)
        return "np.array([\n" + textwrap.fill(body, 96, initial_indent="    ",
                                               subsequent_indent="    ") + ",\n])"  # fmt: skip
    return repr(float(value))


def _entries(mapping: dict[str, str], indent: int = 4) -> str:
    """Dict entries, one a line, keys as double-quoted strings (PyBaMM's own style for parameter
    names), values as written (names and expressions of the module)."""
    return "".join(f"{' ' * indent}{json.dumps(k, ensure_ascii=False)}: {v},\n"
                   for k, v in mapping.items())  # fmt: skip


def _dict(mapping: dict[str, str]) -> str:
    return "{\n" + _entries(mapping) + "}" if mapping else "{}"


def _base(m: FittedModel, p: Physical) -> Piece:
    table = m.config.table
    if table is None:
        return Piece(
            constants=(("VNOM_V", p["vnom"], "rational OCV (eq. 5): Vnom"),
                       ("ONE_MINUS_BETA", p["lc"], "rational OCV (eq. 5): 1 − β")),
            ocv_terms=("VNOM_V * sc / (ONE_MINUS_BETA + (1.0 - ONE_MINUS_BETA) * sc)",),
        )  # fmt: skip
    vals = table.values
    return Piece(
        constants=(("OCV_SOC", flat_ends(table.grid()), "the measured OCV: SOC (and a point "
                    "beyond each end: avoa-pipeline holds the end values)"),
                   ("OCV_V", [vals[0], *vals, vals[-1]], "the measured OCV: V"),
                   ("OCV_OFFSET_V", p["voff"], "the fitted offset of the table")),
        ocv_terms=('pybamm.Interpolant(OCV_SOC, OCV_V, sc, "OCV table")', "OCV_OFFSET_V"),
    )  # fmt: skip


_HEADER = '''"""PyBaMM parameters of one cell: an equivalent-circuit model fitted by avoa-pipeline.

Generated by avoa-pipeline {version} from {source_doc} ({configuration}); needs PyBaMM and
NumPy only. Use it like PyBaMM's own parameter sets:

    import importlib.util
    import pybamm
    spec = importlib.util.spec_from_file_location("cell", "{file_doc}")
    cell = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cell)
    model = cell.model()  # PyBaMM's Thevenin model (OPTIONS), plus this cell's SUBMODELS
    values = pybamm.ParameterValues(cell.get_parameter_values())

or run a record (current held over each interval, as avoa-pipeline's records define it):
voltage = cell.simulate(time_s, current_a[, temperature_c]).

Current is positive on discharge (PyBaMM's convention and avoa-pipeline's). ELEMENTS says how
each part of the model maps; DROPPED lists what the export left out and what that costs.
Edit the values below freely; the thermal values and cut-offs are not identified (see there).
"""

import numpy as np
import pybamm

SOURCE = {source}
ELEMENTS = {elements}
DROPPED = {dropped}
OPTIONS = {options}

CAPACITY_AH = {capacity}
INITIAL_SOC = {soc0}  # {soc0_note}
T_REF_K = {tref}  # reference temperature of the fitted parameters (and the ambient default)
R0_OHM = {r0}
'''

_THERMAL_AND_DRIVE = '''

# The identified model has no thermal dynamics: its resistances see the cell temperature as
# measured. These values make PyBaMM's lumped cell-jig-ambient model follow the ambient
# temperature within about 0.1 ms (time constants of mass/coefficient) and a few mK at tens of
# watts, so that the ambient temperature is the cell's: drive() sets it from a measured one.
# Put your cell's values here to let PyBaMM compute the temperature instead.
CELL_THERMAL_MASS_J_PER_K = 1.0
CELL_JIG_W_PER_K = 1.0e4
JIG_THERMAL_MASS_J_PER_K = 1.0
JIG_AIR_W_PER_K = 1.0e4
THERMAL_LEAD_S = 2.0e-3  # 20 of those time constants
CHUNK_SAMPLES = {chunk}  # simulate() solves a record in pieces of this many intervals
# the model's states, each with the parameter of its initial value: simulate() starts each piece
# of a record where the one before ended
STATES = {states}
# Thevenin's submodels this cell replaces or adds (model()); empty: PyBaMM's Thevenin model
SUBMODELS = {submodels}
{thermal}LOWER_CUTOFF_V = {lower}  # not identified: wide, so that they never stop a record
UPPER_CUTOFF_V = {upper}


def get_parameter_values():
    """The dict for pybamm.ParameterValues (PyBaMM's parameter-set convention)."""
    return {{
        "chemistry": "ecm",
        "Cell capacity [A.h]": CAPACITY_AH,
        "Nominal cell capacity [A.h]": CAPACITY_AH,
        "Initial SoC": INITIAL_SOC,
        "Open-circuit voltage [V]": ocv,
        "Entropic change [V/K]": {entropic},
        "R0 [Ohm]": {r0_value},
{rc_values}        "Current function [A]": CAPACITY_AH,
        "Upper voltage cut-off [V]": UPPER_CUTOFF_V,
        "Lower voltage cut-off [V]": LOWER_CUTOFF_V,
        "Ambient temperature [K]": T_REF_K,
        "Initial temperature [K]": T_REF_K,
        "Cell thermal mass [J/K]": CELL_THERMAL_MASS_J_PER_K,
        "Cell-jig heat transfer coefficient [W/K]": CELL_JIG_W_PER_K,
        "Jig thermal mass [J/K]": JIG_THERMAL_MASS_J_PER_K,
        "Jig-air heat transfer coefficient [W/K]": JIG_AIR_W_PER_K,
{extra_values}    }}


def model(predict_temperature=False):
    """PyBaMM's Thevenin model with OPTIONS, its submodels in the slots of SUBMODELS replaced
    or added (the states this cell has beyond Thevenin's), without its SoC events; with
    predict_temperature, THERMAL_SUBMODELS too (the cell's thermal state from the ambient)."""
    thevenin = pybamm.equivalent_circuit.Thevenin(options=OPTIONS, build=False)
    slots = {{**SUBMODELS, **(THERMAL_SUBMODELS if predict_temperature else {{}})}}
    for slot, submodel in slots.items():
        thevenin.submodels[slot] = submodel(thevenin.param, thevenin.options)
    # the voltage reads what the others add to the OCV (entropic): built after them
    thevenin.submodels["Voltage"] = thevenin.submodels.pop("Voltage")
    thevenin.build_model()
    # avoa-pipeline's model has no SoC bounds (its OCV holds its end values): Thevenin's events
    # at SoC 0 and 1 would stop a record that starts full (INITIAL_SOC 1) or charges beyond it
    thevenin.events = [e for e in thevenin.events if e.name not in ("Minimum SoC", "Maximum SoC")]
    return thevenin


def held(time_s, values, lead_s=0.0):
    """A function of time for PyBaMM that holds values[k] from time_s[k] − lead_s to
    time_s[k+1] − lead_s (row k's value holds over [t_k, t_k+1), as in avoa-pipeline's records).
    PyBaMM's solvers need a continuous input, so each switch is a linear ramp over 1e-6 of its
    interval; give the sample times as t_eval, so that the solver stops at every switch."""
    t = np.asarray(time_s, dtype=float)
    y = np.asarray(values, dtype=float)
    if t.ndim != 1 or y.shape != t.shape or t.size < 2 or not np.all(np.diff(t) > 0):
        raise ValueError("held: need 1-D time and values of one length (≥ 2), time increasing")
    dt = np.diff(t)
    if not 0.0 <= lead_s < 0.5 * dt.min():
        raise ValueError("held: lead_s must lie in [0, half the shortest interval)")
    start = np.concatenate([[t[0] - dt[0]], t[1:] - lead_s])
    end = np.concatenate([t[1:] - lead_s - 1e-6 * dt, [t[-1] + dt[-1]]])
    x = np.column_stack([start, end]).ravel()
    y2 = np.repeat(y, 2)
    return lambda time: pybamm.Interpolant(x, y2, time, interpolator="linear")


def drive(time_s, current_a, temperature_c=None, ambient_c=None):
    """(parameter updates, t_eval) that run a record: the current (A, positive = discharge) held
    over each interval; a measured temperature (°C) held too, as the ambient temperature that
    the cell follows, switched THERMAL_LEAD_S early so that the cell has reached it at each
    sample time; or an ambient (°C, one number) for the thermal state (model(True)) to
    predict the cell temperature from. Times count from the first sample."""
    t = np.asarray(time_s, dtype=float)
    t = t - t[0]
    current = np.asarray(current_a, dtype=float){current_terms}
    updates = {{"Current function [A]": held(t, current)}}
{drive_extra}    if temperature_c is not None:
        temp_k = np.asarray(temperature_c, dtype=float) + 273.15
        lead = min(THERMAL_LEAD_S, 0.1 * float(np.min(np.diff(t))))
        updates["Ambient temperature [K]"] = held(t, temp_k, lead)
        updates["Initial temperature [K]"] = float(temp_k[0])
    if ambient_c is not None:
        updates["Ambient temperature [K]"] = float(ambient_c) + 273.15
    return updates, t


def simulate(time_s, current_a, temperature_c=None, initial_soc=None, rtol={tol}, atol={tol},
             chunk=CHUNK_SAMPLES, ambient_c=None):
    """Terminal voltage (V) at each sample of a record, from PyBaMM's Thevenin model with these
    parameters (IDAKLU solver; the voltage at t_k is the one just after row k's current is
    applied, as avoa-pipeline computes it). Solved in pieces of ``chunk`` intervals, each
    starting from the state the one before ended in (STATES; the temperature is the
    record's): PyBaMM's time per step grows with the length of the held current, so one piece
    for a whole long record costs time quadratic in its length.

    Two temperature modes: the measured ``temperature_c`` (or none: T_REF_K), which the cell
    follows; or ``ambient_c`` (°C) alone, from which the cell's thermal state (THERMAL_SUBMODELS,
    needs a heat block) predicts the temperature, starting at the ambient: then the result is
    (voltage V, cell temperature °C), each at every sample."""
    predict = ambient_c is not None
    if predict and (temperature_c is not None or not THERMAL_SUBMODELS):
        raise ValueError("simulate: ambient_c needs THERMAL_SUBMODELS (a model.json with a heat "
                         "block) and no temperature_c")
    states = {{**STATES, **(THERMAL_STATES if predict else {{}})}}
    t = np.asarray(time_s, dtype=float)
    cur = np.asarray(current_a, dtype=float)
    temp = None if temperature_c is None else np.asarray(temperature_c, dtype=float)
    values = pybamm.ParameterValues(get_parameter_values())
    if initial_soc is not None:
        values["Initial SoC"] = float(initial_soc)
    if predict:
        values["Initial temperature [K]"] = float(ambient_c) + 273.15
    solver = pybamm.IDAKLUSolver(rtol=rtol, atol=atol)
    pieces, temps = [], []
    a = 0
    while True:
        b = min(a + int(chunk), t.size - 1)  # this piece: samples a..b, b shared with the next
        part = slice(a, b + 1)
        updates, tt = drive(t[part], cur[part], None if temp is None else temp[part], ambient_c)
        stops = tt
        if predict:  # LumpedHeat samples as avoa-pipeline's records are (sampling_gates)
            gates, stops = sampling_gates(tt)
            updates.update(gates)
        values.update(updates)
        sim = pybamm.Simulation(model(predict), parameter_values=values, solver=solver)
        solution = sim.solve(t_eval=stops, t_interp=stops)
        at = np.isin(stops, tt)[: solution.t.size]  # the samples among the stops
        voltage = solution["Voltage [V]"].entries[at]
        if voltage.size != tt.size:
            raise RuntimeError(f"PyBaMM stopped at {{t[a] + solution.t[-1]:g}} s of "
                               f"{{t[-1]:g}} s ({{solution.termination}})")
        cell_c = solution["Cell temperature [degC]"].entries[at] if predict else voltage
        if b == t.size - 1:
            pieces.append(voltage)
            temps.append(cell_c)
            v = np.concatenate(pieces)
            return (v, np.concatenate(temps)) if predict else v
        pieces.append(voltage[:-1])
        temps.append(cell_c[:-1])
        values = values.copy()
        for state, initial in states.items():
            values[initial] = float(solution[state].entries[-1])
        a = b
'''


def _resistance_function(name: str, value: str, factors: list[str], terms: list[str],
                         doc: str, held_soc: bool = False) -> str:  # fmt: skip
    expr = " * ".join([value, *factors])
    expr = " + ".join([expr, *terms])
    start = "    soc = soc_at_interval_start(soc, current, T_cell)\n" if held_soc else ""
    return f'\n\ndef {name}(T_cell, current, soc):\n    """{doc}"""\n{start}    return {expr}\n'


_SOC = re.compile(r"\bsoc\b")
SINCE = "Time since the interval's start [s]"

_INTERVAL_START = f'''
def soc_at_interval_start(soc, current, T_cell):
    """The SoC at the start of the record's interval: avoa-pipeline holds an SOC-dependent
    resistance over each interval at its value there (zero-order hold; the RC branches' update
    reads it). The current (and the temperature, so the capacity) is held over the interval, so
    that SoC is the SoC now plus the charge counted since; drive() gives the time since (a
    sawtooth, 0 at each sample). Its default, 0, follows the SoC as it moves (a continuous-time
    model)."""
    since = pybamm.FunctionParameter("{SINCE}", {{"Time [s]": pybamm.t}})
    return soc + counted(current, T_cell) * since / (3600 * CAPACITY_AH)


def since_interval_start(time_s):
    """A function of time for PyBaMM: the time since the start of the interval it lies in (0
    at each time_s[k], rising to the interval's length), back to 0 over the last 1e-6 of each
    interval, as held() switches."""
    t = np.asarray(time_s, dtype=float)
    dt = np.diff(t)
    x = np.append(np.column_stack([t[:-1], t[1:] - 1e-6 * dt]).ravel(), [t[-1], t[-1] + dt[-1]])
    y = np.append(np.column_stack([0.0 * dt, (1.0 - 1e-6) * dt]).ravel(), [0.0, dt[-1]])
    return lambda time: pybamm.Interpolant(x, y, time, interpolator="linear")
'''


def _interval_start_piece(p: Physical) -> Piece:
    """What SOC-dependent resistances add: the SoC at each interval's start, from the charge
    counted since (:data:`_INTERVAL_START`), so that PyBaMM holds them as our simulator does."""
    c = counted_piece(p)
    return Piece(constants=c.constants, helpers=(*c.helpers, _INTERVAL_START),
                 parameters=(*c.parameters, (SINCE, "0.0")))  # fmt: skip


def module_source(model: FittedModel, initial_soc: float, soc0_note: str, source: str,
                  dropped: dict | None = None, file_name: str = "cell.py") -> str:  # fmt: skip
    """The text of the PyBaMM parameter module of ``model`` (already without the elements it
    cannot hold: :func:`without`); ``dropped``: element → why and what dropping it cost."""
    cannot = [e for e in model.config.effects if not elements.get(e).pybamm.exported]
    if cannot:
        raise ValueError(f"module_source: {', '.join(cannot)} cannot be exported; drop first")
    p = ecm.physical(model.x, model.knots)
    pieces = {"base": _base(model, p), "rc1": rc_piece(1)(p)}
    pieces |= {e: elements.get(e).pybamm.piece(p) for e in model.config.effects}
    # a resistance that follows the SoC reads it at the interval's start, as our simulator does
    held_soc = any(_SOC.search(f) for q in pieces.values() for _, f in (*q.factors, *q.terms))
    if held_soc:
        pieces["interval_start"] = _interval_start_piece(p)
    consts = {name: (value, note) for p in pieces.values() for name, value, note in p.constants}
    # a branch with R = 0 holds no voltage (it starts at 0): left out, the rest renumbered
    branches = sorted(b for p in pieces.values() for b in p.branches if consts[b[1]][0] != 0.0)
    hows = {"base": BASE_HOW, **{e: elements.get(e).pybamm.how for e in model.config.effects}}
    text = _HEADER.format(
        version=__version__,
        source_doc=_plain(Path(source).name),
        configuration=model.config.name,
        file_doc=_plain(Path(file_name).name),
        source=_literal({"model": str(source), "configuration": model.config.name,
                         "avoa_pipeline": __version__}),
        elements=_literal(hows),
        dropped=_literal(dropped or {}),
        options=_literal({"number of rc elements": len(branches)}),
        capacity=_literal(p["lq"]),
        soc0=_literal(initial_soc),
        soc0_note=_plain(soc0_note),
        tref=_literal(model.tref_k),
        r0=_literal(p["r0"]),
    )  # fmt: skip
    for name, (value, note) in consts.items():
        line = f"{name} = {_literal(value)}  # {note}\n"
        text += line if "\n" not in line[:-1] else f"# {note}\n{name} = {_literal(value)}\n"
    for h in dict.fromkeys(h for p in pieces.values() for h in p.helpers):
        text += "\n" + h
    text += _ocv_function(model, pieces)
    laws, r0_value, rc_values = _resistance_functions(pieces, branches, held_soc)
    return text + laws + _tail(model, pieces, branches, held_soc, r0_value, rc_values)


def _ocv_function(model: FittedModel, pieces: dict[str, Piece]) -> str:
    """The module's ``ocv(soc)``: the base's OCV source plus every piece's OCV terms."""
    if model.config.table is not None:
        doc, sc = "the measured table (linear, flat beyond it)\n    plus its offset", "soc"
    else:
        doc = "the paper's eq. 5, Vnom·s/(1 − β(1 − s)),\n    s clipped to [0, 1.2]"
        sc = "pybamm.minimum(pybamm.maximum(soc, 0.0), 1.2)"
    extra = [e for e in model.config.effects if pieces[e].ocv_terms]
    if extra:
        doc += ", plus " + " and ".join(extra)
    ocv_terms = [t for p in pieces.values() for t in p.ocv_terms]
    ocv_expr = (
        ocv_terms[0]
        if len(ocv_terms) == 1
        else "(\n        " + "\n        + ".join(ocv_terms) + "\n    )"
    )
    return (f'\n\ndef ocv(soc):\n    """Open-circuit voltage [V] at SoC: {doc}."""\n'
            f"    sc = {sc}\n    return {ocv_expr}\n")  # fmt: skip


def _resistance_functions(pieces: dict[str, Piece], branches, held_soc: bool):
    """(the functions of R0 and of each RC branch's R and C that follow a law, R0's value in
    the parameter values, the RC branches' entries there)."""
    factors = [f for p in pieces.values() for f in p.factors]
    terms = [t for p in pieces.values() for t in p.terms]

    def of(kind, *resistors):
        return [e for r, e in kind if r in resistors]

    text, r0_value = "", "R0_OHM"
    if of(factors, "R0") or of(terms, "R0"):
        text += _resistance_function(
            "r0",
            "R0_OHM",
            of(factors, "R0"),
            of(terms, "R0"),
            "R0 [Ohm] at the cell temperature (°C), current and SoC.",
            held_soc,
        )
        r0_value = "r0"
    rc_values = ""
    # "TAU": factors of every branch's time constant (thermal_tau), written into C = τ·factor/R
    tau_factors = of(factors, "TAU")
    for n, (j, r_name, tau_name) in enumerate(branches, start=1):
        f, t = of(factors, "RC", f"R{j}"), of(terms, "RC", f"R{j}")
        r_val = r_name
        if f or t:
            text += _resistance_function(
                f"r{n}", r_name, f, t, f"R{n} [Ohm] (RC branch {j} of the fitted model).", held_soc
            )
            r_val = f"r{n}"
        if f or t or tau_factors:
            tau = " * ".join([tau_name, *tau_factors])
            r_call = f"r{n}(T_cell, current, soc)" if r_val != r_name else r_name
            law = "τ times its temperature law" if tau_factors else "the time constant stays fixed"
            text += (f'\n\ndef c{n}(T_cell, current, soc):\n    """C{n} [F] = τ/R{n}: {law}.'
                     f'"""\n    return {tau} / {r_call}\n')  # fmt: skip
            c_val = f"c{n}"
        else:
            c_val = f"{tau_name} / {r_name}"
        rc_values += (f'        "R{n} [Ohm]": {r_val},\n        "C{n} [F]": {c_val},\n'
                      f'        "Element-{n} initial overpotential [V]": 0.0,\n')  # fmt: skip
    return text, r0_value, rc_values


def _tail(model: FittedModel, pieces: dict[str, Piece], branches, held_soc: bool,
          r0_value: str, rc_values: str) -> str:  # fmt: skip
    """The module's parameter values, states, submodels, drive and thermal block."""
    states = {"SoC": "Initial SoC"} | {
        f"Element-{n} overpotential [V]": f"Element-{n} initial overpotential [V]"
        for n in range(1, len(branches) + 1)
    }
    states |= {v: i for p in pieces.values() for v, i in p.states}
    submodels = {slot: cls for p in pieces.values() for slot, cls in p.submodels}
    extra_values = {name: expr for p in pieces.values() for name, expr in p.parameters}
    # PyBaMM's own entropic change, which the header writes (0 without entropic)
    entropic = extra_values.pop("Entropic change [V/K]", "0.0")
    current_terms = "".join(f" + {t}" for p in pieces.values() for t in p.current_terms)
    extra_values |= thermal_parameters(model)
    return _THERMAL_AND_DRIVE.format(
        lower=_literal(VOLTAGE_CUTOFFS_V[0]), upper=_literal(VOLTAGE_CUTOFFS_V[1]),
        r0_value=r0_value, rc_values=rc_values, tol=repr(SOLVER_TOL), chunk=CHUNK_SAMPLES,
        states=_dict({k: json.dumps(v, ensure_ascii=False) for k, v in states.items()}),
        drive_extra=(f"    updates[{json.dumps(SINCE)}] = since_interval_start(t)\n"
                     if held_soc else ""),
        submodels=_dict(submodels), current_terms=current_terms,
        extra_values=_entries(extra_values, indent=8), entropic=entropic,
        thermal=thermal_block(model),
    )  # fmt: skip


# ----------------------------------------------------------------------------------------------
# the thermal state (issue 28 item 4): model.json's heat block as a submodel of the module

_LUMPED_HEAT = '''
# The cell's thermal state, from model.json's heat block (avoa-pipeline's model/heat.py):
#     C_th·dT/dt = q − hA·(T − T_amb),   q = I·(OCV − V) − I·T·dU/dT
# used by simulate(..., ambient_c=...) (model(predict_temperature=True)). The heat is read from
# the model's own variables: I·(OCV − V) is every overpotential of this cell (R0 with its laws,
# the RC branches, the surface-SoC lag, hysteresis), which PyBaMM's ThermalSubModel does not sum
# (it adds each element's I²R-type heat and the diffusion overpotential only).
HEAT_C_TH_J_PER_K = {c_th!r}  # fitted: the cell's heat capacity
HEAT_HA_W_PER_K = {ha!r}  # fitted: the conductance from the cell to the ambient
HEAT_DUDT_V_PER_K = {dudt!r}  # the heat block's dU/dT (reversible heat only; 0: not identified)
SAMPLING_FRACTION = 1.0e-3  # a sampling window's length, in the shortest interval
SAMPLING_RATE_PER_WINDOW = 20.0  # a held value's rate while sampling: within e^-20 of its input


class LumpedHeat(pybamm.BaseSubModel):
    """The cell temperature as a state, fed by the heat q = I·(OCV − V) − I·T·dU/dT and cooled
    through hA to the ambient ("Ambient temperature [K]"). It fills the slot of PyBaMM's
    cell-jig-ambient ThermalSubModel; the jig is the ambient (no jig state). dU/dT: PyBaMM's
    reversible heat (its "Entropic change [V/K]", the entropic element's where this cell has one)
    plus the heat block's own. The voltage is built after every other submodel (model()), so
    reading it raises KeyError until then, and PyBaMM builds this submodel again afterwards.

    Sampled as avoa-pipeline's records are: its simulator holds the temperature over each
    interval at its value at the sample, and its heat.py holds the heat. Two states do the same:
    "Cell temperature [degC]" (what the resistances and the OCV read) follows the continuous
    one only while the "Temperature sampling gate" is 1, and the "Held heat generation [W]"
    that drives it follows q only while the "Heat sampling gate" is 1. simulate(..., ambient_c)
    opens the first just before each sample and the second just after it (sampling_gates());
    their default, 1, follows continuously (a continuous-time model)."""

    def __init__(self, param, options=None):
        super().__init__(param)
        self.model_options = options

    def get_fundamental_variables(self):
        T_cont = pybamm.Variable("Cell temperature (continuous) [degC]")
        T_cell = pybamm.Variable("Cell temperature [degC]")
        q_held = pybamm.Variable("Held heat generation [W]")
        T_amb = self.param.T_amb(pybamm.t)
        ha = pybamm.Parameter("Cell-ambient heat transfer coefficient [W/K]")
        return {{
            "Cell temperature (continuous) [degC]": T_cont,
            "Cell temperature (continuous) [K]": T_cont + 273.15,
            "Cell temperature [degC]": T_cell,
            "Cell temperature [K]": T_cell + 273.15,
            "Held heat generation [W]": q_held,
            "Jig temperature [degC]": T_amb,
            "Jig temperature [K]": T_amb + 273.15,
            "Ambient temperature [degC]": T_amb,
            "Ambient temperature [K]": T_amb + 273.15,
            "Heat transfer from cell to jig [W]": -ha * (T_cont - T_amb),
            "Heat transfer from jig to ambient [W]": -ha * (T_cont - T_amb),
        }}

    def get_coupled_variables(self, variables):
        voltage = variables["Voltage [V]"]  # KeyError until the voltage is built: retried
        current = variables["Current [A]"]
        q_irr = current * (variables["Open-circuit voltage [V]"] - voltage)
        dudt = pybamm.Parameter("Heat-only entropic change [V/K]")
        q_rev = (variables["Reversible heat generation [W]"]
                 - current * variables["Cell temperature [K]"] * dudt)
        variables.update({{
            "Irreversible heat generation [W]": q_irr,
            "Reversible heat generation [W]": q_rev,
            "Total heat generation [W]": q_irr + q_rev,
        }})
        return variables

    def set_rhs(self, variables):
        T_cont = variables["Cell temperature (continuous) [degC]"]
        T_cell = variables["Cell temperature [degC]"]
        q_held = variables["Held heat generation [W]"]
        c_th = pybamm.Parameter("Cell heat capacity [J/K]")
        rate = pybamm.Parameter("Sampling rate [1/s]")
        time = {{"Time [s]": pybamm.t}}
        gate_t = pybamm.FunctionParameter("Temperature sampling gate", time)
        gate_q = pybamm.FunctionParameter("Heat sampling gate", time)
        q = variables["Total heat generation [W]"]
        self.rhs = {{
            T_cont: (q_held + variables["Heat transfer from cell to jig [W]"]) / c_th,
            T_cell: gate_t * rate * (T_cont - T_cell),
            q_held: gate_q * rate * (q - q_held),
        }}

    def set_initial_conditions(self, variables):
        self.initial_conditions = {{
            variables["Cell temperature (continuous) [degC]"]: self.param.initial_T_cell,
            variables["Cell temperature [degC]"]: self.param.initial_T_cell,
            variables["Held heat generation [W]"]: pybamm.Scalar(0.0),
        }}


def sampling_gates(time_s):
    """(parameter updates, stops) that make LumpedHeat sample as avoa-pipeline does: the
    temperature's gate open over [t_k − 2δ, t_k − δ] (so that the voltage at t_k reads the
    temperature at t_k), the heat's over [t_k, t_k + δ] (the heat of row k's current), δ =
    SAMPLING_FRACTION of the shortest interval. The stops (the solver's t_eval) lie inside each
    window, where its gate is 1: an implicit step that ended where the gate is 0 would step
    over the window unseen."""
    t = np.asarray(time_s, dtype=float)
    d = SAMPLING_FRACTION * float(np.min(np.diff(t)))
    r = 0.1 * d  # each gate's ramps

    def gate(starts):
        x = np.column_stack([starts - r, starts, starts + d, starts + d + r]).ravel()
        y = np.tile([0.0, 1.0, 1.0, 0.0], starts.size)
        x = np.concatenate([[t[0] - 10 * d - 1.0], x, [t[-1] + 10 * d + 1.0]])
        y = np.concatenate([[0.0], y, [0.0]])
        return lambda time: pybamm.Interpolant(x, y, time, interpolator="linear")

    t_starts = t[1:] - 2 * d
    updates = {{"Temperature sampling gate": gate(t_starts), "Heat sampling gate": gate(t),
                "Sampling rate [1/s]": SAMPLING_RATE_PER_WINDOW / d}}
    inside = np.concatenate([t_starts + 0.5 * d, t_starts + d, t[:-1] + 0.5 * d, t[:-1] + d])
    return updates, np.union1d(t, inside)


# simulate(..., ambient_c=...): the submodel it adds, and the state it carries between pieces
THERMAL_SUBMODELS = {{"Thermal": LumpedHeat}}
THERMAL_STATES = {{"Cell temperature (continuous) [K]": "Initial temperature [K]"}}
'''

_NO_HEAT = """
# model.json has no heat block: no thermal state (simulate() needs a measured temperature or
# none; ambient_c is refused)
THERMAL_SUBMODELS = {}
THERMAL_STATES = {}
"""


def thermal_block(model: FittedModel) -> str:
    """The module's thermal section: the heat block's constants, the ``LumpedHeat`` submodel
    and ``THERMAL_SUBMODELS``/``THERMAL_STATES`` where ``model.heat`` is fitted, else empty ones.

    Why a submodel of our own and not PyBaMM's ``ThermalSubModel`` (cell + jig): mapped as the
    cell-jig coefficient = hA and a jig held at the ambient, it would equal our lumped state
    in its dynamics, but its heat sums each element's "irreversible heat generation" and the
    diffusion overpotential only: hysteresis is missing and a resistance with a current law
    (Butler–Volmer) gives I²·R(I) where q counts I·η(I). ``LumpedHeat`` takes q from the
    model's own OCV and voltage, as ``model/heat.py`` does, so every element enters.

    Sampled as ours: our simulator holds the temperature over each interval at its sample's
    value and heat.py holds the heat; a continuous PyBaMM state differs from that by 0.11-0.83
    mV RMS on the Panasonic joint model (0.02-0.03 K are tenths of a millivolt through its
    Arrhenius resistances, docs/pybamm.md, "The thermal state"), so ``LumpedHeat`` holds both
    by gated states that sample at each sample time (``sampling_gates`` in the module):
    0.002-0.007 mV RMS there."""
    h = model.heat
    if h is None:
        return _NO_HEAT
    return _LUMPED_HEAT.format(c_th=float(h.c_th), ha=float(h.ha), dudt=float(h.dudt))


def thermal_parameters(model: FittedModel) -> dict[str, str]:
    """The parameters ``LumpedHeat`` reads (entries of ``get_parameter_values``; none without
    a heat block)."""
    if model.heat is None:
        return {}
    return {"Cell heat capacity [J/K]": "HEAT_C_TH_J_PER_K",
            "Cell-ambient heat transfer coefficient [W/K]": "HEAT_HA_W_PER_K",
            "Heat-only entropic change [V/K]": "HEAT_DUDT_V_PER_K",
            # LumpedHeat's default: sampling always, so following continuously (0.1 ms)
            "Temperature sampling gate": "1.0", "Heat sampling gate": "1.0",
            "Sampling rate [1/s]": "1.0e4"}  # fmt: skip


def thermal_agreement(module: types.ModuleType, model: FittedModel, frame: pd.DataFrame,
                      soc0: float, ambient_c: float) -> dict:  # fmt: skip
    """Ambient-only mode: PyBaMM's voltage and cell temperature from a loaded module (its
    ``simulate(..., ambient_c=...)``) against ``model/heat.py``'s prediction (its fixed point,
    to :data:`REFERENCE_TOL_K`) on ``frame``, both from ``soc0`` and the ambient: RMS and
    largest |difference| in mV and K, PyBaMM's seconds; ``error`` when PyBaMM fails."""
    import time

    from ..model import heat

    pybamm = require_pybamm()
    ref = heat.predict(model, model.heat, frame, ambient_c, soc0=soc0, tol_k=REFERENCE_TOL_K)
    run = frame.drop(columns=["temperature_c"], errors="ignore")
    start = time.perf_counter()
    try:
        v, temp_c = module.simulate(run["time_s"].to_numpy(), run["current_a"].to_numpy(),
                                    initial_soc=soc0, ambient_c=ambient_c)  # fmt: skip
    except (RuntimeError, pybamm.SolverError) as exc:
        return {"error": " ".join(str(exc).split())}
    d = 1e3 * np.abs(np.asarray(v) - ref.voltage_v)
    k = np.abs(np.asarray(temp_c) + heat.KELVIN - ref.temp_k)
    return {"rms_mv": float(np.sqrt(np.mean(d**2))), "max_abs_mv": float(d.max()),
            "rms_k": float(np.sqrt(np.mean(k**2))), "max_abs_k": float(k.max()),
            "seconds": time.perf_counter() - start, "passes": ref.passes}  # fmt: skip


REFERENCE_TOL_K = 1e-5
"""The reference's fixed point (``heat.predict``) is solved to 10⁻⁵ K here, not to its 0.01 K:
0.01 K of its own residue would move an Arrhenius resistance by up to 0.2 % (``heat``'s
FIXED_POINT_TOL_K), a part of the 0.1 mV this comparison resolves."""


# ----------------------------------------------------------------------------------------------
# loading, checking, writing


def load_source(text: str, name: str = "avoa_pybamm_export") -> types.ModuleType:
    """The generated module from its text (needs PyBaMM)."""
    require_pybamm()
    module = types.ModuleType(name)
    module.__file__ = f"<{name}>"
    exec(compile(text, module.__file__, "exec"), module.__dict__)
    return module


def build(module: types.ModuleType):
    """(options, pybamm.ParameterValues) of a loaded module, checked: the Thevenin model with
    these options takes every parameter it needs from these values."""
    pybamm = require_pybamm()
    values = pybamm.ParameterValues(module.get_parameter_values())
    model = module.model()
    values.process_model(model, inplace=False)  # raises on a missing parameter
    return dict(module.OPTIONS), values


def initial_soc_of(model: FittedModel, frame: pd.DataFrame | None, soc0: float | None,
                   record: str | None = None) -> tuple[float, str]:  # fmt: skip
    """The export's initial SOC and where it came from: ``soc0`` if given, else the library's
    rule on the record's first sample (as ``simulate`` does), else :data:`DEFAULT_SOC0`."""
    if soc0 is not None:
        return float(soc0), "given (--soc0)"
    if frame is not None:
        return model.initial_soc(model.record(frame)), (
            f"the library's rule on the first sample of {Path(record or 'the record').name}"
        )
    return DEFAULT_SOC0, "default (full); --soc0 or --record sets it"


@dataclass
class Export:
    """One export: the module text and what went into it."""

    text: str
    model: FittedModel  # the model as exported (dropped elements neutral)
    dropped: list[str]
    cost: pd.DataFrame | None  # what dropping costs on the record (:func:`dropping_cost`)
    summary: dict | None  # the record, RMS and largest |difference_mv| of ``cost``
    initial_soc: float
    soc0_note: str


def export(model: FittedModel, source: str, soc0: float | None = None,
           frame: pd.DataFrame | None = None, record: str | None = None,
           drop_unsupported: bool = False, file_name: str = "cell.py") -> Export:  # fmt: skip
    """The module text of ``model`` (``source``: its file, for messages and the module's SOURCE).

    ``frame``: a record of the cell (``record``: its name); the model's voltage on it must be a
    cell's (``FittedModel.check_cell``, the check ``simulate`` makes; without a record, on a 1C
    probe); it sets the initial SOC (unless ``soc0``) and, when elements are dropped, is where
    their cost is measured (required then).
    """
    drop = check_exportable(model, source, drop_unsupported)
    # what simulate refuses, the export refuses too, by simulate's own check (on the record, or
    # without one on FittedModel's probe): a module is never written for a model that is no cell
    model.check_cell(frame, soc0, source)
    if drop and frame is None:
        raise UserError(f"--drop-unsupported drops {', '.join(drop)}: give a record of the cell "
                        "(--record) to measure what that costs")  # fmt: skip
    s0, note = initial_soc_of(model, frame, soc0, record)
    exported = without(model, drop)
    cost, summary, dropped = None, None, {}
    if drop:
        cost = dropping_cost(model, exported, frame, s0)
        d = cost["difference_mv"].abs()
        summary = {"record": str(record), "rms_mv": float(np.sqrt(np.mean(d**2))),
                   "max_abs_mv": float(d.max())}  # fmt: skip
        dropped = {e: {"why": elements.get(e).pybamm.how, **summary} for e in drop}
    text = module_source(exported, s0, note, source, dropped, file_name)
    return Export(text, exported, drop, cost, summary, s0, note)


def agreement(module: types.ModuleType, model: FittedModel, frame: pd.DataFrame,
              soc0: float) -> dict:  # fmt: skip
    """PyBaMM's voltage from a loaded module (its ``simulate``, the record's temperature as the
    ambient where it has one) against ``model.simulate`` on ``frame``, both from ``soc0``: RMS
    and largest |difference| (mV) and PyBaMM's seconds; ``error`` instead when PyBaMM fails."""
    import time

    pybamm = require_pybamm()
    ours = model.simulate(frame, soc0=soc0)
    temp = frame["temperature_c"].to_numpy() if "temperature_c" in frame.columns else None
    start = time.perf_counter()
    try:
        theirs = module.simulate(frame["time_s"].to_numpy(), frame["current_a"].to_numpy(), temp,
                                 initial_soc=soc0)  # fmt: skip
    except (RuntimeError, pybamm.SolverError) as exc:
        return {"error": " ".join(str(exc).split())}
    d = 1e3 * np.abs(np.asarray(theirs) - ours)
    return {"rms_mv": float(np.sqrt(np.mean(d**2))), "max_abs_mv": float(d.max()),
            "seconds": time.perf_counter() - start}  # fmt: skip


def dropping_cost(model: FittedModel, exported: FittedModel, frame: pd.DataFrame,
                  soc0: float) -> pd.DataFrame:  # fmt: skip
    """What dropping costs on ``frame``, by the package's simulator, both from ``soc0``:
    time_s, voltage_v (measured), model_v (the full model, as ``simulate`` gives it),
    exported_v (the model as exported: dropped elements neutral, nothing refitted) and
    difference_mv = 1000·(exported_v − model_v)."""
    full = model.simulate(frame, soc0=soc0)
    part = exported.simulate(frame, soc0=soc0)
    return pd.DataFrame({
        "time_s": frame["time_s"].to_numpy(), "voltage_v": frame["voltage_v"].to_numpy(),
        "model_v": full, "exported_v": part, "difference_mv": 1e3 * (part - full),
    })  # fmt: skip


def loaded_module(model: FittedModel, soc0: float | None = None, drop_unsupported: bool = False,
                  source: str = "model") -> types.ModuleType:  # fmt: skip
    """The module the export writes for ``model``, executed in place, for a model that passes
    the export's check without a record (``FittedModel.check_cell``). Elements PyBaMM cannot
    hold are a UserError unless ``drop_unsupported`` (then dropped without a cost: the CLI
    measures that on a record)."""
    drop = check_exportable(model, source, drop_unsupported)
    model.check_cell(None, soc0, source)  # as export without a record: the 1C probe
    s0, note = initial_soc_of(model, None, soc0)
    text = module_source(without(model, drop), s0, note, source,
                         {e: {"why": elements.get(e).pybamm.how} for e in drop})  # fmt: skip
    return load_source(text)


def parameter_values(model: FittedModel, soc0: float | None = None,
                     drop_unsupported: bool = False, source: str = "model"):  # fmt: skip
    """(options, pybamm.ParameterValues) of PyBaMM's Thevenin model for ``model``: the same
    module text the export writes (:func:`loaded_module`). A model with states beyond
    Thevenin's (diffusion, hysteresis, the coulombic efficiency) needs the module's own model,
    with its submodels: :func:`pybamm_model`."""
    return build(loaded_module(model, soc0, drop_unsupported, source))


def pybamm_model(model: FittedModel, soc0: float | None = None,
                 drop_unsupported: bool = False, source: str = "model"):  # fmt: skip
    """(the PyBaMM model, pybamm.ParameterValues) for ``model``: the module's ``model()``
    (Thevenin with the cell's submodels) and its values, checked together (:func:`build`)."""
    module = loaded_module(model, soc0, drop_unsupported, source)
    _, values = build(module)
    return module.model(), values
