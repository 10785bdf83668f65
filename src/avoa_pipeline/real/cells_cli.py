"""Samsung 30Q and NASA B0005: import and experiments 2-3, for Snakemake and the command line.

The functions below are what the workflow's rules call (in the Snakemake process, with the
validated config); their subcommands (``samsung-import``, ``nasa-import``, ``arrhenius``,
``fade``) are part of ``python -m avoa_pipeline.real``. Expected errors print one line on stderr
and exit 2, and leave no output file (every writer is atomic).
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from pathlib import Path

from ..errors import ConfigError
from ..io import write_log


def _real(cfg: Mapping, section: str) -> Mapping:
    real = cfg.get("real") or {}
    if section not in real or not real[section]:
        raise ConfigError(f"config: field real.{section} missing (docs/real-data.md)")
    return real[section]


def samsung_import(cfg, temperature: str, out_csv, log=None) -> None:
    from . import samsung

    _real(cfg, "samsung")
    frame, side = samsung.import_hppc(cfg, temperature, out_csv)
    write_log(log, f"wrote {out_csv}: {len(frame)} samples from {side['source_file']}")


def nasa_import(cfg, out_csv, log=None) -> None:
    from . import nasa

    _real(cfg, "nasa")
    frame, side = nasa.import_b0005(cfg, out_csv)
    write_log(log, f"wrote {out_csv}: {len(frame)} samples, {len(side['discharges'])} discharges")


def arrhenius(cfg, hppc: Mapping[str, str], out_rc, out_arrhenius, log=None) -> None:
    from . import arrhenius as arr

    rc, table = arr.run(hppc, _real(cfg, "samsung"), out_rc, out_arrhenius)
    pooled = table[(table["scope"] == "pooled_pulses")].set_index("quantity")
    write_log(
        log,
        f"wrote {out_rc} ({len(rc)} pulses) and {out_arrhenius}; pooled Ea [kJ/mol]: "
        + ", ".join(f"{q} {r['ea_kj_mol']:.2f}" for q, r in pooled.iterrows()),
    )


def fade(cfg, record, out_states, out_fits, log=None) -> None:
    from . import fade as fade_mod

    table, fits = fade_mod.run(record, _real(cfg, "nasa"), out_states, out_fits)
    write_log(
        log,
        f"wrote {out_states} ({len(table)} states) and {out_fits}; RMSE: "
        + ", ".join(f"{r.quantity}/{r.law} {r.rmse:.4g}" for r in fits.itertuples()),
    )


# What the workflow's rules need to know, kept here so workflow/rules/real.smk holds rules only.

OUTPUTS = {
    "samsung": ("results/real/samsung_rc_vs_temperature.csv", "results/real/samsung_arrhenius.csv"),
    "nasa": ("results/real/nasa_fade.csv", "results/real/nasa_fade_fit.csv"),
    "report": ("results/notebooks/real_cells.ipynb",),
}


def source_path(cfg: Mapping, key: str) -> str:
    """A source file as the rules name it: under real.root, relative to the working directory."""
    return str(Path(cfg["real"]["root"]) / key)


def nasa_source_sha256(cfg: Mapping) -> dict[str, str]:
    """The NASA index and every discharge file listed in real.sources, with their sha256."""
    nasa = _real(cfg, "nasa")
    folder = Path(nasa["discharge_dir"])
    sources = cfg["real"]["sources"]
    keys = [nasa["index"]] + [k for k in sources if Path(k).parent == folder]
    return {k: sources.get(k, "") for k in keys}


def nasa_source_paths(cfg: Mapping) -> list[str]:
    return [source_path(cfg, k) for k in nasa_source_sha256(cfg)]


def targets(cfg: Mapping) -> list[str]:
    """The final outputs of experiments 2 and 3 for the sections the config has."""
    real = cfg.get("real") or {}
    out = []
    for section in ("samsung", "nasa"):
        if real.get(section):
            out += OUTPUTS[section]
    if real.get("samsung") and real.get("nasa"):
        out += OUTPUTS["report"]
    return out


def experiments(cfg, workdir) -> dict:
    """Both experiments from the configured source files, intermediate files in ``workdir``
    (for a notebook run on its own); returns the four output tables by name."""
    from . import arrhenius as arr
    from . import fade as fade_mod

    work = Path(workdir)
    hppc = {}
    for temperature in _real(cfg, "samsung")["hppc"]:
        hppc[temperature] = work / f"samsung_hppc_{temperature}.csv"
        samsung_import(cfg, temperature, hppc[temperature])
    rc, table = arr.run(hppc, _real(cfg, "samsung"), work / "rc.csv", work / "arrhenius.csv")
    nasa_import(cfg, work / "nasa_b0005.csv")
    states, fits = fade_mod.run(
        work / "nasa_b0005.csv", _real(cfg, "nasa"), work / "fade.csv", work / "fade_fit.csv"
    )
    return {"rc": rc, "arrhenius": table, "fade": states, "fade_fit": fits}


def _pair(text: str) -> tuple[str, str]:
    key, sep, value = text.partition("=")
    if not sep or not key or not value:
        raise argparse.ArgumentTypeError(f"expected TEMPERATURE=CSV (e.g. 20degC=a.csv): {text!r}")
    return key, value


def add_commands(sub) -> None:
    """The Samsung and NASA subcommands, added to ``python -m avoa_pipeline.real``'s parser."""
    s = sub.add_parser("samsung-import", help="one Samsung HPPC file into the canonical form")
    s.add_argument("--temperature", required=True, help="key of real.samsung.hppc, e.g. 20degC")
    s.add_argument("--out", required=True, help="canonical CSV (sidecar .json beside it)")
    n = sub.add_parser("nasa-import", help="the 168 B0005 discharges into one canonical record")
    n.add_argument("--out", required=True)
    a = sub.add_parser("arrhenius", help="experiment 2: R0, Rtr, tau per pulse and Arrhenius fits")
    a.add_argument("--hppc", type=_pair, nargs="+", required=True, metavar="TEMP=CSV")
    a.add_argument("--out-rc", required=True)
    a.add_argument("--out-arrhenius", required=True)
    f = sub.add_parser("fade", help="experiment 3: capacity/resistance per state and fade laws")
    f.add_argument("--record", required=True, help="canonical B0005 record (nasa-import)")
    f.add_argument("--out-states", required=True)
    f.add_argument("--out-fits", required=True)


def run_command(cfg, args) -> None:
    """Carry out one subcommand of :func:`add_commands`."""
    if args.command == "samsung-import":
        samsung_import(cfg, args.temperature, args.out)
    elif args.command == "nasa-import":
        nasa_import(cfg, args.out)
    elif args.command == "arrhenius":
        arrhenius(cfg, dict(args.hppc), args.out_rc, args.out_arrhenius)
    else:
        fade(cfg, args.record, args.out_states, args.out_fits)
