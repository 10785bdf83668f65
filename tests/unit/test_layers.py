"""No import runs up a layer (issue 39): every module's imports, at the top of the file and inside
functions, checked against the layer table of docs/architecture.md, the one place that says which
module sits where."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "avoa_pipeline"
DOCS = ROOT / "docs" / "architecture.md"
ROOT_NAME = "avoa_pipeline"


def read_layers(text: str) -> dict[str, int]:
    """Entry (a module or package path below ``avoa_pipeline``) → rank, 0 the bottom layer. The
    table between the ``layers: begin``/``end`` markers lists the top layer first; its second
    column holds the entries, each in backticks."""
    block = re.search(r"<!-- layers: begin.*?-->(.*?)<!-- layers: end -->", text, re.S)
    assert block, f"{DOCS}: no layer table between '<!-- layers: begin' and '<!-- layers: end -->'"
    rows = [r for r in block.group(1).splitlines() if r.startswith("|")][2:]  # header, rule
    layers: dict[str, int] = {}
    for rank, row in enumerate(reversed(rows)):
        cells = [c.strip() for c in row.strip("|").split("|")]
        for entry in re.findall(r"`([^`]+)`", cells[1]):
            assert entry not in layers, f"{DOCS}: {entry} is in two layers"
            layers[entry] = rank
    return layers


def module_names(package: Path) -> dict[str, Path]:
    """Dotted name below the package (``__init__`` for the package's own) → file."""
    names = {}
    for path in sorted(package.rglob("*.py")):
        parts = list(path.relative_to(package).with_suffix("").parts)
        if parts[-1] == "__init__" and len(parts) > 1:
            parts = parts[:-1]
        names[".".join(parts)] = path
    return names


def _package_of(name: str, path: Path) -> list[str]:
    """The package a relative import of module ``name`` starts from, as path parts."""
    parts = [] if name == "__init__" else name.split(".")
    return parts if path.name == "__init__.py" else parts[:-1]


def imports_of(name: str, path: Path, modules) -> list[tuple[int, str]]:
    """(line, imported module below the package) for every import of the package in the file:
    ``from X import y`` imports ``X.y`` when that is a module or a table entry (the root's
    ``__version__``), else ``X``; an import of the package itself is of ``__init__``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = _package_of(name, path)
                base = base[: len(base) - (node.level - 1)]
                source = ".".join([ROOT_NAME, *base] + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            targets = []
            for alias in node.names:
                whole = f"{source}.{alias.name}"
                below = whole.removeprefix(ROOT_NAME + ".")
                targets.append(whole if below in modules else source)
        else:
            continue
        for target in targets:
            if target == ROOT_NAME:
                found.append((node.lineno, "__init__"))
            elif target.startswith(ROOT_NAME + "."):
                found.append((node.lineno, target.removeprefix(ROOT_NAME + ".")))
    return found


def layer_of(name: str, layers: dict[str, int]) -> int | None:
    """The rank of the longest entry that is ``name`` or a package holding it."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        rank = layers.get(".".join(parts[:k]))
        if rank is not None:
            return rank
    return None


def upward_imports(package: Path, layers: dict[str, int]) -> list[str]:
    """One line per import from a lower layer to a higher one, and per unplaced module."""
    modules = module_names(package)
    known = set(modules) | set(layers)
    found = []
    for name, path in modules.items():
        own = layer_of(name, layers)
        if own is None:
            found.append(f"{name}: in no layer of {DOCS.name}")
            continue
        for line, target in imports_of(name, path, known):
            rank = layer_of(target, layers)
            if rank is None:
                found.append(f"{name}:{line} imports {target}, which is in no layer")
            elif rank > own:
                found.append(f"{name}:{line} imports {target} (layer {rank} above {own})")
    return found


LAYERS = read_layers(DOCS.read_text())


def test_no_import_runs_up():
    assert upward_imports(PACKAGE, LAYERS) == []


def test_table_places_the_issue_39_layers():
    """The order the issue asks for: importers below the input layer, the experiments below
    report, jobs and the commands, and the modules others are adding (the CLI's command
    package, the Python API, the diagnosis pipeline, the split model library) at their place
    before they exist; the workflow's jobs beside the commands, since both call the one
    diagnose pipeline."""
    names = ("importers.cycler", "inputs", "model.ecm", "records", "real.experiments.fade",
             "report", "jobs", "cli")  # fmt: skip
    at = {e: layer_of(e, LAYERS) for e in names}
    assert at["records"] < at["importers.cycler"] < at["model.ecm"] < at["inputs"]
    assert at["real.experiments.fade"] < at["report"] < at["jobs"] == at["cli"]
    tops = ("commands.diagnose", "api", "diagnosis", "__main__", "__init__", "real.__main__")
    for top in tops:
        assert layer_of(top, LAYERS) == max(LAYERS.values()), top
    assert layer_of("model.parameters", LAYERS) == at["model.ecm"]


def test_every_import_form_is_read(tmp_path):
    """A tiny package: each kind of import is found and resolved (top level, inside a function,
    relative at two depths, absolute, a name from a module, a submodule from a package)."""
    pkg = tmp_path / ROOT_NAME
    (pkg / "low").mkdir(parents=True)
    (pkg / "__init__.py").write_text('__version__ = "0"\n')
    (pkg / "low" / "__init__.py").write_text("")
    (pkg / "high.py").write_text("X = 1\n")
    (pkg / "low" / "deep.py").write_text(
        "from .. import __version__\n"
        "from ..high import X\n"
        "import avoa_pipeline.high\n"
        "def f():\n"
        "    from avoa_pipeline import high\n"
        "    from . import other\n"
    )
    (pkg / "low" / "other.py").write_text("")
    modules = set(module_names(pkg)) | {"__version__"}
    got = sorted(imports_of("low.deep", pkg / "low" / "deep.py", modules))
    assert got == [(1, "__version__"), (2, "high"), (3, "high"), (5, "high"), (6, "low.other")]


def test_an_upward_import_fails(tmp_path):
    """The negative case: a function-level import of a higher layer is reported, with its line;
    the same import the other way round is not; a module in no layer is reported."""
    pkg = tmp_path / ROOT_NAME
    (pkg / "lower").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "lower" / "__init__.py").write_text("")
    (pkg / "lower" / "reader.py").write_text(
        "import math\n\n\ndef f():\n    from ..upper import g\n"
    )
    (pkg / "upper.py").write_text("from .lower.reader import f\n\n\ndef g():\n    pass\n")
    layers = {"__init__": 2, "upper": 1, "lower": 0}
    assert upward_imports(pkg, layers) == ["lower.reader:5 imports upper (layer 1 above 0)"]
    assert upward_imports(pkg, {"__init__": 2, "upper": 0, "lower": 1}) == [
        "upper:1 imports lower.reader (layer 1 above 0)"
    ]
    (pkg / "stray.py").write_text("")
    assert f"stray: in no layer of {DOCS.name}" in upward_imports(pkg, layers)


def test_a_table_entry_in_two_layers_is_refused():
    text = (
        "<!-- layers: begin -->\n| layer | modules | what |\n|---|---|---|\n"
        "| top | `cli` | x |\n| bottom | `io`, `cli` | y |\n<!-- layers: end -->"
    )
    with pytest.raises(AssertionError, match="cli is in two layers"):
        read_layers(text)
    assert read_layers(text.replace(", `cli`", "")) == {"io": 0, "cli": 1}


GENERATED = {"model/_simulator.py"}  # the compiled loops, one function each on purpose (loopgen)
MAX_FUNCTION_LINES = 80  # issue 39: a function a reader can hold on one screen and a half


def long_functions(package: Path) -> list[str]:
    """``path:function lines`` for every function of the package over MAX_FUNCTION_LINES lines,
    the generated compiled loops aside."""
    out = []
    for path in sorted(package.rglob("*.py")):
        rel = path.relative_to(package).as_posix()
        if rel in GENERATED:
            continue
        for n in ast.walk(ast.parse(path.read_text())):
            if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = n.end_lineno - n.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    out.append(f"{rel}:{n.name} {lines}")
    return out


def test_no_function_over_80_lines():
    assert long_functions(PACKAGE) == []


def test_a_long_function_is_found(tmp_path):
    body = "".join(f"    x{j} = {j}\n" for j in range(MAX_FUNCTION_LINES))
    (tmp_path / "m.py").write_text(f"def short():\n    pass\n\n\ndef long():\n{body}")
    assert long_functions(tmp_path) == [f"m.py:long {MAX_FUNCTION_LINES + 1}"]
