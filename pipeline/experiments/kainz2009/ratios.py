"""This paper's timing claims: ratios of runs timed together, each judged with its bootstrap interval.

Every timing claim of these experiments compares runs of one interleave group
(:attr:`~pipeline.experiments.kit.model.Run.interleave`): their timed frames alternate, so a ratio of
two of them is resampled round by round (:mod:`pipeline.experiments.kit.intervals`) and a claim whose
interval straddles its bound is inconclusive. Two scopes are compared, each like with like:

* :data:`TECHNIQUE` between runs of cl-tiled: its kernels (binning, fragment count, pixel kernel),
  the paper's frame, whose host sends only the camera; not our per-frame Python and uploads;
* :data:`TOTAL` between cl-tiled and the peelers: OpenCL profiling events and OpenGL pass timers
  measure different scopes (a peeler's host loop, which waits on a query after every layer, is
  outside its passes), so only whole frames compare.
"""

import pandas as pd

from pipeline.experiments.kainz2009.methods import METHOD_NAMES, TILED, devices
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import all_of, ratio
from pipeline.experiments.kit.pages import format_number
from pipeline.experiments.kit.results import numeric, rows_matching

TECHNIQUE = "time_technique"
TOTAL = "time_total"

KERNELS = "cl-tiled's kernels, time_technique"
"""How :data:`TECHNIQUE` is named in a claim's ``expected`` text."""

FRAMES = "whole frames, time_total"
"""How :data:`TOTAL` is named in a claim's ``expected`` text."""


def timed(df, what, column, **match):
    """The rows of ``df`` matching ``match`` that have a ``column`` time; ValueError naming ``what`` if none."""
    rows = rows_matching(df, what, **match)
    rows = rows[numeric(rows, column).notna()]
    if rows.empty:
        raise ValueError(f"no {column} of {what}")
    return rows


def point(rows, column, statistic="median"):
    """``statistic`` of the rows' ``column`` (their median frames)."""
    return float(intervals.REDUCE[statistic](numeric(rows, column).dropna().to_numpy()))


def draws(rows, column, resampler, statistic="median"):
    """Bootstrap draws of :func:`point` (``None`` where a row kept no frames)."""
    return intervals.statistic_draws(rows, column, statistic, resampler)


def frame_ratios(df, scenes, top, bottom, *, what, **bounds):
    """``top``'s whole frame over ``bottom``'s (two configs, one of them cl-tiled) on every one of ``scenes`` both
    render, each judged against ``bounds`` with its interval; ``what`` says the ratio in the detail, before the
    devices the two ran on."""
    resampler = intervals.Resampler()
    decisions, compared = {}, []
    for name in scenes:
        pair = [rows_matching(df, name, scene=name, role="test", config=config) for config in (top, bottom)]
        pair = [part[numeric(part, TOTAL).notna()] for part in pair]
        if not any(part.empty for part in pair):
            decisions[name] = ratio(*pair, TOTAL, resampler, **bounds)
            compared += pair
    if not decisions:
        peer = METHOD_NAMES[bottom if top == TILED else top]
        raise ValueError(f"no scene of {', '.join(scenes)} rendered by both {peer} and cl-tiled")
    return all_of(decisions, extra=f"{what}; {devices(pd.concat(compared))}")


def counts(rows, column, label="scene"):
    """``"C1: 1.05e+06, C8: 7.05e+06"``: a counter of each row (samples, fragments: they do not depend on the
    machine) for a claim's detail, beside its times; ``"n/a"`` where no run reported it."""
    if column not in rows:
        return "n/a"
    values = pd.to_numeric(rows[column], errors="coerce")
    names = [int(n) if isinstance(n, float) and n.is_integer() else n for n in rows[label]]  # 1000.0 read back
    return ", ".join(f"{name}: {format_number(value)}" for name, value in zip(names, values))
