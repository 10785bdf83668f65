"""Import Kollmeyer's Panasonic NCR18650PF tests into the canonical record (docs/real-data.md).

What the source needs before it is a canonical record:

- **MATLAB v5 files** with a struct ``meas`` (read with :func:`scipy.io.loadmat`).
- **Sign**: the tester writes discharge as negative current. Each file's sign is checked against
  the voltage's answer before it is flipped (``records.require_sign``, the package's one sign
  check): the terminal voltage must move with the source current (charging raises it). A file
  whose voltage says otherwise raises a DataError instead of being silently flipped.
- **Repeated rows**: the logger writes some instants twice (step boundaries); the later row of
  each repeated ``Time`` is kept. ``Time`` going backwards is an error.
- **HPPC pulses and SOC steps in two files**: the pulse file holds the pulses and their rests, the
  ``*_dis5_10p`` file the 0.87 A discharges between pulse sets, each file with its own ``Time``.
  Both are placed on the wall clock of their ``TimeStamp`` column (1-s resolution; ``Time``
  drifts against it by ~8 s a day, so each file's clock is a least-squares line
  ``TimeStamp ≈ a + b·Time``; where the wall clock jumps, the file is split and each piece
  placed by its own line, ``Time`` ordering and spacing the rows within it), cut into blocks at
  their logging gaps, and the blocks are
  interleaved in time order; where a block starts before the previous one has ended (clock
  resolution), the earlier block's overlap is dropped. The tester's ``Ah`` counter runs on
  across both files, so the merged counter must be monotonic: that is checked, and it catches a
  wrong interleaving. Blocks of the SOC-step file after the pulse file's end belong to the next
  test (the EIS SOC steps, after a recharge) and are left out.
- **Thermal soaks** before some drive cycles (up to 2 h of rest logged every 60 s): a leading rest
  longer than ``max_leading_rest_s`` is cut to its last ``keep_rest_s`` seconds; the sidecar says
  how much was cut.
- **Resampling to a uniform step** (the model's recursion needs one; 0.1 s drive cycles, 1-60 s
  elsewhere), with charge conserved exactly: the current is taken as piecewise constant between
  samples (each sample's value held until the next one; over logging intervals longer than
  ``gap_s`` the tester's own Ah counter gives the interval's mean current, ΔAh/Δt, because a
  sample held over a minute-long gap, or over the 1-s interval after a 17 A pulse ends, would
  invent or lose charge). Each output sample is the
  exact mean of that piecewise-constant current over its bin, so the output's charge equals the
  piecewise-constant signal's integral to rounding. Voltage and temperature are taken as
  piecewise linear between samples and averaged exactly over each bin the same way (a bin mean,
  not a point sample, so the voltage sample pairs with the bin's mean current the way the
  model's R0·I term needs, and 0.1 s noise is averaged rather than aliased). Both integrals are
  scipy ``PPoly`` antiderivatives.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.io
from scipy.interpolate import PPoly, make_interp_spline

from ..errors import ConfigError, DataError
from ..records import check_source, require_sign, write

FIELDS = ("TimeStamp", "Time", "Current", "Voltage", "Ah", "Battery_Temp_degC")
_NUMERIC = FIELDS[1:]
_TS_FORMAT = "%m/%d/%Y %I:%M:%S %p"

# Below this the tester is at rest (its current reads 0 or a few mA of offset).
REST_A = 0.05


@dataclass(frozen=True)
class Settings:
    sample_s: float = 1.0
    gap_s: float = 0.5  # longer logging intervals take their mean current from the Ah counter
    block_gap_s: float = 600.0  # a logging gap this long separates blocks of a file (HPPC merge)
    max_leading_rest_s: float = 600.0
    keep_rest_s: float = 60.0


# --- reading ----------------------------------------------------------------------------------


def read_mat(path: str | Path) -> pd.DataFrame:
    """The ``meas`` struct of one file as a frame of :data:`FIELDS`, repeated instants dropped."""
    path = Path(path)
    try:
        mat = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)
    except FileNotFoundError:
        raise DataError(f"{path}: missing") from None
    except (ValueError, TypeError, OSError, NotImplementedError) as exc:
        raise DataError(f"{path}: not a readable MATLAB file ({exc})") from None
    if "meas" not in mat:
        raise DataError(f"{path}: field 'meas': missing (not a Panasonic 18650PF test file)")
    meas = mat["meas"]
    cols = {}
    for name in FIELDS:
        if not hasattr(meas, name):
            raise DataError(f"{path}: field 'meas.{name}': missing")
        cols[name] = np.atleast_1d(getattr(meas, name))
    n = {len(v) for v in cols.values()}
    if len(n) != 1:
        raise DataError(f"{path}: fields of 'meas' differ in length ({sorted(n)})")
    for name in _NUMERIC:
        try:
            values = cols[name].astype(float)
        except (TypeError, ValueError):
            raise DataError(f"{path}: field 'meas.{name}': not numeric") from None
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise DataError(f"{path}: field 'meas.{name}' row {i + 1}: not finite ({values[i]})")
        cols[name] = values
    df = pd.DataFrame(cols)
    if len(df) < 2:
        raise DataError(f"{path}: {len(df)} rows; need at least 2")
    dt = np.diff(df["Time"].to_numpy())
    if (dt < 0).any():
        i = int(np.flatnonzero(dt < 0)[0]) + 1
        raise DataError(f"{path}: field 'meas.Time' row {i + 1}: time goes backwards")
    # the logger writes some instants twice (step boundaries); the later row is the later reading
    keep = np.r_[dt > 0, True]
    out = df[keep].reset_index(drop=True)
    out.attrs["repeated_rows_dropped"] = int((~keep).sum())
    return out


CLOCK_TOLERANCE_S = 3.0
"""How far a file's clock line may miss a ``TimeStamp`` before the clock counts as having jumped.
The stamp's truncation to the second leaves ±0.5 s about the true clock, and the drift's
departure from a line adds at most 1.2 s more on the files that import (worst residual 1.71 s,
the 25 °C SOC-step file over 1.9 days); an hour's jump is far above it (docs/real-data.md)."""

MIN_PIECE_ROWS = 3
"""A line through two stamps always fits them, so a piece needs three to show that its clocks
agree."""

MAX_CLOCK_DRIFT = 1e-3
"""How far a wall clock's rate may differ from ``Time``'s: a PC's quartz clock drifts by ~1e-4
(measured ≤ 8.8e-5, 7.6 s a day), and this is ten times that. Stamps running faster or slower
show the clocks disagreeing on how fast time passes, which no placement can mend."""


@dataclass(frozen=True)
class Piece:
    """Rows ``[start, stop)`` of a file between clock jumps; its line ``a + b·(Time − t_start)``."""

    start: int
    stop: int
    offset_s: float
    rate: float
    why_unplaced: str | None = None

    @property
    def placed(self) -> bool:
        return self.why_unplaced is None


@dataclass(frozen=True)
class Clock:
    """Where every row of one file lies on the wall clock (s since 2017-01-01), piece by piece.

    Rows of a piece that cannot be placed carry their raw stamps (``TimeStamp`` + 0.5 s): good
    enough to tell whether they lie after the test, which :func:`merge` leaves out; the others
    it refuses with :meth:`refusal`.
    """

    path: str
    time: np.ndarray
    wall: np.ndarray
    stamps: tuple[str, ...]
    pieces: tuple[Piece, ...]

    def refusal(self, piece: Piece) -> str:
        return (
            f"{self.path}: field 'meas.TimeStamp': the piece from {self.stamps[piece.start]} "
            f"between clock jumps cannot be placed ({piece.why_unplaced})"
        )

    def jumps(self) -> list[dict]:
        """Each piece after the first: where it starts, its rows, and how far the wall clock
        jumped there (its first row against the previous piece's line carried on)."""
        out = []
        for prev, piece in itertools.pairwise(self.pieces):
            carried = prev.offset_s + prev.rate * (self.time[piece.start] - self.time[prev.start])
            out.append(
                {
                    "from": self.stamps[piece.start],
                    "rows": piece.stop - piece.start,
                    "jump_s": round(float(self.wall[piece.start] - carried), 1),
                    "placed": piece.placed,
                }
            )
        return out


def _line(t: np.ndarray, sec: np.ndarray) -> tuple[float, float]:
    # through more than two rows a least-squares line; the rule that stood before jumps were split
    b, a = np.polyfit(t - t[0], sec, 1) if len(t) > 2 and t[-1] > t[0] else (1.0, sec[0])
    return float(a), float(b)


def _split_at_jumps(t: np.ndarray, sec: np.ndarray) -> list[tuple[int, int]]:
    """Rows ``[start, stop)`` of each piece: while a stretch's line misses a stamp by more than
    CLOCK_TOLERANCE_S, split it where ``TimeStamp − Time`` changes most between two rows."""
    todo, pieces = [(0, t.size)], []
    while todo:
        a, b = todo.pop()
        off, rate = _line(t[a:b], sec[a:b])
        worst = np.max(np.abs(off + rate * (t[a:b] - t[a]) - sec[a:b]))
        if worst <= CLOCK_TOLERANCE_S:
            pieces.append((a, b))
            continue
        k = a + 1 + int(np.argmax(np.abs(np.diff(sec[a:b] - t[a:b]))))
        todo += [(a, k), (k, b)]
    return sorted(pieces)


def _unplaced(t: np.ndarray, rate: float) -> str | None:
    """Why a piece's line cannot place it, or None."""
    if t.size < MIN_PIECE_ROWS:
        return f"{t.size} row{'s' if t.size > 1 else ''}; a line needs {MIN_PIECE_ROWS}"
    # a line within the tolerance of the stamps at both ends tilts by at most 4·tol over the span
    allowed = MAX_CLOCK_DRIFT + 4.0 * CLOCK_TOLERANCE_S / (t[-1] - t[0])
    if abs(rate - 1.0) > allowed:
        return f"its stamps run {rate:.4g} times as fast as 'Time'"
    return None


def wall_clock(df: pd.DataFrame, path) -> Clock:
    """Every row on the wall clock, from TimeStamp (1 s resolution) and Time (docs/real-data.md,
    "Which clock the import trusts").

    ``TimeStamp`` is truncated to the second, so ``TimeStamp + 0.5`` is an unbiased reading; a
    least-squares line through it against ``Time`` gives sub-second times that follow the wall
    clock's drift. Where the wall clock jumps, the file is split and each piece placed by its
    own line: within a piece ``Time`` orders and spaces the rows. Rows logged at midnight carry
    only a date.
    """
    stamps = pd.Series(df["TimeStamp"]).astype(str).str.strip()
    stamps = stamps.where(stamps.str.contains(":"), stamps + " 12:00:00 AM")
    try:
        wall = pd.to_datetime(stamps, format=_TS_FORMAT)
    except ValueError as exc:
        raise DataError(f"{path}: field 'meas.TimeStamp': unreadable ({exc})") from None
    sec = (wall - pd.Timestamp("2017-01-01")).dt.total_seconds().to_numpy() + 0.5
    t = df["Time"].to_numpy()
    placed, pieces = sec.copy(), []
    for a, b in _split_at_jumps(t, sec):
        off, rate = _line(t[a:b], sec[a:b])
        why = _unplaced(t[a:b], rate)
        if why is None:
            placed[a:b] = off + rate * (t[a:b] - t[a])
        pieces.append(Piece(a, b, off, rate, why))
    return Clock(str(path), t, placed, tuple(stamps), tuple(pieces))


# --- sign -----------------------------------------------------------------------------------


def check_sign(df: pd.DataFrame, path) -> dict:
    """The source's current (negative = discharge) against the voltage (``records.require_sign``
    of its negation); DataError if the voltage says otherwise. Returns the evidence."""
    ev = require_sign(df["Time"], -df["Current"], df["Voltage"], str(path),
                      "field 'meas.Current'", "negative = discharge")  # fmt: skip
    return ev.as_dict()


# --- merging ----------------------------------------------------------------------------------


def _blocks(t: np.ndarray, gap: float) -> list[tuple[int, int]]:
    cut = np.flatnonzero(np.diff(t) > gap) + 1
    edges = np.r_[0, cut, t.size]
    return [(int(a), int(b)) for a, b in itertools.pairwise(edges)]


def merge(frames: list[tuple[pd.DataFrame, Clock]], block_gap_s: float, source: str):
    """Interleave files on the wall clock; ``frames`` = [(frame, its :func:`wall_clock`)].
    Adds ``wall``.

    The first frame is the test itself (the pulse file); blocks of the others that start more
    than ``block_gap_s`` after its end belong to later tests (the SOC-step files run on into
    the EIS test after a recharge) and are left out. Blocks are cut at logging gaps and at clock
    jumps; a block of a piece that cannot be placed is refused unless it is left out so.
    """
    end = float(np.max(frames[0][1].wall)) + block_gap_s
    pieces, later = [], 0
    for df, clock in frames:
        wall = clock.wall
        for piece in clock.pieces:
            for a, b in _blocks(wall[piece.start : piece.stop], block_gap_s):
                a, b = a + piece.start, b + piece.start
                if wall[a] > end:
                    later += b - a
                    continue
                if not piece.placed:
                    raise DataError(clock.refusal(piece))
                pieces.append(df.iloc[a:b].assign(wall=wall[a:b]))
    pieces.sort(key=lambda p: p["wall"].iloc[0])
    kept = [pieces[0]]
    overlap_dropped = 0
    for p in pieces[1:]:
        start = p["wall"].iloc[0]
        prev = kept[-1]
        over = prev["wall"].to_numpy() >= start
        if over.any():
            overlap_s = float(prev["wall"].iloc[-1] - start)
            if overlap_s > 5.0:
                raise DataError(
                    f"{source}: blocks of the merged files overlap by {overlap_s:.1f} s "
                    "(field 'meas.TimeStamp')"
                )
            overlap_dropped += int(over.sum())
            kept[-1] = prev[~over]
        kept.append(p)
    out = pd.concat([k for k in kept if len(k)], ignore_index=True)
    ah = out["Ah"].to_numpy()
    # discharge-only tests: the tester's running Ah count may only fall (1e-4 Ah of jitter)
    rise = np.diff(ah)
    if (rise > 1e-4).any():
        i = int(np.flatnonzero(rise > 1e-4)[0])
        raise DataError(
            f"{source}: field 'meas.Ah': the merged Ah counter rises by {rise[i]:.4f} Ah at "
            f"merged row {i + 1}; the files do not interleave consistently"
        )
    out.attrs["overlap_rows_dropped"] = overlap_dropped
    out.attrs["later_rows_dropped"] = later
    out.attrs["n_blocks"] = len(kept)
    return out


# --- resampling ---------------------------------------------------------------------------


def interval_current(t: np.ndarray, current: np.ndarray, ah: np.ndarray, gap_s: float):
    """Mean current over each interval [t_j, t_j+1): the sample held, or ΔAh/Δt over gaps."""
    dt = np.diff(t)
    held = current[:-1].astype(float).copy()
    gaps = dt > gap_s
    held[gaps] = np.diff(ah)[gaps] * 3600.0 / dt[gaps]
    return held, int(gaps.sum())


def bin_means(t: np.ndarray, piece_current: np.ndarray, linear: dict, step: float):
    """Exact bin means on the grid t0 + k·step of a piecewise-constant current and of
    piecewise-linear signals; the partial last bin is dropped."""
    n_bins = int(np.floor((t[-1] - t[0]) / step + 1e-9))
    if n_bins < 2:
        raise DataError(f"record shorter than two {step} s samples")
    edges = t[0] + step * np.arange(n_bins + 1)
    edges[-1] = min(edges[-1], t[-1])
    charge = PPoly(piece_current[None, :], t).antiderivative()(edges)
    out = {"current": np.diff(charge) / step}
    for name, y in linear.items():
        integral = make_interp_spline(t, y, k=1).antiderivative()(edges)
        out[name] = np.diff(integral) / step
    return step * np.arange(n_bins, dtype=float), out


def resample(df: pd.DataFrame, time_col: str, settings: Settings):
    """Uniform record (source sign still) from a cleaned source frame; charge bookkeeping."""
    t = df[time_col].to_numpy(dtype=float)
    cur, n_gaps = interval_current(t, df["Current"].to_numpy(), df["Ah"].to_numpy(), settings.gap_s)
    grid, means = bin_means(
        t,
        cur,
        {"voltage": df["Voltage"].to_numpy(), "temperature": df["Battery_Temp_degC"].to_numpy()},
        settings.sample_s,
    )
    n = grid.size
    span = grid[-1] + settings.sample_s
    # the piecewise-constant signal's own charge over the resampled span, for the sidecar
    charge_pc = float(PPoly(cur[None, :], t).integrate(t[0], t[0] + span)) / 3600.0
    charge_out = float(np.sum(means["current"]) * settings.sample_s) / 3600.0
    ah = df["Ah"].to_numpy()
    tester_ah = float(np.interp(t[0] + span, t, ah) - ah[0])
    # reported as discharged charge (positive = discharge, the canonical sign)
    info = {
        "sample_s": settings.sample_s,
        "n_samples": n,
        "gap_intervals_from_ah_counter": n_gaps,
        "discharged_ah": -charge_out,
        "discharged_ah_piecewise_constant": -charge_pc,
        "discharged_ah_tester_counter": -tester_ah,
    }
    frame = pd.DataFrame(
        {
            "time_s": grid,
            "current_a": means["current"],
            "voltage_v": means["voltage"],
            "temperature_c": means["temperature"],
        }
    )
    return frame, info


def trim_leading_rest(frame: pd.DataFrame, settings: Settings) -> tuple[pd.DataFrame, float]:
    """Cut a leading rest longer than ``max_leading_rest_s`` (a thermal soak) to ``keep_rest_s``."""
    active = np.flatnonzero(np.abs(frame["current_a"].to_numpy()) > REST_A)
    if active.size == 0:
        return frame, 0.0
    t = frame["time_s"].to_numpy()
    first = t[active[0]]
    if first <= settings.max_leading_rest_s:
        return frame, 0.0
    start = first - settings.keep_rest_s
    out = frame[t >= start].reset_index(drop=True)
    cut = float(out["time_s"].iloc[0])
    out["time_s"] = out["time_s"] - cut
    return out, cut


# --- one record -------------------------------------------------------------------------------


def _sources(cfg_real: dict, key: str) -> Path:
    sources = cfg_real.get("sources", {})
    if key not in sources:
        raise ConfigError(f"config field real.sources: no sha256 for {key!r}")
    root = Path(cfg_real["root"])
    return check_source(root / key, sources[key], key=key)


def _sidecar(cfg_real: dict, test_type: str, keys: list[str], ambient_c: float, **extra):
    pan = cfg_real["panasonic"]
    root = Path(cfg_real["root"])
    return {
        "cell": pan["cell"],
        "nominal_capacity_ah": float(pan["nominal_capacity_ah"]),
        "ambient_temperature_c": float(ambient_c),
        "test_type": test_type,
        "source_file": keys[0],
        "source_sha256": cfg_real["sources"][keys[0]],
        "source_files": {k: cfg_real["sources"][k] for k in keys},
        "source_root": str(root),
        "citation": pan["citation"],
        "licence": pan["licence"],
        "current_sign": "positive = discharge (source negated)",
        **extra,
    }


def import_record(
    cfg_real: dict,
    keys: list[str],
    test_type: str,
    ambient_c: float,
    out_csv,
    settings: Settings | None = None,
    trim_soak: bool = False,
) -> dict:
    """Import one test (one file, or an HPPC pulse file and its SOC-step file) to ``out_csv``.

    ``keys`` are paths relative to ``cfg_real['root']``, each with its sha256 in
    ``cfg_real['sources']``. Returns the sidecar written beside the CSV.
    """
    settings = settings or Settings()
    paths = [_sources(cfg_real, k) for k in keys]
    frames, signs, repeated = [], {}, 0
    for key, path in zip(keys, paths, strict=True):
        df = read_mat(path)
        repeated += df.attrs["repeated_rows_dropped"]
        signs[key] = check_sign(df, path)
        frames.append((df, path))
    if len(frames) == 1:
        df = frames[0][0]
        time_col, merge_info = "Time", {}
    else:
        clocks = [wall_clock(d, p) for d, p in frames]
        df = merge([(d, c) for (d, _), c in zip(frames, clocks, strict=True)],
                   settings.block_gap_s, keys[0])  # fmt: skip
        time_col = "wall"
        merge_info = {
            "merged_blocks": df.attrs["n_blocks"],
            "overlap_rows_dropped": df.attrs["overlap_rows_dropped"],
            "later_test_rows_dropped": df.attrs["later_rows_dropped"],
        }
        # only where a clock jumped, so the sidecars of files that never jumped stay as they were
        jumps = {k: c.jumps() for k, c in zip(keys, clocks, strict=True) if len(c.pieces) > 1}
        if jumps:
            merge_info["clock_jumps"] = jumps
    frame, info = resample(df, time_col, settings)
    frame["current_a"] = -frame["current_a"]
    trimmed = 0.0
    if trim_soak:
        frame, trimmed = trim_leading_rest(frame, settings)
    side = _sidecar(
        cfg_real,
        test_type,
        keys,
        ambient_c,
        sign_check=signs,
        repeated_rows_dropped=repeated,
        leading_rest_trimmed_s=trimmed,
        resampling=(
            "bin means over [t0+k*dt, t0+(k+1)*dt): current piecewise constant (sample held; "
            f"intervals > {settings.gap_s} s from the Ah counter), voltage and temperature "
            "piecewise linear"
        ),
        **info,
        **merge_info,
    )
    if trimmed:
        side["n_samples"] = len(frame)
    write(frame, side, out_csv)
    return side


def records(cfg: dict) -> dict[str, dict]:
    """Every Panasonic record the config asks for: name → how to import it.

    Names are ``<temperature>/<test>`` (e.g. ``25degC/us06``, ``0degC/hppc``, ``25degC/ocv_c20``).
    """
    real = cfg.get("real") or {}
    pan = real.get("panasonic")
    if not pan:
        return {}
    out = {}
    for temp, spec in pan["temperatures"].items():
        out[f"{temp}/hppc"] = {
            "keys": [spec["hppc"], spec["hppc_steps"]],
            "test_type": "hppc",
            "ambient_c": spec["ambient_c"],
            "trim_soak": False,
        }
        for cycle, key in spec["drive_cycles"].items():
            out[f"{temp}/{cycle}"] = {
                "keys": [key],
                "test_type": f"drive_cycle:{cycle}",
                "ambient_c": spec["ambient_c"],
                "trim_soak": True,
            }
    out["25degC/ocv_c20"] = {
        "keys": [pan["ocv_c20"]],
        "test_type": "ocv_c20",
        "ambient_c": 25.0,
        "trim_soak": False,
    }
    for name, rec in out.items():
        for key in rec["keys"]:
            if key not in real.get("sources", {}):
                raise ConfigError(
                    f"config field real.panasonic ({name}): {key!r} has no entry in real.sources"
                )
    return out


def import_named(cfg: dict, name: str, out_csv) -> dict:
    """Import the record ``name`` of :func:`records` (root resolved as the other importers do)."""
    from .samsung import data_root

    rec = records(cfg).get(name)
    if rec is None:
        raise ConfigError(f"config field real.panasonic: no record {name!r}")
    real = {**cfg["real"], "root": str(data_root(cfg))}
    return import_record(
        real,
        rec["keys"],
        rec["test_type"],
        rec["ambient_c"],
        out_csv,
        trim_soak=rec["trim_soak"],
    )


__all__ = [
    "CLOCK_TOLERANCE_S",
    "FIELDS",
    "MAX_CLOCK_DRIFT",
    "MIN_PIECE_ROWS",
    "Clock",
    "Piece",
    "Settings",
    "bin_means",
    "check_sign",
    "import_named",
    "import_record",
    "merge",
    "read_mat",
    "records",
    "resample",
    "trim_leading_rest",
    "wall_clock",
]
