"""Tests of ``volbench run`` (pipeline.launch): checks before Snakemake starts, what it says after."""

import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml

from pipeline import launch
from pipeline.cli import main


def test_run_compiles_the_packages_every_job_imports(tmp_path, monkeypatch):
    from importlib.util import cache_from_source

    module = tmp_path / "core" / "module.py"
    module.parent.mkdir()
    module.write_text("VALUE = 1\n")
    monkeypatch.setattr(launch, "ROOT", tmp_path)
    monkeypatch.setattr(launch, "PACKAGES", ("core",))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)  # as PYTHONDONTWRITEBYTECODE=1 sets it
    launch.compile_packages()
    assert Path(cache_from_source(str(module))).is_file()


# ------------------------------------------------------------------------------- volbench run
class FakeSnakemake:
    """Stands in for the Snakemake that ``volbench run`` starts: ``act()`` does its work and returns its exit code."""

    def __init__(self, act):
        self.act, self.commands = act, []

    def __call__(self, command, **kwargs):
        self.commands.append(command)
        return self

    def wait(self):
        return self.act()

    def send_signal(self, signum):
        self.signals = [*getattr(self, "signals", []), signum]


def _refuse(*args, **kwargs):
    pytest.fail("Snakemake must not start")


@pytest.fixture
def project(tmp_path, monkeypatch):
    """``volbench run`` in a project folder of its own, with a small profile: ``(folder, profile file)``.

    Snakemake is refused until a test fakes it: ``launch.subprocess.Popen`` runs the pipeline,
    ``launch.subprocess.run`` a dry run and ``--unlock``.
    """
    monkeypatch.setattr(launch, "ROOT", tmp_path)
    monkeypatch.setattr(launch, "compile_packages", lambda: None)
    monkeypatch.setattr(launch, "subprocess", SimpleNamespace(Popen=_refuse, run=_refuse))
    profile = yaml.safe_load((Path(launch.__file__).parent.parent / "config" / "smoke.yaml").read_text())
    profile.update(experiments=["volbench-convergence"], results="results", cache="cache")
    path = tmp_path / "profile.yaml"
    path.write_text(yaml.safe_dump(profile))
    return tmp_path, path


def _fake_run(calls):
    """A ``subprocess.run`` that records its commands and succeeds."""
    return lambda command, **kwargs: calls.append(command) or subprocess.CompletedProcess(command, 0, "", "")


def _edited(path, **changes):
    """The profile file with ``changes`` made (a value of ``None`` deletes the key)."""
    profile = yaml.safe_load(path.read_text())
    for key, value in changes.items():
        profile.pop(key) if value is None else profile.update({key: value})
    path.write_text(yaml.safe_dump(profile))
    return str(path)


@pytest.mark.parametrize("dry_run", [[], ["--dry-run"]])
@pytest.mark.parametrize("changes, message", [
    ({"image_size": "big"}, "profile 'smoke' image_size (pixels): expected an integer >= 1, got 'big'"),
    ({"render_time_limit": None}, "profile 'smoke': render_time_limit not set; every profile sets"),
    ({"volume_size": None}, "profile 'smoke': volume_size not set"),
])
def test_run_checks_the_profile_before_snakemake_starts(project, capsys, changes, message, dry_run):
    _, path = project
    assert main(["run", "--profile", _edited(path, **changes), *dry_run]) == 2
    assert f"volbench: error: {path}: {message}" in capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["--experiment", "nobody2020-nothing"], "unknown experiments ['nobody2020-nothing']"),
    (["--results", "profile.yaml/results"], "profile 'smoke' results: cannot write to {root}/profile.yaml/results "
                                           "(Not a directory); give a folder you can write with --results"),
    (["--", "--config", "repeat=0"], "{path} with --config repeat=0: profile 'smoke' repeat (timed frames): "
                                     "expected an integer >= 1, got 0"),
    (["--", "--config", "real_data=nowhere"], "real_data: no folder {root}/nowhere; give the folder of the real scans, or null"),
    (["--", "--configfile", "other.yaml"], "--configfile after '--': give the profile with --profile"),
])
def test_run_refuses_what_would_fail_in_snakemake_before_it_starts(project, capsys, args, message):
    root, path = project
    assert main(["run", "--profile", str(path), *args]) == 2
    assert message.format(root=root, path=path) in capsys.readouterr().err


def _plan(path):
    from pipeline.experiments import Profile, plan

    return list(plan(Profile.load(path)).values())


def _write_records(root, runs, outcomes):
    """Records of ``runs`` (in order) with ``outcomes``: ``(status, cause, reason)`` each."""
    import json

    from pipeline.records import run_record_path

    for run, (status, cause, reason) in zip(runs, outcomes):
        record = run_record_path(root / "results", run.experiment, run.id)
        record.parent.mkdir(parents=True, exist_ok=True)
        record.write_text(json.dumps({"status": status, "cause": cause, "reason": reason, "spec_hash": run.spec_hash()}))


def test_run_exits_1_when_runs_failed_and_says_why_per_cause(project, capsys, monkeypatch):
    root, path = project
    runs = _plan(path)
    outcomes = [("failed", "error", "RuntimeError: kaboom\nTraceback lines"), ("ok", "", ""),
                ("failed", "time-limit", "exceeded the profile's render_time_limit of 300 s"),
                ("failed", "error", "ValueError: other"), ("skipped", "unavailable", "no GPU"), ("failed", "error", "old")]
    other_plan = runs[5].__class__(**{**runs[5].as_dict(), "options": {"step_factor": 9.0}})  # an earlier plan's run

    def snakemake():
        _write_records(root, runs, outcomes[:5])
        _write_records(root, [other_plan], outcomes[5:])
        return 0

    fake = FakeSnakemake(snakemake)
    monkeypatch.setattr(launch.subprocess, "Popen", fake)
    assert main(["run", "--profile", str(path)]) == 1
    out, err = capsys.readouterr()
    assert f"volbench: report at {root}/results/report/index.html" in out
    assert err.splitlines() == [
        f"volbench: 3 of {len(runs)} runs failed; their records are under {root}/results/runs:",
        f"volbench:   2 error (the run raised an error), e.g. volbench-convergence/{runs[0].id}.json: RuntimeError: kaboom",
        f"volbench:   1 time-limit (the run exceeded the profile's render_time_limit), e.g. "
        f"volbench-convergence/{runs[2].id}.json: exceeded the profile's render_time_limit of 300 s"]
    assert "--keep-going" in fake.commands[0]  # a failed job stops only the jobs that need its output
    _write_records(root, runs, [("ok", "", "")] * len(runs))
    monkeypatch.setattr(launch.subprocess, "Popen", FakeSnakemake(lambda: 0))
    assert main(["run", "--profile", str(path)]) == 0


def test_a_report_the_run_did_not_replace_says_so_until_a_run_finishes(project, capsys, monkeypatch):
    import re

    import pandas as pd

    from reports.html import build_report

    root, path = project
    build_report(pd.DataFrame(columns=["experiment", "run", "status"]), pd.DataFrame(columns=["experiment", "claim"]), [],
                 results_dir=root / "results", environment={})
    index = root / "results" / "report" / "index.html"
    built = index.read_text()
    log = root / ".snakemake" / "log" / "2026-01-01T120000.000000.snakemake.log"

    def failing():
        log.parent.mkdir(parents=True)
        log.write_text("Error in rule render:\n    jobid: 5\nError in rule evaluate:\n    jobid: 9\n"
                       "Exiting because a job execution failed. Look below for error messages\n")
        return 1

    monkeypatch.setattr(launch.subprocess, "Popen", FakeSnakemake(failing))
    assert main(["run", "--profile", str(path)]) == 1
    err = capsys.readouterr().err
    assert f"volbench: the pipeline did not finish: 2 jobs failed (Snakemake's log: {log})" in err
    assert f"{index} is from an earlier run; its pages now say so at the top" in err
    notice = re.search(r'<nav>.*</nav>\n<p class="notice unfinished">(.*)</p>\n', index.read_text())[1]
    assert re.fullmatch(r"This report was written before the pipeline run started \d{4}-\d\d-\d\d \d\d:\d\d UTC, "
                        rf"which did not finish: 2 jobs failed \(Snakemake&#x27;s log: {re.escape(str(log))}\)\. "
                        "It does not show that run&#x27;s results.", notice)
    monkeypatch.setattr(launch.subprocess, "Popen", FakeSnakemake(lambda: 0))  # the next run finishes: the report is current
    assert main(["run", "--profile", str(path)]) == 0
    assert index.read_text() == built


def test_sigterm_goes_to_snakemake_which_stops_its_jobs(project, monkeypatch):
    import os
    import signal

    root, _ = project

    def terminated():
        os.kill(os.getpid(), signal.SIGTERM)  # as test_cluster.py's terminate() or a batch system sends it
        return -signal.SIGTERM

    snakemake = FakeSnakemake(terminated)
    monkeypatch.setattr(launch.subprocess, "Popen", snakemake)
    assert launch._run_snakemake(["snakemake"], runs={}, results=root / "results") == 128 + signal.SIGTERM
    assert snakemake.signals == [signal.SIGTERM]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # this process's own handling is back


def test_ctrl_c_lets_snakemake_stop_and_remove_its_lock(project, monkeypatch):
    root, _ = project
    waits = []

    def interrupted():
        waits.append(1)
        if len(waits) == 1:
            raise KeyboardInterrupt  # Ctrl-C, which the terminal sent to Snakemake too
        return -2

    monkeypatch.setattr(launch.subprocess, "Popen", FakeSnakemake(interrupted))
    with pytest.raises(KeyboardInterrupt):
        launch._run_snakemake(["snakemake"], runs={}, results=root / "results")
    assert len(waits) == 2  # waited for Snakemake, not killed after 0.25 s as subprocess.run does
    assert not list((root / launch.RUN_FILES).glob("*"))


def _lock(root, *paths, kind="output"):
    """A Snakemake lock file in the project listing ``paths``; return the locks folder."""
    locks = root / ".snakemake" / "locks"
    locks.mkdir(parents=True, exist_ok=True)
    (locks / f"0.{kind}.lock").write_text("".join(f"{p}\n" for p in paths))
    return locks


def test_a_stale_lock_is_removed_with_snakemakes_unlock_and_a_dry_run_says_it_will_be(project, capsys, monkeypatch):
    root, path = project
    locks = _lock(root, "results/runs.csv")  # left by a Snakemake killed with kill -9
    calls = []
    monkeypatch.setattr(launch.subprocess, "run", _fake_run(calls))
    assert main(["run", "--profile", str(path), "--dry-run"]) == 0
    assert f"volbench: {locks} holds a stale lock (no Snakemake runs in {root}: a run was killed); volbench run " \
           "without --dry-run removes it" in capsys.readouterr().out
    assert len(calls) == 1 and "--dry-run" in calls[0] and list(locks.glob("*.lock"))  # a dry run changes nothing
    monkeypatch.setattr(launch.subprocess, "Popen", FakeSnakemake(lambda: 0))
    assert main(["run", "--profile", str(path)]) == 0
    assert calls[1][-5:] == ["--configfile", str(path), "--cores", "1", "--unlock"]  # Snakemake's own unlock
    assert f"volbench: removed a stale Snakemake lock from {locks}: no Snakemake runs in {root}" in capsys.readouterr().out


@pytest.fixture
def live_snakemake(project):
    """``(folder, profile, pid)``: a process whose command line is a Snakemake working in the project (it sleeps)."""
    root, path = project
    process = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)", "-m", "snakemake", "--directory", str(root)])
    yield root, path, process.pid
    process.kill()
    process.wait()


def _phantom(path):
    """The cache file of one phantom the profile's runs read (relative to the project)."""
    from pipeline.experiments import Profile
    from pipeline.scene_io import phantom_requests

    profile = Profile.load(path)
    requests = phantom_requests([entry for run in _plan(path) for entry in run.volume_entries], size=profile.volume_size)
    return f"cache/{next(iter(requests))}.npy"


@pytest.mark.parametrize("held, kind", [("results/runs.csv", "output"), ("results/runs.csv", "input"),
                                        ("phantom", "output"), ("missing phantom", "input")])
def test_a_live_snakemakes_lock_on_this_runs_files_stops_the_run_naming_the_process(live_snakemake, capsys, held, kind):
    root, path, pid = live_snakemake
    if "phantom" in held:  # one it writes and this run reads, or one it reads and this run would write
        held, exists = _phantom(path), held == "phantom"
        (root / held).parent.mkdir(parents=True, exist_ok=True)
        if exists:
            (root / held).write_bytes(b"")
    locks = _lock(root, "cache/elsewhere.npy", held, kind=kind)
    for dry_run in ([], ["--dry-run"]):  # a dry run says what the run would meet
        assert main(["run", "--profile", str(path), *dry_run]) == 2
        err = capsys.readouterr().err
        assert f"another Snakemake run holds files of this run in {root} (locked in {locks}: {held})" in err
        assert f"running there: pid {pid} ({sys.executable} -c import time; time.sleep(60) -m snakemake --directory {root}" in err
        assert "Wait for it to finish, or stop it (kill PID) and run this command again" in err
    assert list(locks.glob("*.lock"))  # never unlocked under a live run


def test_a_live_snakemakes_lock_on_other_files_lets_the_run_go_beside_it(live_snakemake, monkeypatch):
    root, path, _ = live_snakemake
    shared = _phantom(path)  # a phantom both runs read
    (root / shared).parent.mkdir(parents=True)
    (root / shared).write_bytes(b"")
    locks = _lock(root, "results-other/runs.csv", "cache/not-a-phantom-of-this-run.npy", shared, kind="input")
    monkeypatch.setattr(launch.subprocess, "Popen", FakeSnakemake(lambda: 0))
    assert main(["run", "--profile", str(path)]) == 0
    assert list(locks.glob("*.lock"))


def test_snakemake_processes_are_found_by_their_folder(tmp_path):
    from pipeline.launch import snakemake_processes

    here, elsewhere = tmp_path / "here", tmp_path / "elsewhere"
    here.mkdir(), elsewhere.mkdir()
    sleep = [sys.executable, "-c", "import time; time.sleep(60)", "-m", "snakemake"]
    processes = [subprocess.Popen([*sleep], cwd=here), subprocess.Popen([*sleep, "--directory", "../here"], cwd=elsewhere),
                 subprocess.Popen([*sleep, f"--directory={here}"], cwd=elsewhere),
                 subprocess.Popen([*sleep, "--directory", str(elsewhere)], cwd=here),
                 subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"], cwd=here)]  # not a Snakemake
    try:
        assert sorted(p.pid for p in snakemake_processes(here)) == sorted(p.pid for p in processes[:3])
    finally:
        for process in processes:
            process.kill()
            process.wait()


def test_a_volbench_run_of_another_machine_counts_as_live_and_a_killed_one_here_is_forgotten(project, capsys):
    import json
    import socket

    root, path = project
    runs = root / launch.RUN_FILES
    runs.mkdir(parents=True)
    (runs / "login2.4242.json").write_text(json.dumps({"host": "login2", "pid": 4242, "started": "2026-01-01 10:00 UTC"}))
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    killed = runs / f"{socket.gethostname()}.{dead.pid}.json"
    killed.write_text(json.dumps({"host": socket.gethostname(), "pid": dead.pid, "started": "2026-01-01 09:00 UTC"}))
    _lock(root, "results/runs.csv")
    assert main(["run", "--profile", str(path)]) == 2
    assert (f"running there: a volbench run on login2 (pid 4242, started 2026-01-01 10:00 UTC; if it is not running "
            f"any more, delete {runs / 'login2.4242.json'})") in capsys.readouterr().err
    assert not killed.exists()
