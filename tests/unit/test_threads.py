"""The thread policy (``threads``): the kernel's blocks only where a call's work pays for them and
never more than the threads given or the cores; a job and the CLI give what they were given; the
scores are the same, bit for bit, whatever the blocks."""

import subprocess
import sys
from types import SimpleNamespace

import numba
import numpy as np
import pytest

from avoa_pipeline import jobs, problem, threads
from avoa_pipeline.cli import main


@pytest.fixture(autouse=True)
def _all_cores_after():
    yield
    threads.use(None)


def test_a_call_below_the_break_even_runs_on_the_calling_thread(monkeypatch):
    monkeypatch.setattr(threads, "cores", lambda: 8)
    threads.use(8)
    work, rows = threads.PARALLEL_MIN_WORK, 4 * threads.MIN_BLOCK_ROWS
    assert threads.kernel_blocks(rows, work // rows - 1) == 1
    expected = min(numba.get_num_threads(), 4)
    assert threads.kernel_blocks(rows, -(-work // rows)) == expected
    # a population of 20 (the paper's) is never split: blocks of at least MIN_BLOCK_ROWS rows
    assert threads.kernel_blocks(20, 100 * work) == 1


def test_never_more_threads_than_given_nor_than_the_cores(monkeypatch):
    monkeypatch.setattr(threads, "cores", lambda: 2)
    assert threads.use(None) == 2
    assert threads.use(8) == 2
    assert threads.kernel_blocks(600, threads.PARALLEL_MIN_WORK) <= 2
    assert threads.use(1) == 1
    assert threads.kernel_blocks(600, threads.PARALLEL_MIN_WORK) == 1
    threads.use(None)
    numba.set_num_threads(1)  # numba's own setting caps the blocks too
    try:
        assert threads.kernel_blocks(600, threads.PARALLEL_MIN_WORK) == 1
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    with pytest.raises(ValueError, match="positive"):
        threads.use(0)


def test_the_scores_are_the_same_in_blocks_and_on_one_thread(cfg, monkeypatch):
    """Every call split (break-even 0) against every call on the calling thread."""
    prob = problem.build(cfg, 4, 4)
    rng = np.random.default_rng(4)
    X = prob.lb + rng.random((37, prob.lb.size)) * (prob.ub - prob.lb)
    threads.use(1)
    one = prob.objective(X)
    monkeypatch.setattr(threads, "PARALLEL_MIN_WORK", 0)
    monkeypatch.setattr(threads, "cores", lambda: 2)
    threads.use(2)
    if numba.config.NUMBA_NUM_THREADS >= 2:
        assert threads.kernel_blocks(*X.shape[:1], prob.time_s.size) == 2
    np.testing.assert_array_equal(prob.objective(X), one)


def test_a_job_uses_the_threads_its_rule_gives(monkeypatch):
    monkeypatch.setattr(threads, "cores", lambda: 2)
    monkeypatch.setattr("avoa_pipeline.jobguard.watch", lambda *a, **k: None)
    assert jobs.start(SimpleNamespace(threads=1, log=["x.log"])) == "x.log"
    assert threads.given() == 1
    assert threads.kernel_blocks(600, threads.PARALLEL_MIN_WORK) == 1
    jobs.start(SimpleNamespace(threads=2, log=[]))
    assert threads.given() == 2


def test_a_job_start_loads_no_numba():
    """A table or an import job does not pay numba's import for the thread policy."""
    code = ("import sys; from types import SimpleNamespace; from avoa_pipeline import jobs, "
            "jobguard; jobguard.watch = lambda *a, **k: None; "
            "jobs.start(SimpleNamespace(threads=1, log=[])); "
            "print('numba' in sys.modules)")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_the_commands_take_threads(tmp_path, capsys, monkeypatch):
    seen = []
    monkeypatch.setattr(threads, "use", lambda n: seen.append(n) or 1)
    monkeypatch.setattr("avoa_pipeline.fit.run", lambda *a, **k: {"stopped": "here"})
    out = tmp_path / "r.json"
    args = ["fit", "--scenario", "1", "--case", "1", "--algorithm", "avoa", "--seed", "1",
            "--out", str(out), "--iterations", "1"]  # fmt: skip
    assert main([*args, "--threads", "1"]) == 0
    assert main(args) == 0
    assert seen == [1, None]
    assert main([*args, "--threads", "0"]) == 2
    assert "--threads must be positive" in capsys.readouterr().err
    done = SimpleNamespace(write=lambda out: None, warning_lines=lambda out: [],
                           summary_line=lambda out: "diagnosed")  # fmt: skip
    monkeypatch.setattr("avoa_pipeline.diagnosis.diagnose", lambda *a, **k: done)
    data = tmp_path / "x.csv"
    data.write_text("time_s,current_a,voltage_v\n0,0,3.6\n")
    assert main(["diagnose", str(data), "--out", str(tmp_path / "d"), "--threads", "2"]) == 0
    assert seen[-1] == 2
