"""The diagnose pipeline, once: records and options in, one :class:`Diagnosis` out, which writes
itself (issue 39).

:func:`diagnose` reads the inputs through the input layer (``inputs.py``; records already read
are taken as they are), refuses a bad sidecar ambient before any fit (``heat.training_ambients``),
runs the diagnosis (``gap.diagnose.diagnose_records``: the ladder's verdict and the model handed
over, ``handover.py``) and fits the handed-over model's heat block where its training records
allow (``heat.attach``; with or without a temperature law, docs/temperature-rule.md part 6;
diagnosis.json's ``heat`` says which, ``heat.block_summary``). :meth:`Diagnosis.write` is the
one writer of ``diagnosis.json``, ``model.json`` and ``diagnosis.png`` (all or none,
``io.atomic_paths``), and the Diagnosis says the lines a command prints
(:meth:`Diagnosis.warning_lines`, :meth:`Diagnosis.summary_line`).
The ``diagnose`` command, the workflow's job (``jobs.real.diagnose_one``), the transfer
benchmark (``jobs.transfer.diagnose_split``) and the Python API (``avoa_pipeline.diagnose``)
all call it, so what one of them writes the others write too.

Layer: beside the commands and jobs, above ``gap/`` and ``report/`` (it draws through
``report.gap_figures``); docs/architecture.md. Its imports are made where they are used, so that
``import avoa_pipeline`` and the CLI's start load none of the model library.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .names import CURRENT_SIGNS

FILES = ("diagnosis.json", "diagnosis.png", "model.json")
"""What :meth:`Diagnosis.write` writes, in the order the command checks them."""


def _is_path(item) -> bool:
    return isinstance(item, str | os.PathLike)


def check_outputs(folder, given=(), figure: bool = True) -> None:
    """Before any fit: ``folder`` and the files :meth:`Diagnosis.write` puts there can be
    written and are none of the input files ``given`` (``io.check_output``, naming ``--out``)."""
    from .io import check_output

    out = Path(folder)
    check_output(out, inputs=given, folder=True)
    for name in FILES if figure else (FILES[0], FILES[2]):
        check_output(out / name, inputs=given)


def _read_given(data, validate, ocv, cycler, current_sign):
    """The inputs of a diagnosis: paths, checked records (``records.Checked``) or frames. Paths
    alone are read as the command reads them (``inputs.read_inputs``: the sign across files, the
    same file twice refused); otherwise each one on its own, a frame checked under the name of
    its ``attrs["source"]`` (else ``frame <k>``)."""
    from . import inputs

    if all(map(_is_path, (*data, *validate))) and (ocv is None or _ocv_is_paths(ocv)):
        return inputs.read_inputs([str(p) for p in data], [str(p) for p in validate],
                                  None if ocv is None else _ocv_arg(ocv), cycler=cycler,
                                  current_sign=current_sign)  # fmt: skip
    train = [_one(x, k, cycler, current_sign) for k, x in enumerate(data)]
    held = [_one(x, len(data) + k, cycler, current_sign) for k, x in enumerate(validate)]
    table = ocv
    if ocv is not None and _ocv_is_paths(ocv):
        if not _is_path(ocv) and len(ocv) > 1:  # the slow tests' table at the records' Tref
            paths = inputs.ocv_paths(ocv)  # a test given twice: one temperature, refused
            reads = [inputs.read_record(p, cycler=cycler, current_sign=current_sign)
                     for p in paths]  # fmt: skip
            table = inputs.over_temperature(reads, paths, train)
        else:
            table = inputs.read_ocv(_ocv_arg(ocv), cycler=cycler, current_sign=current_sign)
    notes = [w for c in (*train, *held) for w in c.warnings]
    notes += list(getattr(table, "notes", ()))
    return inputs.Inputs(train, held, table, tuple(notes))


def _ocv_is_paths(ocv) -> bool:
    """``ocv`` is a path, or a list of paths (``--ocv`` once per temperature)."""
    return _is_path(ocv) or (isinstance(ocv, list | tuple) and all(map(_is_path, ocv)))


def _ocv_arg(ocv):
    """One path as a string (as before), several as a list of strings."""
    paths = [str(p) for p in ([ocv] if _is_path(ocv) else ocv)]
    return paths[0] if len(paths) == 1 else paths


def _one(item, k: int, cycler, current_sign):
    """One record of :func:`_read_given`'s mixed inputs, checked once."""
    import pandas as pd

    from . import inputs, records

    if _is_path(item):
        return inputs.read_record(str(item), cycler=cycler, current_sign=current_sign)
    if isinstance(item, records.Checked):
        return item
    if isinstance(item, pd.DataFrame):
        name = str(item.attrs.get("source") or f"frame {k}")
        return records.check(item, name, current_sign=current_sign)
    raise TypeError(f"a record is a path, a records.Checked or a DataFrame, not {type(item)!r}")


@dataclass
class Diagnosis:
    """One diagnosis: the report (what diagnosis.json holds), the handed-over model (what
    model.json holds; its heat block fitted where the records allow), the figure's arrays, the
    inputs as read, and the summary of the heat fit (``heat.attach``)."""

    report: dict
    model: object  # model.fitted.FittedModel
    arrays: dict
    inputs: object  # inputs.Inputs
    names: tuple[str, ...]  # the training records as given (the summary line's)
    heat_line: str
    given: tuple[str, ...] = field(default=())  # the input files (never an output)

    @property
    def verdict(self) -> dict:
        return self.report["verdict"]

    @property
    def intervals(self) -> dict | None:
        return self.report.get("intervals")

    @property
    def handed_over(self) -> dict:
        return self.report["handed_over"]

    @property
    def warnings(self) -> list[str]:
        """What :meth:`warning_lines` says, the files named without a folder."""
        return self.warning_lines(None)

    def write(self, folder, figure: bool = True) -> list[Path]:
        """diagnosis.json, model.json and (``figure``) diagnosis.png in ``folder``: all of them
        or none. The figure is drawn into its temporary first; a failure there leaves no JSON
        either, and a failed rename puts back the files renamed before it. Returns the paths."""
        from .io import atomic_paths
        from .report import gap_figures

        out = Path(folder)
        check_outputs(out, self.given, figure)
        report_text = json.dumps(self.report, indent=1, allow_nan=False) + "\n"
        names = (FILES[1], FILES[0], FILES[2]) if figure else (FILES[0], FILES[2])
        paths = [out / n for n in names]
        with atomic_paths(*paths) as tmps:
            if figure:
                gap_figures.render(self.report, self.arrays, tmps[0])
            tmps[-2].write_text(report_text)
            tmps[-1].write_text(json.dumps(self.model.to_json(), indent=1, allow_nan=False) + "\n")
        return paths

    def warning_lines(self, folder) -> list[str]:
        """The command's warnings, one line each (without ``warning:``): the inputs', the
        model's flagged parameters and heat block, the elements the records may not identify,
        the hand-over's. ``folder``: where the files were written (None: bare names)."""
        from .model import heat

        out = Path(folder) if folder is not None else None
        model_json = FILES[2] if out is None else out / FILES[2]
        report_json = FILES[0] if out is None else out / FILES[0]
        lines = list(self.inputs.warnings)
        lines += [f"{report_json}: validation record refused, left out: {r['refusal']}"
                  for r in self.report.get("refused_validation", ())]  # fmt: skip
        lines += flag_lines(model_json, self.report.get("at_bounds", ()), self.intervals)
        if self.model.heat is not None:
            lines += [f"{model_json}: {flag}" for flag in heat.flags(self.model.heat)]
        lines += [f"{report_json}: {u['effect']} selected, but {u['why']}: these records may "
                  f"not identify it; would decide it: {u['would_decide']}"
                  for u in self.report.get("undecided", ())]  # fmt: skip
        return lines + [f"{report_json}: {w}" for w in self.handed_over["warnings"]]

    def summary_line(self, folder, figure: bool = True) -> str:
        """The command's one line: the verdict, the selected and handed-over models, the heat
        block, and the files written into ``folder``."""
        from . import handover

        out = Path(folder)
        v = self.verdict
        wrote = [out / FILES[0], *([out / FILES[1]] if figure else []), out / FILES[2]]
        return (
            f"{', '.join(self.names)}: verdict {v['effect']}"
            + (f" (held-out shrink {v['shrink']:.1%})" if v["effect"] != "none" else "")
            + f"; selected {self.report['selected']['name']}; "
            f"{handover.summary_line(self.handed_over)}; {self.heat_line}; wrote "
            + ", ".join(map(str, wrote))
        )


def _without_refused(read, capacity_ah, soc0, current_accuracy_a):
    """(``read`` without the validation records the diagnosis's checks refuse, and per refused
    record its ``record`` and its ``refusal``: the one line naming file and field). The checks
    are the diagnosis's own (``gap.diagnose.check_options``: a known capacity tells units,
    ``records.check_scale``), each validation record taken with the training records alone; a
    fault of the training records or the options stops the diagnosis as before."""
    from dataclasses import replace

    from .errors import DataError, UserError
    from .gap import diagnose as gap_diagnose

    gap_diagnose.check_options(read.train, [], capacity_ah, soc0, read.ocv, current_accuracy_a)
    kept, refused = [], []
    for c in read.validate:
        try:
            gap_diagnose.check_options(read.train, [c], capacity_ah, soc0, read.ocv,
                                       current_accuracy_a)  # fmt: skip
        except (DataError, UserError) as e:
            refused.append({"record": c.source, "refusal": str(e)})
            continue
        kept.append(c)
    return replace(read, validate=kept), refused


def diagnose(data, validate: Sequence = (), ocv=None, *, capacity_ah: float | None = None,
             soc0: float | None = None, current_accuracy_a: float | None = None,
             cycler: str | None = None, current_sign: str = CURRENT_SIGNS[0],
             progress=True, skip_refused_validation: bool = False) -> Diagnosis:  # fmt: skip
    """The diagnosis of one cell's training records ``data`` (paths, checked records or frames;
    one or a list), fitted together; ``validate``: records never used for any choice; ``ocv``:
    the cell's OCV (a table ``soc, ocv_v`` or a slow test, as a path, or an ``OcvTable``; None:
    the rational curve), or a list of slow tests' paths, one per temperature (their ∂U/∂T
    profile, docs/temperature-rule.md part 5). The options are the ``diagnose`` command's
    (``--capacity-ah``, ``--soc0``, ``--current-accuracy-a``, ``--cycler``,
    ``--current-sign``); ``progress`` as ``gap.diagnose.diagnose_records``. One-line DataError
    or UserError on bad input, before any fit. ``skip_refused_validation`` (the workflow's
    experiments, which predict many unseen records): a validation record the checks refuse is
    left out and its one-line refusal kept in diagnosis.json's ``refused_validation`` and the
    warnings, instead of stopping; nothing is loosened (the command, given a file, refuses it)."""
    from .gap import diagnose as gap_diagnose
    from .model import heat

    data = [data] if _is_path(data) or not isinstance(data, Sequence) else list(data)
    validate = list(validate)
    read = _read_given(data, validate, ocv, cycler, current_sign)
    refused = []
    if skip_refused_validation and read.validate:
        read, refused = _without_refused(read, capacity_ah, soc0, current_accuracy_a)
    heat.training_ambients(read.train)  # a bad sidecar ambient is refused before any fit
    report, arrays, model = gap_diagnose.diagnose_records(
        read.train, capacity_ah, soc0, ocv_table=read.ocv, validate=read.validate,
        warnings=read.warnings, progress=progress,
        current_accuracy_a=current_accuracy_a)  # fmt: skip
    if refused:  # absent otherwise: a diagnosis.json without refusals is as before
        report["refused_validation"] = refused
    _entropic_scale(report, model)
    heat_line = heat.attach(model, read.train)  # the thermal state, where the records allow
    report["heat"] = heat.block_summary(model, heat_line)  # and whether the voltage reads it
    # the files read, never to be written over: paths, and checked records read from a file
    ocvs = [] if ocv is None else [ocv] if _is_path(ocv) or not _ocv_is_paths(ocv) else ocv
    given = [str(p) for p in (*data, *validate, *ocvs) if _is_path(p)]
    given += [c.source for c in (*read.train, *read.validate) if c.origin.get("read_as") != "frame"]
    names = tuple(str(x) if _is_path(x) else c.source
                  for x, c in zip(data, read.train, strict=True))  # fmt: skip
    return Diagnosis(report, model, arrays, read, names, heat_line, tuple(dict.fromkeys(given)))


def _entropic_scale(report: dict, model) -> None:
    """Where the handed-over model's entropic term scales the slow tests' ∂U/∂T profile, its
    scale beside the profile in diagnosis.json's ``ocv.dudt_profile`` (1: as measured)."""
    profile = (report.get("ocv") or {}).get("dudt_profile")
    if profile is None or "entropic" not in model.config.effects:
        return
    table = model.config.table
    profile["scale_handed_over"] = model.parameters()["entropic_dudt_v_per_k"] / table.dudt_peak()


def flag_lines(source, at_bounds, intervals: dict | None) -> list[str]:
    """One warning line per flagged parameter of a model (``FittedModel.at_bounds`` and the
    flags of its intervals, ``model/intervals.py``): ``diagnose`` says them of the model it
    writes, ``simulate`` and ``export`` of the model they run."""
    lines = [f"{source}: {f['parameter']} = {f['value']:.4g} at its {f['bound']} bound "
             f"({f['bounds'][0]:.4g}..{f['bounds'][1]:.4g}): set by the bound, not by the records"
             for f in at_bounds]  # fmt: skip
    flags = (intervals or {}).get("flags", ())
    # those at a bound were named above, with their values
    return lines + [f"{source}: {flag}" for flag in flags
                    if not flag.endswith("at a bound of its fit")]  # fmt: skip
