"""The model library's parameter table and column layout: the base's parameters and every
registered element's, their internal coordinates (the optimiser's, :data:`NAMES`) and physical
columns (the simulator's, :data:`PHYS`), and the map between them (:func:`to_physical`).
``ecm`` re-exports every name here; ``model/loopgen.py`` writes the compiled loop's column
numbers from this layout."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from . import elements
from .elements.element import N_KNOTS, Param

_R_WHY = "0-2 Ω: above the resistance of any cell this library models (mΩ to about 1 Ω)"
BASE_PARAMS: dict[str, Param] = {
    "vnom": Param("vnom_v", "lin", 0.0, (1.5, 5.0), "a lithium-ion cell's voltage",
                  element="rational"),
    "lc": Param("beta", "log10_1m", 0.0, (-2.0, 0.9999), "β: the OCV rises with SOC",
                element="rational"),
    "lq": Param("capacity_ah", "log10", 0.0, (1e-3, 1e4),
                "1 mAh to 100 A / records.MIN_C_RATE (the largest cells)", element="base"),
    "soc0": Param("soc0", "lin", 0.0, (0.0, 1.0), "a state of charge", per_record=True,
                  element="base"),
    "r0": Param("r0_ohm", "lin", 0.0, (0.0, 2.0), _R_WHY, element="base"),
    "r1": Param("r1_ohm", "lin", 0.0, (0.0, 2.0), _R_WHY, element="base"),
    "ltau1": Param("tau1_s", "log10", 1.0, (0.05, 2e4),
                   "50 ms (a logger's fastest useful step) to 5.6 h", scale="tau", element="base"),
}  # fmt: skip
"""The base model's parameters (the rational OCV's two, then the circuit's)."""


def _params() -> dict[str, Param]:
    """The base's parameters, then each element's scalars, then the vector elements' coordinates
    (their physical values are N_KNOTS each, :data:`VECTORS`), each marked with its element."""
    els = elements.REGISTRY.values()
    scalars = {n: replace(p, element=e.name) for e in els if e.vector is None
               for n, p in e.params.items()}  # fmt: skip
    vectors = {n: replace(p, element=e.name) for e in els if e.vector is not None
               for n, p in e.params.items()}  # fmt: skip
    return {**BASE_PARAMS, **scalars, **vectors}


PARAMS: dict[str, Param] = _params()
"""The one table of parameters: report name, transform, neutral value, limits and their reason,
element, and whether the value belongs to a record (initial state) rather than to the cell."""
NAMES = tuple(PARAMS)

LIMITS: dict[str, tuple[float, float]] = {n: p.limits for n, p in PARAMS.items()}
"""The library's physical range of every parameter (report units), whatever the records: a
fit's bounds (``fitting.bounds_for``) lie inside it, and a loaded ``model.json`` is judged
against it, not against bounds read from the same file."""
IDX = {n: k for k, n in enumerate(NAMES)}
NX = len(NAMES)
NEUTRAL = np.array([PARAMS[n].neutral for n in NAMES])
BY_REPORT = {p.report: n for n, p in PARAMS.items()}

# physical layout: the scalar names, then N_KNOTS values at the knots for each vector element
# (for the ones of today: the OCV correction (V), the log-multipliers of R0 and of R1). The
# compiled loop (``model/_simulator.py``) has these columns written in as numbers, by
# ``model/loopgen.py`` from this layout; ``tests/unit/test_loopgen.py`` keeps it up to date.
_VECTOR_ELEMENTS = tuple(e.name for e in elements.REGISTRY.values() if e.vector is not None)
N_SCALAR = NX - sum(len(elements.get(e).params) for e in _VECTOR_ELEMENTS)
NP = N_SCALAR + N_KNOTS * len(_VECTOR_ELEMENTS)
_PREFIX = {"ocv_shape": "d", "r0_soc": "l0_", "r1_soc": "l1_"}  # the names they always had
PHYS = (*NAMES[:N_SCALAR], *(f"{_PREFIX.get(e, e + '_')}{j}" for e in _VECTOR_ELEMENTS
                             for j in range(N_KNOTS)))  # fmt: skip

_LOG = np.array([PARAMS[n].transform == "log10" for n in NAMES[:N_SCALAR]])
_LOG1M = np.array([PARAMS[n].transform == "log10_1m" for n in NAMES[:N_SCALAR]])
_POW = np.flatnonzero(_LOG | _LOG1M)  # physical = 10**internal (for β the physical column is 1 − β)


def element_params(element: str, ocv_kind: str = "rational") -> tuple[str, ...]:
    """Internal names an element adds (``base``: the base model's, which depend on the OCV)."""
    if element == "base":
        base = ("lq", "soc0", "r0", "r1", "ltau1")
        return ("vnom", "lc", *base) if ocv_kind == "rational" else (*base, "voff")
    return tuple(elements.get(element).params)


def _basis(lowest: int) -> np.ndarray:
    """(N_KNOTS, N_KNOTS − lowest): discrete orthogonal polynomials over the knots of degree
    ``lowest``..N_KNOTS − 1, scaled to a largest entry of 1."""
    x = np.linspace(-1.0, 1.0, N_KNOTS)
    q, _ = np.linalg.qr(np.vander(x, N_KNOTS, increasing=True))
    b = q[:, lowest:]
    return b / np.abs(b).max(axis=0)


VECTORS = tuple(
    (
        e,
        tuple(elements.get(e).params),
        _basis(elements.get(e).vector.lowest),
        N_SCALAR + j * N_KNOTS,
    )
    for j, e in enumerate(_VECTOR_ELEMENTS)
)
"""The elements whose coordinates map onto values at the N_KNOTS SOC knots: (element, internal
names, basis, first physical column). ocv_shape's basis has no constant or linear part (those
are in the base's reach: Vnom, β, capacity, SOC0, the table's offset; leaving them out keeps the
fit well posed and keeps ocv_shape from mimicking a voltage offset); r0_soc's and r1_soc's has
no constant (a constant factor is R0's or R1's own)."""
_VEC_IDX = [np.array([NAMES.index(n) for n in names]) for _, names, _, _ in VECTORS]


def columns(element) -> np.ndarray:
    """An element's physical columns."""
    for e, _, _, col in VECTORS:
        if e == element.name:
            return np.arange(col, col + N_KNOTS)
    return np.array([IDX[n] for n in element.params])


EXTRAS_COLUMNS = np.concatenate([columns(e) for e in elements.REGISTRY.values()
                          if e.compiled == "extras"])  # fmt: skip
"""The physical columns of the elements the "extras" version of the simulator carries
(:func:`_kernel`): the version runs where any is not zero (their neutral value)."""


def to_physical(X: np.ndarray) -> np.ndarray:
    """Physical rows (m, NP) of internal rows (m, NX)."""
    X = np.atleast_2d(np.asarray(X, dtype=float))
    P = np.empty((X.shape[0], NP))
    P[:, :N_SCALAR] = X[:, :N_SCALAR]
    P[:, _POW] = 10.0 ** X[:, _POW]
    for (_, _, basis, col), idx in zip(VECTORS, _VEC_IDX, strict=True):
        P[:, col : col + N_KNOTS] = X[:, idx] @ basis.T
    return P


# the columns that the rest of the package reads by name (the base's, and some elements')
_BY = {"VNOM": "vnom", "OMB": "lc", "Q": "lq", "SOC0": "soc0", "R0": "r0", "R1": "r1",
       "TAU1": "ltau1", "R2": "r2", "TAU2": "ltau2", "R3": "r3", "TAU3": "ltau3", "KLOW": "klow",
       "SIG": "lsig", "KD": "kd", "TAUD": "ltaud", "HM": "hm", "GAM": "lgamma", "H0": "h0",
       "BVG": "bvg", "TH0": "th0", "TH1": "th1", "IOFF": "ioff", "VOFF": "voff", "ETA": "eta",
       "RHO": "rho", "THBV": "thbv", "THTAU": "thtau", "DUDT": "dudt", "KQ": "kq"}  # fmt: skip
(VNOM, OMB, Q, SOC0, R0, R1, TAU1, R2, TAU2, R3, TAU3, KLOW, SIG, KD, TAUD, HM, GAM, H0, BVG,
 TH0, TH1, IOFF, VOFF, ETA, RHO, THBV, THTAU, DUDT, KQ) = (
    IDX[n] for n in _BY.values())  # fmt: skip
_FIRST = {e: col for e, _, _, col in VECTORS}
D0, L0, L1 = _FIRST["ocv_shape"], _FIRST["r0_soc"], _FIRST["r1_soc"]
