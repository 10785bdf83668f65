"""Job execution any executor can run: every package rule names a script that calls the
package with what the rule passes, a job stops when its
Snakemake dies, and a killed run's locks are cleared only when no Snakemake works there."""

import ast
import contextlib
import importlib
import inspect
import json
import os
import re
import runpy
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from types import SimpleNamespace

import psutil
import pytest

from avoa_pipeline import jobguard, snakemake_compat

REPO = Path(__file__).resolve().parents[2]


def _fake_snakemake(tmp_path: Path, body: str) -> Path:
    """A Python script whose file name is ``snakemake`` (what the guard and the lock check
    recognise in a command line)."""
    path = tmp_path / "bin" / "snakemake"
    path.parent.mkdir(exist_ok=True)
    path.write_text(textwrap.dedent(body))
    return path


def _rule_blocks() -> list[tuple[str, str]]:
    """(rule name, its text) of every rule in workflow/rules; the per-block fit rules
    (``rule:`` with ``name: f"fit_{_block}"``) are named ``fit_<block>``."""
    out = []
    for smk in sorted((REPO / "workflow/rules").glob("*.smk")):
        chunks = re.split(r"(?m)^(?=[ \t]*rule\b)", smk.read_text())
        for chunk in chunks[1:]:
            m = re.match(r"\s*rule\s*(\w*):", chunk)
            name = m.group(1) if m and m.group(1) else "fit_<block>"
            out.append((name, chunk))
    return out


def _section_names(block: str, section: str) -> set[str]:
    """The names given in a rule's ``section:`` (``name=...`` lines one level in)."""
    lines = block.splitlines()
    for i, line in enumerate(lines):
        if line.split("#")[0].strip() == f"{section}:":
            indent = len(line) - len(line.lstrip())
            names = set()
            for sub in lines[i + 1 :]:
                if sub.strip() and len(sub) - len(sub.lstrip()) <= indent:
                    break
                m = re.match(rf"^ {{{indent + 4}}}(\w+)=", sub)
                if m:
                    names.add(m.group(1))
            return names
    return set()


def _script_rules() -> list[tuple[str, str, Path]]:
    out = []
    for name, block in _rule_blocks():
        m = re.search(r'script:\s*\n\s*"([^"]+)"', block)
        if m:
            out.append((name, block, (REPO / "workflow/rules" / m.group(1)).resolve()))
    return out


def _used(tree: ast.AST, section: str) -> set[str]:
    """Names a script reads from ``snakemake.<section>``, directly or through an alias
    (``p = snakemake.params``, ``w, p = snakemake.wildcards, snakemake.params``)."""

    def is_section(node):
        return (isinstance(node, ast.Attribute) and node.attr == section
                and isinstance(node.value, ast.Name) and node.value.id == "snakemake")  # fmt: skip

    aliases = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign):
            for target in node.targets:
                pairs = (zip(target.elts, node.value.elts, strict=False)
                         if isinstance(target, ast.Tuple) and isinstance(node.value, ast.Tuple)
                         else [(target, node.value)])  # fmt: skip
                aliases |= {t.id for t, v in pairs if isinstance(t, ast.Name) and is_section(v)}
    used = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and (
            is_section(node.value)
            or (isinstance(node.value, ast.Name) and node.value.id in aliases)
        ):
            used.add(node.attr)
    return used - {"keys", "get"}


def test_every_package_rule_names_a_script_that_calls_what_the_package_has():
    """Each rule names its own script (no dispatch on the rule's name); every script exists,
    starts the job (jobs.start), calls package functions that exist with arguments their
    signatures accept, and reads only ``params``, ``input`` and ``output`` names its rule gives
    and never Snakemake's ``config``."""
    rules = _script_rules()
    assert {"dataset", "fit_<block>", "gap_diagnose", "panasonic_import"} <= {
        r for r, _, _ in rules
    }
    for rule, block, script in rules:
        assert script.is_file(), f"rule {rule}: no script {script}"
        text = script.read_text()
        tree = ast.parse(text)
        assert "jobs.start(snakemake)" in text, script.name
        assert "snakemake.config" not in text, script.name
        for section in ("params", "input", "output"):
            given = _section_names(block, section)
            for name in _used(tree, section):
                assert name in given, (
                    f"{script.name}: snakemake.{section}.{name} not in rule {rule}"
                )
        imported = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module.startswith("avoa_pipeline"):
                module = importlib.import_module(node.module)
                for alias in node.names:
                    try:  # a function, or a submodule (``from avoa_pipeline import jobs``)
                        obj = getattr(module, alias.name, None) or importlib.import_module(
                            f"{node.module}.{alias.name}"
                        )
                    except ImportError:
                        obj = None
                    assert obj is not None, f"{script.name}: {node.module}.{alias.name}"
                    imported[alias.asname or alias.name] = obj
        calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call)
                 and isinstance(n.func, ast.Name)
                 and callable(imported.get(n.func.id))]  # fmt: skip
        calls += [n.args[0] for n in ast.walk(tree) if isinstance(n, ast.Call)
                  and isinstance(n.func, ast.Name) and n.func.id == "partial"]  # fmt: skip
        assert calls, f"{script.name} calls no package function"
        for call in calls:
            if isinstance(call, ast.Call):
                fn = imported[call.func.id]
                inspect.signature(fn).bind(*[None] * len(call.args),
                                           **{k.arg: None for k in call.keywords})  # fmt: skip


def test_each_script_calls_the_jobs_module_of_its_rules_file():
    """One jobs module per rules file: a rule's script imports its job from
    ``avoa_pipeline.jobs.<the rules file's stem>``, and every module of the package is named
    after a rules file. The planning that common.smk calls (``avoa_pipeline.plan``) runs in the
    Snakemake process and so loads no job module (their package pins the BLAS threads)."""
    import pkgutil

    import avoa_pipeline.jobs as jobs_pkg

    rules = sorted((REPO / "workflow/rules").glob("*.smk"))
    modules = {m.name for m in pkgutil.iter_modules(jobs_pkg.__path__)}
    assert modules
    assert modules <= {p.stem for p in rules}
    scripts = 0
    for smk in rules:
        for m in re.finditer(r'script:\s*\n\s*"([^"]+)"', smk.read_text()):
            tree = ast.parse((REPO / "workflow/rules" / m.group(1)).resolve().read_text())
            froms = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
            assert f"avoa_pipeline.jobs.{smk.stem}" in froms, f"{smk.name}: {m.group(1)}"
            scripts += 1
    assert scripts >= len(modules)
    code = ("import sys; from avoa_pipeline import plan; plan.gap(None); print(sorted(m for m "
            "in sys.modules if m.startswith('avoa_pipeline.jobs')))")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_a_rule_passes_only_what_its_job_reads(cfg):
    """config.part: the named parts in the config's nesting, copies (a job cannot change the
    config), tuple paths for keys with dots, one line naming a missing field."""
    from avoa_pipeline import config as config_mod
    from avoa_pipeline.errors import ConfigError

    part = config_mod.part(cfg, "base_seed", "budget.pop_size", ("real", "panasonic", "cell"))
    assert part == {"base_seed": cfg["base_seed"],
                    "budget": {"pop_size": cfg["budget"]["pop_size"]},
                    "real": {"panasonic": {"cell": cfg["real"]["panasonic"]["cell"]}}}  # fmt: skip
    key = next(iter(cfg["real"]["sources"]))
    assert config_mod.part(cfg, ("real", "sources", key))["real"]["sources"] == {
        key: cfg["real"]["sources"][key]
    }
    part["budget"]["pop_size"] = -1
    assert cfg["budget"]["pop_size"] > 0
    with pytest.raises(ConfigError, match=r"field budget\.nonsense missing"):
        config_mod.part(cfg, "budget.nonsense")


def _run_script(name: str, **job) -> None:
    job.setdefault("log", [])
    job.setdefault("threads", 1)  # Snakemake always gives it
    runpy.run_path(str(REPO / "workflow/scripts" / name), init_globals={
        "snakemake": SimpleNamespace(**job)})  # fmt: skip


def test_the_dataset_and_fit_scripts_run_without_snakemake_on_their_rules_parts(cfg, tmp_path):
    """The dataset and a fit block (two algorithms in one job) from the parts their rules pass
    equal those from the whole config and one algorithm per call, record for record (timings
    aside; the same job_key, so a run's records stay current): the jobs read nothing else."""
    from avoa_pipeline import config as config_mod
    from avoa_pipeline import plan
    from avoa_pipeline.jobs import data as data_jobs
    from avoa_pipeline.jobs import identify

    cfg = {**cfg, "budget": {"pop_size": 8, "iterations": 5, "max_nfe": None}}
    data = tmp_path / "s4c4.csv"
    settings = config_mod.part(cfg, *plan.DATASET_PARTS)
    _run_script("dataset.py", params=SimpleNamespace(settings=settings),
                wildcards=SimpleNamespace(scenario="4", case="4"),
                output=SimpleNamespace(csv=str(data)), log=[str(tmp_path / "d.log")])  # fmt: skip
    assert "wrote" in (tmp_path / "d.log").read_text()
    whole = tmp_path / "whole.csv"
    data_jobs.dataset(cfg, 4, 4, str(whole))
    assert data.read_bytes() == whole.read_bytes()
    algorithms = ["avoa", "nelder_mead"]
    outs = [str(tmp_path / a / f"seed{s}.json") for a in algorithms for s in (1, 2)]
    _run_script("fit.py", params=SimpleNamespace(settings=config_mod.part(cfg, *plan.FIT_PARTS),
                                                 algorithms=algorithms, seeds=[1, 2]),
                input=SimpleNamespace(data=str(data)),
                wildcards=SimpleNamespace(scenario="4", case="4"), output=outs)  # fmt: skip
    ref = [str(tmp_path / "ref" / a / f"seed{s}.json") for a in algorithms for s in (1, 2)]
    for k, alg in enumerate(algorithms):
        identify.fit_batch(cfg, str(data), 4, 4, alg, [1, 2], ref[2 * k : 2 * k + 2])
    for a, b in zip(outs, ref, strict=True):
        ra, rb = (json.loads(Path(p).read_text()) for p in (a, b))
        for key in ("best_params", "best_ise", "nfe", "iterations", "job_key"):
            assert ra[key] == rb[key], key
        for key in ("best_ise", "nfe"):
            assert ra["history"][key] == rb["history"][key], key


def test_a_job_stops_when_its_snakemake_is_killed(tmp_path):
    """A job (grandchild through a shell, as Snakemake's shell rules run it) ends within a
    second or two of a kill -9 of its Snakemake; without a Snakemake ancestor it is left alone."""
    child = tmp_path / "child.py"
    child.write_text("import time\nfrom avoa_pipeline import jobguard\n"
                     "jobguard.watch(0.1)\ntime.sleep(60)\n")  # fmt: skip
    shell_cmd = f"{sys.executable} {child}"
    fake = _fake_snakemake(tmp_path, f"""
        import subprocess, time
        subprocess.Popen(["/bin/sh", "-c", {shell_cmd!r}])
        time.sleep(60)
    """)  # fmt: skip
    parent = subprocess.Popen([sys.executable, str(fake)], start_new_session=True)
    try:
        kids = _descendants_named(parent.pid, "child.py")
        time.sleep(1.0)  # the guard is running
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        _, alive = psutil.wait_procs(kids, timeout=5)
        assert not alive
    finally:
        parent.kill()
        parent.wait()
    assert jobguard.snakemake_ancestor() is None  # pytest has no Snakemake above it


def _descendants_named(pid: int, word: str, timeout: float = 30.0) -> list:
    """The descendants of ``pid`` whose command line holds ``word`` (waiting for one)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = []
        for p in psutil.Process(pid).children(recursive=True):
            with contextlib.suppress(psutil.Error):
                if word in " ".join(p.cmdline()):
                    found.append(p)
        if found:
            return found
        time.sleep(0.1)
    raise AssertionError(f"no descendant of {pid} runs {word!r}")


linux_only = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="prctl(PR_SET_PDEATHSIG) is Linux's"
)


@linux_only
@pytest.mark.parametrize("announced", [True, False])
def test_a_direct_child_of_snakemake_is_killed_by_the_kernel(tmp_path, announced):
    """A job that Snakemake starts itself (bash execs a script rule's command) is tied to it by
    PR_SET_PDEATHSIG, not by the poll: it dies with it while it spins on the CPU. Snakemake is
    known by the PID it announces (common.smk) or, without one, by its command line."""
    how = tmp_path / "how.txt"
    child = tmp_path / "child.py"
    child.write_text(
        "import sys\nfrom pathlib import Path\nfrom avoa_pipeline import jobguard\n"
        f"jobguard.watch()\nPath({str(how)!r}).write_text(jobguard.how())\n"
        "while True: pass\n"
    )
    announce = "from avoa_pipeline import jobguard; jobguard.announce()" if announced else ""
    fake = _fake_snakemake(tmp_path, f"""
        import subprocess, sys, time
        {announce}
        subprocess.Popen([sys.executable, {str(child)!r}])
        time.sleep(60)
    """)  # fmt: skip
    parent = subprocess.Popen([sys.executable, str(fake)], start_new_session=True)
    try:
        kids = _descendants_named(parent.pid, "child.py")
        deadline = time.monotonic() + 30
        while not how.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert how.read_text() == "kernel"
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        _, alive = psutil.wait_procs(kids, timeout=5)
        assert not alive
    finally:
        parent.kill()
        parent.wait()


@linux_only
@pytest.mark.parametrize("announced", [True, False])
def test_the_guard_and_every_descendant_die_with_snakemake(tmp_path, announced):
    """``python -m avoa_pipeline.jobguard --log FILE CMD`` started by Snakemake itself, from a
    worker thread as Snakemake does: after a kill -9 of Snakemake the guard, CMD and CMD's own
    child (as papermill's kernel) are gone, and the guard failed nowhere (its signal comes once
    for each of Snakemake's threads)."""
    cmd_py = tmp_path / "cmd.py"
    cmd_py.write_text(
        "import subprocess, sys, time\n"
        "subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)  # grandchild'])\n"
        "print('started', flush=True)\ntime.sleep(60)\n"
    )
    log, err = tmp_path / "cmd.log", tmp_path / "guard.err"
    announce = "from avoa_pipeline import jobguard; jobguard.announce()" if announced else ""
    fake = _fake_snakemake(tmp_path, f"""
        import subprocess, sys, threading, time
        {announce}
        def work():
            subprocess.Popen([sys.executable, "-m", "avoa_pipeline.jobguard", "--log",
                              {str(log)!r}, sys.executable, {str(cmd_py)!r}],
                             stderr=open({str(err)!r}, "w"))
            time.sleep(60)
        threading.Thread(target=work).start()
        time.sleep(60)
    """)  # fmt: skip
    parent = subprocess.Popen([sys.executable, str(fake)], start_new_session=True)
    try:
        _descendants_named(parent.pid, "grandchild")
        kids = psutil.Process(parent.pid).children(recursive=True)
        assert len(kids) == 3  # the guard, CMD, CMD's child
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        _, alive = psutil.wait_procs(kids, timeout=5)
        assert not alive, [p.pid for p in alive]
        assert log.read_text() == "started\n"  # the command's output, written by the guard
        assert err.read_text() == ""
    finally:
        parent.kill()
        parent.wait()


@linux_only
def test_a_job_whose_parent_died_before_it_set_the_signal_stops():
    """The race: the parent that started the job is gone when the job sets its parent-death
    signal (the job has another parent by then), so the signal would never come; it stops."""
    code = "import os, sys\nfrom avoa_pipeline import jobguard\n"
    wrong = code + "jobguard.die_with_parent(parent=os.getppid() + 1)\nsys.exit(0)\n"
    right = code + "assert jobguard.die_with_parent(parent=os.getppid())\n"
    assert subprocess.run([sys.executable, "-c", wrong], timeout=60).returncode == 137
    assert subprocess.run([sys.executable, "-c", right], timeout=60).returncode == 0


def test_stale_locks_are_cleared_only_without_a_live_snakemake_here(tmp_path):
    locks = tmp_path / ".snakemake" / "locks"
    locks.mkdir(parents=True)
    (locks / "0.input.lock").write_text("x")
    fake = _fake_snakemake(tmp_path, "import time; time.sleep(60)")
    live = subprocess.Popen([sys.executable, str(fake)], cwd=tmp_path)
    try:
        time.sleep(0.5)
        assert snakemake_compat.live_snakemakes_here(tmp_path) == [live.pid]
        assert snakemake_compat.clear_stale_locks(tmp_path, True, False) == []
        assert (locks / "0.input.lock").exists()
    finally:
        live.kill()
        live.wait()
    assert snakemake_compat.clear_stale_locks(tmp_path, False, False) == []  # not the main run
    assert snakemake_compat.clear_stale_locks(tmp_path, True, False) == ["0.input.lock"]
    assert not (locks / "0.input.lock").exists()


def test_a_job_whose_announced_snakemake_is_gone_stops_at_once(monkeypatch):
    # a kill -9 of Snakemake before a job looked for it leaves no ancestor to find: the job
    # stops if the Snakemake named in its environment (same host) no longer runs, and runs
    # when that Snakemake lives or when nothing is named (the CLI by hand)
    import socket
    import subprocess
    import sys

    from avoa_pipeline import jobguard

    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    cmd = [sys.executable, "-m", "avoa_pipeline.jobguard", sys.executable, "-c", "pass"]
    monkeypatch.setenv(jobguard.ENV, f"{socket.gethostname()}:{gone.pid}:0.0")
    assert subprocess.run(cmd, timeout=60).returncode == 137
    monkeypatch.setenv(jobguard.ENV, f"another-host:{gone.pid}:0.0")
    assert subprocess.run(cmd, timeout=60).returncode == 0
    jobguard.announce()  # this test process, alive
    assert subprocess.run(cmd, timeout=60).returncode == 0
    monkeypatch.delenv(jobguard.ENV)
    assert subprocess.run(cmd, timeout=60).returncode == 0


def test_snakemakes_reevaluation_timers_are_coalesced(monkeypatch):
    """``snakemake_compat.coalesce_reevaluation``: however many rounds ask for a re-evaluation,
    one timer is pending, a daemon (it never delays the exit); when it fires it opens the
    scheduler's loop once, and the next request starts a new one. Snakemake's own method starts a
    timer per request."""
    import threading
    import time

    from snakemake.scheduling import job_scheduler

    cls = job_scheduler.JobScheduler
    monkeypatch.setattr(cls, "_schedule_reevalutation", cls._schedule_reevalutation)
    sched = cls.__new__(cls)  # only what the timer touches
    sched._open_jobs = threading.Semaphore(0)

    def pending():
        return [t for t in threading.enumerate()
                if isinstance(t, threading.Timer) and t.is_alive()]  # fmt: skip

    before = len(pending())
    for _ in range(5):  # Snakemake's own: one timer each
        cls._schedule_reevalutation(sched, 0.3)
    assert len(pending()) - before == 5
    time.sleep(0.6)
    assert all(sched._open_jobs.acquire(blocking=False) for _ in range(5))

    assert snakemake_compat.coalesce_reevaluation()
    assert snakemake_compat.coalesce_reevaluation()  # applied once
    for _ in range(5):
        cls._schedule_reevalutation(sched, 0.3)
    timers = pending()
    assert len(timers) - before == 1
    assert [t for t in timers if t.daemon]  # the new one; Snakemake starts none as daemons
    time.sleep(0.6)
    assert sched._open_jobs.acquire(blocking=False)
    assert not sched._open_jobs.acquire(blocking=False)  # released once, not five times
    cls._schedule_reevalutation(sched, 0.05)  # the next request arms a new timer
    time.sleep(0.3)
    assert sched._open_jobs.acquire(blocking=False)
