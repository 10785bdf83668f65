"""Load and check a configuration file.

The JSON Schema (``schemas/config.schema.yaml``, the same file Snakemake's ``validate`` uses)
checks shapes and types; :func:`check` adds the checks a schema cannot state (lb < ub, the truth
inside the searched box, currents within the cell's limits). Every failure is one line that names
the file and the field.
"""

from __future__ import annotations

import copy
from importlib import resources
from pathlib import Path

import jsonschema
import yaml

from .errors import ConfigError
from .io import REPO_ROOT
from .model.battery import CASES, PARAM_NAMES

SCHEMA_PATH = Path(str(resources.files("avoa_pipeline") / "schemas" / "config.schema.yaml"))
DEFAULT_CONFIG = REPO_ROOT / "config" / "config.yaml"


def load_schema() -> dict:
    return yaml.safe_load(SCHEMA_PATH.read_text())


def load(path: str | Path | None = None) -> dict:
    """Read, validate and check the configuration at ``path`` (default: config/config.yaml)."""
    path = Path(path) if path is not None else DEFAULT_CONFIG
    try:
        cfg = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such config file") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark else ""
        raise ConfigError(f"{path}: not valid YAML{where}") from None
    if not isinstance(cfg, dict):
        raise ConfigError(f"{path}: expected a mapping at the top level")
    validate(cfg, source=str(path))
    return cfg


def validate(cfg: dict, source: str = "config") -> None:
    try:
        jsonschema.validate(cfg, load_schema())
    except jsonschema.ValidationError as exc:
        field = ".".join(str(p) for p in exc.absolute_path) or "(top level)"
        raise ConfigError(f"{source}: field {field}: {exc.message}") from None
    check(cfg, source)


def check(cfg: dict, source: str = "config") -> None:
    """Semantic checks a JSON Schema cannot express."""

    def fail(field: str, msg: str):
        raise ConfigError(f"{source}: field {field}: {msg}")

    for which in ("bounds_printed", "bounds_used"):
        for temp, box in cfg[which].items():
            for name in PARAM_NAMES:
                lo, hi = box[name]
                if not lo < hi:
                    fail(f"{which}.{temp}.{name}", f"lower bound {lo} must be < upper bound {hi}")
    for temp, truth in cfg["true_params"].items():
        box = cfg["bounds_used"][temp]
        for name in PARAM_NAMES:
            lo, hi = box[name]
            if not lo <= truth[name] <= hi:
                fail(f"true_params.{temp}.{name}", f"{truth[name]} lies outside [{lo}, {hi}]")
        if cfg["constants"]["qdis_ah"] >= truth["q"]:
            fail("constants.qdis_ah", f"must be below the capacity q = {truth['q']} Ah at {temp}")
    cell = cfg["cell"]
    for i, seg in enumerate(cfg["profile"]["segments"]):
        cur = seg["current_a"]
        if cur > cell.get("max_discharge_current_a", float("inf")):
            fail(f"profile.segments.{i}.current_a", f"{cur} A exceeds the cell's discharge limit")
        if -cur > cell.get("max_charge_current_a", float("inf")):
            fail(f"profile.segments.{i}.current_a", f"{-cur} A exceeds the cell's charge limit")
        if seg["duration_s"] < cfg["profile"]["sample_s"]:
            fail(f"profile.segments.{i}.duration_s", "shorter than one sample")
    if cfg["constants"]["cycle_n"] > 10 * cfg["constants"]["n_cycles_ref"]:
        fail("constants.cycle_n", "more than 10 N cycles is outside the fade law's use")


def part(cfg: dict, *paths) -> dict:
    """The parts of ``cfg`` at ``paths``, in the config's own nesting, and nothing else: what a
    workflow rule passes to its job (its ``params``), so that a job reads only what the rule
    names and a change elsewhere in the config neither reaches nor reruns it. A path is a dotted
    string (``"real.panasonic"``) or a tuple of keys (for keys holding dots or slashes, such as
    a source file's name under ``real.sources``). A missing key is a :class:`ConfigError`
    naming the field."""
    out: dict = {}
    for path in paths:
        keys = tuple(path.split(".")) if isinstance(path, str) else tuple(path)
        src, dst = cfg, out
        for i, key in enumerate(keys):
            if not isinstance(src, dict) or key not in src:
                raise ConfigError(f"config: field {'.'.join(keys[: i + 1])} missing")
            src = src[key]
            if i == len(keys) - 1:
                dst[key] = copy.deepcopy(src)  # never a view into the config
            else:
                dst = dst.setdefault(key, {})
    return out


def bounds(cfg: dict, case: int) -> tuple[tuple[str, ...], list[float], list[float]]:
    """Names, lower and upper bounds of the parameters identified in ``case``."""
    c = CASES[case]
    box = cfg["bounds_used"][c.temperature]
    return c.free, [box[n][0] for n in c.free], [box[n][1] for n in c.free]
