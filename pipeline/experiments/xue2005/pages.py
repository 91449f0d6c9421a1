"""What the paper's pages share: rows of one kind, scenes in their order, what a page shows only where its runs are,
the table of every run."""

import functools

import pandas as pd

from pipeline.experiments.kit.pages import linked_table
from pipeline.experiments.kit.results import numeric, rows_matching

STAGE_MS = {"init_ms": "time_init", "draw_ms": "time_draw", "time_ms": "time_total"}
"""The run table's stage times in milliseconds and the columns they come from."""


def tagged(ok, **match):
    """The rows of ``ok`` whose tags equal ``match`` (as text); none where a tag's column is absent."""
    return rows_matching(ok, "", **match) if set(match) <= set(ok.columns) else ok.iloc[:0]


def unless_missing(compute, *args, empty, **options):
    """``compute(*args, **options)``, or ``empty`` where the runs it needs are missing (a KeyError or ValueError)."""
    try:
        return compute(*args, **options)
    except (KeyError, ValueError):
        return empty


def silent_without_runs(sentences):
    """``sentences``, a function of take-aways, saying none where the runs it reads are missing."""
    @functools.wraps(sentences)
    def said(*args, **options):
        return unless_missing(sentences, *args, empty=[], **options)
    return said


def by_scene(rows, *within):
    """``rows`` with the scenes in the order they first appear, sorted by the columns ``within`` inside a scene."""
    first = {name: i for i, name in enumerate(pd.unique(rows.scene))}
    return rows.assign(scene_order=rows.scene.map(first)).sort_values(["scene_order", *within], kind="stable")


def runs_table(ok, ctx, columns):
    """The page's table of every run: ``columns`` (column: its name), stage times of :data:`STAGE_MS` in ms."""
    runs = ok.assign(**{ms: numeric(ok, stage) * 1e3 for ms, stage in STAGE_MS.items() if ms in columns})
    return linked_table("Runs", runs, list(columns), ctx, names=columns)
