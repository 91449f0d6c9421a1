"""Helpers every paper's experiment module shares: frames, registry checks, views, result columns.

The experiment modules (one per paper) plan runs and check claims on the tidy results table;
what they have in common lives here so that each module holds only its paper: how many frames a
timed run takes, whether a backend and its options exist, the views of a data set, reading
columns and rows of the results with errors that name what is missing, image pairs' metrics and
the small formatting of numbers in claims.
"""

import functools
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

import datasets
import renderers
from pipeline.experiments.base import format_number
from pipeline.experiments.verdicts import MissingColumn
from pipeline.experiments.volbench import HEADLINE_VIEW
from reports import blocks

UNTIMED = {"warmup": 0, "repeat": 1}
"""Frames of a ground-truth or picture-only run: one untimed frame."""


def timed_frames(profile, experiment=None):
    """Frames of a timed comparison: at least one warm-up frame and three timed frames.

    An experiment's ``repeat`` setting raises the timed frames above the profile's: these frames
    take milliseconds, and on a shared machine the median of three is at the mercy of one
    interruption.
    """
    repeat = int(profile.repeat if experiment is None else profile.setting(experiment, "repeat", profile.repeat))
    return {"warmup": max(1, int(profile.warmup)), "repeat": max(3, repeat)}


def usable_cores():
    """Cores this process may use (the render jobs take them all)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def is_registered(backend):
    return backend in renderers.names()


def unregistered(*backends):
    """``[(what, reason)]`` for each backend of ``backends`` the registry does not hold."""
    return [(backend, f"backend {backend!r} is not registered (renderers.names(): {', '.join(renderers.names())})")
            for backend in backends if not is_registered(backend)]


def accepts(backend, *options):
    """Whether ``backend`` is registered and its constructor takes every option name given.

    A backend whose module cannot be imported is planned anyway: the runner records its runs as
    skipped with the import error, which the report shows.
    """
    if not is_registered(backend):
        return False
    try:
        valid = renderers.option_names(renderers.backend_class(backend))
    except Exception:  # noqa: BLE001 - import failure: let the runner record the reason
        return True
    return valid is None or set(options) <= set(valid)


def missing_options(backend, *options):
    """``[(what, reason)]`` for options of ``backend`` that it does not take."""
    if not is_registered(backend):
        return []
    try:
        valid = renderers.option_names(renderers.backend_class(backend))
    except Exception:  # noqa: BLE001
        return []
    if valid is None:
        return []
    return [(f"{backend} option {o!r}", f"backend {backend!r} has no option {o!r} (options: {', '.join(valid)})")
            for o in options if o not in valid]


CONTROLS = frozenset({"sphere", "constant_cube", "checkerboard", "fbm_control"})
"""Symmetric controls: viewed with plain orbit angles (their up axis means nothing)."""


def z_up(name):
    """Whether data set ``name`` stores its body axis along z (heads, brains, the engine)."""
    return name not in CONTROLS and datasets.get(name).up_axis == "z"


def upright_view(view, azimuth, elevation=0.0):
    """The camera override that sees a z-up volume (untransformed) as an upright one at these angles.

    The gallery rotates such volumes by :data:`~pipeline.experiments.volbench.UPRIGHT` (scanner z
    up, the face to +z); here the volume keeps its own frame and the camera moves instead, with
    ``up`` along the scanner's z. Azimuth turns about the body axis, as the thesis's Fig. 5.3
    turntable does.
    """
    a, e = math.radians(azimuth), math.radians(elevation)
    upright = (math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a))  # y up, face +z
    x, y, z = upright[0], -upright[2], upright[1]  # scanner frame: z up, face −y
    el = math.degrees(math.asin(max(-1.0, min(1.0, y))))
    az = math.degrees(math.atan2(x, z)) if math.hypot(x, z) > 1e-12 else 0.0
    return {"view": view, "azimuth": round(az, 6), "elevation": round(el, 6), "up": [0.0, 0.0, 1.0]}


def dataset_view(dataset, view, azimuth, elevation=0.0):
    """A view of ``dataset`` at orbit angles of its upright rendering."""
    if z_up(dataset):
        return upright_view(view, azimuth, elevation)
    return {"view": view, "azimuth": float(azimuth), "elevation": float(elevation)}


def headline_view(dataset):
    """The gallery's headline view (30° yaw, 20° pitch) of ``dataset``."""
    return dataset_view(dataset, HEADLINE_VIEW["view"], HEADLINE_VIEW["azimuth"], HEADLINE_VIEW["elevation"])


def numeric(frame, column):
    """``frame[column]`` as floats (NaN where missing); :class:`MissingColumn` (a KeyError) if absent."""
    if column not in frame:
        raise MissingColumn(column)
    return pd.to_numeric(frame[column], errors="coerce")


def text_column(frame, column):
    if column not in frame:
        raise MissingColumn(column)
    return frame[column].astype(str)


def rows_matching(frame, what, **match):
    """The rows of ``frame`` whose tag columns equal ``match`` (compared as text)."""
    rows = frame
    for column, value in match.items():
        rows = rows[text_column(rows, column) == str(value)]
    return rows


def one_row(frame, what, **match):
    """The single row of ``frame`` matching ``match``; ValueError naming ``what`` when none."""
    rows = rows_matching(frame, what, **match)
    if rows.empty:
        raise ValueError(f"no successful run of {what}")
    return rows.iloc[0]


def stage_time(row, stage="total"):
    value = float(row.get(f"time_{stage}", np.nan))
    if not np.isfinite(value):
        raise ValueError(f"run {row.get('run')} reported no {stage!r} time")
    return value


def file_exists(path):
    return isinstance(path, str) and path != "" and Path(path).is_file()


@functools.lru_cache(maxsize=512)


def _read(path, _mtime):
    from reports.imageio import read_image

    return read_image(path)


def read_exr(path):
    """An EXR of the results (cached per file and modification time)."""
    if not file_exists(path):
        raise ValueError(f"image {path!r} is missing")
    return _read(path, Path(path).stat().st_mtime_ns)


def pair_metrics(reference_exr, test_exr):
    """``{"psnr", "ssim", "rmse"}`` between two rendered EXRs (premultiplied RGBA, SSIM over black)."""
    from reports.metrics import psnr, rmse, ssim

    a, b = read_exr(reference_exr), read_exr(test_exr)
    if a.shape != b.shape:
        raise ValueError(f"{test_exr} and {reference_exr} differ in size")
    return {"psnr": float(psnr(a, b)), "ssim": float(ssim(a, b)), "rmse": float(rmse(a, b))}

def fit_line(x, y):
    """Least-squares ``y = slope·x + intercept``: ``(slope, intercept, R²)``."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) < 3 or np.ptp(x) == 0:
        raise ValueError(f"need at least three distinct points to fit a line, got {len(x)}")
    slope, intercept = np.polyfit(x, y, 1)
    residual = y - (slope * x + intercept)
    total = np.sum((y - y.mean()) ** 2)
    r2 = 1.0 - np.sum(residual ** 2) / total if total > 0 else 1.0
    return float(slope), float(intercept), float(r2)

def as_percent(value):
    return f"{format_number(100 * value)} %"


def as_ratio(value):
    return f"×{format_number(value)}"


def not_measurable(items):
    """A paragraph listing what this experiment could not measure here, with the reasons."""
    if not items:
        return []
    return [blocks.Text("Not measurable here: " + "; ".join(f"{what} — {why}" for what, why in items) + ".")]


def speed_points(frame):
    """``time_ms``, ``time_ms_min``, ``time_ms_max`` columns (milliseconds) for speed charts."""
    out = frame.copy()
    out["time_ms"] = numeric(frame, "time_total") * 1e3
    out["time_ms_min"] = pd.to_numeric(frame.get("time_total_min", np.nan), errors="coerce") * 1e3
    out["time_ms_max"] = pd.to_numeric(frame.get("time_total_max", np.nan), errors="coerce") * 1e3
    return out


def ok_rows(results):
    return results[results.status == "ok"].copy() if "status" in results else results.copy()
