"""What an element of the model library declares (:class:`Element`), and the few things its
parts share.

An element declares every part the package needs from it, so that adding one is one module and
one registry line (:mod:`.`): its parameters (internal and report name, transform, neutral
value, limits, each limit's physical reason), what it requires, which compiled version of the
simulator carries its code, its starts, when it applies, its residual signature, its PyBaMM
mapping (or why it has none), the record that would decide it, and whether the withheld-effect
check makes records with it. ``tests/unit/test_elements.py`` fails for an element lacking a part
(a part that does not apply is declared with its reason, never left out).

Hand-written: a registry of typed declarations, as ``optimizers.register`` and PyBaMM's model
options are; no library holds the parts of an equivalent-circuit element.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

N_KNOTS = 6
"""The vector elements (ocv_shape, r0_soc, r1_soc) live at N_KNOTS knots over the SOC range the
fitted base visits (5 segments)."""
GAS_R = 8.314462618  # J/(mol K)
FARADAY = 96485.33212  # C/mol


@dataclass(frozen=True)
class Param:
    """One parameter: ``limits`` are the library's physical range in report units (a fit's bounds
    lie inside it; a loaded model.json is judged against it), ``why`` their physical reason."""

    report: str  # name in reports and model.json (physical value)
    transform: str  # "lin", "log10" (x = log10 value) or "log10_1m" (x = log10(1 − value))
    neutral: float  # internal value at which the element is absent
    limits: tuple[float, float]
    why: str
    per_record: bool = False  # an initial state: one value per record, not per cell
    prior_sd: float | None = (
        None  # a weak Gaussian prior at the neutral value (``fitting.priors_for``)
    )
    # how a fit's bounds follow the records (``fitting.bounds_for``): "" the limits; "tau" a time
    # constant, from the records' step to twice their duration; "per_a" / "a": ``scaled`` (and
    # the prior's sd) divided / multiplied by the records' largest current
    scale: str = ""
    scaled: tuple[float, float] | None = None
    element: str = ""  # filled in by the registry ("base", "rational", "table" or an element)
    # a temperature law's physical prior (docs/temperature-rule.md part 2): (low, high, source)
    # in report units; a law fitted on two test temperatures is admitted only inside it
    physical: tuple[float, float, str] | None = None


@dataclass(frozen=True)
class Physical:
    """One fitted model's physical values, for its elements' reports and exports: ``scalars`` by
    internal name (10^x for log10 names, 1 − β for ``lc``), ``at_knots`` a vector element's
    values at the ``knots`` (SOC)."""

    scalars: Mapping[str, float]
    at_knots: Mapping[str, np.ndarray]
    knots: np.ndarray

    def __getitem__(self, name: str) -> float:
        return self.scalars[name]


@dataclass(frozen=True)
class Vector:
    """A vector element: its coordinates map onto values at the N_KNOTS SOC knots through the
    discrete orthogonal polynomials of degree ``lowest`` and up (``ecm.VECTORS``); ``report``:
    its knot values as report-named numbers (``FittedModel.parameters``)."""

    lowest: int
    report: Callable[[Physical], dict[str, float]]


@dataclass(frozen=True)
class Piece:
    """What one element adds to the generated PyBaMM module (``interop/pybamm.py``).

    ``constants``: (NAME, value, comment); ``helpers``: function sources; ``ocv_terms``:
    expressions of ``sc`` (the SOC the OCV sees) added to the OCV; ``branches``: RC branches as
    (our branch number, R constant, τ constant); ``factors`` and ``terms``: (resistor,
    expression of ``T_cell`` (°C), ``current`` (A, discharge positive), ``soc``) multiplying or
    added to a resistance; the resistor is "R0", "RC" (every RC branch) or "R1".."R3"; a factor
    of resistor "TAU" multiplies every RC branch's time constant (C_j = τ_j·factor/R_j).

    An element with a state of its own beyond Thevenin's (a surface-SOC lag, hysteresis) adds
    ``submodels``: (the Thevenin model's submodel slot it fills or adds, a ``pybamm.BaseSubModel``
    class defined in its ``helpers``); ``parameters``: (PyBaMM parameter name, expression) entries
    of ``get_parameter_values()`` its submodels read; ``states``: (state variable, the parameter
    of its initial value), which the module's ``simulate`` carries from one piece of a record to
    the next. ``current_terms``: expressions added to a measured current by the module's
    ``drive`` (a current sensor's offset, which belongs to the record, not to the cell).
    """

    constants: tuple[tuple[str, object, str], ...] = ()
    helpers: tuple[str, ...] = ()
    ocv_terms: tuple[str, ...] = ()
    branches: tuple[tuple[int, str, str], ...] = ()
    factors: tuple[tuple[str, str], ...] = ()
    terms: tuple[tuple[str, str], ...] = ()
    submodels: tuple[tuple[str, str], ...] = ()
    parameters: tuple[tuple[str, str], ...] = ()
    states: tuple[tuple[str, str], ...] = ()
    current_terms: tuple[str, ...] = ()


@dataclass(frozen=True)
class Export:
    """How the element maps onto PyBaMM's Thevenin model (``piece``: what it adds), or why it
    cannot (``piece`` None; ``how`` says why)."""

    how: str
    piece: Callable[[Physical], Piece] | None = None

    @property
    def exported(self) -> bool:
        return self.piece is not None


@dataclass(frozen=True)
class View:
    """What a residual signature reads: a training record, the base model's residual on it (V),
    the base's SOC, the seconds since the last current step and that step's sign (+1 rising, 0
    before any), each sample's direction (``records.direction``), the records' largest current
    and ``t_mean`` (the t statistic of a residual's mean over the diagnosis's batches)."""

    rec: object  # ecm.Record
    resid: np.ndarray
    soc: np.ndarray
    since: np.ndarray
    step_sign: np.ndarray
    direction: np.ndarray
    imax: float
    t_mean: Callable[[np.ndarray], float]

    def mean_mv(self, mask: np.ndarray) -> float | None:
        return 1e3 * float(np.mean(self.resid[mask])) if mask.any() else None


@dataclass(frozen=True)
class Signature:
    """What the base model's residual looks like where the element would act: ``acts`` in
    words, ``read`` the numbers (diagnosis.json ``signatures``)."""

    acts: str
    read: Callable[[View], dict]


@dataclass(frozen=True)
class State:
    """A state an element adds to the model (beyond the SOC and RC branch 1): ``name`` in the
    SOC filter's state vector (``estimate``), ``reach(p, i)`` the largest |value| it reaches at
    current ``i`` (A) with physical values ``p`` (by internal name): the filter's start takes it
    uniform over ±reach."""

    name: str
    reach: Callable[[Mapping[str, float], float], float]


@dataclass(frozen=True)
class Kernel:
    """An element's physics, stated once, as code for the compiled simulator's slots
    (``model/loopgen.py`` writes the loop from the base's statement and these; its docstring
    lists the slots and the names the base gives a snippet to read and set).

    ``columns``: local array name → the internal parameter whose physical column it copies (one
    value per row), or ``KNOTS`` for a vector element's N_KNOTS values per row. ``flags``: flag
    name → expression of the locals, true where the element acts in some row (its code is guarded
    by it, so that an element neutral in every row costs a test per sample, the branch taken out
    of the loops by the compiler). ``code``: slot → snippet (Python, indented from column 0), or
    (position, snippet) where its place among the slot's other snippets changes the floats (sums
    and products are not associative: snippets of a slot run by position, then registry order).
    ``branch``: the number j of the RC branch it adds (the generator writes its arrays r{j},
    tau{j}, a{j}, v{j}, b{j} and its code, as for the base's branch 1, from ``rc_kernel``).
    ``factors``: a product of the base's (``r1``: branch 1's resistance, ``capacity``: the
    capacity) → the local it multiplies by. ``reads``: quantities the base computes only for an
    element that reads them (``dtemp``: the temperature's rise over the reference, K).
    ``states``: local array → :class:`State`, the arrays its code steps (the simulator starts
    them where ``setup`` does; the filter's one-sample step reads and writes them)."""

    columns: Mapping[str, str] = field(default_factory=dict)
    flags: Mapping[str, str] = field(default_factory=dict)
    code: Mapping[str, str | tuple[int, str]] = field(default_factory=dict)
    branch: int | None = None
    factors: Mapping[str, str] = field(default_factory=dict)
    reads: tuple[str, ...] = ()
    states: Mapping[str, State] = field(default_factory=dict)


@dataclass(frozen=True)
class TableLaw:
    """How an element's law enters the BMS-style table (``interop/table.py``; ``how`` in words).
    Each law is a function of (p: physical values by internal name, soc: the bulk SOC at the grid
    points, tk: the cell temperature there (K), tref_k), an array over the grid points.
    ``factors``: resistor → factor: "r0" (R0, both directions), "r0_charge" (R0 while charging),
    "rc" (every RC resistance), "r1" (RC branch 1's), "tau" (every RC time constant); a value
    (position, law) places it among the resistor's other factors (products round in order).
    ``ocv``: a term added to the ocv_v column. ``columns``: columns of its own, name → (unit,
    meaning, law)."""

    how: str
    factors: Mapping[str, Callable | tuple[int, Callable]] = field(default_factory=dict)
    ocv: Callable | None = None
    columns: Mapping[str, tuple[str, str, Callable]] = field(default_factory=dict)


KNOTS = "@knots"
"""A vector element's column in :attr:`Kernel.columns`: its values at the N_KNOTS knots."""


@dataclass(frozen=True)
class Element:
    """One element of the model library. ``starts(row, imax)``: the values (internal, by name)
    each start of its fit sets on the fitted rows it extends (row: the first record's fitted
    row by internal name; each start is clipped to the bounds); ``applies(recs, imax)``: why it
    cannot be a candidate on these records ("" when it can), beyond what ``requires``,
    ``needs_temperature`` and ``conflicts`` say; ``signature``: its residual signature, or why
    it has none of its own; ``compiled``: the version of the compiled simulator that carries its
    code ("core", or "extras": compiled in only when a row uses it, ``model/loopgen.py``);
    ``kernel``: its physics in the compiled simulator."""

    name: str
    params: dict[str, Param]
    starts: Callable[[Mapping[str, float], float], list[dict]]
    signature: Signature | str
    pybamm: Export
    would_decide: str
    compiled: str = "core"
    requires: str | None = None
    needs_temperature: bool = False
    conflicts: Mapping[str, str] = field(default_factory=dict)  # "table"/"load" → why not
    applies: Callable[[list, float], str] | None = None
    vector: Vector | None = None
    withheld: bool = False  # the withheld-effect check (gap/withheld.py) makes records with it
    kernel: Kernel | None = None  # its physics in the compiled simulator (``model/loopgen.py``)
    table: TableLaw | str = ""  # how its law enters the BMS table export, or why it cannot

    def conflict(self, table: bool, load: bool) -> str:
        """Why the element cannot join a model with a measured OCV table / the paper's load
        ("" when it can)."""
        why = self.conflicts.get("table", "") if table else ""
        return why or (self.conflicts.get("load", "") if load else "")


def slope_mv(x: np.ndarray, y: np.ndarray) -> float | None:
    """The least-squares slope of ``y`` (V) against ``x``, in mV per unit of x (None when x does
    not move)."""
    if x.size < 3 or np.ptp(x) == 0:
        return None
    return 1e3 * float(np.polyfit(x, y, 1)[0])


def flat_ends(x) -> list[float]:
    """Knots with a point beyond each end, so that an interpolant through them is flat there (as
    the simulator holds the end values)."""
    x = [float(v) for v in x]
    return [x[0] - 1.0, *x, x[-1] + 1.0]


def missing_parts(e: Element) -> list[str]:
    """The parts element ``e`` lacks or declares wrongly (empty: complete)."""
    out = []
    if not e.params:
        out.append("no parameters")
    for n, p in e.params.items():
        lo, hi = p.limits
        value = {"log10": 10.0**p.neutral, "log10_1m": 1.0 - 10.0**p.neutral}.get(
            p.transform, p.neutral
        )
        if not (lo < hi and lo <= value <= hi):
            out.append(f"{n}: neutral value {value:g} outside its limits {p.limits}")
        if not p.why.strip():
            out.append(f"{n}: no reason for its limits")
        if (p.scale in ("a", "per_a")) != (p.scaled is not None):
            out.append(f"{n}: scale {p.scale!r} and scaled {p.scaled} disagree")
    if not callable(e.starts):
        out.append("no starts")
    if not (isinstance(e.signature, Signature) and e.signature.acts) and not (
        isinstance(e.signature, str) and e.signature.strip()
    ):
        out.append("no residual signature, nor why it has none")
    if not (isinstance(e.pybamm, Export) and e.pybamm.how.strip()):
        out.append("no PyBaMM mapping, nor why it has none")
    if not e.would_decide.strip():
        out.append("no record that would decide it")
    if e.kernel is None:
        out.append("no physics for the compiled simulator (kernel)")
    if not (isinstance(e.table, TableLaw) and e.table.how.strip()) and not (
        isinstance(e.table, str) and e.table.strip()
    ):
        out.append("no table law, nor why it has none")
    if e.compiled not in ("core", "extras"):
        out.append(f"compiled {e.compiled!r}: neither 'core' nor 'extras'")
    unknown = sorted(set(e.conflicts) - {"table", "load"})
    if unknown:
        out.append(f"conflicts with unknown features {unknown}")
    if e.vector is not None and len(e.params) != N_KNOTS - e.vector.lowest:
        out.append(f"a vector of degree {e.vector.lowest} up needs {N_KNOTS - e.vector.lowest} "
                   "coordinates")  # fmt: skip
    return out
