"""Executes one run (a Snakemake job) and compares it with its reference run.

A run's record is a JSON file; its images sit in a folder of the same name, one EXR (exact) and one
PNG (to look at) per view. A run that cannot happen here is recorded as ``skipped`` with the reason
(backend unavailable, feature unsupported, data absent); one that raised is recorded as ``failed``
with the error. Neither is ever dropped silently.
"""

import json
import os
import traceback
from pathlib import Path

import numpy as np

import datasets
import renderers
from pipeline.environment import host_environment
from core.errors import BackendUnavailableError, UnsupportedFeatureError
from pipeline.scene_io import build_scene, build_volume_instance
from pipeline.timing import measure
from core.transfer import Preset
from reports.imageio import read_image, write_exr, write_png
from reports.metrics import compare, difference_image


def write_json(path, payload):
    """Write JSON atomically, so a parallel reader never sees half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(payload, indent=1, sort_keys=True, default=_json_default))
    os.replace(tmp, path)


def _json_default(value):
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


def execute(run, *, profile, device_environment=None):
    """Render every view of ``run``, write its images and record; return the record."""
    record_path = run_record_path(profile.results, run.experiment, run.id)
    record = {
        "experiment": run.experiment, "run": run.id, "backend": run.backend, "options": run.options,
        "tags": run.tags, "reference": run.reference, "spec_hash": run.spec_hash(),
        "status": "ok", "reason": "", "views": [], "statistics": None,
        "environment": {**host_environment(), **(device_environment or {})},
    }
    try:
        scene = build_scene(run.scene, cache_dir=profile.cache, size=profile.volume_size, data_dir=profile.real_data)
        renderer = renderers.get(run.backend, **run.options)
        renderer.check(scene)
    except (datasets.DataUnavailableError, BackendUnavailableError, UnsupportedFeatureError) as exc:
        record.update(status="skipped", reason=str(exc))
        write_json(record_path, record)
        return record
    image_dir = record_path.with_suffix("")
    image_dir.mkdir(parents=True, exist_ok=True)
    try:
        with renderer:
            record["backend_environment"] = renderer.environment()
            if run.statistics:
                measured = build_volume_instance(run.statistics, cache_dir=profile.cache, size=profile.volume_size,
                                                 data_dir=profile.real_data)
                preset = Preset(measured.transfer_function, measured.gradient_opacity, measured.isovalue)
                record["statistics"] = {**datasets.statistics(measured.volume, preset),
                                        "size": max(measured.volume.shape_xyz)}
            for view in run.views:
                overrides = {k: v for k, v in view.items() if k != "view"}
                view_scene = scene.with_camera(**overrides) if overrides else scene
                result = measure(renderer, view_scene, warmup=run.warmup, repeat=run.repeat)
                exr, png = image_dir / f"{view['view']}.exr", image_dir / f"{view['view']}.png"
                write_exr(exr, result.image, metadata={"run": run.key, "view": view["view"], "backend": run.backend})
                write_png(png, result.image)
                record["views"].append({
                    "view": view["view"], "camera": overrides, "exr": str(exr), "png": str(png),
                    "timings": result.timings, "timings_min": result.timings_min,
                    "timings_max": result.timings_max, "counters": result.counters, "info": result.info,
                })
            # After rendering: some effective options (a step derived from the scene) exist only now.
            record["options"] = {**run.options, **renderer.options}
    except Exception as exc:  # recorded with its traceback: the pipeline must not lose the pair
        record.update(status="failed", reason=f"{type(exc).__name__}: {exc}",
                      traceback=traceback.format_exc(limit=8))
    write_json(record_path, record)
    return record


def evaluate(record_path, reference_path, output_path):
    """Compare each view of a run with the same view of its reference run; write the metrics."""
    record = json.loads(Path(record_path).read_text())
    truth = json.loads(Path(reference_path).read_text())
    metrics = {"experiment": record["experiment"], "run": record["run"], "reference": truth["run"],
               "status": "ok", "reason": "", "views": {}}
    if truth["status"] != "ok":
        metrics.update(status="skipped", reason=f"reference run {truth['run']} is {truth['status']}: {truth['reason']}")
    elif record["status"] != "ok":
        metrics.update(status="skipped", reason=f"run is {record['status']}")
    else:
        truth_views = {v["view"]: v for v in truth["views"]}
        diff_dir = Path(output_path).with_suffix("")
        diff_dir.mkdir(parents=True, exist_ok=True)
        for view in record["views"]:
            if view["view"] not in truth_views:
                continue
            test_image = read_image(view["exr"])
            truth_image = read_image(truth_views[view["view"]]["exr"])
            values = compare(truth_image, test_image)
            diff_path = diff_dir / f"{view['view']}-diff.png"
            write_png(diff_path, difference_image(truth_image, test_image))
            metrics["views"][view["view"]] = {**values, "diff_png": str(diff_path)}
    write_json(output_path, metrics)
    return metrics
