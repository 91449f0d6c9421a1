"""Figures for the volbench report, written as small, reproducible SVG files.

Every function takes a tidy :class:`pandas.DataFrame` (one row per run and view, as in the results
CSV), writes one SVG and returns its path. The figures are built with matplotlib's object API (no
pyplot, no global state) at about 6 × 4 inches. Reruns give byte-identical files: a fixed
``svg.hashsalt`` makes element ids stable and the date is left out of the metadata. Text stays
text (``svg.fonttype = "none"``), which keeps files small and lets the report search them.

Rows whose plotted values are NaN or infinite, or not positive on a logarithmic axis, are dropped
and the title says how many. A frame with nothing left to plot gives a placeholder figure that
says "no data" instead of an error.

Every figure is laid out for reading (:func:`_tidy`, after the chart is drawn, by measuring the laid-out
text rather than per chart): the title and its note are wrapped to the figure's width, axis labels to
the axes; crowded tick labels are wrapped or rotated (categories) or thinned (numbers); a legend that
would cover data or labels, or has many entries, goes outside the axes; a point label that would
overlap another text or the legend, or leave the figure, is left out and the title's note counts it. Series
take distinct (colour, marker) pairs from 20 colours and 10 markers (see :func:`_style`).

matplotlib is imported where a figure is drawn, not with this module: every experiment module
imports this one, and the jobs that only plan or tabulate runs (each Snakemake start, each
experiment's tabulate job) would otherwise pay 0.4 s for charts they never draw.
"""

from pathlib import Path

import numpy as np
import pandas as pd

from core.errors import InputError

__all__ = ["bar_compare", "convergence", "difference_colorbar", "pareto_fronts", "pareto_mask", "scaling",
           "speed_accuracy", "stage_breakdown"]

FIGSIZE = (6.0, 4.0)
# matplotlib's ten colours, then ten more told apart from them (dark, saturated or light hues).
_PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
            "#17becf", "#000000", "#000080", "#808000", "#800000", "#008080", "#c51b7d", "#e6ab02", "#66a61e",
            "#54278f", "#fb8072")
MIN_AXES_HEIGHT = 150.0  # points: the figure grows where titles and labels leave the axes less
MANY_ENTRIES = 6  # a legend with more entries than this always goes beside the axes
COVER_MARGIN = 2  # px: a data point this near the legend's frame lies under it (a marker's centre on its edge)
_RC = {
    "svg.hashsalt": "volbench",
    "svg.fonttype": "none",
    "font.size": 9,
    "axes.grid": True,
    "grid.alpha": 0.3,
}
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">")
_GUIDES = ("--", ":", "-.")  # line styles of convergence guide lines
# Axis labels in words, with units, for the well-known columns of the results table.
_WORDS = {
    "rmse": "RMSE against the reference (intensity 0–1)",
    "psnr": "PSNR against the reference (dB)",
    "ssim": "SSIM against the reference (1 = identical)",
    "flip": "FLIP error against the reference (0 = identical)",
    "max_error": "largest absolute error (intensity 0–1)",
    "step_factor": "step size (voxels)",
    "step": "step size (voxels)",
    "fps": "frames per second",
    "volume_size": "volume size (voxels along the longest axis)",
    "image_size": "image size (pixels along a side)",
}


def _label(column):
    """Axis label for ``column``: words and unit for known columns, else the name with its unit.

    Timings are seconds (CONVENTIONS, Results) unless the column ends in ``_ms``.
    """
    name = str(column)
    if name.lower() in _WORDS:
        return _WORDS[name.lower()]
    if name.startswith("time"):
        unit = "ms" if name.endswith("_ms") else "s"
        what = name.removeprefix("time_").removesuffix("_ms").replace("_", " ") or "time"
        return f"{'frame' if what == 'total' else what} time ({unit})"
    return name.replace("_", " ")


def _tick_text(value, _position=None):
    """A log-axis tick as a plain number (0.5, 2, 1e-05), never as a power expression."""
    if value <= 0:
        return ""
    return f"{value:g}"


def _readable_log(axis):
    """Log-axis ticks labelled as plain numbers: the decades over a wide range, 1, 2 and 5 × 10^k over a few
    decades, and evenly spaced values where even those leave fewer than two ticks in view (a range within one
    decade, such as 0.3 to 0.45, would otherwise show no label, or matplotlib's own labels in powers of ten)."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, LogLocator, MaxNLocator, NullFormatter

    low, high = sorted(axis.get_view_interval())
    decades = np.log10(high / low) if low > 0 else 99
    subs = (1.0, 2.0, 5.0) if decades <= 3 else (1.0,)
    locator = LogLocator(base=10, subs=subs, numticks=12)
    ticks = locator.tick_values(low, high) if low > 0 else np.array([])
    if low > 0 and np.count_nonzero((ticks >= low) & (ticks <= high)) < 2:
        values = MaxNLocator(nbins=4).tick_values(low, high)
        locator = FixedLocator(values[values > 0])
    axis.set_major_locator(locator)
    axis.set_major_formatter(FuncFormatter(_tick_text))
    axis.set_minor_formatter(NullFormatter())


def _check_frame(df, columns):
    """Check that ``df`` is a DataFrame holding ``columns``."""
    if not isinstance(df, pd.DataFrame):
        raise InputError(f"df: expected a pandas DataFrame, got {type(df).__name__}")
    missing = [c for c in columns if c is not None and c not in df.columns]
    if missing:
        raise InputError(f"df: missing column(s) {missing}; available: {list(df.columns)}")


def _numeric(df, column):
    """Column as float, raising InputError naming it if it is not numeric."""
    try:
        return pd.to_numeric(df[column], errors="raise").astype(float)
    except (TypeError, ValueError):
        raise InputError(f"df: column {column!r} must be numeric") from None


def _clean(df, columns, positive=()):
    """Keep rows whose ``columns`` are finite (and > 0 for ``positive``); return (rows, note)."""
    values = pd.DataFrame({c: _numeric(df, c) for c in columns}, index=df.index)
    finite = np.isfinite(values).all(axis=1)
    positive_ok = (values[list(positive)] > 0).all(axis=1) if positive else finite
    keep = finite & positive_ok
    clean = df.loc[keep].copy()
    clean[list(columns)] = values.loc[keep]
    counts = {"NaN/inf": int((~finite).sum()),
              "non-positive on log axis": int((finite & ~positive_ok).sum())}
    notes = [f"{n} {reason}" for reason, n in counts.items() if n]
    return clean, f"dropped rows: {', '.join(notes)}" if notes else ""


def _groups(df, group_col):
    """Yield (label, rows) per group in order of first appearance (one group if no column)."""
    if group_col is None:
        yield None, df
        return
    keys = df[group_col].astype(str)
    for key in pd.unique(keys):
        yield key, df[keys == key]


def _median_curve(rows, x_col, y_col):
    """Median of ``y_col`` per value of ``x_col``, sorted by x."""
    curve = rows.groupby(x_col, sort=True)[y_col].median()
    return curve.index.to_numpy(float), curve.to_numpy(float)


def _style(index):
    """Colour and marker of the ``index``-th series, a pair no other of the first 200 series has.

    The marker advances one extra place each time the colours come round again; 21 (colours + 1)
    and 10 (markers) share no factor, so the pairs repeat only after 20 × 10 series.
    """
    colours, markers = len(_PALETTE), len(_MARKERS)
    return {"color": _PALETTE[index % colours], "marker": _MARKERS[(index + index // colours) % markers]}


def _text_width(text, size):
    """Width in points of one line of ``text`` at ``size`` points, as the SVG writer measures it."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import text_to_path

    return text_to_path.get_text_width_height_descent(text, FontProperties(size=size), ismath=False)[0]


def _wrap(text, width, size):
    """``text`` broken at spaces into lines at most ``width`` points wide.

    A word longer than a line is cut after its last comma that fits, else between characters.
    """
    lines = []
    for paragraph in str(text).split("\n"):
        line = ""
        for word in paragraph.split(" "):
            candidate = f"{line} {word}" if line else word
            if line and _text_width(candidate, size) > width:
                lines.append(line)
                candidate = word
            while len(candidate) > 1 and _text_width(candidate, size) > width:
                fits = [k for k in range(1, len(candidate)) if _text_width(candidate[:k], size) <= width] or [1]
                cut = next((k for k in reversed(fits) if candidate[k - 1] == ","), fits[-1])
                lines.append(candidate[:cut])
                candidate = candidate[cut:]
            line = candidate
        lines.append(line)
    return "\n".join(lines)


def _layout(fig):
    """Lay ``fig`` out (constrained layout, text measured) without writing it."""
    fig.draw_without_rendering()


TEXT_GAP = 2.0
"""Points kept between texts: a browser's text box (the font's ascent and descent) is about 1 point
taller than the box matplotlib measures."""


def _overlap(a, b, pad=1.0):
    """Whether boxes ``a`` and ``b`` overlap by more than ``pad`` points both ways (a negative ``pad``: come closer than it)."""
    return min(a.x1, b.x1) - max(a.x0, b.x0) > pad and min(a.y1, b.y1) - max(a.y0, b.y0) > pad


def _crowded(boxes):
    """Whether any two of ``boxes`` come closer than ``TEXT_GAP``."""
    return any(_overlap(a, b, pad=-TEXT_GAP) for i, a in enumerate(boxes) for b in boxes[i + 1:])


def _crowded_ticks(labels):
    """Whether tick ``labels`` come closer than ``TEXT_GAP``; rotated ones measured across their slant.

    Rotated labels are parallel: their distance across is the distance between their anchors times
    the sine of the angle, which must exceed a line's height (boxes of slanted text would overlap).
    """
    angle = np.radians(labels[0].get_rotation()) if labels else 0.0
    if not np.sin(angle):
        return _crowded([t.get_window_extent() for t in labels])
    anchors = sorted(t.get_window_extent().x1 for t in labels)  # right-aligned at their ticks
    line = max(t.get_fontsize() * 1.2 * (t.get_text().count("\n") + 1) for t in labels)
    return any((b - a) * abs(np.sin(angle)) < line + TEXT_GAP for a, b in zip(anchors, anchors[1:]))


def _shown_ticklabels(axis, ax):
    """The axis' tick labels with text that lie within the axes' extent along the axis."""
    box, labels = ax.get_window_extent(), []
    for label in axis.get_ticklabels():
        if not (label.get_visible() and label.get_text()):
            continue
        extent = label.get_window_extent()
        middle, (low, high) = ((extent.x0 + extent.x1) / 2, (box.x0, box.x1)) if axis is ax.xaxis else \
            ((extent.y0 + extent.y1) / 2, (box.y0, box.y1))
        if low - 1 <= middle <= high + 1:
            labels.append(label)
    return labels


def _fix_ticks(fig, ax):
    """Wrap, rotate or thin the tick labels of each axis until no two overlap; leaves ``fig`` laid out.

    Category labels (fixed texts) are wrapped to the space between ticks where their words fit in
    three lines, else rotated 30°, 45°, 90° (a y axis' categories wrap to 40 % of the figure's width); numbers keep fewer ticks:
    only decades on a logarithmic axis, then fewer decades, fewer steps on a linear one.
    """
    from matplotlib.category import StrCategoryLocator
    from matplotlib.ticker import FixedLocator

    original = {}
    for axis in (ax.xaxis, ax.yaxis):
        categorical = isinstance(axis.get_major_locator(), (FixedLocator, StrCategoryLocator))  # texts at fixed places
        texts = [t.get_text() for t in axis.get_ticklabels()]
        original[axis] = categorical, list(axis.get_majorticklocs()), texts
        if categorical and axis is ax.yaxis and texts:
            size = axis.get_ticklabels()[0].get_fontsize()
            axis.set_ticks(original[axis][1], [_wrap(t, fig.bbox.width * 0.4, size) for t in texts])
    attempts = dict.fromkeys(original, 0)
    while True:
        _layout(fig)
        crowded = [axis for axis in original if attempts[axis] < 5 and _crowded_ticks(_shown_ticklabels(axis, ax))]
        if not crowded:
            return
        for axis in crowded:
            _thin(fig, ax, axis, *original[axis], attempts[axis])
            attempts[axis] += 1


def _thin(fig, ax, axis, categorical, locs, texts, attempt):
    """One more step of :func:`_fix_ticks` on ``axis`` (``attempt`` counts the steps taken)."""
    from matplotlib.ticker import LogLocator, MaxNLocator

    labels = _shown_ticklabels(axis, ax)
    size = labels[0].get_fontsize()
    if categorical and axis is ax.xaxis:
        centres = sorted((t.get_window_extent().x0 + t.get_window_extent().x1) / 2 for t in labels)
        room = min((b - a for a, b in zip(centres, centres[1:])), default=fig.bbox.width) - 2 * TEXT_GAP
        words = [w for t in texts for w in t.split()]
        wrapped = [_wrap(t, room, size) for t in texts] if attempt == 0 and words and \
            max(_text_width(w, size) for w in words) <= room else []
        if wrapped and max(w.count("\n") for w in wrapped) < 3:  # whole words, at most three lines
            axis.set_ticks(locs, wrapped)
        else:
            axis.set_ticks(locs, texts)
            for label in axis.get_ticklabels():
                label.set(rotation=(30, 30, 45, 90, 90)[attempt], horizontalalignment="right", rotation_mode="anchor")
    elif categorical:  # y categories too many for the height: give each its line
        fig.set_figheight(fig.get_figheight() * 1.25)
    elif axis.get_scale() == "log":
        axis.set_major_locator(LogLocator(base=10, subs=(1.0,), numticks=(12, 6, 4, 3, 2)[attempt]))
    else:
        axis.set_major_locator(MaxNLocator(nbins=max(2, len(labels) // 2)))


def _data_boxes(ax):
    """Display-space points and boxes of what ``ax`` draws as data (lines, markers, bars, labels)."""
    from matplotlib.collections import PathCollection

    points = []
    for line in ax.get_lines():
        if line.get_visible():
            points.append(line.get_transform().transform(line.get_xydata()))
    for collection in ax.collections:
        if isinstance(collection, PathCollection):
            points.append(collection.get_offset_transform().transform(collection.get_offsets()))
        else:
            points += [collection.get_transform().transform(path.vertices) for path in collection.get_paths()]
    points = np.vstack([p for p in points if len(p)] or [np.empty((0, 2))])
    boxes = [patch.get_window_extent() for patch in ax.patches if patch.get_visible()]
    boxes += [text.get_window_extent() for text in ax.texts if text.get_visible()]
    return points[np.isfinite(points).all(axis=1)], boxes


def _legend_covers(ax, legend):
    """Whether ``legend`` lies over a data point, bar or label of ``ax`` (within the axes)."""
    from matplotlib.transforms import Bbox

    frame, axes = legend.get_window_extent(), ax.get_window_extent()
    points, boxes = _data_boxes(ax)
    x, y = points.T
    # A marker centred on the frame's edge is half under it, and one centred on the axes' edge is still
    # drawn: both count, with COVER_MARGIN to spare (the browser check reads the page at another scale).
    near, shown = frame.padded(COVER_MARGIN), axes.padded(COVER_MARGIN)
    inside = (x > near.x0) & (x < near.x1) & (y > near.y0) & (y < near.y1)
    inside &= (x >= shown.x0) & (x <= shown.x1) & (y >= shown.y0) & (y <= shown.y1)
    return bool(inside.any()) or any(
        _overlap(frame, clipped) for box in boxes if (clipped := Bbox.intersection(box, axes)) is not None)


def _pin(legend, ax):
    """Keep ``legend`` where it is now: a "best" location is chosen again at every draw, so after the axes
    change shape it could move onto a label that the checks above saw free."""
    frame, axes = legend.get_window_extent(), ax.get_window_extent()
    legend.set_loc(((frame.x0 - axes.x0) / axes.width, (frame.y0 - axes.y0) / axes.height))


def _place_legend(fig, ax, outside=False):
    """Keep the legend inside the axes only if it covers nothing and has few entries; else beside them.

    A legend of more than ``3 * MANY_ENTRIES`` entries goes under the chart in columns, and the
    figure grows by its height; leaves ``fig`` laid out.
    """
    _layout(fig)
    legend = ax.get_legend()
    if legend is None:
        return
    entries = len(legend.get_texts())
    if not (outside or entries > MANY_ENTRIES or _legend_covers(ax, legend)):
        _pin(legend, ax)
        return
    if entries > 3 * MANY_ENTRIES:
        handles, labels = ax.get_legend_handles_labels()
        size = legend.get_texts()[0].get_fontsize()
        column = max(_text_width(label, size) for label in labels) + 3 * size  # the handle and the gaps
        title = legend.get_title().get_text() or None
        legend.remove()
        below = fig.legend(handles, labels, loc="outside lower center", title=title, fontsize=size,
                           ncols=max(1, int(fig.bbox.width * 0.95 // column)))
        _layout(fig)
        fig.set_figheight(fig.get_figheight() + below.get_window_extent().height / fig.dpi)
        _layout(fig)
        return
    legend.set_loc("upper left")
    legend.set_bbox_to_anchor((1.02, 1.0), transform=ax.transAxes)
    for text in [*legend.get_texts(), legend.get_title()]:
        text.set_text(_wrap(text.get_text(), fig.bbox.width * 0.3, text.get_fontsize()))
    _layout(fig)
    needed = legend.get_window_extent().height / fig.dpi + 0.3  # inches, with the layout's padding
    if needed > fig.get_figheight():
        fig.set_figheight(needed)


def _declutter(fig, ax):
    """Leave out point and bar labels that would overlap another text or the legend, or leave the figure.

    Bar value labels that crowd each other are first turned upright, with head room above the bars.
    Expects ``fig`` laid out; returns how many labels were left out.
    """
    from matplotlib.text import Annotation

    bar_labels = [t for t in ax.texts if t.get_gid() == "bar-value"]
    if _crowded([t.get_window_extent() for t in bar_labels if t.get_text()]):
        for label in bar_labels:
            label.set_rotation(90)
        ax.set_ymargin(0.3)
        ax.autoscale_view()
        _layout(fig)
    area, legend = fig.bbox, ax.get_legend()
    others = [t for t in ax.texts if not isinstance(t, Annotation)] + _shown_ticklabels(ax.xaxis, ax) \
        + _shown_ticklabels(ax.yaxis, ax) + [ax.xaxis.label, ax.yaxis.label, *fig.texts]
    taken = [t.get_window_extent() for t in others if t.get_visible() and t.get_text()]
    if legend is not None:
        taken.append(legend.get_window_extent())
    left_out = 0
    for label in [t for t in ax.texts if isinstance(t, Annotation) and t.get_text()]:
        box = label.get_window_extent()
        if area.x0 <= box.x0 and box.x1 <= area.x1 and area.y0 <= box.y0 and box.y1 <= area.y1 \
                and not any(_overlap(box, other, pad=-TEXT_GAP) for other in taken):
            taken.append(box)
        else:
            label.remove()
            left_out += 1
    return left_out


def _tidy(fig, ax, title, notes, legend_outside=False):
    """Lay the drawn figure out for reading (see the module docstring); ``notes`` join the title."""
    heading = fig.suptitle("")

    def set_heading(extra=()):
        text = title + (f"\n({'; '.join([*notes, *extra])})" if [*notes, *extra] else "")
        heading.set_text(_wrap(text, fig.bbox.width - 12, heading.get_fontsize()))

    set_heading()
    if not ax.axison:
        return
    _place_legend(fig, ax, outside=legend_outside)  # leaves the figure laid out
    box = ax.get_window_extent()
    for label, room in ((ax.xaxis.label, box.width), (ax.yaxis.label, box.height)):
        label.set_text(_wrap(label.get_text(), max(room, 60.0), label.get_fontsize()))
    _fix_ticks(fig, ax)
    short = MIN_AXES_HEIGHT - ax.get_window_extent().height  # a long title or slanted labels took the height
    if short > 0:
        fig.set_figheight(fig.get_figheight() + short / fig.dpi)
        _fix_ticks(fig, ax)
    legend = ax.get_legend()
    if legend is not None and _legend_covers(ax, legend):  # the axes changed shape under it
        _place_legend(fig, ax, outside=True)
        _fix_ticks(fig, ax)
    left_out = _declutter(fig, ax)
    if left_out:
        set_heading([f"{left_out} point label{'s' if left_out > 1 else ''} left out where they overlapped"])
        _layout(fig)
        left_out += _declutter(fig, ax)  # the longer title took height from the axes
        set_heading([f"{left_out} point label{'s' if left_out > 1 else ''} left out where they overlapped"])


def _save(fig, path):
    """Write ``fig`` as a deterministic SVG to ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, format="svg", metadata={"Date": None})
    return path


def _plot(path, title, note, empty, draw, *, figsize=FIGSIZE, legend_outside=False):
    """Create the figure, call ``draw(ax)`` unless ``empty`` (then say "no data"), tidy and save it.

    ``note`` (what was dropped) goes on a second title line; ``legend_outside`` puts the legend
    beside the axes whatever it covers.
    """
    if Path(path).suffix.lower() != ".svg":
        raise InputError(f"path: expected a .svg file name, got {str(path)!r}")
    import matplotlib as mpl
    from matplotlib.backends.backend_svg import FigureCanvasSVG
    from matplotlib.figure import Figure

    with mpl.rc_context(_RC):
        # 72 dpi and the SVG canvas: layout measures text in the SVG's own units (points) and metrics.
        fig = Figure(figsize=figsize, dpi=72, layout="constrained")
        FigureCanvasSVG(fig)
        ax = fig.add_subplot()
        if empty:
            ax.set_axis_off()
            ax.text(0.5, 0.5, "no data", ha="center", va="center", fontsize=14,
                    transform=ax.transAxes)
        else:
            draw(ax)
        _tidy(fig, ax, title, [note] if note else [], legend_outside=legend_outside)
        return _save(fig, path)


HIGHER_IS_BETTER = frozenset({"psnr", "ssim"})
"""Accuracy columns that grow as images get closer to the reference (the others are errors)."""


def speed_accuracy(df, path, *, time_col="time_total", error_col="rmse", group_col="backend",
                   label_col=None, title=None, log_x=True, log_y=True, pareto=False,
                   time_range_cols=None, x_label=None, y_label=None, better=None, join=True):
    """Scatter of time against error, one line-and-marker series per group.

    Each series is joined from its least to its most accurate point, so the settings of a quality
    sweep form a curve in quality order even where noisy timings would make a time-ordered line
    zigzag. Aggregate over views first (e.g. median per configuration) for clean curves.

    Parameters
    ----------
    df : pandas.DataFrame
        Tidy results.
    path : str or os.PathLike
        Output ``.svg`` file; parent directories are created.
    time_col, error_col : str, optional
        Columns on the x (seconds) and y axes.
    group_col : str or None, optional
        Column naming the series (legend entries); None for one series.
    label_col : str, optional
        Column whose value annotates each point (e.g. the swept parameter).
    title : str, optional
        Figure title; default ``"<error_col> vs <time_col>"``.
    log_x, log_y : bool, optional
        Logarithmic axes.
    pareto : bool, optional
        Also draw the Pareto front over all points (nothing else is both faster and more exact).
    time_range_cols : (str, str), optional
        Columns with the fastest and slowest frame (same unit as ``time_col``), drawn as
        horizontal error bars.
    x_label, y_label : str, optional
        Axis labels; default words and units for known columns (see ``_label``).
    better : str, optional
        Where the good points lie (e.g. ``"upper left"``), written in the corner opposite.
    join : bool, optional
        Join each series' points by a line (a sweep's curve); ``False`` for points that are not one
        curve (a series over scenes).

    Returns
    -------
    pathlib.Path
        The written file.
    """
    ranges = list(time_range_cols or ())
    _check_frame(df, [time_col, error_col, group_col, label_col, *ranges])
    positive = [c for c, log in ((time_col, log_x), (error_col, log_y)) if log]
    rows, note = _clean(df, [time_col, error_col], positive)

    def draw(ax):
        for i, (name, group) in enumerate(_groups(rows, group_col)):
            least_accurate_first = error_col in HIGHER_IS_BETTER  # PSNR rises with accuracy, RMSE falls
            group = group.sort_values([error_col, time_col], ascending=[least_accurate_first, True], kind="stable")
            x = group[time_col].to_numpy(float)
            xerr = _error_bars(group, x, ranges)
            style = {**_style(i), **({} if join else {"linestyle": "none"})}
            ax.errorbar(x, group[error_col], xerr=xerr, label=name or error_col, capsize=2,
                        elinewidth=0.8, **style)
            if label_col is not None:
                for x, y, text in zip(group[time_col], group[error_col], group[label_col]):
                    ax.annotate(str(text), (x, y), xytext=(3, 3), textcoords="offset points",
                                fontsize=7)
        if pareto:
            errors = rows[error_col].to_numpy(float)
            front = rows[pareto_mask(rows[time_col], errors if error_col in HIGHER_IS_BETTER else -errors)]
            front = front.sort_values(time_col)
            ax.step(front[time_col], front[error_col], where="post", color="0.4", linestyle="--", label="Pareto front")
        _axes(ax, log_x, log_y, x_label or _label(time_col), y_label or _label(error_col))
        if better:
            ax.text(0.99, 0.01, f"better: {better}", transform=ax.transAxes, ha="right", va="bottom",
                    fontsize=7, color="0.4")
        ax.legend(title=group_col.replace("_", " ") if group_col else None)

    return _plot(path, title or f"{_label(error_col)} against {_label(time_col)}", note, rows.empty, draw)


def pareto_fronts(points, path, *, title, psnr_min, techniques=None):
    """Time against PSNR: each technique's Pareto front as a line, its other settings as hollow markers.

    Parameters
    ----------
    points : pandas.DataFrame
        One scene's ``points`` from :func:`reports.decision.panel` (``backend``, ``time_total`` in seconds, ``time_min``,
        ``time_max``, ``psnr``, ``front``).
    path : path
        The ``.svg`` to write.
    title : str
    psnr_min : float
        The accuracy bar (dB), drawn as a dashed line.
    techniques : sequence of str, optional
        Every technique of the charts drawn side by side, so that each keeps its colour and marker in
        all of them; default the techniques of ``points``, sorted.
    """
    order = list(techniques) if techniques is not None else sorted(set(points.backend))

    def draw(ax):
        for backend, rows in points.groupby("backend", sort=True):
            style = _style(order.index(backend))
            front = rows[rows.front].sort_values("time_total")
            ms = front.time_total.to_numpy(float) * 1e3
            spread = np.vstack([np.clip(ms - front.time_min.to_numpy(float) * 1e3, 0, None),
                                np.clip(front.time_max.to_numpy(float) * 1e3 - ms, 0, None)])
            ax.errorbar(ms, front.psnr, xerr=np.nan_to_num(spread), label=backend, capsize=2, elinewidth=0.8,
                        markersize=5, **style)
            others = rows[~rows.front]
            if len(others):
                ax.plot(others.time_total * 1e3, others.psnr, linestyle="none", marker=style["marker"],
                        markerfacecolor="none", markeredgecolor=style["color"], markersize=5, alpha=0.7)
        ax.axhline(psnr_min, color="0.3", linestyle="--", linewidth=0.8)
        ax.annotate(f"{psnr_min:g} dB: accurate", (0, psnr_min), xycoords=("axes fraction", "data"),
                    xytext=(3, 3), textcoords="offset points", fontsize=7, color="0.3")
        _axes(ax, True, False, "median frame time (ms, log scale); bars: fastest to slowest frame",
                    "PSNR against the reference (dB)")
        ax.legend(title="technique", loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=7, title_fontsize=7,
                  borderaxespad=0)

    return _plot(path, title, "", points.empty, draw)


def _error_bars(group, x, ranges):
    """``[x − low, high − x]`` from the (low, high) columns, or None; missing values give no bar."""
    if not ranges:
        return None
    low = pd.to_numeric(group[ranges[0]], errors="coerce").to_numpy(float)
    high = pd.to_numeric(group[ranges[1]], errors="coerce").to_numpy(float)
    below = np.where(np.isfinite(low), np.clip(x - low, 0, None), 0.0)
    above = np.where(np.isfinite(high), np.clip(high - x, 0, None), 0.0)
    return np.vstack([below, above])


def _axes(ax, log_x, log_y, x_label, y_label):
    """Scales, readable ticks and labels of a chart's axes."""
    ax.set_xscale("log" if log_x else "linear")
    ax.set_yscale("log" if log_y else "linear")
    if log_x:
        _readable_log(ax.xaxis)
    if log_y:
        _readable_log(ax.yaxis)
    ax.set_xlabel(x_label)
    ax.set_ylabel(y_label)


def pareto_mask(times, scores):
    """Which points no other beats: none is at least as fast and scores at least as high while better in one.

    ``times``: lower is better; ``scores``: higher is better (a PSNR; pass ``-error`` for an error).
    Points with a non-finite value are never on the front.
    """
    times, scores = np.asarray(times, float), np.asarray(scores, float)
    mask = np.zeros(len(times), bool)
    finite = np.flatnonzero(np.isfinite(times) & np.isfinite(scores))
    best = -np.inf
    for index in finite[np.lexsort((-scores[finite], times[finite]))]:  # fastest first, best score first
        if scores[index] > best:
            mask[index], best = True, scores[index]
    return mask


def convergence(df, path, *, x_col="step", y_col="rmse", group_col=None, reference_slopes=(1, 2),
                title=None, x_label=None, y_label=None):
    """Log-log plot of error against step size, with guide lines of known slopes.

    Each series shows the median of ``y_col`` per value of ``x_col``. A guide line of slope ``k``
    (error ∝ step^k, convergence of order k) passes through the point with the largest step and
    largest error, so the data should run parallel to it.

    Parameters
    ----------
    df : pandas.DataFrame
        Tidy results.
    path : str or os.PathLike
        Output ``.svg`` file.
    x_col, y_col : str, optional
        Step (or resolution) and error columns; both must be positive.
    group_col : str, optional
        Column naming the series; None for one series.
    reference_slopes : sequence of float, optional
        Slopes of the guide lines; empty for none.
    title : str, optional
        Figure title; default ``"<y_col> vs <x_col>"``.
    x_label, y_label : str, optional
        Axis labels; default words and units for known columns.

    Returns
    -------
    pathlib.Path
        The written file.
    """
    _check_frame(df, [x_col, y_col, group_col])
    rows, note = _clean(df, [x_col, y_col], [x_col, y_col])

    def draw(ax):
        for i, (name, group) in enumerate(_groups(rows, group_col)):
            x, y = _median_curve(group, x_col, y_col)
            ax.plot(x, y, label=name or y_col, **_style(i))
        x = np.array([rows[x_col].min(), rows[x_col].max()])
        anchor_x, anchor_y = x[1], rows.loc[rows[x_col] == x[1], y_col].max()
        for i, k in enumerate(reference_slopes):
            ax.plot(x, anchor_y * (x / anchor_x) ** k, color="0.5", linestyle=_GUIDES[i % 3],
                    label=f"slope {k:g} (error ∝ step^{k:g})", zorder=1)
        _axes(ax, True, True, x_label or _label(x_col), y_label or _label(y_col))
        ax.legend(fontsize=7)

    return _plot(path, title or f"{_label(y_col)} against {_label(x_col)}", note, rows.empty, draw)


def stage_breakdown(df, path, *, stage_cols, group_col="backend", title="time per stage", unit="ms"):
    """Stacked horizontal bars of the median time of each stage, one bar per group.

    A NaN stage time means the stage does not exist for that run and counts as 0; infinite values
    are dropped and counted in the title.

    Parameters
    ----------
    df : pandas.DataFrame
        Tidy results.
    path : str or os.PathLike
        Output ``.svg`` file.
    stage_cols : sequence of str
        Stage time columns in seconds, stacked in this order (exclude ``time_total``).
    group_col : str, optional
        Column naming the bars.
    title : str, optional
        Figure title.
    unit : {"ms", "s"}, optional
        Unit of the x axis (the columns are seconds).

    Returns
    -------
    pathlib.Path
        The written file.
    """
    factor = {"s": 1.0, "ms": 1e3}.get(unit)
    if factor is None:
        raise InputError(f"unit: expected 's' or 'ms', got {unit!r}")
    stage_cols = list(stage_cols)
    if not stage_cols:
        raise InputError("stage_cols: expected at least one column")
    _check_frame(df, [*stage_cols, group_col])
    times = pd.DataFrame({c: _numeric(df, c) for c in stage_cols}, index=df.index)
    infinite = int(np.isinf(times).to_numpy().sum())
    times = times.replace([np.inf, -np.inf], np.nan)
    times[group_col] = df[group_col].astype(str)
    medians = times.groupby(group_col, sort=False)[stage_cols].median().fillna(0.0) * factor
    note = f"dropped: {infinite} infinite values" if infinite else ""

    def draw(ax):
        left = np.zeros(len(medians))
        rows = np.arange(len(medians))
        for i, stage in enumerate(stage_cols):
            ax.barh(rows, medians[stage], left=left, label=_label(stage).removesuffix(" (s)"),
                    color=_PALETTE[i % len(_PALETTE)])
            left += medians[stage].to_numpy()
        ax.set_yticks(rows, [str(name) for name in medians.index])
        ax.invert_yaxis()  # first group on top
        ax.set_xlabel(f"median time per frame ({unit})")
        ax.grid(axis="y", visible=False)
        ax.legend(title="stage")

    # About a fifth of an inch per bar beyond the first dozen, so that labels keep a line each.
    figsize = (FIGSIZE[0], max(FIGSIZE[1], 1.6 + 0.22 * len(medians)))
    return _plot(path, title, note, medians.empty, draw, figsize=figsize, legend_outside=True)


def scaling(df, path, *, x_col, y_col, group_col=None, log_x=False, log_y=False, title=None,
            x_label=None, y_label=None):
    """Lines of the median of ``y_col`` against ``x_col``, one per group.

    Parameters
    ----------
    df : pandas.DataFrame
        Tidy results.
    path : str or os.PathLike
        Output ``.svg`` file.
    x_col, y_col : str
        Columns on the x and y axes (e.g. image size and time).
    group_col : str, optional
        Column naming the series; None for one series.
    log_x, log_y : bool, optional
        Logarithmic axes.
    title : str, optional
        Figure title; default ``"<y_col> vs <x_col>"``.

    Returns
    -------
    pathlib.Path
        The written file.
    """
    _check_frame(df, [x_col, y_col, group_col])
    positive = [c for c, log in ((x_col, log_x), (y_col, log_y)) if log]
    rows, note = _clean(df, [x_col, y_col], positive)

    def draw(ax):
        for i, (name, group) in enumerate(_groups(rows, group_col)):
            ax.plot(*_median_curve(group, x_col, y_col), label=name or y_col, **_style(i))
        _axes(ax, log_x, log_y, x_label or _label(x_col), y_label or _label(y_col))
        ax.legend()

    return _plot(path, title or f"{_label(y_col)} against {_label(x_col)}", note, rows.empty, draw)


def lines(frame, path, *, x, y, group, title, x_label, y_label, y_range=None, log_x=False, log_y=False,
          vlines=(), guides=(), join=True, label=None):
    """Lines of ``y`` against ``x`` per ``group``, with vertical error bars from ``y_range`` columns.

    Unlike :func:`scaling` (medians, no bars) each row is one point, so a sweep whose rows carry
    their fastest and slowest frame shows the spread.

    Parameters
    ----------
    frame : pandas.DataFrame
        Tidy results; non-numeric or (on log axes) non-positive values are dropped and counted.
    path : str or os.PathLike
        Output ``.svg`` file.
    x, y : str
        Columns on the axes.
    group : str or None
        Column naming the series.
    title, x_label, y_label : str
        Title (say the finding) and axis labels in words with units.
    y_range : (str, str), optional
        Columns of each point's low and high value, drawn as error bars.
    log_x, log_y : bool, optional
        Logarithmic axes.
    vlines : sequence of float, optional
        x positions marked with dotted lines (e.g. the principal-axis switches of shear-warp).
    guides : sequence of (label, xs, ys), optional
        Reference curves drawn in grey (e.g. the paper's slope).
    join : bool, optional
        Join a series' points by a line; ``False`` where its points are not one sweep (one per scene).
    label : str, optional
        Column whose value annotates each point (e.g. the scene, where points are not joined).

    Returns
    -------
    pathlib.Path
        The written file.
    """
    _check_frame(frame, [x, y, group, label, *(y_range or ())])
    rows = frame.copy()
    for column in [x, y, *(y_range or ())]:
        rows[column] = pd.to_numeric(rows[column], errors="coerce")
    keep = np.isfinite(rows[[x, y]]).all(axis=1)
    if log_x:
        keep &= rows[x] > 0
    if log_y:
        keep &= rows[y] > 0
    dropped = int((~keep).sum())
    rows = rows[keep]

    def draw(ax):
        for i, (name, part) in enumerate(rows.groupby(group, sort=False) if group else [(None, rows)]):
            part = part.sort_values(x)
            yerr = None
            if y_range:
                low, high = part[y_range[0]].to_numpy(float), part[y_range[1]].to_numpy(float)
                values = part[y].to_numpy(float)
                yerr = np.vstack([np.where(np.isfinite(low), np.clip(values - low, 0, None), 0.0),
                                  np.where(np.isfinite(high), np.clip(high - values, 0, None), 0.0)])
            style = {**_style(i), **({} if join else {"linestyle": "none", "markersize": 5})}
            ax.errorbar(part[x], part[y], yerr=yerr, label=str(name) if name is not None else y, capsize=2,
                        elinewidth=0.8, **{"markersize": 3, **style})
            if label is not None:
                for px, py, text in zip(part[x], part[y], part[label]):
                    ax.annotate(str(text), (px, py), xytext=(3, 3), textcoords="offset points", fontsize=7)
        for position in vlines:
            ax.axvline(position, color="0.6", linestyle=":", linewidth=0.8, zorder=0)
        for i, (guide, gx, gy) in enumerate(guides):
            ax.plot(gx, gy, color="0.5", linestyle=("--", ":", "-.")[i % 3], label=guide, zorder=1)
        _axes(ax, log_x, log_y, x_label, y_label)
        ax.legend(fontsize=7)

    note = f"dropped {dropped} rows without a value" if dropped else ""
    return _plot(path, title, note, rows.empty, draw)


def _bar_text(value):
    """Bar label: the value to 3 significant digits, nothing for a missing bar."""
    return "" if np.isnan(value) else f"{value:.3g}"


def bar_compare(df, path, *, category_col, value_cols, value_label=None, title=None, log_y=False):
    """Grouped bars: one group per category, one bar per value column (e.g. paper vs measured).

    Each bar is the median over the rows of its category and is labelled with its value. A NaN
    value (e.g. the paper gives none) leaves its bar out and is counted in the title.

    Parameters
    ----------
    df : pandas.DataFrame
        One or more rows per category.
    path : str or os.PathLike
        Output ``.svg`` file.
    category_col : str
        Column naming the groups on the x axis.
    value_cols : sequence of str
        Numeric columns, one bar each (legend entries).
    value_label : str, optional
        y-axis label; default ``"value"``.
    title : str, optional
        Figure title; default ``"<value_cols> by <category_col>"``.
    log_y : bool, optional
        Logarithmic y axis (non-positive values are then left out too).

    Returns
    -------
    pathlib.Path
        The written file.
    """
    value_cols = list(value_cols)
    if not value_cols:
        raise InputError("value_cols: expected at least one column")
    _check_frame(df, [category_col, *value_cols])
    values = pd.DataFrame({c: _numeric(df, c) for c in value_cols}, index=df.index)
    bad = ~np.isfinite(values) | ((values <= 0) if log_y else False)
    dropped = int(bad.to_numpy().sum())
    values = values.mask(bad)
    values[category_col] = df[category_col].astype(str)
    medians = values.groupby(category_col, sort=False)[value_cols].median()
    note = f"dropped: {dropped} missing or invalid values" if dropped else ""
    empty = bool(medians.isna().to_numpy().all())

    def draw(ax):
        x = np.arange(len(medians))
        width = 0.8 / len(value_cols)
        for i, column in enumerate(value_cols):
            offset = (i - (len(value_cols) - 1) / 2) * width
            bars = ax.bar(x + offset, medians[column], width, label=column, color=_PALETTE[i % len(_PALETTE)])
            for label in ax.bar_label(bars, labels=[_bar_text(v) for v in medians[column]], fontsize=7):
                label.set_gid("bar-value")  # _declutter may turn these upright or leave some out
        ax.set_xticks(x, list(medians.index))
        ax.set_yscale("log" if log_y else "linear")
        if log_y:
            _readable_log(ax.yaxis)
        ax.set_xlabel(str(category_col))
        ax.set_ylabel(value_label or "value")
        ax.grid(axis="x", visible=False)
        ax.legend()

    return _plot(path, title or f"{', '.join(value_cols)} by {category_col}", note, empty, draw)


def difference_colorbar(path, scale, *, label=None):
    """The colour bar of :func:`reports.metrics.difference_image` at ``scale``, as a small SVG.

    Magma from 0 (black) to ``scale`` (pale yellow); the arrow at the top end says that larger
    errors clip to pale yellow.

    Parameters
    ----------
    path : str or os.PathLike
        Output ``.svg`` file.
    scale : float
        The absolute error at the top of the colour map (> 0).
    label : str, optional
        Text under the bar; default names the quantity and the scale.

    Returns
    -------
    pathlib.Path
        The written file.
    """
    if Path(path).suffix.lower() != ".svg":
        raise InputError(f"path: expected a .svg file name, got {str(path)!r}")
    try:
        scale = float(scale)
    except (TypeError, ValueError):
        raise InputError(f"scale: expected a number, got {scale!r}") from None
    if not (np.isfinite(scale) and scale > 0):
        raise InputError(f"scale: expected a finite number > 0, got {scale!r}")
    import matplotlib as mpl
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from matplotlib.ticker import FuncFormatter

    with mpl.rc_context({**_RC, "axes.grid": False}):
        fig = Figure(figsize=(4.5, 0.85), layout="constrained")
        ax = fig.add_subplot()
        mappable = ScalarMappable(norm=Normalize(0.0, scale), cmap=colormaps["magma"])
        bar = fig.colorbar(mappable, cax=ax, orientation="horizontal", extend="max")
        bar.set_label(label or f"largest absolute RGBA error per pixel (0 → {scale:g}; larger clips)")
        bar.ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _p: f"{v:g}"))
        return _save(fig, path)
