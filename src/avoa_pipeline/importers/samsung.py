"""Samsung INR18650-30Q HPPC records (ARTS-Lab, cell DNN01, 20/30/40 °C) into the canonical form.

Source CSV (PROVENANCE.md of ``samsung_30q_hppc``): columns ``current`` [A, negative = discharge],
``voltage`` [V], ``temperature`` [°C, cell], ``soc`` [%, the authors' coulomb count]; **no time
column**. The sampling is uniform at 1 s (the programmed step lengths come out as whole numbers of
rows), so ``time_s`` is the row index times ``sample_s`` and the sidecar says so. The current is
negated (canonical: positive = discharge) and the result is checked against the voltage: where the
discharge current steps up the voltage must step down (``records.require_sign``), otherwise the
declared sign contradicts the data and the import stops. The ``soc`` column is not carried over
(the canonical form has no SOC); the reference capacity it implies is measured and written to the
sidecar (≈ 2.85 Ah rather than the nominal 3.0 Ah).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .. import records
from ..errors import ConfigError, DataError
from ..io import REPO_ROOT, read_csv

SOURCE_COLUMNS = ("current", "voltage", "temperature", "soc")


def read_numeric_csv(path: str | Path, columns) -> pd.DataFrame:
    """The ``columns`` of a source CSV as floats; one-line DataError naming file, column and row."""
    path = Path(path)
    raw = read_csv(path)
    out = {}
    for col in columns:
        if col not in raw.columns:
            raise DataError(f"{path}: missing column {col!r} (need {', '.join(columns)})")
        values = pd.to_numeric(raw[col], errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            what = "missing value (NaN)" if pd.isna(raw[col].iloc[i]) else "not a finite number"
            raise DataError(f"{path}: column {col!r} row {i + 2}: {what} ({raw[col].iloc[i]!r})")
        out[col] = values
    if len(raw) < 2:
        raise DataError(f"{path}: {len(raw)} rows; need at least 2")
    return pd.DataFrame(out)


SOC_CAPACITY_TOLERANCE = 0.25
"""The capacity implied by the source's ``soc`` column must lie within this fraction of the
nominal capacity. It is what checks the assumed sampling step: at 0.1 s or 10 s per row the
coulomb count would be 10 times off."""


def implied_soc_capacity_ah(raw: pd.DataFrame, sample_s: float, source: str) -> float:
    """Reference capacity [Ah] the source's ``soc`` column was counted against (slope of soc
    against the charge discharged, with rows ``sample_s`` apart)."""
    q_out = np.cumsum(-raw["current"].to_numpy()) * sample_s / 3600.0
    slope = np.polyfit(q_out, raw["soc"].to_numpy(), 1)[0]  # % per Ah, negative
    if not slope < 0:
        raise DataError(
            f"{source}: column 'soc' rises while the cell discharges (slope {slope:.3g} %/Ah): "
            "it contradicts the sign of column 'current'"
        )
    return float(-100.0 / slope)


def to_canonical(raw: pd.DataFrame, source: str, sample_s: float = 1.0) -> pd.DataFrame:
    """Canonical frame of a source record (time built from the row index, sign flipped, checked)."""
    if not sample_s > 0:
        raise DataError(f"{source}: sample_s must be > 0, got {sample_s}")
    frame = pd.DataFrame(
        {
            "time_s": np.arange(len(raw), dtype=float) * sample_s,
            "current_a": -raw["current"].to_numpy(dtype=float),
            "voltage_v": raw["voltage"].to_numpy(dtype=float),
            "temperature_c": raw["temperature"].to_numpy(dtype=float),
        }
    )
    frame = records.validate(frame, source, required=records.COLUMNS)
    records.require_sign(frame["time_s"], frame["current_a"], frame["voltage_v"], source,
                         "column 'current'", "negative = discharge (PROVENANCE.md)")  # fmt: skip
    return frame


def data_root(cfg: dict) -> Path:
    """``real.root``. A relative root is taken from the working directory (where Snakemake runs,
    so the rules' inputs and the importers see the same files), or from the repository when it
    does not exist there (a notebook or test started elsewhere)."""
    root = Path(cfg["real"]["root"])
    if root.is_absolute() or root.is_dir():
        return root
    return REPO_ROOT / root


def samsung_cfg(cfg: dict) -> dict:
    try:
        return cfg["real"]["samsung"]
    except KeyError:
        raise ConfigError("config: field real.samsung missing") from None


def import_hppc(cfg: dict, temperature: str, out_csv: str | Path, root: str | Path | None = None):
    """Import the HPPC record of ``temperature`` (a key of ``real.samsung.hppc``, e.g. "20degC")."""
    s = samsung_cfg(cfg)
    if temperature not in s["hppc"]:
        raise ConfigError(
            f"config: real.samsung.hppc has no {temperature!r} (have {', '.join(s['hppc'])})"
        )
    entry = s["hppc"][temperature]
    key = entry["file"]
    root = data_root(cfg) if root is None else Path(root)
    if key not in cfg["real"]["sources"]:
        raise ConfigError(f"config: real.sources has no entry for {key!r} (real.samsung.hppc)")
    path = records.check_source(root / key, cfg["real"]["sources"][key], key=key)
    sample_s = float(s["sample_s"])
    raw = read_numeric_csv(path, SOURCE_COLUMNS)
    frame = to_canonical(raw, str(path), sample_s)
    q_soc = implied_soc_capacity_ah(raw, sample_s, str(path))
    nominal = float(s["nominal_capacity_ah"])
    if abs(q_soc / nominal - 1.0) > SOC_CAPACITY_TOLERANCE:
        raise DataError(
            f"{path}: column 'soc' implies a capacity of {q_soc:.3g} Ah with {sample_s:g} s per "
            f"row, against {nominal:g} Ah nominal: the sampling step (real.samsung.sample_s) or "
            "the current is wrong"
        )
    sidecar = {
        "cell": s["cell"],
        "nominal_capacity_ah": nominal,
        "ambient_temperature_c": float(entry["ambient_c"]),
        "test_type": "HPPC: per 5 % SOC step, 10 s 1C (3 A) discharge pulse, 180 s rest, "
        "100 s 0.3 A charge pulse, 180 s rest, 540 s 1 A discharge, 3600 s rest",
        "source_file": key,
        "source_sha256": cfg["real"]["sources"][key],
        "citation": s["citation"],
        "licence": s["licence"],
        "sample_s": sample_s,
        "time_s": f"built: the source has no time column; time_s = row index x {sample_s:g} s "
        "(uniform sampling, checked from the programmed step lengths in PROVENANCE.md)",
        "current_a": "source column 'current' negated (source: negative = discharge); the sign "
        "was checked against the voltage response at the pulse edges",
        "temperature_c": "source column 'temperature' (cell surface), unchanged",
        "dropped_columns": {
            "soc": "the authors' coulomb-counted SOC [%], not part of the canonical form; its "
            f"implied reference capacity is {q_soc:.4f} Ah"
        },
        "n_samples": len(frame),
    }
    records.write(frame, sidecar, out_csv)
    return frame, sidecar
