"""NASA PCoE B0005 discharges (168 ageing states) into one canonical record.

Sources (PROVENANCE.md of ``nasa_pcoe_b0005``): one CSV per discharge, ``dis_<k>_cap_<Ah>.csv``
(k = 1..168 in test order), columns ``voltage`` [V, cell terminal], ``current`` [A, **negative =
discharge**], ``temperature`` [°C, cell], ``current_load``, ``voltage_load`` (at the load; not
used: ``current_load`` changes sign convention between records) and ``time`` [s from the start of
that record], sampled unevenly (about 18.7 s early, 9.4 s later); and an index with each
discharge's start date and time (``index_from_PenjiMakesStuff/B0005_discharge.csv``, row k =
discharge k).

Decision: **one canonical file** for the 168 discharges, on one time axis, ``time_s`` = seconds
since the start of discharge 1 (the index's start time of discharge k + the record's own
``time``). The samples are kept where they were measured (no resampling: the capacity is a
coulomb count, which needs no uniform grid, and the resistance reads the voltage at a fixed delay
after the load switches on, interpolated between measured samples; see :mod:`.fade`). One file
keeps the real timeline, including the rests between discharges that the capacity recovers in.
The sidecar's ``discharges`` lists, for each k, its rows, start time, NASA cycle number and NASA's
own capacity figure, so a discharge is one slice of the record.

Checks, each a one-line DataError naming the file and field: every source's sha256; columns,
numbers, finite values and strictly increasing time per record; the current sign against the
voltage at the load steps (``records.require_sign``); the index row k against
``dis_k`` (capacity, record length); discharge k ending before k+1 starts; k = 1..K without gaps.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numpy as np
import pandas as pd

from .. import records
from ..errors import ConfigError, DataError
from ..io import read_csv
from .samsung import data_root, read_numeric_csv

SOURCE_COLUMNS = ("voltage", "current", "temperature", "time")
INDEX_COLUMNS = ("cycle", "amb_temp", "date_time", "time", "capacity")
INDEX_TIME_FORMAT = "%d %b %Y, %H:%M:%S"
_NAME = re.compile(r"^dis_(\d+)_cap_([0-9.eE+-]+)\.csv$")

CAPACITY_MATCH_AH = 1e-6
"""Index capacity and file-name capacity of the same discharge agree to this (PROVENANCE: 5e-10)."""

RECORD_END_MATCH_S = 0.01
"""The index's ``time`` (last sample of the record) and the record's last ``time`` agree to this."""


def nasa_cfg(cfg: dict) -> dict:
    try:
        return cfg["real"]["nasa"]
    except KeyError:
        raise ConfigError("config: field real.nasa missing") from None


def discharge_keys(cfg: dict) -> list[tuple[int, str, float]]:
    """(k, source key, capacity in the file name) of every discharge in ``real.sources``, by k."""
    prefix = nasa_cfg(cfg)["discharge_dir"].rstrip("/") + "/"
    found = []
    for key in cfg["real"]["sources"]:
        if not key.startswith(prefix):
            continue
        m = _NAME.match(key[len(prefix) :])
        if m is None:
            raise ConfigError(f"config: real.sources[{key!r}]: not a dis_<k>_cap_<Ah>.csv name")
        found.append((int(m.group(1)), key, float(m.group(2))))
    found.sort()
    if not found:
        raise ConfigError(f"config: real.sources lists no discharge under {prefix!r}")
    ks = [k for k, _, _ in found]
    if ks != list(range(1, len(ks) + 1)):
        missing = sorted(set(range(1, max(ks) + 1)) - set(ks))
        dup = sorted({k for k in ks if ks.count(k) > 1})
        raise ConfigError(
            f"config: real.sources under {prefix!r}: discharges must be 1..K without gaps "
            f"(missing {missing[:5]}, duplicated {dup[:5]})"
        )
    return found


def read_index(path: Path) -> pd.DataFrame:
    raw = read_csv(path)
    for col in INDEX_COLUMNS:
        if col not in raw.columns:
            raise DataError(f"{path}: missing column {col!r} (need {', '.join(INDEX_COLUMNS)})")
    out = pd.DataFrame(index=raw.index)
    for col in ("cycle", "amb_temp", "time", "capacity"):
        values = pd.to_numeric(raw[col], errors="coerce")
        if values.isna().any() or not np.isfinite(values.to_numpy(dtype=float)).all():
            i = int(np.flatnonzero(~np.isfinite(values.to_numpy(dtype=float)))[0])
            raise DataError(f"{path}: column {col!r} row {i + 2}: not a finite number")
        out[col] = values.astype(float)
    start = pd.to_datetime(raw["date_time"], format=INDEX_TIME_FORMAT, errors="coerce")
    if start.isna().any():
        i = int(np.flatnonzero(start.isna().to_numpy())[0])
        raise DataError(
            f"{path}: column 'date_time' row {i + 2}: not a date like '02 Apr 2008, 15:25:41' "
            f"({raw['date_time'].iloc[i]!r})"
        )
    out["start"] = start
    return out


def _listing_sha256(entries: list[tuple[str, str]]) -> str:
    """sha256 of the ``sha256sum``-style listing "<sha256>  <key>" of the files, in order."""
    text = "".join(f"{sha}  {key}\n" for key, sha in entries)
    return hashlib.sha256(text.encode()).hexdigest()


def _discharge_frame(index_path, k: int, cap_name: float, ix, path, raw, start_s: float):
    """Discharge ``k``'s canonical frame, its time from the index's start (``start_s``), after
    checking it against its index row ``ix`` (capacity, last time) and by the records layer."""
    if abs(ix["capacity"] - cap_name) > CAPACITY_MATCH_AH:
        raise DataError(
            f"{index_path}: row {k + 1} field 'capacity' {ix['capacity']:.6f} Ah does not "
            f"match {path.name} ({cap_name:.6f} Ah): index and discharge files are out of step"
        )
    if abs(ix["time"] - raw["time"].iloc[-1]) > RECORD_END_MATCH_S:
        raise DataError(
            f"{index_path}: row {k + 1} field 'time' {ix['time']:.3f} s is not the last time "
            f"of {path.name} ({raw['time'].iloc[-1]:.3f} s)"
        )
    frame = pd.DataFrame(
        {
            "time_s": start_s + raw["time"].to_numpy(),
            "current_a": -raw["current"].to_numpy(),
            "voltage_v": raw["voltage"].to_numpy(),
            "temperature_c": raw["temperature"].to_numpy(),
        }
    )
    # the record's own checks first, so a message names the discharge file, not the merge
    frame = records.validate(frame, str(path), required=records.COLUMNS)
    records.require_sign(frame["time_s"], frame["current_a"], frame["voltage_v"],
                         str(path), "column 'current'",
                         "negative = discharge (PROVENANCE.md)")  # fmt: skip
    return frame


def _b0005_sidecar(n: dict, n_discharges: int, listing, discharges: list[dict],
                   n_samples: int) -> dict:  # fmt: skip
    """The merged record's sidecar: the cell, the test, the sources and their digest, what each
    column is, and one entry per discharge."""
    return {
        "cell": n["cell"],
        "nominal_capacity_ah": float(n["nominal_capacity_ah"]),
        "ambient_temperature_c": float(n["ambient_c"]),
        "test_type": "ageing: CC discharge at 2 A to 2.7 V (then load off, relaxation), after a "
        "CC-CV charge (1.5 A to 4.2 V, 20 mA), repeated at each ageing state",
        "source_file": f"{n['discharge_dir']}/dis_<k>_cap_<Ah>.csv (k = 1..{n_discharges}) and "
        f"{n['index']}",
        "source_sha256": _listing_sha256(listing),
        "source_sha256_of": "the sha256sum-style listing '<sha256>  <file>' of the index and then "
        "discharges 1..K (each file's own sha256 is in the config's real.sources)",
        "citation": n["citation"],
        "licence": n["licence"],
        "time_s": "seconds since the start of discharge 1: index 'date_time' of discharge k "
        "(local time, 1 s resolution) + the record's 'time'; samples where measured (uneven, "
        "about 18.7 s early and 9.4 s later), not resampled",
        "current_a": "source column 'current' (Current_measured) negated (source: negative = "
        "discharge); the sign was checked against the voltage at the load steps of every record",
        "temperature_c": "source column 'temperature' (cell), unchanged",
        "dropped_columns": {
            "current_load": "current at the load; its sign convention flips between records",
            "voltage_load": "voltage at the load",
        },
        "discharges": discharges,
        "n_samples": n_samples,
    }


def import_b0005(cfg: dict, out_csv: str | Path, root: str | Path | None = None):
    """Check, read and merge every B0005 discharge into ``out_csv`` (+ sidecar)."""
    n = nasa_cfg(cfg)
    root = data_root(cfg) if root is None else Path(root)
    sources = cfg["real"]["sources"]
    if n["index"] not in sources:
        raise ConfigError(f"config: real.sources has no entry for {n['index']!r} (real.nasa.index)")
    index_path = records.check_source(root / n["index"], sources[n["index"]], key=n["index"])
    index = read_index(index_path)
    keys = discharge_keys(cfg)
    if len(index) != len(keys):
        raise DataError(
            f"{index_path}: {len(index)} rows, but real.sources lists {len(keys)} discharges"
        )
    t_first = index["start"].iloc[0]
    frames, discharges, listing = [], [], [(n["index"], sources[n["index"]])]
    row = 0
    prev_end = -np.inf
    for (k, key, cap_name), (_, ix) in zip(keys, index.iterrows(), strict=True):
        path = records.check_source(root / key, sources[key], key=key)
        listing.append((key, sources[key]))
        raw = read_numeric_csv(path, SOURCE_COLUMNS)
        start_s = (ix["start"] - t_first).total_seconds()
        frame = _discharge_frame(index_path, k, cap_name, ix, path, raw, start_s)
        if frame["time_s"].iloc[0] <= prev_end:
            raise DataError(
                f"{index_path}: row {k + 1} field 'date_time': discharge {k} starts before "
                f"discharge {k - 1} ends"
            )
        prev_end = frame["time_s"].iloc[-1]
        discharges.append(
            {
                "discharge": k,
                "nasa_cycle": int(ix["cycle"]),
                "start": ix["start"].isoformat(),
                "start_s": start_s,
                "first_row": row,
                "n_rows": len(frame),
                "capacity_nasa_ah": float(ix["capacity"]),
                "ambient_c": float(ix["amb_temp"]),
                "source_file": key,
            }
        )
        row += len(frame)
        frames.append(frame)
    merged = pd.concat(frames, ignore_index=True)
    sidecar = _b0005_sidecar(n, len(keys), listing, discharges, len(merged))
    records.write(merged, sidecar, out_csv)
    return merged, sidecar


def discharge_slices(frame: pd.DataFrame, sidecar: dict, source: str = "<record>"):
    """Yield (entry, sub-frame) for each discharge listed in the sidecar."""
    entries = sidecar.get("discharges")
    if not isinstance(entries, list) or not entries:
        raise DataError(f"{source}: sidecar field 'discharges' missing or empty")
    for e in entries:
        try:
            a, m = int(e["first_row"]), int(e["n_rows"])
        except (KeyError, TypeError, ValueError):
            raise DataError(f"{source}: sidecar field 'discharges': bad entry {e!r}") from None
        if a < 0 or m < 2 or a + m > len(frame):
            raise DataError(
                f"{source}: sidecar field 'discharges': discharge {e.get('discharge')} rows "
                f"{a}..{a + m - 1} outside the record ({len(frame)} rows)"
            )
        yield e, frame.iloc[a : a + m].reset_index(drop=True)
