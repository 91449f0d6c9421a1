"""Tests of the disturbance readings (pipeline.disturbance): the machine's load from /proc and why frames were disturbed."""

import io
import time
from pathlib import Path

import pytest

from pipeline import disturbance
from pipeline.disturbance import Snapshot, between, snapshot, starvation, verdict

TICK = disturbance._TICK


@pytest.fixture
def four_cpus(monkeypatch):
    monkeypatch.setattr(disturbance.os, "cpu_count", lambda: 4)


def _ticks(seconds):
    return round(seconds * TICK)


def test_foreign_work_is_the_machines_busy_time_less_this_process(four_cpus):
    start = Snapshot(wall=100.0, busy=_ticks(50), steal=_ticks(1), own=_ticks(10))
    # Over 2 s the machine was busy 3 CPU-seconds, this process 1: 2 s of other work, one core on average.
    end = Snapshot(wall=102.0, busy=_ticks(53), steal=_ticks(1.4), own=_ticks(11))
    load = between(start, end)
    assert load["seconds"] == 2.0
    assert load["foreign_cores"] == pytest.approx(1.0) and load["own_cores"] == pytest.approx(0.5)
    assert load["steal_share"] == pytest.approx(0.4 / 2 / 4)  # of the four CPUs' time
    # This process counted more than the machine (ticks are sampled): no negative foreign work.
    quiet = between(start, Snapshot(wall=102.0, busy=_ticks(51), steal=_ticks(1), own=_ticks(11.5)))
    assert quiet["foreign_cores"] == 0.0 and quiet["own_cores"] == pytest.approx(0.75)


def test_spans_too_short_for_the_counters_or_without_proc_have_no_load():
    start = Snapshot(wall=0.0, busy=0, steal=0, own=0)
    short = between(start, Snapshot(wall=disturbance.MIN_SPAN * 0.9, busy=_ticks(1), steal=0, own=0))
    assert short == {"seconds": disturbance.MIN_SPAN * 0.9, "foreign_cores": None, "own_cores": None,
                     "steal_share": None, "orchestrator_cores": None}
    assert between(start, Snapshot(wall=disturbance.MIN_SPAN, busy=_ticks(1), steal=0, own=0))["foreign_cores"] > 0
    unreadable = Snapshot(wall=5.0, busy=None, steal=None, own=None)
    assert between(start, unreadable)["foreign_cores"] is None and between(unreadable, start)["own_cores"] is None


QUIET = {"seconds": 2.0, "foreign_cores": 0.05, "own_cores": 1.0, "steal_share": 0.0, "waited_share": 0.01}


def test_quiet_frames_are_not_disturbed():
    assert verdict(QUIET, [1.0] * 10, waits=[0.001] * 10, walls=[1.0] * 10) == ""
    # At the limits is still quiet; without /proc nothing is flagged.
    at_limits = {**QUIET, "foreign_cores": disturbance.FOREIGN_LIMIT, "steal_share": disturbance.STEAL_LIMIT,
                 "waited_share": disturbance.WAIT_LIMIT}
    assert verdict(at_limits, [1.0] * 8 + [3.0, 3.0]) == ""
    assert verdict({"foreign_cores": None, "steal_share": None, "waited_share": None}, [1.0, 1.1]) == ""


@pytest.mark.parametrize("load, totals, waits, reason", [
    ({"foreign_cores": 1.0}, [], (), "other work used 1.00 cores while it was timed"),
    ({"steal_share": 0.2}, [], (), "the hypervisor took 20 % of the CPU time (steal)"),
    ({"waited_share": 0.3, "foreign_cores": 0.2}, [], (), "its threads waited 30 % of the time for a CPU"),
    ({}, [1.0] * 8 + [3.5, 4.0], (), "2 of 10 frames took over 3× the median"),
    ({"foreign_cores": 0.2}, [1.0] * 10, [0.0] * 8 + [0.2, 0.2], "2 of 10 frames waited over 10 % of their time for a CPU"),
])
def test_each_disturbance_gives_its_reason(load, totals, waits, reason):
    walls = [1.0] * len(waits)
    assert verdict({**QUIET, **load}, totals, waits=waits, walls=walls) == reason


def test_waits_with_no_other_work_are_the_process_waiting_for_itself():
    # llvmpipe's threads outnumber the cores: on a quiet machine the process waits for its own threads.
    self_waits = {**QUIET, "foreign_cores": 0.0, "waited_share": 0.5}
    assert verdict(self_waits, [1.0] * 10, waits=[0.5] * 10, walls=[1.0] * 10) == ""
    assert verdict({**self_waits, "foreign_cores": None}, [1.0] * 10, waits=[0.5] * 10, walls=[1.0] * 10) == ""
    assert "waited 50 %" in verdict({**self_waits, "foreign_cores": 0.2}, [1.0] * 10, waits=[0.5] * 10,
                                    walls=[1.0] * 10)


def test_several_reasons_are_said_together():
    assert verdict({**QUIET, "foreign_cores": 0.8, "steal_share": 0.1}, [1.0] * 4 + [5.0]) == (
        "other work used 0.80 cores while it was timed; the hypervisor took 10 % of the CPU time (steal); "
        "1 of 5 frames took over 3× the median")


def test_a_parallel_run_is_starved_when_other_work_leaves_fewer_free_cores_than_workers(four_cpus):
    assert starvation({"foreign_cores": 1.5}, 4) == "4 workers had 2.5 free cores (other work used 1.50)"
    assert starvation({"foreign_cores": 1.5}, 2) == ""  # two workers, 2.5 cores free
    assert starvation({"foreign_cores": 0.2}, 4) == ""  # within the noise of the counters
    assert starvation({"foreign_cores": 3.5}, 1) == ""  # one thread is never starved by others' cores
    assert starvation({"foreign_cores": None}, 4) == "" and starvation({"foreign_cores": 3.0}, None) == ""


def _proc(files):
    """An ``open`` that serves ``{path: text}`` and fails on any other path."""
    def fake_open(path, *args, **kwargs):
        if path not in files:
            raise FileNotFoundError(path)
        return io.StringIO(files[path])
    return fake_open


def test_snapshot_reads_busy_steal_and_this_process_from_proc(monkeypatch):
    # user nice system idle iowait irq softirq steal guest guest_nice; a command name with spaces and ')'.
    fields = " ".join(str(v) for v in ["S", 1, 2, 3, 0, -1, 4194304, 10, 0, 0, 0, 700, 300, 0, 0, 20, 0])
    monkeypatch.setattr(disturbance, "open", _proc({
        "/proc/stat": "cpu  100 5 50 1000 20 1 2 7 30 0\ncpu0 1 2 3 4 5 6 7 8 9 10\n",
        "/proc/self/stat": f"4242 (volbench (render) x) {fields}\n"}), raising=False)
    taken = snapshot()
    assert (taken.busy, taken.steal, taken.own) == (165, 7, 1000)  # busy less idle and iowait; utime + stime
    monkeypatch.setattr(disturbance, "open", _proc({}), raising=False)
    assert snapshot().busy is None and snapshot().own is None


def test_snapshot_on_this_machine_counts_this_process_working():
    start = snapshot()
    assert isinstance(start.busy, int) and isinstance(start.steal, int) and isinstance(start.own, int)
    deadline = time.process_time() + 0.1
    while time.process_time() < deadline:
        pass
    end = snapshot()
    assert end.own - start.own >= _ticks(0.05) and end.busy - start.busy >= end.own - start.own - 2
    assert end.wall > start.wall


def test_the_orchestrators_share_of_other_work_is_read_from_the_watched_processes(four_cpus):
    start = Snapshot(wall=10.0, busy=_ticks(50), steal=0, own=_ticks(10), orchestrator={7: _ticks(3), 8: _ticks(1)})
    # Process 8 ended meanwhile: only 7's 0.2 s count, over 2 s.
    end = Snapshot(wall=12.0, busy=_ticks(53), steal=0, own=_ticks(11), orchestrator={7: _ticks(3.2)})
    load = between(start, end)
    assert load["orchestrator_cores"] == pytest.approx(0.1) and load["foreign_cores"] == pytest.approx(1.0)
    assert between(Snapshot(10.0, 0, 0, 0), Snapshot(12.0, 0, 0, 0))["orchestrator_cores"] is None


def test_watched_processes_are_read_in_every_snapshot_and_this_one_is_never_watched():
    import os
    import subprocess
    import sys

    busy = subprocess.Popen([sys.executable, "-c", "import time\nt = time.process_time() + 0.3\n"
                                                   "while time.process_time() < t: pass"])
    try:
        disturbance.watch([busy.pid, os.getpid(), 0])
        start = snapshot()
        busy.wait()
        assert list(start.orchestrator) == [busy.pid]
    finally:
        disturbance.watch([])
    assert snapshot().orchestrator == {}


def test_the_orchestrator_is_found_among_a_jobs_ancestors(tmp_path):
    import subprocess
    import sys

    # A job's process under a shell under a process whose command line runs Snakemake.
    job = tmp_path / "job.py"
    job.write_text("from pipeline import disturbance\nprint(len(disturbance.orchestrator_pids()))\n")
    fake = tmp_path / "snakemake"
    fake.write_text(f"import subprocess\nsubprocess.run(['bash', '-c', '{sys.executable} {job}; true'])\n")
    out = subprocess.run([sys.executable, str(fake)], capture_output=True, text=True, cwd=Path(__file__).parent.parent)
    assert out.stdout.strip() == "2"  # the shell, then the "Snakemake"
    assert disturbance.orchestrator_pids(levels=1) == []  # pytest's parent runs no workflow
    assert disturbance.is_orchestrator(["python", "-m", "pipeline.driver", "--cores", "2"])
    assert not disturbance.is_orchestrator(["bash", "-c", "cat .snakemake/x"])


def test_thread_waits_reads_the_schedulers_run_queue_delay(monkeypatch):
    first = disturbance.thread_waits()
    assert isinstance(first, float) and 0 <= first <= disturbance.thread_waits()
    monkeypatch.setattr(disturbance, "open", _proc({
        "/proc/self/task/1/schedstat": "5000000 2500000000 40\n", "/proc/self/task/2/schedstat": "1 500000000 2\n"}),
        raising=False)
    monkeypatch.setattr(disturbance.os, "listdir", lambda path: ["1", "2", "3"])  # 3 ended meanwhile
    assert disturbance.thread_waits() == pytest.approx(3.0)

    def no_proc(path):
        raise FileNotFoundError(path)

    monkeypatch.setattr(disturbance.os, "listdir", no_proc)
    assert disturbance.thread_waits() is None
