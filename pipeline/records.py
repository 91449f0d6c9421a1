"""A run's record and its images on disk: where they are, how they are written, whether they are intact.

A run's record is a JSON file; its images sit in a folder of the same name, one EXR (exact) and one
PNG (to look at) per view. A run that cannot happen here is recorded as ``skipped`` with the reason
(backend unavailable, feature unsupported, data absent); one that raised is recorded as ``failed``
with the error. Neither is ever dropped silently. The record's ``cause``
(one of :data:`core.outcomes.CAUSES`) says which, so that a report can tell a planned limit (a
feature the backend lacks) from a run that should have happened and did not.
"""

import hashlib
import json
import os
from pathlib import Path

from pipeline.environment import host_environment, now_utc


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


def new_record(run, device_environment):
    """The record of ``run`` before it renders: status ``ok``, no views yet, and this host's environment.

    ``device_environment`` (the workflow's probe of the OpenGL and OpenCL devices, or ``None``) is
    merged into the host's facts. ``date`` is now, not when the process started: a worker of the
    render service (:mod:`pipeline.workers`) renders runs for as long as the pipeline runs.
    """
    return {
        "experiment": run.experiment, "run": run.id, "backend": run.backend, "options": run.options,
        "tags": run.tags, "reference": run.reference, "spec_hash": run.spec_hash(), "interleave": run.interleave,
        "status": "ok", "reason": "", "cause": "", "views": [], "statistics": None,
        "planned_views": [view["view"] for view in run.views],
        "environment": {**host_environment(), "date": now_utc(), **(device_environment or {})},
    }


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
