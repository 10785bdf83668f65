"""Compiles every cached numba kernel the workflow runs, once, before any job (issue 42).

    python -m avoa_pipeline.warmup           # compile (or load) them all; write the marker
    python -m avoa_pipeline.warmup --check   # exit 0 if the marker says they are compiled

Why: the kernels are ``@nb.njit(cache=True)``, so a process loads what an earlier one compiled,
but in a fresh clone nothing is compiled yet: the first fit job paid about 8.5 s of compilation,
and the first jobs of ``snakemake -j2`` each compiled the same kernels at once. ``scripts/
setup.sh`` runs this module after it installs the environment, and again whenever ``--check``
fails, so the jobs find every kernel compiled. It drives each kernel through the code path the
jobs use (a fit job's own function on a tiny budget, the simulator's wrappers, the heat model,
the SOC filter's model), because numba compiles one version per argument types and only the
types the jobs pass are worth caching.

Where the caches live, decided: where numba puts them, beside the sources
(``src/avoa_pipeline/**/__pycache__``), or under ``$NUMBA_CACHE_DIR`` when it is set (set it
for set-up and jobs alike). Numba keys a cache by its source file's absolute folder and its
modification time, so a folder per environment would not let a second clone reuse the first
one's kernels anyway: what can be saved is compiling in the jobs, and set-up does it once per
clone. The marker, which says that this clone's kernels are compiled for this environment, sits
in the environment (``<venv>/var/avoa-pipeline``), named by the package folder: it holds a stamp
of what numba's caches depend on (Python, numba, ``NUMBA_CACHE_DIR``, every module's path, size
and modification time) and the cache index files written, so ``--check`` fails when a source
changes, the environment changes, or the caches were deleted, without importing numba.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import sys
import tempfile
import time
from importlib import metadata
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
MARKER_DIR = Path(sys.prefix) / "var" / "avoa-pipeline"
KERNEL_MODULES = (  # every module with an @nb.njit(cache=True) (tests/unit/test_warmup.py)
    "avoa_pipeline.model.kernel",
    "avoa_pipeline.model._simulator",
    "avoa_pipeline.model.heat",
    "avoa_pipeline.optimizers.base",
    "avoa_pipeline.optimizers.gto",
    "avoa_pipeline.optimizers.gwo",
    "avoa_pipeline.optimizers.nelder_mead",
    "avoa_pipeline.optimizers.run",
)
TINY_BUDGET = {"pop_size": 4, "iterations": 2, "max_nfe": None}  # every step of every
# algorithm runs once at least; the kernels' types do not depend on the budget
POPULATION_ROWS = 64  # enough rows for the kernel's thread blocks (threads.kernel_blocks)
FIT_SCENARIO, FIT_CASE = 4, 4  # any scenario × case passes the kernels the same types
SAMPLES = 600  # the small records' length (s at 1 s): every element's code runs on it


def marker() -> Path:
    digest = hashlib.sha256(str(PACKAGE).encode()).hexdigest()[:16]
    return MARKER_DIR / f"warmup-{digest}.json"


def stamp() -> str:
    """What numba's caches of this package depend on, hashed."""
    try:
        numba_version = metadata.version("numba")
    except metadata.PackageNotFoundError:  # pragma: no cover - a dependency
        numba_version = "none"
    h = hashlib.sha256()
    h.update(f"{platform.python_version()} {numba_version} {sys.prefix}\n".encode())
    h.update(f"NUMBA_CACHE_DIR={os.environ.get('NUMBA_CACHE_DIR', '')}\n".encode())
    for path in sorted(PACKAGE.rglob("*.py")):
        st = path.stat()
        h.update(f"{path.relative_to(PACKAGE)} {st.st_size} {st.st_mtime_ns}\n".encode())
    return h.hexdigest()


def current(path: Path | None = None) -> bool:
    """Whether the marker (default :func:`marker`) says every kernel is compiled for this clone
    and environment."""
    try:
        mark = json.loads((marker() if path is None else path).read_text())
    except (FileNotFoundError, json.JSONDecodeError, UnicodeDecodeError):
        return False
    return (isinstance(mark, dict) and mark.get("stamp") == stamp()
            and all(Path(p).is_file() for p in mark.get("indexes", ())))  # fmt: skip


def paper_fits(tmp: Path) -> None:
    """The fit job (``jobs.identify.fit_algorithms``) for every algorithm on the workflow's own
    dataset file, then the population kernel with threads (the CLI's fits; the fit job runs on
    one thread)."""
    import numba
    import numpy as np

    from . import config, problem
    from .jobs.data import dataset
    from .jobs.identify import fit_algorithms
    from .optimizers import ALGORITHMS

    cfg = config.load()
    cfg["budget"] = dict(TINY_BUDGET)
    csv = str(tmp / "data.csv")
    dataset(cfg, FIT_SCENARIO, FIT_CASE, csv)
    algorithms, seeds = list(ALGORITHMS), [1, 2]
    outs = [str(tmp / f"{a}-{s}.json") for a in algorithms for s in seeds]
    threads = numba.get_num_threads()
    try:
        fit_algorithms(cfg, csv, FIT_SCENARIO, FIT_CASE, algorithms, seeds, outs)
    finally:
        numba.set_num_threads(threads)
    prob = problem.build(cfg, FIT_SCENARIO, FIT_CASE, data=csv)
    x = (prob.lb + prob.ub) / 2
    prob.objective(x[None, :])
    prob.objective(np.tile(x, (POPULATION_ROWS, 1)))


def nelder_mead_ties() -> None:
    """Nelder–Mead's path for a simplex with tied values (sorted by numpy, as scipy sorts it,
    then begun again in compiled code) and its centroid: a fit may never tie, so the paper fits
    above need not reach them."""
    import numpy as np

    from .optimizers import nelder_mead as nm

    search = nm.Simplexes(np.zeros(2), np.ones(2), 1)
    search.restart(np.array([0]), np.array([[0.5, 0.5]]))
    alive = np.ones(1, dtype=bool)
    for _ in range(4):  # the initial simplex's three vertices, each told the same value
        search.fcalls += alive
        search.advance(np.zeros(1), alive)
    nm.centroid(search.sim)


def simulator() -> None:
    """Both versions of the generated simulator (``SIMULATE``: core and extras), with and
    without an OCV table, and the heat model."""
    import numpy as np
    import pandas as pd

    from .model import ecm, heat

    t = np.arange(SAMPLES, dtype=float)
    cur = np.where((t // 100) % 2 == 1, 1.5, 0.0)
    frame = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": np.full_like(t, 3.7),
                          "temperature_c": 25.0 + 0.01 * t})  # fmt: skip
    base = {"vnom_v": 3.7, "capacity_ah": 2.5, "soc0": 0.9, "r0_ohm": 0.05, "r1_ohm": 0.015,
            "tau1_s": 100.0}  # fmt: skip
    extras = {**base, "entropic_dudt_v_per_k": 1e-4}  # an element compiled in extras only
    soc = np.linspace(0.0, 1.0, 21)
    table = ecm.OcvTable.from_points(soc, 3.3 + 0.8 * soc, source="warm-up")
    for params in (base, extras):
        for cfg in (ecm.Config(), ecm.Config(table=table)):
            ecm.simulate_params(frame, params, cfg)
    heat.temperature(t, 0.1 * cur**2, 298.15, 60.0, 0.5)


def soc_filter() -> None:
    """The SOC filter's compiled step (``estimate.Model``: transition and measurement)."""
    import numpy as np

    from . import estimate
    from .model import ecm

    x = ecm.vector({"vnom_v": 3.7, "capacity_ah": 2.5, "r0_ohm": 0.05, "r1_ohm": 0.015,
                    "tau1_s": 100.0})  # fmt: skip
    model = estimate.Model(ecm.to_physical(x), estimate.layout_of(()), ecm.Knots(0.0, 0.2), None)
    X = np.zeros((3, model.layout.n))
    X[:, model.layout["soc"]] = 0.5
    model.transition(X, 1.0, 1.0, 0.0, 0.05)
    model.measurement(X, 1.0, 0.0, 0.05)


def cache_indexes() -> tuple[list[str], list[str]]:
    """(index files of the cached kernels, the kernels whose index file is missing). A kernel
    called only from other kernels is compiled with its first caller; once its callers load
    from the cache, it is not compiled again, so its index file, not its loaded signatures,
    tells that it was."""
    import importlib

    from numba.core.caching import NullCache
    from numba.core.dispatcher import Dispatcher

    indexes, missing = set(), []
    for name in KERNEL_MODULES:
        module = importlib.import_module(name)
        for attr, obj in sorted(vars(module).items()):
            if not isinstance(obj, Dispatcher) or isinstance(obj._cache, NullCache):
                continue
            if obj.targetoptions.get("inline") == "always":
                continue  # compiled into its callers only
            index = obj._cache._cache_file._index_path
            if Path(index).is_file():
                indexes.add(index)
            else:
                missing.append(f"{name}.{attr}")
    return sorted(indexes), missing


def warm(path: Path | None = None) -> dict:
    """Compile (or load) every kernel; write the marker at ``path`` (default :func:`marker`)
    when every cached kernel has its index file. Returns the marker's content."""
    path = marker() if path is None else path
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="avoa-warmup-") as tmp:
        paper_fits(Path(tmp))
    nelder_mead_ties()
    simulator()
    soc_filter()
    indexes, missing = cache_indexes()
    mark = {"stamp": stamp(), "indexes": indexes, "missing": missing,
            "seconds": round(time.perf_counter() - started, 2)}  # fmt: skip
    if not missing:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp_mark = path.with_suffix(".tmp")
        tmp_mark.write_text(json.dumps(mark, indent=1))
        os.replace(tmp_mark, path)
    return mark


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="exit 1 unless the marker is current")
    ap.add_argument(
        "--marker",
        type=Path,
        default=None,
        help=f"the marker file (default {MARKER_DIR}/warmup-<package hash>.json)",
    )
    args = ap.parse_args(argv)
    if args.check:
        return 0 if current(args.marker) else 1
    mark = warm(args.marker)
    if mark["missing"]:
        print(f"warm-up: not compiled (the jobs will compile them): {', '.join(mark['missing'])}",
              file=sys.stderr)  # fmt: skip
        return 1
    print(f"warm-up: {len(mark['indexes'])} cached kernels ready in {mark['seconds']:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
