"""A run's record, its time limit and what makes Snakemake rerun it; :mod:`pipeline.rendering` renders it.

A run's record is a JSON file; its images sit in a folder of the same name, one EXR (exact) and one
PNG (to look at) per view. A run that cannot happen here is recorded as ``skipped`` with the reason
(backend unavailable, feature unsupported, data absent); one that raised is recorded as ``failed``
with the error. Neither is ever dropped silently. The record's ``cause``
(one of :data:`core.outcomes.CAUSES`) says which, so that a report can tell a planned limit (a
feature the backend lacks) from a run that should have happened and did not.
"""

import hashlib
import json
import multiprocessing
import os
import time
import traceback
from pathlib import Path

import renderers
from core.errors import InputError
from pipeline.environment import host_environment


def write_json(path, payload):
    """Write JSON atomically, so a parallel reader never sees half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(payload, indent=1, sort_keys=True, default=_json_default))
    os.replace(tmp, path)


def _json_default(value):
    import numpy as np  # only a render's record holds NumPy values, and a render has it loaded

    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def run_record_path(results_dir, experiment, run_id):
    """``results/runs/<experiment>/<run>.json``; the run's images go in the folder beside it."""
    return Path(results_dir) / "runs" / experiment / f"{run_id}.json"


def metrics_record_path(results_dir, experiment, run_id):
    """``results/metrics/<experiment>/<run>.json``; difference images go in the folder beside it."""
    return Path(results_dir) / "metrics" / experiment / f"{run_id}.json"


def _new_record(run, device_environment):
    return {
        "experiment": run.experiment, "run": run.id, "backend": run.backend, "options": run.options,
        "tags": run.tags, "reference": run.reference, "spec_hash": run.spec_hash(),
        "status": "ok", "reason": "", "cause": "", "views": [], "statistics": None,
        "planned_views": [view["view"] for view in run.views],
        "environment": {**host_environment(), **(device_environment or {})},
    }


def time_limit_reason(limit):
    """The recorded reason of a run killed at the profile's time limit."""
    return f"exceeded the profile's render_time_limit of {limit:g} s"


START_METHODS = ("spawn", "fork")


def execute_limited(run, *, profile, device_environment=None, start_method="spawn"):
    """:func:`execute` under the profile's ``render_time_limit``; return the record.

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
    if start_method not in START_METHODS:
        raise InputError(f"start_method {start_method!r}: use one of {', '.join(START_METHODS)}")
    limit = profile.render_time_limit
    if limit is None:
        from pipeline.rendering import execute

        return execute(run, profile=profile, device_environment=device_environment)
    record_path = run_record_path(profile.results, run.experiment, run.id)
    record_path.unlink(missing_ok=True)  # an old record must not pass for this attempt's
    context = multiprocessing.get_context(start_method)
    child = context.Process(target=_execute_child, name=f"volbench render {run.key}", daemon=True,
                            args=(run, profile, device_environment, dict(renderers.BACKENDS)))
    started = time.monotonic()
    child.start()
    child.join(limit)
    if child.is_alive():
        child.kill()
        child.join()
        reason, cause = time_limit_reason(limit), "time-limit"
    elif record_path.is_file():
        return json.loads(record_path.read_text())
    else:
        reason, cause = f"the render process died without a record (exit code {child.exitcode})", "crash"
    record = _new_record(run, device_environment)
    record.update(status="failed", reason=reason, cause=cause, elapsed=time.monotonic() - started)
    write_json(record_path, record)
    return record


def _execute_child(run, profile, device_environment, backends):
    """Body of :func:`execute_limited`'s child: the parent's registry, then :func:`execute`.

    An error :func:`execute` lets through (a scene that cannot be built) is recorded as a failed
    run here, since the parent only sees an exit code.
    """
    from pipeline.rendering import execute

    renderers.BACKENDS.update(backends)
    try:
        execute(run, profile=profile, device_environment=device_environment)
    except Exception as exc:
        record = _new_record(run, device_environment)
        record.update(status="failed", reason=f"{type(exc).__name__}: {exc}", cause="error",
                      traceback=traceback.format_exc(limit=8))
        write_json(run_record_path(profile.results, run.experiment, run.id), record)


# ---------------------------------------------------------------------------------------------
# What makes the Snakefile rerun a job: the code that shapes its output, and failed runs.

ROOT = Path(__file__).resolve().parent.parent

JOB_SOURCES = {
    "volume": ("core", "datasets"),
    "environment": ("core", "pipeline/environment.py", "renderers/gl/context.py", "renderers/cl/context.py"),
    "render": ("core", "datasets", "renderers/__init__.py", "renderers/base", "pipeline/runner.py", "pipeline/rendering.py",
               "pipeline/scene_io.py", "pipeline/timing.py", "pipeline/environment.py",
               "pipeline/experiments/base.py", "reports/imageio.py"),
    "evaluate": ("core", "pipeline/runner.py", "pipeline/rendering.py", "reports/metrics.py", "reports/imageio.py"),
    "phantoms": ("core", "datasets", "pipeline/collect.py", "pipeline/scene_io.py", "pipeline/experiments"),
    "tabulate": ("core", "pipeline/runner.py", "pipeline/collect.py", "pipeline/environment.py", "pipeline/experiments",
                 "reports/metrics.py"),
    "collect": ("pipeline/collect.py",),
    "report": ("core", "pipeline/experiments", "reports"),
}
"""Per Snakemake rule, the files and folders (relative to the repository) whose code shapes its
output; a render job adds its backend's package. Each job's digest (:func:`job_code_digest`)
also covers its entry function in :mod:`pipeline.jobs`. Folders count every file in them
(templates and shaders too), except ``__pycache__``."""


def source_files(entries, *, root=ROOT):
    """The files named by ``entries`` (files or folders, relative to ``root``), sorted."""
    root = Path(root)
    files = set()
    for entry in entries:
        path = root / entry
        if path.is_file():
            files.add(path)
        elif path.is_dir():
            files.update(p for p in path.rglob("*")
                         if p.is_file() and "__pycache__" not in p.parts and p.suffix not in (".pyc", ".nbi", ".nbc"))
        else:
            raise FileNotFoundError(f"job source {entry!r} does not exist under {root}")
    return sorted(files)


def source_digest(entries, *, root=ROOT, extra=()):
    """Hex digest of the content (and relative names) of the files ``entries`` name, plus ``extra`` strings.

    Content, not modification times: a checkout or a copy that changes no byte reruns nothing.
    """
    root = Path(root)
    digest = hashlib.sha256()
    for path in source_files(entries, root=root):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    for text in extra:
        digest.update(text.encode() + b"\0")
    return digest.hexdigest()[:16]


def job_code_digest(rule, *, backend=None, root=ROOT):
    """The digest a Snakemake job carries as a param: its :data:`JOB_SOURCES`, entry function and backend."""
    import inspect

    from pipeline import jobs

    entries = list(JOB_SOURCES[rule])
    if backend is not None:
        # The backend's whole package under renderers/ (its shaders, kernels and helper modules too),
        # not only the module the registry names.
        package = Path(*renderers.backend_module(backend).split(".")[:2])
        entries.append(str(package) if (Path(root) / package).is_dir() else f"{package}.py")
    return source_digest(entries, root=root, extra=[inspect.getsource(getattr(jobs, rule))])


def retry_marker_path(results_dir, experiment, run_id):
    """``results/.retry/<experiment>/<run>``: an input of the run's render job (see :func:`mark_retry`)."""
    return Path(results_dir) / ".retry" / experiment / run_id


def image_digest(path):
    """What a record keeps of an image it names: its SHA-256, size and modification time.

    :func:`image_damage` compares the file with it at every workflow start.
    """
    path = Path(path)
    with path.open("rb") as f:
        sha256 = hashlib.file_digest(f, "sha256").hexdigest()
    stat = path.stat()
    return {"sha256": sha256, "bytes": stat.st_size, "mtime_ns": stat.st_mtime_ns}


def image_damage(record):
    """Why the images an ``ok`` record names cannot be trusted (a phrase), or ``""`` when every one is intact.

    Each view's EXR and PNG must exist, with the size and SHA-256 of :func:`image_digest` in the
    record. A file whose size and modification time are still those recorded is not read again:
    hashing every image at every workflow start would read the whole results folder (gigabytes at
    paper scale), while a truncated, rewritten or replaced image changes one or the other.
    """
    for view in record.get("views", []):
        digests = view.get("digests")
        if not isinstance(digests, dict):
            return f"view {view.get('view')!r} carries no image digests (written before records had them)"
        for kind in ("exr", "png"):
            path, recorded = Path(view[kind]), digests.get(kind) or {}
            if not path.is_file():
                return f"view {view['view']!r}: its {kind.upper()} {path} is missing"
            stat = path.stat()
            if stat.st_size != recorded.get("bytes"):
                return f"view {view['view']!r}: its {kind.upper()} {path} has {stat.st_size} bytes, not {recorded.get('bytes')}"
            if stat.st_mtime_ns != recorded.get("mtime_ns") and image_digest(path)["sha256"] != recorded.get("sha256"):
                return f"view {view['view']!r}: its {kind.upper()} {path} does not match its SHA-256"
    return ""


def mark_retry(results_dir, experiment, run_id):
    """Make the run's retry marker say whether its render job must run again; return its path.

    A failed run's record is a finished output to Snakemake, which would keep it forever. So
    every render job takes this marker as an input, and the workflow calls this for every run
    when it starts: for a run whose record is ``failed`` (or unreadable), or ``ok`` but naming an
    image that is missing or damaged (:func:`image_damage`), the marker is rewritten now, newer
    than the record and with text naming that record (Snakemake skips a newer input whose checksum
    it has recorded before), so Snakemake reruns the job ("updated input files"), a dry run
    included; for any other run the marker is empty and dated 1970, older than any record, so it
    never triggers. The record stays until the retry replaces it, and skipped runs (which cannot
    happen here) are not retried.
    """
    marker = retry_marker_path(results_dir, experiment, run_id)
    record_path = run_record_path(results_dir, experiment, run_id)
    why = ""
    if record_path.is_file():
        try:
            record = json.loads(record_path.read_text())
            status = record.get("status")
        except (OSError, ValueError, AttributeError):
            why = "is unreadable"
        else:
            if status not in ("ok", "skipped"):
                why = f"is {status}"
            elif status == "ok":
                damage = image_damage(record)
                why = f"names a damaged image ({damage})" if damage else ""
    marker.parent.mkdir(parents=True, exist_ok=True)
    if why:
        # Snakemake ignores a newer input whose checksum it has seen before, so the marker's text
        # names this very record (its modification time and digest): each failure is new to it.
        stamp = f"{record_path.stat().st_mtime_ns} {hashlib.sha256(record_path.read_bytes()).hexdigest()[:16]}"
        marker.write_text(f"retry {experiment}/{run_id}: its last record ({stamp}) {why}\n")
        now = time.time()
        os.utime(marker, (now, max(now, record_path.stat().st_mtime + 1)))
    else:
        marker.write_text("")
        os.utime(marker, (0, 0))
    return marker
