"""The set-up's warm-up (``avoa_pipeline.warmup``, issue 42): it reaches every cached kernel, and
its marker goes stale when what numba's caches depend on changes."""

from __future__ import annotations

import json
import re
from pathlib import Path

from avoa_pipeline import warmup

PACKAGE = Path(warmup.__file__).resolve().parent
# a decorator or a wrapping call that caches: `@nb.njit(cache=True, ...)`, `nb.njit(cache=True)(f)`
CACHED = re.compile(r"^\s*@nb\.njit\([^)]*cache=True|=\s*nb\.njit\([^)]*cache=True", re.M)


def test_every_module_with_cached_kernels_is_warmed():
    """A module that gains an ``@nb.njit(cache=True)`` must be in KERNEL_MODULES (the warm-up's
    coverage check walks those modules only). loopgen writes the decorator into _simulator.py."""
    found = set()
    for path in PACKAGE.rglob("*.py"):
        if CACHED.search(path.read_text(encoding="utf-8")):
            parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
            found.add(".".join(parts))
    assert found == set(warmup.KERNEL_MODULES)


def test_warm_up_leaves_every_cached_kernel_compiled(tmp_path, monkeypatch):
    """After it, each cached kernel has its index file and the marker is current; a different
    cache folder or a missing index file makes it stale (set-up then warms up again)."""
    path = tmp_path / "marker.json"
    assert not warmup.current(path)
    mark = warmup.warm(path)
    assert mark["missing"] == []
    assert len(mark["indexes"]) >= len(warmup.KERNEL_MODULES)
    assert warmup.current(path)
    assert warmup.cache_indexes() == (mark["indexes"], [])
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "elsewhere"))
    assert not warmup.current(path)
    monkeypatch.undo()
    assert warmup.current(path)
    stale = {**mark, "indexes": [*mark["indexes"], str(tmp_path / "deleted.nbi")]}
    path.write_text(json.dumps(stale))
    assert not warmup.current(path)


def test_check_is_the_marker_only(tmp_path, capsys):
    """``--check`` answers from the marker (exit 1 without one), without compiling anything."""
    path = tmp_path / "marker.json"
    assert warmup.main(["--check", "--marker", str(path)]) == 1
    path.write_text(json.dumps({"stamp": warmup.stamp(), "indexes": []}))
    assert warmup.main(["--check", "--marker", str(path)]) == 0
    assert capsys.readouterr().out == ""
