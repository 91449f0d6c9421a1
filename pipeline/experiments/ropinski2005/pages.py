"""What the lens experiments' pages share: their runs and their tables of every run, frame times, ratios with
their intervals as table columns, the notes under their pictures and the overhead figure."""

import numpy as np
import pandas as pd

from pipeline.experiments.kit.judging import median_count
from pipeline.experiments.kit.pages import figure, format_number, linked_table
from pipeline.experiments.kit.results import numeric, ok_rows, role_rows, rows_matching, speed_points, text_column
from pipeline.experiments.ropinski2005.methods import scenes_of
from reports import blocks, plots

CI = ("95 % CI low", "95 % CI high")
"""The columns of an interval's ends in the pages' tables."""

PERCENT_CI = ("95 % CI low (%)", "95 % CI high (%)")
"""The columns of an interval's ends in % (of the lens-off frame, of the frame without the occluder)."""

RUN_COLUMNS = {"config": "method", "count_samples": "samples", "count_samples_region0": "region₀ samples",
               "count_samples_region1": "region₁ samples", "count_samples_region2": "region₂ samples",
               "count_rays": "rays", "count_lens_rays": "rays through the lens"}
"""The names of the runs' columns in the tables of every run (where the table names them no other way)."""


def tests_of(results):
    return role_rows(ok_rows(results))


def headline(frame):
    return frame[text_column(frame, "view") == "headline"]


def scene_by_scene(frame, chosen):
    """``chosen(here)`` of each scene's rows ``here`` of ``frame``, one scene after another in their order."""
    parts = [chosen(rows_matching(frame, scene, scene=scene)) for scene in scenes_of(frame)]
    return pd.concat(parts) if parts else frame


def run_table(frame, columns, ctx, *, csv_name, timed=True, method=None, names=None, **options):
    """The table "Every run (headline view)": ``columns`` of ``frame``'s headline rows, each linked to its run, with
    the frame times in ms where ``timed``, a column ``method(config)`` where given, and ``names`` beside
    :data:`RUN_COLUMNS`; ``options`` go to :func:`~pipeline.experiments.kit.pages.linked_table`."""
    rows = speed_points(headline(frame)) if timed else headline(frame)
    if method is not None:
        rows = rows.assign(method=[method(c) for c in text_column(rows, "config")])
    return linked_table("Every run (headline view)", rows, columns, ctx, csv_name=csv_name,
                        names={**RUN_COLUMNS, **(names or {})}, **options)


def rounded_table(title, frame, *, digits=3, **options):
    """``[Table]`` of ``frame`` rounded to ``digits`` decimals (``options``: the table's), or ``[]`` without a row."""
    return [] if frame.empty else [blocks.Table(title, frame.round(digits), **options)]


def median_ms(rows):
    return 1e3 * numeric(rows, "time_total").median()


def samples_ratio(lens, off):
    return median_count(lens, "count_samples") / median_count(off, "count_samples")


def region_samples(rows):
    """``{"region2 samples": …, "region1 samples": …, "region0 samples": …}``: each region's median count."""
    return {f"region{i} samples": median_count(rows, f"count_samples_region{i}") for i in (2, 1, 0)}


def interval_columns(value, interval, name, *, ends=CI, scale=lambda v: v):
    """``{name: value, low: …, high: …}`` of a ratio and its interval's ``ends`` (NaN without one), via ``scale``."""
    low, high = interval or (np.nan, np.nan)
    return {name: scale(value), ends[0]: scale(low), ends[1]: scale(high)}


def psnr_note(row):
    return f"PSNR {format_number(getattr(row, 'psnr', np.nan))} dB"


def overhead_figure(points, ctx, name, *, heading, caption, **options):
    """A figure of each point's overhead (%) with its interval, one line per ``series`` of ``points``; ``options``
    go to :func:`reports.plots.lines` (``x``, its label, the title)."""
    return [figure(ctx, name, plots.lines, points, heading=heading, caption=caption, y="overhead (%)",
                   group="series", y_range=PERCENT_CI, y_label="overhead, t(lens) / t(no lens) − 1 (%)", **options)]
