"""The render service (pipeline.workers): warm workers, the time limit per run, crashes, the job's fallback."""

import dataclasses
import json
import os
import sys
import threading

import pytest

from pipeline import workers
from pipeline.experiments import Profile, Run
from pipeline.records import run_record_path

SCENE = {"width": 12, "height": 10, "shading": {"model": "phong"}, "volumes": [{"dataset": "sphere", "size": 12}]}

# A stand-in worker speaking the service's protocol: it answers with its process id, or sleeps past the
# time limit, or dies, as the run's tag `act` says.
FAKE_WORKER = r'''
import json, os, sys, time
out = os.fdopen(int(sys.argv[sys.argv.index("--reply-fd") + 1]), "wb")
def reply(payload):
    out.write(json.dumps(payload).encode() + b"\n"); out.flush()
reply({"ready": True})
for line in sys.stdin.buffer:
    request = json.loads(line)
    runs = json.loads(request["runs"]); runs = runs if isinstance(runs, list) else [runs]
    act = runs[0]["tags"].get("act", "ok")
    if act == "sleep":
        time.sleep(60)
    if act == "crash":
        os._exit(3)
    if act == "wait":
        time.sleep(0.5)
    reply({"outcomes": [{"key": f"{r['experiment']}/{r['id']}", "status": "ok",
                         "reason": f"{os.getpid()} {request['threads']} {request['watch'][0]}"} for r in runs]})
'''


@pytest.fixture
def service(tmp_path):
    script = tmp_path / "fake_worker.py"
    script.write_text(FAKE_WORKER)
    with workers.RenderService(cores=2, root=tmp_path, log_dir=tmp_path / "logs",
                               worker_command=(sys.executable, str(script))) as running:
        yield running


def _profile(tmp_path, limit=30.0):
    return Profile(name="t", volume_size=12, results=str(tmp_path / "results"), cache=str(tmp_path / "cache"),
                   render_time_limit=limit)


def _request(service, profile, *runs, threads=1):
    body = json.dumps([run.as_dict() for run in runs]) if len(runs) > 1 else json.dumps(runs[0].as_dict())
    return workers.request_render(service.socket_path, runs=body, profile=json.dumps(dataclasses.asdict(profile)),
                                  device_env=None, threads=threads)


def _run(run_id, backend="reference", act="ok"):
    return Run("volbench-phantoms", run_id, backend, SCENE, ({"view": "front"},), tags={"act": act})


def _worker_pid(outcome):
    return int(outcome["reason"].split()[0])


def test_runs_go_to_an_idle_worker_that_has_already_rendered_their_backends(service, tmp_path):
    profile = _profile(tmp_path)
    first, = _request(service, profile, _run("a"), threads=2)
    second, = _request(service, profile, _run("b"))
    assert _worker_pid(first) == _worker_pid(second)  # warm: one process for the runs of a backend
    assert first["reason"].split()[1:] == ["2", str(os.getpid())]  # the job's cores; the service's process watched
    # While that worker renders, a run of another backend gets a worker of its own ...
    busy = threading.Thread(target=lambda: _request(service, profile, _run("slowish", act="wait")))
    busy.start()
    import time

    time.sleep(0.2)
    other, = _request(service, profile, _run("c", backend="shearwarp"))
    busy.join()
    assert _worker_pid(other) != _worker_pid(first) and service.started == 2
    # ... and when both are idle, each backend's runs go back to the worker that rendered it.
    assert _worker_pid(_request(service, profile, _run("d", backend="shearwarp"))[0]) == _worker_pid(other)
    assert _worker_pid(_request(service, profile, _run("e"))[0]) == _worker_pid(first)
    # Any idle worker takes a backend none has rendered yet: it imports it on its first run.
    assert _worker_pid(_request(service, profile, _run("f", backend="volpack"))[0]) in (_worker_pid(first),
                                                                                       _worker_pid(other))
    assert service.started == 2


def test_a_run_past_the_time_limit_is_recorded_failed_and_the_next_gets_a_fresh_worker(service, tmp_path):
    profile = _profile(tmp_path, limit=1.0)
    before, = _request(service, _profile(tmp_path), _run("a"))
    late, = _request(service, profile, _run("slow", act="sleep"))
    after, = _request(service, _profile(tmp_path), _run("b"))
    assert late["status"] == "failed" and late["reason"] == "exceeded the profile's render_time_limit of 1 s"
    record = json.loads(run_record_path(profile.results, "volbench-phantoms", "slow").read_text())
    assert (record["status"], record["cause"]) == ("failed", "time-limit")
    assert _worker_pid(after) != _worker_pid(before)


def test_the_limit_of_an_interleave_group_is_the_limit_times_its_runs(service, tmp_path):
    profile = _profile(tmp_path, limit=0.5)
    outcomes = _request(service, profile, _run("x", act="sleep"), _run("y"))
    assert [o["reason"] for o in outcomes] == ["exceeded the profile's render_time_limit of 0.5 s per run "
                                               "(1 s for its interleave group of 2)"] * 2


def test_a_worker_that_dies_is_a_crash_of_its_runs(service, tmp_path):
    profile = _profile(tmp_path)
    died, = _request(service, profile, _run("boom", act="crash"))
    assert died["status"] == "failed"
    assert died["reason"] == "the render process died without a record (exit code 3)"
    again, = _request(service, profile, _run("fine"))
    assert again["status"] == "ok"


def test_requests_at_once_get_a_worker_each(service, tmp_path):
    profile = _profile(tmp_path)
    outcomes = []
    threads = [threading.Thread(target=lambda i=i: outcomes.extend(_request(service, profile, _run(f"w{i}", act="wait"))))
               for i in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len({_worker_pid(o) for o in outcomes}) == 2


def test_closing_the_service_ends_its_workers(tmp_path):
    script = tmp_path / "fake_worker.py"
    script.write_text(FAKE_WORKER)
    service = workers.RenderService(cores=1, root=tmp_path, log_dir=tmp_path / "logs",
                                    worker_command=(sys.executable, str(script))).start()
    outcome, = _request(service, _profile(tmp_path), _run("a"))
    service.close()
    with pytest.raises(ProcessLookupError):
        os.kill(_worker_pid(outcome), 0)
    with pytest.raises(workers.ServiceUnavailable, match="no render service at"):
        _request(service, _profile(tmp_path), _run("b"))


@pytest.mark.parametrize("environ, address", [
    ({}, None),
    ({workers.SERVICE_VARIABLE: "elsewhere:/tmp/x/socket"}, None),  # a cluster node inherits the login node's
    ({workers.SERVICE_VARIABLE: "{host}:/tmp/x/socket", "SLURM_JOB_ID": "7"}, None),
    ({workers.SERVICE_VARIABLE: "{host}:/tmp/x/socket"}, "/tmp/x/socket"),
])
def test_a_job_uses_the_service_only_on_its_host_outside_slurm(environ, address):
    import socket

    environ = {key: value.format(host=socket.gethostname()) for key, value in environ.items()}
    assert workers.service_address(environ) == address


def test_a_real_worker_renders_run_after_run_in_one_process(tmp_path):
    """The worker itself: imports once, renders two requests, records say which process and what it cost."""
    profile = Profile(name="t", volume_size=12, results=str(tmp_path / "results"), cache=str(tmp_path / "cache"),
                      render_time_limit=120)
    with workers.RenderService(cores=1, root=os.getcwd(), log_dir=tmp_path / "logs") as service:
        for run_id in ("first", "second"):
            run = Run("volbench-phantoms", run_id, "reference", SCENE, ({"view": "front"},),
                      options={"step_factor": 1.0}, warmup=0, repeat=1)
            outcome, = _request(service, profile, run)
            assert outcome["status"] == "ok", outcome
    records = [json.loads(run_record_path(profile.results, "volbench-phantoms", name).read_text())
               for name in ("first", "second")]
    harness = [record["harness"] for record in records]
    assert [h["process"] for h in harness] == ["worker", "worker"]
    assert [h["new"] for h in harness] == [True, False]
    assert harness[0]["pid"] == harness[1]["pid"] and harness[0]["startup"] > 0
    assert records[0]["views"][0]["info"]["untimed_seconds"] > 0


def test_a_real_worker_runs_job_steps_and_says_how_they_ended(tmp_path, monkeypatch, capsys):
    """volume, evaluate and tabulate jobs hand their arguments to a warm worker; its output and exit status
    are the job's, a failure included."""
    import socket

    from pipeline import jobs

    with workers.RenderService(cores=1, root=os.getcwd(), log_dir=tmp_path / "logs") as service:
        assert workers.request_step(service.socket_path, ["evaluate", "--pairs", "[]"]) == (0, "")
        status, output = workers.request_step(service.socket_path, ["tabulate", "--profile", "{", "--experiment", "x"])
        assert status == 1 and "Traceback" in output and "JSONDecodeError" in output
        status, output = workers.request_step(service.socket_path, ["evaluate"])
        assert status == 2 and "--pairs" in output  # argparse's refusal
        monkeypatch.setenv(workers.SERVICE_VARIABLE, f"{socket.gethostname()}:{service.socket_path}")
        jobs.main(["evaluate", "--pairs", "[]"])
        with pytest.raises(SystemExit) as failed:
            jobs.main(["tabulate", "--profile", "{", "--experiment", "x"])
        assert failed.value.code == 1 and "JSONDecodeError" in capsys.readouterr().out
        assert service.started == 1  # one warm worker ran every step


def test_a_request_that_avoids_a_workers_process_gets_another(service, tmp_path):
    """A replicate is timed in a process that has not timed its runs before."""
    profile = _profile(tmp_path)
    first, = _request(service, profile, _run("a"))
    body = json.dumps(_run("a").as_dict())
    again, = workers.request_render(service.socket_path, runs=body, profile=json.dumps(dataclasses.asdict(profile)),
                                    device_env=None, threads=1, avoid=[_worker_pid(first)])
    assert _worker_pid(again) != _worker_pid(first) and service.started == 2
    third, = _request(service, profile, _run("b"))  # without a process to avoid: the warm one most recently used
    assert _worker_pid(third) == _worker_pid(again)


def test_timed_runs_go_only_to_workers_that_did_nothing_untimed(service, tmp_path):
    """A worker that rendered a ground truth (or ran a step) takes untimed work only; a timed run gets another,
    and the untimed work after it goes back to the first."""
    profile = _profile(tmp_path)
    untimed = dataclasses.replace(_run("truth"), warmup=0, repeat=1)
    first, = _request(service, profile, untimed)
    timed, = _request(service, profile, _run("a"))
    assert _worker_pid(timed) != _worker_pid(first) and service.started == 2
    assert _worker_pid(_request(service, profile, dataclasses.replace(untimed, id="truth2"))[0]) == _worker_pid(first)
    assert _worker_pid(_request(service, profile, _run("b"))[0]) == _worker_pid(timed)
    assert service.started == 2


def _replicated_group(tmp_path):
    profile = Profile(name="t", volume_size=12, results=str(tmp_path / "results"), cache=str(tmp_path / "cache"),
                      render_time_limit=120)
    runs = [Run("volbench-phantoms", name, "reference", SCENE, ({"view": "front"},), options={"step_factor": step},
                warmup=1, repeat=3, interleave="g", replicates=2) for name, step in (("fine", 0.5), ("coarse", 1.0))]
    arguments = ["render", "--run", json.dumps([run.as_dict() for run in runs]),
                 "--profile", json.dumps(dataclasses.asdict(profile)), "--threads", "1"]
    return profile, runs, arguments


def _assert_two_processes_each(profile, runs, job_pid):
    for run in runs:
        record = json.loads(run_record_path(profile.results, run.experiment, run.id).read_text())
        assert record["status"] == "ok", record["reason"]
        processes = record["views"][0]["processes"]
        assert len(processes) == 2 and len({p["pid"] for p in processes}) == 2
        assert job_pid not in record["harness"]["pids"]
        assert all(len(p["frames"]["total"]) >= 3 for p in processes)


def test_a_replicated_group_is_timed_once_in_each_of_two_workers_in_alternating_order(tmp_path, monkeypatch):
    """replicates=2: the job has the service render the group twice, in two workers, reversing its order the
    second time, and each run's record keeps both processes' frames."""
    import socket

    from pipeline import jobs

    profile, runs, arguments = _replicated_group(tmp_path)
    orders = []
    execute = jobs._render_once

    def spy(args, runs_json, *rest, **kwargs):
        orders.append([run["id"] for run in json.loads(runs_json)])
        return execute(args, runs_json, *rest, **kwargs)

    monkeypatch.setattr(jobs, "_render_once", spy)
    with workers.RenderService(cores=1, root=os.getcwd(), log_dir=tmp_path / "logs") as service:
        monkeypatch.setenv(workers.SERVICE_VARIABLE, f"{socket.gethostname()}:{service.socket_path}")
        jobs.main(arguments)
        assert service.started == 2
    assert orders == [["fine", "coarse"], ["coarse", "fine"]]
    _assert_two_processes_each(profile, runs, os.getpid())


def test_a_group_in_parts_times_each_part_in_processes_of_its_own_in_alternating_order(tmp_path, monkeypatch):
    """A group of two OpenGL stacks comes as parts: in each replicate each part is rendered in a worker the other
    part did not use in that replicate, nor it before, the parts' order reversed the second time."""
    import socket

    from pipeline import jobs

    profile, runs, arguments = _replicated_group(tmp_path)
    arguments[2] = json.dumps([[run.as_dict()] for run in runs])  # the parts: one run each
    orders = []
    execute = jobs._render_once

    def spy(args, runs_json, *rest, **kwargs):
        orders.append(([run["id"] for run in json.loads(runs_json)], tuple(kwargs["avoid"])))
        return execute(args, runs_json, *rest, **kwargs)

    monkeypatch.setattr(jobs, "_render_once", spy)
    with workers.RenderService(cores=1, root=os.getcwd(), log_dir=tmp_path / "logs") as service:
        monkeypatch.setenv(workers.SERVICE_VARIABLE, f"{socket.gethostname()}:{service.socket_path}")
        jobs.main(arguments)
        assert service.started == 2  # the two workers swap parts in the second replicate
    assert [ids for ids, _ in orders] == [["fine"], ["coarse"], ["coarse"], ["fine"]]
    assert len(orders[0][1]) == 0 and len(orders[1][1]) == 1 and len(orders[2][1]) == 1 and len(orders[3][1]) == 2
    _assert_two_processes_each(profile, runs, os.getpid())
    fine, coarse = (json.loads(run_record_path(profile.results, run.experiment, run.id).read_text()) for run in runs)
    assert fine["harness"]["pids"] == coarse["harness"]["pids"][::-1]  # never in one process at once


def test_a_replicated_group_without_a_service_is_timed_in_a_child_process_per_replicate(tmp_path):
    """Where no service answers (a cluster node), the job forks a child per replicate. Run as a job is, in a
    process of its own: a fork of this test process, whose Numba threads have started, is not a job's."""
    import subprocess

    profile, runs, arguments = _replicated_group(tmp_path)
    env = {key: value for key, value in os.environ.items() if key != workers.SERVICE_VARIABLE}
    job = subprocess.run([sys.executable, "-m", "pipeline.jobs", *arguments], env=env, capture_output=True, text=True,
                         timeout=300)
    assert job.returncode == 0, job.stderr
    _assert_two_processes_each(profile, runs, None)
