"""The canonical form of a measured record, shared by every real-data importer.

A record is a CSV with the columns ``time_s, current_a, voltage_v, temperature_c`` (current
positive = discharge, as in the paper and the synthetic data) plus a JSON sidecar of the same stem
saying what it is and where it came from. Importers check each source file's sha256 against the
config before reading it (:func:`check_source`), build a frame, and hand it to :func:`write`, which
validates it and writes both files atomically: an error leaves neither file behind.

Every error is one :class:`~avoa_pipeline.errors.DataError` line naming the file and the field.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import pandas as pd

from .. import records
from ..errors import DataError
from ..io import atomic_path, read_csv, read_json, sha256

COLUMNS = records.COLUMNS

# What a reader needs to use a record without opening the source: identity, conditions, provenance.
SIDECAR_KEYS = (
    "cell",
    "nominal_capacity_ah",
    "ambient_temperature_c",
    "test_type",
    "source_file",
    "source_sha256",
    "citation",
    "licence",
)


def check_source(path: str | Path, sha256_expected: str, *, key: str | None = None) -> Path:
    """Return ``path`` if it exists and its sha256 is the configured one.

    ``key`` is the file's name in the config's ``real.sources`` (its path relative to the data
    root); it defaults to ``path`` and only shapes the message.
    """
    path = Path(path)
    key = str(path) if key is None else key
    if not path.is_file():
        raise DataError(f"{path}: missing (config real.sources[{key!r}])")
    got = sha256(path)
    if got != str(sha256_expected).strip().lower():
        raise DataError(
            f"{path}: sha256 {got} does not match config real.sources[{key!r}] "
            f"({sha256_expected}); the file changed or is another version"
        )
    return path


def _check_sidecar(sidecar: dict, source: str) -> str:
    if not isinstance(sidecar, dict):
        raise DataError(f"{source}: sidecar is not a mapping ({type(sidecar).__name__})")
    for key in SIDECAR_KEYS:
        if key not in sidecar:
            raise DataError(f"{source}: sidecar field {key!r} missing")
    try:
        return json.dumps(sidecar, indent=1, allow_nan=False) + "\n"
    except (TypeError, ValueError) as exc:
        raise DataError(f"{source}: sidecar not JSON-able ({exc})") from None


def sidecar_path(out_csv: str | Path) -> Path:
    return Path(out_csv).with_suffix(".json")


def write(frame: pd.DataFrame, sidecar: dict, out_csv: str | Path) -> None:
    """Write the validated record to ``out_csv`` and its sidecar beside it (same stem, .json).

    Everything is checked before anything is written; both files go through temporaries and are
    renamed only once both are complete.
    """
    out_csv = Path(out_csv)
    source = str(sidecar.get("source_file", out_csv)) if isinstance(sidecar, dict) else str(out_csv)
    clean = records.validate(frame, source, first_row=0, required=COLUMNS)
    text = _check_sidecar(sidecar, source)
    # Nested: the JSON is renamed when the inner block ends, the CSV when the outer one does; an
    # exception in either write leaves both temporaries unrenamed and deleted.
    json_path = sidecar_path(out_csv)
    renamed_json = False
    try:
        with atomic_path(out_csv) as tmp_csv:
            with atomic_path(json_path) as tmp_json:
                clean.to_csv(tmp_csv, index=False)
                tmp_json.write_text(text)
            renamed_json = True
    except BaseException:
        if renamed_json:
            with contextlib.suppress(FileNotFoundError):
                json_path.unlink()
        raise


def read(path_csv: str | Path) -> tuple[pd.DataFrame, dict]:
    """Read a canonical record and its sidecar; the same checks as :func:`write`."""
    path_csv = Path(path_csv)
    frame = read_csv(path_csv)
    frame = records.validate(frame, str(path_csv), first_row=2, required=COLUMNS)
    json_path = sidecar_path(path_csv)
    sidecar = read_json(json_path, f"sidecar of {path_csv.name}")
    _check_sidecar(sidecar, str(json_path))
    return frame, sidecar
