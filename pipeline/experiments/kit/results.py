"""Reading an experiment's tidy results: columns, rows, times, images, with errors that name what is missing.

A claim's check and a report section read the experiment's rows of ``runs.csv`` (one row per run and
view); these helpers raise :class:`MissingColumn` (a ``KeyError``) for a column no run reported and
``ValueError`` naming the run that is missing, which a claim turns into "not measured" and
:mod:`~pipeline.experiments.kit.verdicts` into "blocked" where a run that should have happened did not.
"""

import functools
import re
from pathlib import Path

import numpy as np
import pandas as pd


class MissingColumn(KeyError):
    """A check needs a column no run of its frame reported (``column`` names it)."""

    def __init__(self, column):
        super().__init__(f"column {column!r} (no run reported it)")
        self.column = column


def compact(frame):
    """``frame`` with its text columns as Python objects, in a few consolidated blocks.

    pandas 3 keeps every column of its string dtype in a block of its own, so selecting rows of a
    ``runs.csv`` of 570 columns copied 570 blocks: the report's and the tables' thousands of selections
    took most of their time. Object columns share one block; their values (text, NaN) are the same.
    """
    text = {column: object for column in frame.columns if isinstance(frame[column].dtype, pd.StringDtype)}
    return (frame.astype(text) if text else frame).copy()


def ok_rows(results):
    """The rows of runs that succeeded."""
    return results[results.status == "ok"].copy() if "status" in results else results.copy()


def numeric(frame, column):
    """``frame[column]`` as floats (NaN where missing); :class:`MissingColumn` if absent."""
    if column not in frame:
        raise MissingColumn(column)
    return pd.to_numeric(frame[column], errors="coerce")


def text_column(frame, column):
    """``frame[column]`` as text; :class:`MissingColumn` if absent."""
    if column not in frame:
        raise MissingColumn(column)
    return frame[column].astype(str)


def rows_matching(frame, what, **match):
    """The rows of ``frame`` whose tag columns equal ``match``: a number compared as a number, anything else as
    text. ``runs.csv`` holds an integer tag as a float where another experiment leaves its column empty
    (``8.0``), which compared as text would match nothing."""
    rows = frame
    for column, value in match.items():
        if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_)):
            rows = rows[numeric(rows, column) == value]
        else:
            rows = rows[text_column(rows, column) == str(value)]
    return rows


def nonempty(found, *, what=None):
    """``found``, the rows or the scenes a selection found, unless it found none.

    Parameters
    ----------
    found : pandas.DataFrame or sequence
    what : str, optional
        What was looked for, in words (``"seismic at 512²"``), for the error.

    Raises
    ------
    ValueError
        ``found`` is empty: "no successful run of ``what``" (``"no successful run"`` without ``what``), which a
        claim turns into "not measured".
    """
    if found.empty if isinstance(found, pd.DataFrame) else not len(found):
        raise ValueError("no successful run" + (f" of {what}" if what else ""))
    return found


def complete_groups(frame, configs, *, by, missing):
    """The rows of every one of ``configs`` (their ``config`` tag), for each value of the tag ``by`` where all rendered.

    Parameters
    ----------
    frame : pandas.DataFrame
        The experiment's successful rows.
    configs : iterable of str
        The configurations a claim compares.
    by : str
        The tag they are compared within: ``"scene"``, ``"dataset"``.
    missing : str
        The error's message where no value of ``by`` has them all.

    Returns
    -------
    dict
        ``{value: {config: rows}}``, values in the order they first appear.

    Raises
    ------
    ValueError
        No value of ``by`` has a row of every configuration: the claim is not measured.
    """
    groups = {}
    for value in pd.unique(text_column(frame, by)):
        part = frame[text_column(frame, by) == value]
        rows = {config: part[text_column(part, "config") == config] for config in configs}
        if not any(r.empty for r in rows.values()):
            groups[value] = rows
    if not groups:
        raise ValueError(missing)
    return groups


def one_row(frame, what, **match):
    """The single row of ``frame`` matching ``match``; ValueError naming ``what`` when none."""
    rows = rows_matching(frame, what, **match)
    if rows.empty:
        raise ValueError(f"no successful run of {what}")
    return rows.iloc[0]


def stage_time(row, stage="total"):
    """A row's median time of ``stage`` in seconds; ValueError naming the run where it reported none."""
    value = float(row.get(f"time_{stage}", np.nan))
    if not np.isfinite(value):
        raise ValueError(f"run {row.get('run')} reported no {stage!r} time")
    return value


def speed_points(frame):
    """``time_ms``, ``time_ms_min``, ``time_ms_max`` columns (milliseconds) for speed charts."""
    out = frame.copy()
    out["time_ms"] = numeric(frame, "time_total") * 1e3
    out["time_ms_min"] = pd.to_numeric(frame.get("time_total_min", np.nan), errors="coerce") * 1e3
    out["time_ms_max"] = pd.to_numeric(frame.get("time_total_max", np.nan), errors="coerce") * 1e3
    return out


def stage_points(frame, stage, *, name):
    """``frame`` with the median, fastest and slowest frame of column ``stage`` in milliseconds, for a chart.

    Parameters
    ----------
    frame : pandas.DataFrame
        The runs' rows, with ``stage`` (seconds) and, where timed, ``<stage>_min`` and ``<stage>_max``.
    stage : str
        The time column, ``"time_warp"`` say (:func:`speed_points` does ``"time_total"``).
    name : str
        The new columns' name: ``name``, ``<name>_min`` and ``<name>_max`` (NaN where a frame range is absent).

    Returns
    -------
    pandas.DataFrame
        A copy of ``frame`` with the three columns.
    """
    out = frame.copy()
    out[name] = numeric(frame, stage) * 1e3
    for end in ("min", "max"):
        out[f"{name}_{end}"] = pd.to_numeric(frame.get(f"{stage}_{end}", np.nan), errors="coerce") * 1e3
    return out


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


def role_rows(ok, role="test"):
    """The rows of ``ok`` (successful runs) of runs in ``role`` (their ``role`` tag), none where no run has one."""
    return ok[text_column(ok, "role") == role].copy() if "role" in ok else ok.iloc[:0]


def reference_exr(results, row):
    """The EXR of ``row``'s reference run, same view (``None`` if it did not render)."""
    match = results[(results.run == row.reference) & (results.view == row.view) & (results.status == "ok")]
    return match.exr.iloc[0] if not match.empty else None


def pair_metrics(reference_exr, test_exr):
    """``{"psnr", "ssim", "rmse"}`` between two rendered EXRs (premultiplied RGBA, SSIM over black)."""
    from reports.metrics import psnr, rmse, ssim

    a, b = read_exr(reference_exr), read_exr(test_exr)
    if a.shape != b.shape:
        raise ValueError(f"{test_exr} and {reference_exr} differ in size")
    return {"psnr": float(psnr(a, b)), "ssim": float(ssim(a, b)), "rmse": float(rmse(a, b))}


FOOTPRINT_ALPHA = 1 / 255
"""A pixel is in the object's footprint where either image's opacity exceeds one 8-bit step."""


def footprint_psnr(reference_exr, test_exr):
    """PSNR (premultiplied RGBA) over the object's footprint: the pixels either image covers.

    The whole frame's PSNR counts the empty background as perfect, and a wider field of view with the
    camera framing the volume shrinks the object on the image: the whole-frame PSNR then rises as the
    error per covered pixel grows. Over the footprint it measures the error where there is something.

    Parameters
    ----------
    reference_exr, test_exr : str or pathlib.Path
        The two rendered images (same size).

    Raises
    ------
    ValueError
        The images differ in size, or neither covers a pixel (:data:`FOOTPRINT_ALPHA`).
    """
    from reports.metrics import psnr  # here: the metrics import SciPy, which planning the experiments never needs

    a, b = read_exr(reference_exr), read_exr(test_exr)
    if a.shape != b.shape:
        raise ValueError(f"{test_exr} and {reference_exr} differ in size")
    covered = (a[..., 3] > FOOTPRINT_ALPHA) | (b[..., 3] > FOOTPRINT_ALPHA)
    if not covered.any():
        raise ValueError(f"{reference_exr} and {test_exr} cover no pixel")
    return psnr(a[covered][np.newaxis], b[covered][np.newaxis])


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


def view_angle(view):
    """The angle a view's name ends with, in degrees (``"az22.5"`` → 22.5, ``"deg090"`` → 90).

    Parameters
    ----------
    view : str
        A view's name, as the turntables of the experiments name them.

    Raises
    ------
    ValueError
        The name ends with no number.
    """
    match = re.search(r"(-?\d+(?:\.\d+)?)$", str(view))
    if not match:
        raise ValueError(f"view {view!r} names no angle")
    return float(match.group(1))


def tagged(ok, **match):
    """The rows of ``ok`` whose tags equal ``match`` (compared as text), none where a tag's column is absent.

    Parameters
    ----------
    ok : pandas.DataFrame
        An experiment's successful rows.
    **match
        Tag columns and their values (``backend="gl-isbvr"``, ``role="test"``).

    Returns
    -------
    pandas.DataFrame
        The matching rows; empty (with ``ok``'s columns) where ``ok`` lacks a column of ``match``, so that a page
        of runs that never ran shows nothing rather than failing.
    """
    return rows_matching(ok, "", **match) if set(match) <= set(ok.columns) else ok.iloc[:0]


def interleave_groups(frame, **match):
    """``{interleave group: rows}`` of the rows of ``frame`` whose tags equal ``match``, groups in the order they
    first appear.

    Parameters
    ----------
    frame : pandas.DataFrame
        An experiment's successful rows, with the ``interleave`` column (:attr:`~.model.Run.interleave`).
    **match
        Tag columns and their values (compared as text, :func:`rows_matching`).

    Returns
    -------
    dict
        Each group's name and its rows: the runs timed together in one job (the points of a sweep).
    """
    rows = rows_matching(frame, "the sweep", **match)
    names = text_column(rows, "interleave")
    return {name: rows[names == name] for name in pd.unique(names)}


def nonempty_or(found, message):
    """``found``, the rows, values or decisions a check gathered, unless it gathered none.

    :func:`nonempty` words its error as a missing run; this one says what ``message`` says (``"fewer than three
    task sizes swept"``), for the checks whose missing input is not a run.

    Parameters
    ----------
    found : pandas.DataFrame, sequence or mapping
    message : str
        The error's whole message.

    Raises
    ------
    ValueError
        ``found`` is empty: ``message``, which a claim turns into "not measured".
    """
    if found.empty if isinstance(found, pd.DataFrame) else not len(found):
        raise ValueError(message)
    return found
