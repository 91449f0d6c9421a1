"""A run under the profile's ``render_time_limit``: a child process that renders it, killed at the limit.

The rendering itself is :mod:`pipeline.rendering`'s, imported only where it runs (in the child, or
here without a limit): the process that only waits on a render never loads the data sets, the
backends or the image libraries.
"""

import json
import multiprocessing
import os
import time
import traceback

import renderers
from core.errors import InputError
from pipeline.records import new_record, run_record_path, write_json


def time_limit_reason(limit):
    """The recorded reason of a run killed at the profile's time limit."""
    return f"exceeded the profile's render_time_limit of {limit:g} s"


START_METHODS = ("spawn", "fork")


def execute_limited(run, *, profile, device_environment=None, start_method="spawn"):
    """:func:`pipeline.rendering.execute` under the profile's ``render_time_limit``; return the record.

    With a limit, the run executes in a child process started by ``start_method``: ``"spawn"``, a
    fresh interpreter, is safe whatever threads or device contexts this process has started (it
    gets this process's backend registry); ``"fork"`` inherits this process's imports, about 0.2 s
    less per run, and is safe only in a process that has started none, such as a render job's
    (:mod:`pipeline.jobs`). A child
    still running at the limit is killed (SIGKILL: a compiled kernel cannot be interrupted
    otherwise) and the run is recorded as ``failed`` with :func:`time_limit_reason`; a child that
    dies without writing its record (a crash in native code) is recorded as failed with its exit
    code. Either way this returns normally, so the job succeeds, the report lists the failure and
    the rest of the pipeline goes on. The limit covers the whole run: start-up, every view and
    every warm-up and timed frame.
    """
    return execute_together_limited([run], profile=profile, device_environment=device_environment,
                                    start_method=start_method)[0]


def execute_together_limited(runs, *, profile, device_environment=None, start_method="spawn", own_process=False):
    """The runs of one interleave group (:func:`pipeline.rendering.execute_together`) under the time limit.

    As :func:`execute_limited`, with the limit times the number of runs for the whole group; a group
    killed at its limit, or whose process died, records every run it had not finished as failed.
    Without a limit the runs render in this process, unless ``own_process`` (a replicate: each one's
    process is its own).
    """
    if start_method not in START_METHODS:
        raise InputError(f"start_method {start_method!r}: use one of {', '.join(START_METHODS)}")
    limit = profile.render_time_limit
    if limit is None and not own_process:
        return execute_in_process(runs, profile=profile, device_environment=device_environment,
                                  harness={"process": "job"})
    paths = [run_record_path(profile.results, run.experiment, run.id) for run in runs]
    for path in paths:
        path.unlink(missing_ok=True)  # an old record must not pass for this attempt's
    context = multiprocessing.get_context(start_method)
    name = runs[0].key if len(runs) == 1 else f"{runs[0].experiment}/{runs[0].interleave}"
    child = context.Process(target=_execute_child, name=f"volbench render {name}", daemon=True,
                            args=(runs, profile, device_environment, dict(renderers.BACKENDS)))
    started = time.monotonic()
    child.start()
    child.join(None if limit is None else limit * len(runs))
    killed = child.is_alive()
    if killed:
        child.kill()
        child.join()
    return record_unfinished(runs, profile=profile, device_environment=device_environment, killed=killed,
                             exitcode=child.exitcode, started=started)


def record_unfinished(runs, *, profile, device_environment, killed, exitcode, started):
    """The records of ``runs`` after their process ended: each one's own where it wrote it, else a failure.

    A run without a record failed at the time limit (``killed``: the limit times the number of runs
    of its group) or with the process (``exitcode``); ``started`` (monotonic) is when the process
    began, for the record's ``elapsed``. Used by :func:`execute_together_limited` and by the render
    service of :mod:`pipeline.workers`.
    """
    limit = profile.render_time_limit
    records = []
    for run in runs:
        path = run_record_path(profile.results, run.experiment, run.id)
        if path.is_file():
            records.append(json.loads(path.read_text()))
            continue
        if killed:
            group = f" per run ({limit * len(runs):g} s for its interleave group of {len(runs)})" if len(runs) > 1 else ""
            reason, cause = time_limit_reason(limit) + group, "time-limit"
        else:
            reason, cause = f"the render process died without a record (exit code {exitcode})", "crash"
        record = new_record(run, device_environment)
        record.update(status="failed", reason=reason, cause=cause, elapsed=time.monotonic() - started)
        write_json(path, record)
        records.append(record)
    return records


def _execute_child(runs, profile, device_environment, backends):
    """Body of :func:`execute_together_limited`'s child: the parent's registry, then the rendering."""
    renderers.BACKENDS.update(backends)
    execute_in_process(runs, profile=profile, device_environment=device_environment,
                       harness={"process": "job", "pid": os.getpid()})


def execute_in_process(runs, *, profile, device_environment=None, harness=None):
    """:func:`pipeline.rendering.execute_together` in this process; the records of ``runs``.

    An error ``execute_together`` lets through (a scene that cannot be built) is recorded as a failed
    run, so that the process that waits on this one (a job's parent, the render service) finds a record
    for every run; ``harness`` is what the records say of the process (:mod:`pipeline.workers`).
    """
    from pipeline.rendering import execute_together

    try:
        return execute_together(runs, profile=profile, device_environment=device_environment, harness=harness)
    except Exception as exc:
        records = []
        for run in runs:
            path = run_record_path(profile.results, run.experiment, run.id)
            if path.is_file():
                records.append(json.loads(path.read_text()))
                continue
            record = new_record(run, device_environment)
            record.update(status="failed", reason=f"{type(exc).__name__}: {exc}", cause="error",
                          traceback=traceback.format_exc(limit=8))
            write_json(path, record)
            records.append(record)
        return records
