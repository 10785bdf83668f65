"""The input layer: every file a command reads becomes a checked record (or an OCV) here, once.

A path is a canonical CSV (``time_s, current_a, voltage_v[, temperature_c]``), or, with a cycler
named, that cycler's raw export (``importers.cycler``, read through PyProBE). Either way its
frame goes through the records layer's one validator, scale check and sign check (``records.py``)
and comes out as a :class:`~avoa_pipeline.records.Checked` record in the pipeline's sign. The
commands (``convert``, ``diagnose`` with ``--ocv`` and ``--validate``, ``simulate``) read through
here, check their output paths (``io.check_output``) and only then compute; the diagnosis takes
checked records and checks none again.

What this layer adds to one record's checks is what only the set of inputs shows:

- the declared ``--current-sign`` applies to every canonical file of a command (training,
  ``--validate``, a slow test given as ``--ocv``); where the voltage of some files contradicts
  it, the message says whether the flag (all files contradicted) or the file (only some) is to
  be changed, so it never advises a flag under which another file would fail;
- the same file given twice (by path or by content) is refused.

Layers (docs/inputs.md draws them): ``errors``, ``names``, ``io`` < ``records`` <
``importers.cycler`` and ``model`` < ``inputs`` < ``gap``, ``cli``. Nothing below imports
anything above.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, replace
from pathlib import Path

import pandas as pd

from . import records
from .errors import DataError, UserError
from .io import READ_NOTES, read_csv, sha256, unchanged_while_read
from .names import CURRENT_SIGNS

TABLE_COLUMNS = ("soc", "ocv_v")


def is_canonical(path: str | Path) -> bool:
    """True if the file's first line holds the canonical columns (or an OCV table's)."""
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            header = {c.strip() for c in f.readline().split(",")}
    except OSError:
        return True  # let the canonical reader name the problem
    return set(records.REQUIRED) <= header or set(TABLE_COLUMNS) <= header


def _refuse_raw_export(path: Path) -> None:
    """A cycler's raw export read as a canonical CSV would fail on a missing column or a codec:
    say which cycler it looks like (``cycler.sniff``, the header alone) and the flag."""
    if not path.is_file() or is_canonical(path):
        return
    from .importers import cycler as cyc

    hint = cyc.looks_like(path)
    if hint:
        raise DataError(f"{path}: {hint}")
    if path.suffix.lower() in (".xlsx", ".xlsm", ".xls"):
        raise DataError(f"{path}: a workbook; a record is a CSV ({', '.join(records.REQUIRED)}),"
                        " or a cycler's export read with --cycler")  # fmt: skip


def _read(path, cycler: str | None, current_sign: str, rest_ok: bool = False) -> records.Checked:
    """A file read and checked, its sign not yet judged (the set of files decides the advice)."""
    if current_sign not in CURRENT_SIGNS:
        raise UserError(f"--current-sign must be one of {', '.join(CURRENT_SIGNS)}")
    path = Path(path)
    if cycler is not None and not is_canonical(path):
        from .importers import cycler as cyc

        with unchanged_while_read(path):  # an export still being written is refused
            frame, info = cyc.convert(path, cycler)  # checked there, on the current channel
        origin = {"read_as": f"{cycler} export", "conversion": info}
        return records.converted(frame, str(path), info, origin)
    _refuse_raw_export(path)
    return records.read(path, keys=None, required=records.REQUIRED, current_sign=current_sign,
                        judge_sign=False, rest_ok=rest_ok)  # fmt: skip


def _canonical(c: records.Checked) -> bool:
    return c.origin["read_as"] == "canonical CSV"


def _judge(reads: list[records.Checked], current_sign: str) -> list[records.Checked]:
    """The sign verdicts of a command's files, judged together (module docstring)."""
    canonical = [r for r in reads if _canonical(r)]
    wrong = [r for r in canonical if r.sign.contradicts]
    if wrong:
        r = wrong[0]
        other = CURRENT_SIGNS[1 - CURRENT_SIGNS.index(current_sign)]
        if len(wrong) == len(canonical):
            advice = f"rerun with --current-sign {other}"
        else:
            fine = next(x for x in canonical if not x.sign.contradicts)
            advice = (
                f"{fine.source} is {current_sign} as declared, and --current-sign applies to "
                "every file: negate this file's current_a"
            )
        raise DataError(
            records.sign_contradiction(r.source, "column 'current_a'", current_sign, r.sign)
            + f"; {advice}"
        )
    # a record that only rests has no sign to tell (estimate reads one: its SOC is the OCV's)
    unclear = [_canonical(r) and r.sign.verdict == records.CANNOT_TELL
               and not records.only_rests(r.frame["current_a"]) for r in reads]  # fmt: skip
    return [
        replace(r, warnings=(*r.warnings,
                             records.sign_unclear(r.source, "column 'current_a'", r.sign)))
        if u else r
        for r, u in zip(reads, unclear, strict=True)
    ]  # fmt: skip


def _no_duplicates(paths) -> None:
    seen: dict[str, Path] = {}
    for p in paths:
        p = Path(p)
        if not p.is_file():
            continue  # the reader names a missing file
        key = sha256(p)
        if key in seen:
            same = "the same file" if seen[key].resolve() == p.resolve() else "identical content"
            raise UserError(
                f"{p}: {same} as {seen[key]}; each record may be given once "
                "(training, --validate, --ocv)"
            )
        seen[key] = p


def read_record(
    path, *, cycler: str | None = None, current_sign: str = CURRENT_SIGNS[0], rest_ok: bool = False
) -> records.Checked:
    """One checked record of a path (a canonical CSV, or ``cycler``'s raw export); ``rest_ok``:
    one that only rests passes (``records.check_scale``)."""
    (checked,) = _judge([_read(path, cycler, current_sign, rest_ok)], current_sign)
    return checked


@dataclass(frozen=True)
class Inputs:
    """Every input of a diagnosis, checked: training and validation records and the OCV."""

    train: list[records.Checked]
    validate: list[records.Checked]
    ocv: object | None  # model.ecm.OcvTable
    warnings: tuple[str, ...]

    def paths(self) -> list[str]:
        return [r.source for r in (*self.train, *self.validate)]


def ocv_paths(ocv) -> list[str]:
    """``--ocv`` as a list of paths: none, one, or one per temperature."""
    if ocv is None:
        return []
    return [str(ocv)] if isinstance(ocv, str | Path) else [str(p) for p in ocv]


def read_inputs(
    train, validate=(), ocv=None, *, cycler: str | None = None, current_sign: str = CURRENT_SIGNS[0]
) -> Inputs:
    """The diagnosis's inputs, each read and checked once, judged together (module docstring).
    ``ocv``: a table ``soc, ocv_v``, or a slow test (canonical or raw, as the records); or
    several slow tests, one per temperature (:func:`over_temperature`)."""
    ocvs = ocv_paths(ocv)
    _no_duplicates([*train, *validate, *ocvs])
    reads = [_read(p, cycler, current_sign) for p in (*train, *validate)]
    table, ocv_reads = None, []
    for path in ocvs:
        table, ocv_read = _read_ocv(path, cycler, current_sign)
        if table is not None and len(ocvs) > 1:
            raise DataError(f"{path}: columns 'soc', 'ocv_v': a table has no temperature; where "
                            "--ocv is given more than once, each is a slow test (time_s, "
                            "current_a, voltage_v) at its own temperature")  # fmt: skip
        ocv_reads += [ocv_read] if ocv_read is not None else []
    checked = _judge(reads + ocv_reads, current_sign)
    n_train, n_read = len(train), len(reads)
    notes = [w for c in checked for w in c.warnings]
    slow, checked = checked[n_read:], checked[:n_read]
    if len(slow) == 1:
        from .model import ocv as ocv_mod

        table = ocv_mod.from_slow_test(slow[0].frame, str(ocvs[0]))
    elif len(slow) > 1:
        table = over_temperature(slow, ocvs, checked[:n_train])
    if table is not None:
        notes += list(table.notes)
    return Inputs(checked[:n_train], checked[n_train:], table, tuple(notes))


def over_temperature(slow: list[records.Checked], paths, train: list[records.Checked]):
    """The OCV table of slow tests at several temperatures (docs/temperature-rule.md part 5):
    each test's ambient read as a record's (``heat.ambient_of``: its sidecar's
    ``ambient_temperature_c``, else its first temperature sample), one test per test
    temperature (``heat.ambient_groups``: two within 2 K are refused, naming both), each turned
    into an OCV as one ``--ocv`` is (``ocv.from_slow_test``), then ∂U/∂T over their ambients and
    the table at the training records' reference temperature (``ocv.over_temperature``)."""
    from .model import heat
    from .model import ocv as ocv_mod
    from .model.fitted import reference_temperature
    from .model.record import T_DEFAULT_K

    ambients = []
    for c in slow:
        try:
            ambients.append(heat.ambient_of(c)[0])
        except DataError as e:
            raise DataError(f"{e}; --ocv is given more than once, and each slow test's "
                            "temperature is needed for ∂U/∂T") from None  # fmt: skip
    for group in heat.ambient_groups(ambients):
        if len(group) > 1:
            at = ", ".join(f"{paths[k]} at {ambients[k]:.4g} °C" for k in group)
            raise DataError(f"{at}: slow tests within {heat.AMBIENT_GROUP_K:g} K of each other "
                            "are one test temperature; give one slow test per temperature "
                            "(--ocv once each)")  # fmt: skip
    tables = [ocv_mod.from_slow_test(c.frame, str(p)) for c, p in zip(slow, paths, strict=True)]
    tref = reference_temperature([c.frame for c in train])
    tref_c = (T_DEFAULT_K if tref is None else tref) - 273.15  # no temperature: run at 25 °C
    table = ocv_mod.over_temperature(tables, ambients, tref_c)
    return replace(table, notes=tuple(n for t in tables for n in t.notes))


def _read_ocv(path, cycler, current_sign):
    """(an OCV table, None) for a table, (None, the slow test's record, its sign unjudged)."""
    from .model import ocv as ocv_mod

    path = Path(path)
    if cycler is None or is_canonical(path):
        _refuse_raw_export(path)
        raw = read_csv(path)
        if set(TABLE_COLUMNS) <= set(raw.columns):
            frame = raw[list(TABLE_COLUMNS)]
            for col in TABLE_COLUMNS:
                values = pd.to_numeric(frame[col], errors="coerce")
                if values.isna().any():
                    row = int(values.isna().to_numpy().argmax())
                    raise DataError(f"{path}: column {col!r} row {row + 2}: not a number")
            table = ocv_mod.from_table(frame.apply(pd.to_numeric), str(path))
            read_notes = raw.attrs.get(READ_NOTES, ())  # a partial last row dropped
            return replace(table, notes=(*read_notes, *table.notes)), None
        if not set(records.REQUIRED) <= set(raw.columns):
            raise DataError(
                f"{path}: need columns 'soc', 'ocv_v' (an OCV table) or 'time_s', "
                "'current_a', 'voltage_v' (a slow test)"
            )
    return None, _read(path, cycler, current_sign)


def read_ocv(path, *, cycler: str | None = None, current_sign: str = CURRENT_SIGNS[0]):
    """``--ocv`` alone: an OCV table of a table or a slow test (its record checked); several
    paths: slow tests at several temperatures (:func:`over_temperature`, the table at 25 °C,
    where a record without a temperature runs)."""
    paths = ocv_paths(path)
    if len(paths) > 1:
        return read_inputs([], (), paths, cycler=cycler, current_sign=current_sign).ocv
    table, read = _read_ocv(paths[0], cycler, current_sign)
    if table is not None:
        return table
    from .model import ocv as ocv_mod

    (checked,) = _judge([read], current_sign)
    table = ocv_mod.from_slow_test(checked.frame, str(paths[0]))
    return replace(table, notes=(*checked.warnings, *table.notes))


def warn(notes) -> None:
    """Warnings on stderr, one line each."""
    for note in notes:
        print(f"warning: {note}", file=sys.stderr)
