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


SUMMED_INFO = ("cold_seconds", "untimed_seconds", "timed_seconds", "rerun_seconds", "frames")
"""A view's ``info`` entries that add up over the processes that timed it (the harness's account)."""


def merge_processes(attempts, *, planned=None):
    """The record of a run timed in several processes (:attr:`~pipeline.experiments.kit.model.Run.replicates`).

    ``attempts`` are the records each process wrote, in order, of ``planned`` processes (default: as many).
    A run that one process could not render is that process's record (a failure names the process).
    Otherwise the last process's record (its images are the ones on disk) with, per view, ``processes``:
    each process's frames, times, process id, disturbance and ``info`` (its own, but the harness's seconds summed
    below: what a backend records of how one process shared out its work); ``timings`` the mean over the processes of
    their medians (the time a table shows, :func:`pipeline.experiments.kit.intervals.process_time`),
    ``timings_min``/``_max`` the extremes of all frames, the harness's seconds summed and ``disturbed``
    naming each process that was.
    """
    import copy
    import statistics

    count = planned or len(attempts)
    for number, attempt in enumerate(attempts, 1):
        if attempt["status"] != "ok":
            record = copy.deepcopy(attempt)
            if record["status"] == "failed":
                record["reason"] = f"process {number} of {count}: {record['reason']}"
            return record
    merged = copy.deepcopy(attempts[-1])
    pids = [(attempt.get("harness") or {}).get("pid") for attempt in attempts]
    for view in merged["views"]:
        each = [next(v for v in attempt["views"] if v["view"] == view["view"]) for attempt in attempts]
        view["processes"] = [
            {"pid": pid, "frames": v["frames"], "timings": v["timings"], "timings_min": v["timings_min"],
             "timings_max": v["timings_max"], "disturbed": v["info"].get("disturbed") or "", "rerun": v.get("rerun"),
             "info": {key: value for key, value in v["info"].items() if key not in SUMMED_INFO}}
            for pid, v in zip(pids, each)]
        stages = dict.fromkeys(stage for v in each for stage in v["timings"])
        view["timings"] = {stage: statistics.fmean(statistics.median(v["frames"][stage]) if v["frames"].get(stage)
                                                   else v["timings"][stage] for v in each if stage in v["timings"])
                           for stage in stages}
        view["timings_min"] = {stage: min(v["timings_min"][stage] for v in each if stage in v["timings_min"])
                               for stage in view["timings_min"]}
        view["timings_max"] = {stage: max(v["timings_max"][stage] for v in each if stage in v["timings_max"])
                               for stage in view["timings_max"]}
        view["frames"] = {stage: [t for v in each for t in v["frames"].get(stage, [])] for stage in view["frames"]}
        for key in SUMMED_INFO:
            values = [v["info"][key] for v in each if isinstance(v["info"].get(key), (int, float))]
            if values:
                view["info"][key] = sum(values)
        disturbed = [f"process {number}: {v['info']['disturbed']}" for number, v in enumerate(each, 1)
                     if v["info"].get("disturbed")]
        view["info"]["disturbed"] = "; ".join(disturbed)
        reruns = [v.get("rerun") for v in each if v.get("rerun")]
        view["rerun"] = reruns[-1] if reruns else None
    harnesses = [attempt.get("harness") or {} for attempt in attempts]
    merged["harness"] = {**harnesses[-1], "processes": count, "pids": pids,
                         "seconds": sum(h.get("seconds") or 0.0 for h in harnesses),
                         "new": any(h.get("new") for h in harnesses),
                         "startup": sum(h.get("startup") or 0.0 for h in harnesses if h.get("new"))}
    return merged
