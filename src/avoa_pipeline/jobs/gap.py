"""The jobs of ``workflow/rules/gap.smk``: the withheld-effect, pair, PyBaMM and paper datasets,
one diagnosis per record (the CSV only, as a user runs it), and the tables (``gap.evaluate``).
Each writes its outputs atomically and a one-line log."""

from __future__ import annotations

import time
from pathlib import Path

import pandas as pd

from ..gap import evaluate as ev
from ..io import write_json, write_log


def diagnose_file(csv_path, out_json, log=None) -> None:
    """Diagnose one CSV as a user would (CSV content only) and write the diagnosis JSON."""
    from ..gap.diagnose import diagnose
    from ..inputs import read_record

    record = read_record(csv_path)
    start = time.perf_counter()
    result = diagnose(record)
    wall = time.perf_counter() - start
    write_json({**result, "wall_s": wall, "source": str(csv_path)}, out_json)
    verdict = result["verdict"]
    write_log(log, f"{csv_path}: verdict {verdict['effect']} (shrink {verdict['shrink']}), "
                   f"{wall:.1f} s")  # fmt: skip


def generate(base_seed, gcfg, profile, replicate, out_dir, log=None) -> None:
    """Every withheld-effect dataset (and control) of one base cell."""
    from ..gap import withheld

    start = time.perf_counter()
    paths = withheld.write_batch(int(base_seed), dict(gcfg), profile, int(replicate), out_dir)
    write_log(log, f"{len(paths)} datasets in {out_dir}, {time.perf_counter() - start:.1f} s")


def generate_pairs(base_seed, gcfg, profile, replicate, out_dir, log=None) -> None:
    """Every two-effect dataset of one base cell."""
    from ..gap import withheld

    start = time.perf_counter()
    paths = withheld.write_pair_batch(int(base_seed), dict(gcfg), profile, int(replicate),
                                      out_dir)  # fmt: skip
    write_log(log, f"{len(paths)} pair datasets in {out_dir}, {time.perf_counter() - start:.1f} s")


def pybamm(base_seed, name, out_csv, log=None) -> None:
    """One PyBaMM record (made once, then a cached file)."""
    from ..gap import pybamm_data
    from ..synthetic import write

    start = time.perf_counter()
    ds = pybamm_data.make(int(base_seed), name)
    write(ds, out_csv)
    write_log(log, f"{out_csv}: {ds.meta['generator']}, {time.perf_counter() - start:.1f} s")


def paper_job(cfg, scenario, case, out_csv, log=None) -> None:
    """``cfg``: the parts a paper dataset is made from (``plan.DATASET_PARTS``)."""
    info = ev.paper_dataset(cfg, int(scenario), int(case), out_csv)
    write_log(log, f"{out_csv}: {info}")


def evaluate_job(data_jsons, diag_jsons, out: dict, threshold, log=None, pairs_csv=()) -> None:
    """The withheld-effect tables; ``pairs_csv`` (none or one ``pairs.csv``) adds the pair
    targets to ``target.csv``."""
    pair_df = pd.concat([pd.read_csv(p) for p in pairs_csv]) if pairs_csv else None
    ev.evaluate(list(zip(data_jsons, diag_jsons, strict=True)), out, float(threshold), pair_df)
    write_log(log, pd.read_csv(out["target"]).to_string(index=False))


def pair_table_job(data_jsons, diag_jsons, out_csv, threshold, log=None) -> None:
    """``pairs.csv``: one judged row per pair dataset; the log holds the pair targets."""
    rows = [ev.pair_record(d, g) for d, g in zip(data_jsons, diag_jsons, strict=True)]
    df = ev.with_pair_judgement(pd.DataFrame(rows, columns=list(ev.PAIR_COLUMNS)), float(threshold))
    ev.write_csv(df, out_csv)
    write_log(log, ev.pair_target(df, float(threshold)).to_string(index=False))


def table_job(make_row, data_jsons, diag_jsons, out_csv, log=None) -> None:
    rows = [make_row(d, g) for d, g in zip(data_jsons, diag_jsons, strict=True)]
    ev.write_csv(pd.DataFrame(rows), out_csv)
    write_log(log, f"{out_csv}: {len(rows)} rows")


def demo_records(base_seed: int = 1, out_dir=None) -> pd.DataFrame:
    """A few withheld-effect datasets diagnosed by :func:`diagnose_file` (a tiny grid), so
    notebooks/gap_validation.ipynb runs on its own. Not a measurement: the workflow's grid is."""
    import tempfile

    if out_dir is None:
        with tempfile.TemporaryDirectory(prefix="gap-demo-") as tmp:
            return demo_records(base_seed, tmp)
    from ..gap import withheld
    from ..synthetic import write

    picks = [("none", 0.0), ("thermal", 40000.0), ("ocv_shape", 0.05), ("hysteresis", 0.04)]
    files = []
    folder = Path(out_dir)
    for effect, mag in picks:
        ds = withheld.make(base_seed, effect, mag, 1.0, "drive", 1)
        ds.meta["name"] = effect
        csv = folder / f"{effect}.csv"
        write(ds, csv)
        diagnose_file(csv, folder / f"{effect}.diagnosis.json")
        files.append((folder / f"{effect}.json", folder / f"{effect}.diagnosis.json"))
    return ev.records(files)
