"""Writes the compiled simulator's source from the base's statement and every registered
element's (:class:`.elements.element.Kernel`), so that an element states its physics once.

    python -m avoa_pipeline.model.loopgen --write   # rewrite model/_simulator.py
    python -m avoa_pipeline.model.loopgen --check   # exit 1 if it differs from what is written

Why generated: numba compiles the loop as one function per version, on purpose (an array passed
to a called function, even an inlined one, costs a reference count per call: the loop split into
four inlined functions ran the base model at 39.6 ns per sample-row against 6.8), so an
element's code cannot be a function in its own module; and no library writes a numba loop from
element statements (PyBaMM assembles symbolic submodels for its own solvers). So this module is
hand-written: a template of the base with slots, filled with the elements' snippets in a fixed
order. ``model/_simulator.py`` is checked in for review; ``tests/unit/test_loopgen.py`` keeps it
equal to what :func:`source` writes now, and ``tests/unit/test_kernel_golden.py`` holds its
voltages to the hand-written loop's bit for bit.

Two versions, each one function: ``core`` carries the elements whose ``compiled`` is "core",
``extras`` every element (a run-time flag for the issue-19 elements cost the base model 10-25 %;
``ecm.simulate_physical`` picks the version by whether a row uses an extras element).

The slots (indentation is the generator's; a snippet starts at column 0):

===========================  ==============================================================
``setup``                    before the time loop: arrays of its own (zeros, first decays)
``hold_setup``               may turn the held-current shortcut off (``fast = False``) or
                             make a hold end where the temperature moves (``tdep``)
``held``                     per sample: may end a hold (``held``) for a reason of its own
``uneven``                   per row, for an uneven time step ``dtk``: decays of its own
``sample``                   per sample, after them (e.g. the RC decays' temperature law)
``row`` / ``hold_row``       per row (full pass / start of a hold): factors ``g`` (both
                             resistances, 1), ``f1`` (the RC resistances, 1), ``g1`` (its own)
``current``                  the cell's current ``ip`` from the measured ``ik0``
``surface``                  the SOC the OCV sees, ``so`` (default the bulk SOC ``s``)
``ocv``                      terms added to the OCV ``e`` (``sc``: the SOC the curve was read at)
``r0_factor``                ``f0``, R0's factor that is traced (1)
``r0_multiplier``            ``ro *= ...``: R0 after ``f0·g·R0``
``overpotential``            ``v -= ...`` without the load (``rtf``: 2RT/F, ``i``: current)
``counted``                  ``ie``, the current the SOC counts (default ``i``)
``capacity``                 locals of a capacity factor (``factors["capacity"]``)
``hold_increment``           per row at a hold's start: its state's per-sample increment
``hold_increment_charge``    the same, after ``dqs[c]`` (the SOC step) is known
``hold_step``                per held sample, its own loop over rows (guarded by its flag)
``update``                   the state update of the full pass (``gi = f1·g·i``)
``update_charge``            the same, after ``dq`` (the SOC step) is known
``trace``                    row 0's traces beyond the base's (``tr[1, k]``: hysteresis)
===========================  ==============================================================

Markers inside the template and snippets: ``@slot NAME`` (a line: the slot's snippets),
``@each_branch LINE`` (LINE once per RC branch, ``{j}`` its number), ``@col(NAME)`` (a physical
column), ``@factors(NAME)`` (`` * f`` per element factor of that product), ``@branch_sum`` (the
RC voltages' sum, branch 1 first), ``@reads(NAME)`` (the flags of the elements that read a
quantity, or-ed; ``False`` when none); ``@update`` (a line of the templates: :data:`UPDATE`, the
state update both share).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.util
import os
import re
import sys
import tempfile
import textwrap
from pathlib import Path

from .elements.element import FARADAY, GAS_R, KNOTS, N_KNOTS, Kernel

TARGET = Path(__file__).with_name("_simulator.py")
KELVIN_PER_TWO_RT_F = FARADAY / (2.0 * GAS_R)

SLOTS = ("setup", "hold_setup", "held", "uneven", "sample", "row", "hold_row", "current",
         "surface", "ocv", "r0_factor", "r0_multiplier", "overpotential", "counted", "capacity",
         "hold_increment", "hold_increment_charge", "hold_step", "update", "update_charge",
         "trace")  # fmt: skip

ARGS = ("P, table, tab_lo, tab_step, dudt_shape, nk, k_lo, k_step, cur, dt, uniform, dinv_t, "
        "two_rt_f, g_load, sel, out, tr")  # fmt: skip

UPDATE = """\
        gi = f1 * g * i
        v1[c] = a1[c] * v1[c] + r1[c]@factors(r1) * (1.0 - a1[c]) * gi
        @slot update
        ie = i
        @slot counted
        @slot capacity
        dq = ie * dtk / (q3600[c]@factors(capacity))
        @slot update_charge
        soc[c] = s - dq
"""
"""The state update after a sample, the same text in the simulator and in the filter's step
(both templates take it at 8 spaces), so the two cannot drift apart."""

BASE = """\
m = P.shape[0]
n = cur.shape[0]
record = tr.shape[0] > 0
rational = table.shape[0] == 0
nt = table.shape[0]
vnom = P[:, @col(vnom)].copy()
omb = P[:, @col(lc)].copy()
beta = 1.0 - omb
q3600 = 3600.0 * P[:, @col(lq)]
soc = P[:, @col(soc0)].copy()
r0 = P[:, @col(r0)].copy()
r1 = P[:, @col(r1)].copy()
tau1 = P[:, @col(ltau1)].copy()
@copies
a1 = np.exp(-dt[0] / tau1)
v1 = np.zeros(m)
b1 = np.zeros(m)
dqs = np.zeros(m)
@slot setup
@flags
load = g_load != 0.0
# a held current between returned samples: the state's per-sample increments are constants
# of the hold (no element there depends on the state itself), so they are computed once and
# the states stepped in tight loops, the same operations in the same order as below
fast = not load and not record
tdep = False  # the state's increments depend on the temperature: a hold ends where it moves
@slot hold_setup
k = 0
while k < n:
    dtk = dt[k]
    ik0 = cur[k]
    # the same current over the same step as the sample before (a cycler's hold; never under
    # a load, whose current follows the voltage): decays of the hold are the same numbers
    held = not load and k > 0 and ik0 == cur[k - 1] and dtk == dt[k - 1]
    @slot held
    dinv = dinv_t[k]
    rtf = two_rt_f[k]
    row = sel[k]
    # an uneven step's decays: made afresh only where the step differs from the last one (a
    # rest merged into one step by ``ecm.simulate_physical``, an uneven logger); the same
    # numbers where it does not
    if not uniform and not (k > 0 and dtk == dt[k - 1]):
        for c in range(m):
            a1[c] = np.exp(-dtk / tau1[c])
            @slot uneven
    dtemp = 0.0  # T − Tref (K), for the elements that read it
    @slot sample
    if @reads(dtemp):
        tk = rtf * @kelvin
        dtemp = tk - 1.0 / (1.0 / tk - dinv)
    if fast and row < 0:
        e = k + 1
        while (e < n and sel[e] < 0 and cur[e] == ik0 and dt[e] == dtk
               and (not tdep or dinv_t[e] == dinv)):
            e += 1
        if e - k > 1:
            for c in range(m):
                ip = ik0
                @slot current
                i = ip
                g = 1.0
                f1 = 1.0
                @slot hold_row
                gi = f1 * g * i
                b1[c] = r1[c] * (1.0 - a1[c]) * gi
                @slot hold_increment
                ie = i
                @slot counted
                @slot capacity
                dqs[c] = ie * dtk / (q3600[c]@factors(capacity))
                @slot hold_increment_charge
            for _ in range(e - k):
                for c in range(m):
                    v1[c] = a1[c] * v1[c] + b1[c]
                @slot hold_step
                for c in range(m):
                    soc[c] = soc[c] - dqs[c]
            k = e
            continue
    # the terminal voltage is needed only where it is returned or recorded, or where a load
    # makes the current follow it; elsewhere only the state is stepped (a fit returns a
    # thinned subset of a long record, so most samples only carry the state forward)
    need_v = load or record or row >= 0
    for c in range(m):
        s = soc[c]
        g = 1.0
        f1 = 1.0
        @slot row
        ip = ik0
        @slot current
        i = ip
        if need_v:
            so = s
            @slot surface
            if rational:
                sc = min(max(so, 0.0), 1.2)  # the rational curve is singular outside
                e = vnom[c] * sc / (omb[c] + beta[c] * sc)
            else:
                x = (so - tab_lo) / tab_step
                if x <= 0.0:
                    e = table[0]
                elif x >= nt - 1:
                    e = table[nt - 1]
                else:
                    j = int(x)
                    w = x - j
                    e = (1.0 - w) * table[j] + w * table[j + 1]
                sc = so
            @slot ocv
            f0 = 1.0
            @slot r0_factor
            ro = f0 * g * r0[c]
            @slot r0_multiplier
            e -= @branch_sum
            if load:  # the load's current follows the terminal voltage: solved exactly
                v = (e - ro * ip) / (1.0 + ro * g_load)
                i = ip + v * g_load
            else:
                v = e - ro * i
                @slot overpotential
            if row >= 0:
                out[row, c] = v
            if record and c == 0:
                tr[0, k] = s
                tr[2, k] = @branch_sum
                tr[3, k] = f0
                tr[4, k] = i
                @slot trace
@update
    k += 1
"""
"""The base's statement: the rational or table OCV, R0, RC branch 1, the capacity and the SOC,
the held-current shortcut and the thinned voltage (issue 25); every element's code in its
slots. Every state update is the same operations in the same order in the hold and in the full
pass, so a thinned call returns the full pass's voltages bit for bit (on the same steps: where
``ecm.simulate_physical`` merges a record's rests into single steps, within rounding)."""

STEP_ARGS = ("P, table, tab_lo, tab_step, dudt_shape, nk, k_lo, k_step, grid, i_read, dtk, dinv, "
             "rtf, X, bias, need_v, update, ext, out")  # fmt: skip

STEP = """\
m = P.shape[0]
rational = table.shape[0] == 0
dt = np.full(1, dtk)  # what the setup reads as the first step
vnom = P[:, @col(vnom)].copy()
omb = P[:, @col(lc)].copy()
beta = 1.0 - omb
q3600 = 3600.0 * P[:, @col(lq)]
r0 = P[:, @col(r0)].copy()
r1 = P[:, @col(r1)].copy()
tau1 = P[:, @col(ltau1)].copy()
@copies
a1 = np.exp(-dt[0] / tau1)
@slot setup
@flags
@load_states
held = False  # the hysteresis decay is computed afresh
dtemp = 0.0  # T − Tref (K), for the elements that read it
@slot sample
if @reads(dtemp):
    tk = rtf * @kelvin
    dtemp = tk - 1.0 / (1.0 / tk - dinv)
for c in range(m):
    s = soc[c]
    g = 1.0
    f1 = 1.0
    @slot row
    ip = i_read
    @slot current
    ip += bias[c]  # the filter's current-sensor bias state
    i = ip
    if need_v:
        so = s
        @slot surface
        if rational:
            sc = min(max(so, 0.0), 1.2)  # the rational curve is singular outside
            e = vnom[c] * sc / (omb[c] + beta[c] * sc)
        else:
            e = np.interp(so, grid, table)
            if ext[0] != 0.0:  # the filter's table goes on past its ends with their slopes
                above = (so - ext[2]) * ext[4] if so > ext[2] else 0.0
                below = (so - ext[1]) * ext[3] if so < ext[1] else 0.0
                e = e + (above + below)
            sc = so
        @slot ocv
        f0 = 1.0
        @slot r0_factor
        ro = f0 * g * r0[c]
        @slot r0_multiplier
        @each_branch e -= v{j}[c]
        v = e - ro * i
        @slot overpotential
        out[c] = v
    if update:
@update
if update:
    @store_states
"""
"""The SOC filter's base (``estimate``): one sample for a batch of rows (sigma points), the
state read from and written back to the columns of ``X`` (:func:`states`), the voltage before
the step. The same element snippets as :data:`BASE`; where the base differs it is the filter's
own: a current-sensor bias per row, the OCV table read by ``np.interp`` and continued past its
ends (``ext``: on, first and last SOC, slope below and above), the RC voltages subtracted one by
one (the filter's order since issue 29)."""

STEP_DOC = """\
One sample of the SOC filter's state-space model for every row (``estimate.Model``).

``X`` (m, states): the states of ``loopgen.states``, in that order (:data:`STATES`), stepped
in place when ``update``; ``out`` (m,): the terminal voltage before the step when ``need_v``.
Written by ``model/loopgen.py`` from the elements' statements, the same as the simulator's."""


DOC = """\
Terminal voltage of every physical row of ``P`` at the selected samples ({version}: {which}).

``table``: the OCV table on a uniform grid (empty: the rational OCV); ``dudt_shape``: the
shape of its ∂U/∂T over SOC on the same grid, which the entropic coefficient multiplies (empty:
none, the coefficient alone). ``sel[k]``: the row of
``out`` (n_selected, m) that sample k goes to, or −1. ``tr`` (5, n) records SOC, h, the RC
voltages, the thermal R0 factor and the battery current of row 0 when non-empty (zeros where
no element writes them). An element whose parameter is neutral in every row is skipped (the
flags do not change inside the loops, so the compiler takes the branches out of them).

Long records (issue 25): the voltage is computed only at samples that are returned or traced
(or under a load, where the current follows it); between them only the state is stepped, and
across a held current (same current, step and temperature) with the hold's increments computed
once. Written by ``model/loopgen.py`` from the elements' statements; one function on purpose
(its docstring says why)."""


def _snippets(kernels: list[Kernel], slot: str) -> list[str]:
    """The snippets of ``slot``, by position, then registry order (sorted() is stable)."""
    found = []
    for k in kernels:
        code = k.code.get(slot)
        if code is not None:
            found.append(code if isinstance(code, tuple) else (0, code))
    return [c for _, c in sorted(found, key=lambda pc: pc[0])]


def _expand(text: str, kernels: list[Kernel], branches: list[int], depth: int = 0) -> list[str]:
    """``text``'s lines with ``@slot`` and ``@each_branch`` lines expanded (recursively: a
    snippet may open a slot for the elements that require it)."""
    if depth > 8:
        raise ValueError("slots nested too deep (a snippet fills its own slot?)")
    out = []
    for line in textwrap.dedent(text).splitlines():
        body = line.lstrip()
        pad = line[: len(line) - len(body)]
        if body.startswith("@slot "):
            for snippet in _snippets(kernels, body.split()[1]):
                out += [pad + s if s else s
                        for s in _expand(snippet, kernels, branches, depth + 1)]  # fmt: skip
        elif body.startswith("@each_branch "):
            out += [pad + body[len("@each_branch ") :].format(j=j) for j in branches]
        else:
            out.append(line)
    return out


def states(kernels: list[Kernel]) -> list[tuple[str, str]]:
    """(local, name) of every state, in the filter's order: the SOC, RC branch 1, then each
    element's in registry order."""
    return [("soc", "soc"), ("v1", "v1"),
            *((loc, st.name) for k in kernels for loc, st in k.states.items())]  # fmt: skip


def _version(name: str, kernels: list[Kernel], layout: dict[str, int], template: str = BASE,
             args: str = ARGS, doc: str = "") -> str:  # fmt: skip
    """The source of one compiled function from ``template``: ``kernels`` are the elements it
    carries."""
    opened = {m for k in kernels for c in k.code.values()
              for m in re.findall(r"@slot (\w+)", c if isinstance(c, str) else c[1])}  # fmt: skip
    for k in kernels:
        unknown = set(k.code) - set(SLOTS) - opened
        if unknown:
            raise ValueError(f"unknown slots {sorted(unknown)} (slots: {', '.join(SLOTS)})")
    branches = [1, *(k.branch for k in kernels if k.branch is not None)]
    copies, flags = [], []
    loads = [f"{loc} = X[:, {j}].copy()" for j, (loc, _) in enumerate(states(kernels))]
    stores = [f"X[:, {j}] = {loc}" for j, (loc, _) in enumerate(states(kernels))]
    for k in kernels:
        for local, param in k.columns.items():
            if param == KNOTS:
                col = layout[f"{KNOTS}{local}"]
                copies.append(f"{local} = P[:, {col} : {col} + nk].copy()")
            else:
                copies.append(f"{local} = P[:, {layout[param]}].copy()")
        flags += [f"{f} = {expr}" for f, expr in k.flags.items()]
    lines = []
    blocks = {"@copies": copies, "@flags": flags, "@load_states": loads, "@store_states": stores}
    for line in _expand(template.replace("@update\n", UPDATE), kernels, branches):
        body = line.lstrip()
        pad = line[: len(line) - len(body)]
        lines += [pad + b for b in blocks[body]] if body in blocks else [line]
    text = "\n".join(lines)

    def reads(match):
        fl = [f for k in kernels if match[1] in k.reads for f in k.flags]
        return " or ".join(fl) if fl else "False"

    text = re.sub(r"@col\((\w+)\)", lambda mt: str(layout[mt[1]]), text)
    text = re.sub(r"@factors\((\w+)\)",
                  lambda mt: "".join(f" * {k.factors[mt[1]]}" for k in kernels
                                     if mt[1] in k.factors), text)  # fmt: skip
    text = text.replace("@branch_sum", " + ".join(f"v{j}[c]" for j in branches))
    text = text.replace("@kelvin", repr(KELVIN_PER_TWO_RT_F))
    text = re.sub(r"@reads\((\w+)\)", reads, text)
    if "@" in text.replace("@nb.", ""):
        raise ValueError(f"a marker left in the loop: {text[text.index('@') :][:60]!r}")
    if not doc:
        which = "every element" if name == "extras" else "the elements compiled in the core"
        doc = DOC.format(version=name, which=which)
    doc = textwrap.indent(doc, "    ")
    return (f"@nb.njit(cache=True, nogil=True)\ndef {name}({args}):  # noqa: C901\n"
            f'    """{doc.lstrip()}\n    """\n' + textwrap.indent(text, "    "))  # fmt: skip


def source(registry=None) -> str:
    """The module ``model/_simulator.py`` for ``registry`` (default: the package's)."""
    from . import elements
    from . import layout as lay

    registry = elements.REGISTRY if registry is None else registry
    layout = {n: lay.IDX[n] for n in lay.NAMES[: lay.N_SCALAR]}
    for e, _, _, col in lay.VECTORS:
        for local, param in registry[e].kernel.columns.items():
            if param == KNOTS:
                layout[f"{KNOTS}{local}"] = col
    core = [e.kernel for e in registry.values() if e.compiled == "core"]
    every = [e.kernel for e in registry.values()]
    listed = textwrap.fill("The elements, in registry order: " + ", ".join(registry) + ".", 96)
    head = ('"""The compiled simulator, WRITTEN BY ``python -m avoa_pipeline.model.loopgen '
            '--write``:\ndo not edit (edit the base in ``model/loopgen.py`` or an element\'s '
            f'``Kernel``).\n\n{listed}\n"""\n\n'
            "# fmt: off\n# ruff: noqa\nimport numba as nb\nimport numpy as np\n\n"
            f"N_KNOTS = {N_KNOTS}  # the vector elements' knots\n\n\n")  # fmt: skip
    names = ", ".join(f'"{n}"' for _, n in states(every))
    return (head + _version("simulate_core", core, layout) + "\n\n"
            + _version("simulate_extras", every, layout) + "\n\n"
            + _version("step", every, layout, STEP, STEP_ARGS, STEP_DOC) + "\n\n"
            + "SIMULATE = {False: simulate_core, True: simulate_extras}\n"
            + f"STATES = ({names},)  # the columns of step's X\n")  # fmt: skip


def generated_folder() -> Path:
    """Where a registry's own simulator is written (:func:`compiled`): under ``$NUMBA_CACHE_DIR``
    when it is set, else in the environment (``<sys.prefix>/var/avoa-pipeline/simulators``), else,
    where the environment is read-only, in the temporary folder. Not the temporary folder first:
    it is one per machine, not per environment (numba's caches beside the module were compiled
    by one environment's numba; another user's folder there is not writable), and it is emptied
    at reboot, which compiles the loop again."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"]) / "avoa-simulators"
    if os.access(sys.prefix, os.W_OK):
        return Path(sys.prefix) / "var" / "avoa-pipeline" / "simulators"
    return Path(tempfile.gettempdir()) / "avoa-simulators"


def compiled():
    """The compiled simulator's module for the registry as it is now: ``model/_simulator.py``
    when that is what :func:`source` writes, else the source written once to
    :func:`generated_folder` under its hash and imported from there: a registry with an element
    added at run time (``elements.register``: a plug-in, a test's toy element) gets its own loop,
    still one compiled function per version, cached by numba beside it. The workflow's registry
    is the package's, so its jobs run ``_simulator.py`` (compiled at set-up,
    ``avoa_pipeline.warmup``); a plug-in's loop is compiled at its first use."""
    text = source()
    if TARGET.read_text(encoding="utf-8") == text:
        from . import _simulator

        return _simulator
    name = "avoa_simulator_" + hashlib.sha256(text.encode()).hexdigest()[:16]
    if name in sys.modules:
        return sys.modules[name]
    folder = generated_folder()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.py"
    if not path.exists():  # written whole, then renamed: another process may import it meanwhile
        fd, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    group = ap.add_mutually_exclusive_group(required=True)
    group.add_argument("--write", action="store_true", help=f"rewrite {TARGET.name}")
    group.add_argument("--check", action="store_true", help="exit 1 if it is not up to date")
    args = ap.parse_args(argv)
    text = source()
    if args.write:
        TARGET.write_text(text)
        return 0
    if TARGET.read_text() != text:
        print(f"{TARGET} differs from what the elements state: run "
              "python -m avoa_pipeline.model.loopgen --write", file=sys.stderr)  # fmt: skip
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
