"""Report pages: claim take-aways, linked tables, numbers in words, one difference scale.

Words with a sign go through one helper each, so that no page says "-8.69 % slower":
:func:`change_words` for ratios ("8.69 % faster", "×14.9 slower"), :func:`db_words` for differences in
dB ("2 dB less"); :func:`setting_words` says a backend's options as words ("step 0.5 voxel").

Every experiment's ``report`` builds its blocks (:mod:`reports.blocks`) with these, so that every
page links a number to its run the same way and draws every difference map on :data:`DIFF_SCALE`.
"""

import functools

import numpy as np
import pandas as pd

from datasets.registry import DATASETS
from pipeline.experiments.kit.results import reference_exr
from pipeline.experiments.kit.verdicts import claim_sentences
from pipeline.experiments.kit.words import as_percent, as_ratio, format_number
from reports import blocks
from reports.decision import device_family
from reports.takeaways import change_words, db_words, setting_words

__all__ = ["DIFF_SCALE", "as_percent", "as_ratio", "change_words", "claim_evidence", "claim_takeaways", "db_words",
           "device_takeaways", "difference_gallery", "figure", "format_number", "frame_note", "frames_caption",
           "frames_counted", "frames_note", "GL_TIMING", "gl_timing_words", "gl_devices", "linked_table", "links",
           "ms", "not_measurable", "setting_words", "title_or"]

DIFF_SCALE = 0.1
"""Absolute error at the top of every difference image's colour map, on every page (one stated scale)."""

LINKS = {"record": "JSON", "EXR": "EXR"}
"""The link columns of a run table (:func:`links`) and the text of their links."""

METRICS = {"rmse": "RMSE", "psnr": "PSNR (dB)", "ssim": "SSIM", "flip": "FLIP"}
"""Metric columns and their names in the report's tables."""

TIME_COLUMNS = {"time_ms": "median frame (ms)", "time_ms_min": "fastest (ms)", "time_ms_max": "slowest (ms)"}
"""The columns :func:`~pipeline.experiments.kit.results.speed_points` makes, named for a table."""


def ms(frame, column="time_total"):
    """Median, fastest and slowest frame of ``column`` in milliseconds, as three columns."""
    out = pd.DataFrame(index=frame.index)
    out["time (ms)"] = frame[column] * 1e3
    for end, name in (("min", "fastest (ms)"), ("max", "slowest (ms)")):
        out[name] = frame[f"{column}_{end}"] * 1e3 if f"{column}_{end}" in frame else np.nan
    return out


def links(frame, ctx):
    """Columns ``record`` and ``EXR``: each row's run record and image, copied into the report."""
    linked = ctx.run_links(frame.reindex(columns=["record", "exr"]))
    return linked.rename(columns={"exr": "EXR"})


def linked_table(title, frame, columns, ctx, *, names=None, **options):
    """A table of ``columns`` (those ``frame`` has, named by ``names``), each row linked to its run."""
    columns = [c for c in columns if c in frame]
    table = frame[columns].rename(columns={**TIME_COLUMNS, **METRICS, **(names or {})}).reset_index(drop=True)
    table = pd.concat([table, links(frame.reset_index(drop=True), ctx)], axis=1)
    return blocks.Table(title, table, links=LINKS, **options)


def figure(ctx, name, plot, frame, *, heading, caption, **options):
    """``plot(frame, path, **options)`` (a chart of :mod:`reports.plots`) drawn as the page's plot ``name``, as a
    figure with ``heading`` and ``caption``."""
    path, rel = ctx.plot_path(name)
    plot(frame, path, **options)
    return blocks.Figure(heading, rel, caption)


def frame_note(row, *, psnr="PSNR"):
    """A gallery picture's note: its median frame time and, where measured, ``psnr`` (its PSNR's name) in dB."""
    value = getattr(row, "psnr", np.nan)
    shown = f", {psnr} {format_number(value)} dB" if pd.notna(value) else ""
    return f"{format_number(row.time_total * 1e3)} ms{shown}"


def difference_gallery(title, rows, ctx, *, label, caption="", against=None, note=frame_note):
    """A gallery of ``rows``' pictures in their order, each with its difference on the one scale :data:`DIFF_SCALE`.

    Parameters
    ----------
    title, caption : str
        The gallery's heading and what its pictures show.
    rows : pandas.DataFrame
        The runs' views to show (``png``, ``exr``).
    ctx : reports.html.ReportContext
    label : callable
        ``label(row)``: the words under a picture (``"head, RC-b"``).
    against : pandas.DataFrame or callable, optional
        What each difference is taken against: the experiment's results (each row's reference run, same
        view: :func:`~pipeline.experiments.kit.results.reference_exr`), or ``against(row)`` giving an EXR
        path or ``None`` (no difference beside that picture). ``None``: pictures only.
    note : callable
        ``note(row)``: the smaller line under a picture (default :func:`frame_note`).
    """
    if isinstance(against, pd.DataFrame):
        results = against
        against = lambda row: reference_exr(results, row)  # noqa: E731
    gallery = blocks.Gallery(title, caption=caption, diff_scale=DIFF_SCALE if against is not None else None)
    for row in rows.itertuples():
        difference = ctx.difference(against(row), row.exr, DIFF_SCALE) if against is not None else None
        gallery.items.append(blocks.GalleryItem(label(row), ctx.image(row.png), difference=difference,
                                                note=note(row)))
    return gallery


def frames_note(row):
    """How a run was timed, in words: "single untimed frame" when there was one frame and no warm-up."""
    frames, warmup = getattr(row, "info_frames", np.nan), getattr(row, "info_warmup", np.nan)
    if frames == 1 and warmup == 0:
        return "single untimed frame"
    if pd.notna(frames):
        if warmup == 0:  # the first frame compiled nothing and the next agreed with it (pipeline.timing)
            return f"median of {int(frames)} frames after the first frame"
        return f"median of {int(frames)} frames after {int(warmup) if pd.notna(warmup) else '?'} warm-up"
    return ""


def frames_counted(frame, *, unit="frames"):
    """``"median of N frames"`` from the runs' ``info_frames`` (``"median frame"`` where none says)."""
    frames = pd.to_numeric(frame["info_frames"], errors="coerce") if "info_frames" in frame else pd.Series(dtype=float)
    return f"median of {int(frames.median())} {unit}" if frames.notna().any() else "median frame"


GL_TIMING = {"query": "passes timed on the device with GL timer queries",
             "finish": "each pass timed by waiting for it (glFinish): a software rasterizer's timer queries do not "
                       "cover its deferred work"}
"""How the GL backends time their passes (their ``timing`` option, as it took effect), in words."""


def gl_timing_words(frame):
    """How the GL runs of ``frame`` timed their passes (:data:`GL_TIMING`, from ``option_effective_timing``)."""
    methods = set(frame.option_effective_timing.dropna()) if "option_effective_timing" in frame else set()
    return "; ".join(GL_TIMING.get(m, f"passes timed by {m!r}") for m in sorted(methods)) or "timing method not recorded"


def frames_caption(frame, *, untimed="uploads excluded as their own stage", how=None, unit="frames"):
    """How the frames of ``frame`` were timed, for a figure's caption: frames counted, what was not timed, how.

    ``untimed``: what the timed frames leave out, in words; ``how``: how the stages were timed (default: the GL
    backends' timing method, :func:`gl_timing_words`); ``unit``: what was counted.
    """
    how = gl_timing_words(frame) if how is None else how
    return f"{frames_counted(frame, unit=unit)} after warm-up, {untimed}; {how}."


def not_measurable(items):
    """A paragraph listing what this experiment could not measure here, with the reasons."""
    if not items:
        return []
    return [blocks.Text("Not measurable here: " + "; ".join(f"{what} — {why}" for what, why in items) + ".")]


def claim_takeaways(ctx, *more):
    """The take-aways block of a section: each judged claim in a sentence, as ``claims.csv`` says, then ``more``.

    ``ctx`` is the report's context of the experiment: it carries the experiment's claims as judged
    (:func:`~pipeline.experiments.kit.verdicts.claim_sentences`); a claim blocked by a run that did
    not happen gets no sentence.
    """
    return blocks.Takeaways(claim_sentences(ctx.claims) + [s for sentences in more for s in sentences])


def gl_devices(frame):
    """The GL device each row was timed on (VTK's own context for its rows; ``"unknown device"`` if unrecorded)."""
    device = frame.get("gl_renderer", pd.Series(np.nan, index=frame.index))
    if "vtk_gl_renderer" in frame:
        device = device.fillna(frame.vtk_gl_renderer)
    return device.fillna("unknown device").astype(str)


def per_gl_device(frame, table):
    """``table(rows)`` for the rows of each GL device (:func:`gl_devices`), one table with a ``device`` column.

    Parameters
    ----------
    frame : pandas.DataFrame
        Timed rows.
    table : callable
        Makes a page table (a DataFrame) of one device's rows.

    Returns
    -------
    pandas.DataFrame
        The devices' tables one after another; empty where ``frame`` is.
    """
    tables = [table(rows).assign(device=device) for device, rows in frame.groupby(gl_devices(frame))]
    return pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()


def device_takeaways(tests, *, software):
    """Which GL devices timed a page, in a sentence; ``software`` says what a CPU rasterizer's numbers mean
    for this paper (added when every timed row ran on one)."""
    if tests.empty:
        return []
    names = sorted(set(gl_devices(tests)))
    sentence = f"Frame times on this page were measured on {', '.join(names)}"
    if "gl_software_rasterizer" in tests and tests.gl_software_rasterizer.dropna().astype(bool).all():
        sentence += f", a CPU rasterizer: {software}"
    elif len(names) > 1:
        sentence += "; ratios are computed per device, never across devices"
    return [sentence + "."]


def claim_evidence(verdict, rows):
    """What ``claims.csv`` carries for :func:`reports.takeaways.likely_cause`, from a claim's
    :class:`~pipeline.experiments.kit.verdicts.Verdict` and its experiment's ``rows``.

    Returns ``{"disturbed_views": n, "software_rasterizer": names, "stand_in": phantoms}``: how many
    disturbed views the verdict rests on, the CPU rasterizers that timed the
    experiment's GL backends' runs, and its phantoms that stand in for a paper's data set (the registry gives
    them the original's statistics as targets: :attr:`datasets.registry.DatasetSpec.targets_by_preset`)
    where it reads no real scan; empty text where none.
    """
    ok = rows[rows.status == "ok"] if "status" in rows else rows
    software = ""
    # Every run records the machine's GL device; only the GL backends' frames are timed on it.
    gl = ok[[device_family(str(b)) == "gl" for b in ok.backend]] if "backend" in ok else ok
    if {"gl_software_rasterizer", "gl_renderer"} <= set(gl.columns):
        cpu = gl[gl.gl_software_rasterizer.astype("boolean").fillna(False).astype(bool)]
        software = ", ".join(sorted(set(cpu.gl_renderer.dropna().astype(str))))
    names = sorted(set(ok.dataset.dropna().astype(str))) if "dataset" in ok else []
    stand_ins = [n for n in names if n in DATASETS and DATASETS[n].kind == "phantom" and DATASETS[n].targets_by_preset]
    if any(n in DATASETS and DATASETS[n].kind != "phantom" for n in names):
        stand_ins = []  # the claim reads a real scan too: a phantom does not explain its verdict
    return {"disturbed_views": verdict.disturbed_views, "software_rasterizer": software,
            "stand_in": _stand_in_words(stand_ins)}


def _stand_in_words(names):
    if not names:
        return ""
    shown = ", ".join(names[:2]) + (f" and {len(names) - 2} more" if len(names) > 2 else "")
    return f"{shown} standing in for the paper's data"


def title_or(make, data, fallback, *, errors=(KeyError, ValueError)):
    """A chart title built from the results, or ``fallback`` where they cannot say it.

    Parameters
    ----------
    make : callable
        ``make(data)``: the title, from a claim's result say.
    data : pandas.DataFrame
        What ``make`` reads.
    fallback : str
        The title where ``make`` raises one of ``errors`` (a run or a column it needs is missing).
    errors : tuple of type
        The exceptions that mean "not measurable"; any other propagates.
    """
    try:
        return make(data)
    except errors:
        return fallback


def unless_missing(compute, *args, empty, **options):
    """``compute(*args, **options)``, or ``empty`` where the runs it reads are missing.

    Parameters
    ----------
    compute : callable
        What a page shows from the results: a table, its rows, take-aways.
    *args, **options
        ``compute``'s arguments.
    empty
        What the page shows instead where ``compute`` raises ``KeyError`` or ``ValueError`` (a run or a column it
        needs is missing): an empty table, no sentence.
    """
    try:
        return compute(*args, **options)
    except (KeyError, ValueError):
        return empty


def silent_without_runs(sentences):
    """``sentences``, a function of take-aways, made to say none where the runs it reads are missing.

    Parameters
    ----------
    sentences : callable
        Returns a list of sentences; called through :func:`unless_missing` with ``empty=[]``.
    """
    @functools.wraps(sentences)
    def said(*args, **options):
        return unless_missing(sentences, *args, empty=[], **options)
    return said


def by_scene(rows, *within):
    """``rows`` with the scenes in the order they first appear, sorted by the columns ``within`` inside a scene.

    Parameters
    ----------
    rows : pandas.DataFrame
        Rows with a ``scene`` column (a gallery's pictures).
    *within : str
        Columns that order the rows of one scene (a stable sort: ties keep their order).

    Returns
    -------
    pandas.DataFrame
        The rows reordered, with the scene's rank as ``scene_order``.
    """
    first = {name: i for i, name in enumerate(pd.unique(rows.scene))}
    return rows.assign(scene_order=rows.scene.map(first)).sort_values(["scene_order", *within], kind="stable")


def speed_psnr_figure(ctx, name, frame, *, heading, caption, title, group, label, x_label="median frame time (ms)",
                      **options):
    """Each row's median frame time against its PSNR against the reference, as the page's chart ``name`` (a
    :func:`figure` of :func:`reports.plots.speed_accuracy`), higher and further left better.

    Parameters
    ----------
    ctx : reports.html.ReportContext
    name : str
    frame : pandas.DataFrame
        The rows, with ``time_ms``, ``time_ms_min`` and ``time_ms_max`` (:func:`~.results.speed_points`) and ``psnr``.
    heading, caption, title : str
        The figure's heading and caption, the chart's title.
    group, label : str
        The column whose values are the series, and the one that labels each point.
    x_label : str
        The time axis in words; the chart adds that its bars span the fastest to the slowest frame.
    **options
        More options of the chart (``log_x``).
    """
    from reports import plots  # matplotlib: only when a page draws it

    return figure(ctx, name, plots.speed_accuracy, frame, heading=heading, caption=caption, time_col="time_ms",
                  error_col="psnr", group_col=group, label_col=label, title=title, log_y=False,
                  time_range_cols=("time_ms_min", "time_ms_max"), better="upper left",
                  x_label=f"{x_label}; bars: fastest to slowest frame", y_label="PSNR against the reference (dB)",
                  **options)


def time_lines_figure(ctx, name, frame, *, heading, caption, title, x, group, x_label,
                      y_label="median frame time (ms)", **options):
    """Each row's median frame time against ``x``, one line per ``group`` with bars from the fastest to the slowest
    frame, as the page's chart ``name`` (a :func:`figure` of :func:`reports.plots.lines`).

    Parameters
    ----------
    ctx : reports.html.ReportContext
    name : str
    frame : pandas.DataFrame
        The rows, with ``time_ms``, ``time_ms_min`` and ``time_ms_max`` (:func:`~.results.speed_points`, or
        :func:`~.results.stage_points` named ``"time_ms"``) and the columns ``x`` and ``group``.
    heading, caption, title : str
        The figure's heading and caption, the chart's title.
    x, group : str
        The column along the horizontal axis, and the one whose values are the lines.
    x_label, y_label : str
        The axes in words.
    **options
        More options of the chart (``log_x``, ``guides``, ``vlines``).
    """
    from reports import plots  # matplotlib: only when a page draws it

    return figure(ctx, name, plots.lines, frame, heading=heading, caption=caption, x=x, y="time_ms", group=group,
                  y_range=("time_ms_min", "time_ms_max"), title=title, x_label=x_label, y_label=y_label, **options)


TIMED_CAPTION = ("Time: median frame after warm-up, with the fastest and slowest timed frame. Each row links to its "
                 "run's JSON record and EXR image.")
"""What a :func:`timed_metrics_table` shows, by default."""


def timed_metrics_table(title, frame, columns, ctx, *, by, caption=TIMED_CAPTION, **options):
    """A table of a sweep's every setting: ``columns``, each run's median, fastest and slowest frame (:func:`ms`)
    and its image's metrics against the reference (:data:`METRICS`), each row linked to its run.

    Parameters
    ----------
    title : str
    frame : pandas.DataFrame
        The runs' rows, with ``time_total`` (seconds) and, where timed, ``time_total_min`` and ``time_total_max``.
    columns : list of str
        The columns shown before the times (the scene, the setting).
    ctx : reports.html.ReportContext
    by : list of str
        The columns the rows are sorted by, the times' own (``"time (ms)"``) among those it may name.
    caption : str
        What the table shows: by default how its times were taken and what its links open.
    **options
        More options of :func:`linked_table` (``names``, ``csv_name``).

    Returns
    -------
    reports.blocks.Table
    """
    times = ms(frame)
    table = pd.concat([frame, times], axis=1).sort_values(list(by))
    return linked_table(title, table, [*columns, *times, *METRICS], ctx, caption=caption, **options)
