"""Several seeds in one job: the same records as one fit per job, and a batch that finds current
records on disk computes only what is new."""

import copy
import json

from avoa_pipeline import synthetic
from avoa_pipeline.cli import main
from avoa_pipeline.jobs import identify


def _small(cfg):
    c = copy.deepcopy(cfg)
    c["budget"] = {"pop_size": 6, "iterations": 5, "max_nfe": None}
    return c


def _strip(rec):
    return {k: v for k, v in rec.items() if k not in ("wall_s", "history", "job_key", "versions")}


def test_batch_equals_single_fits_and_computes_only_new_seeds(cfg, tmp_path):
    c = _small(cfg)
    data = tmp_path / "s1c2.csv"
    synthetic.write(synthetic.generate(c, 1, 2), data)
    outs = [tmp_path / f"seed{s}.json" for s in (1, 2, 3)]
    got = identify.fit_batch(c, str(data), 1, 2, "gwo", [1, 2], outs[:2])
    assert got == {"computed": 2, "kept": 0}
    single = tmp_path / "single.json"  # the command line's one fit: the same record
    args = [
        "fit",
        "--scenario",
        "1",
        "--case",
        "2",
        "--algorithm",
        "gwo",
        "--seed",
        "2",
        "--data",
        str(data),
        "--pop-size",
        "6",
        "--iterations",
        "5",
        "--out",
        str(single),
    ]
    assert main(args) == 0
    assert _strip(json.loads(outs[1].read_text())) == _strip(json.loads(single.read_text()))

    before = [p.read_bytes() for p in outs[:2]]
    got = identify.fit_batch(c, str(data), 1, 2, "gwo", [1, 2, 3], outs)
    assert got == {"computed": 1, "kept": 2}
    assert [p.read_bytes() for p in outs[:2]] == before  # untouched
    assert json.loads(outs[2].read_text())["seed"] == 3

    c2 = copy.deepcopy(c)
    c2["budget"]["iterations"] = 6  # another budget: every record is stale
    got = identify.fit_batch(c2, str(data), 1, 2, "gwo", [1, 2, 3], outs)
    assert got == {"computed": 3, "kept": 0}
    assert json.loads(outs[0].read_text())["iterations"] == 6
