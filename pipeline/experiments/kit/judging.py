"""Judging claims: the helpers every paper's claims use, written once.

A claim's check reads the experiment's successful rows and returns a
:class:`~pipeline.experiments.kit.model.ClaimResult`. What the papers' checks share is here, with one
rule each: the rows of one configuration (:func:`config_rows`), the ratio of two configurations' frame
times with its bootstrap interval (:func:`time_ratio`, :func:`ratio_of_draws`), a machine-independent
count over the views (:func:`median_count`, :func:`counted` where a claim rests on it, :func:`counts` in words),
two stages taken once per view (:func:`view_ratio`), two configurations on every scene both rendered
(:func:`ratios_where_both`), the deciding row of an all-of over values (:func:`worst_of`), a value decided
with the interval of its draws (:func:`decided`, :func:`ratio`, :func:`statistic` over rows, :func:`line` and
:func:`r_squared` of a fitted line), a value with its interval in words (:func:`with_interval`,
:func:`labelled`), several labelled decisions that must all hold (:func:`all_of`), phrased one way on every page:
``measured`` is the deciding (worst) label's value and interval, named; the detail lists every label; and a verdict
that a starved parallel run may have decided, turned inconclusive (:func:`unless_starved`).

Every timing claim names the stage it compares and compares the same stage on both sides: the technique
(:data:`TECHNIQUE`, the backend's kernels or library calls), the compositing loop (:data:`COMPOSITE`) or the
whole frame (:data:`TOTAL`).

Judging imports no page code (:mod:`.pages` imports this module's words, not the other way round).
"""

from collections.abc import Mapping
from dataclasses import replace

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.model import ClaimResult
from pipeline.experiments.kit.results import file_exists, fit_line, numeric, rows_matching, stage_time, text_column
from pipeline.experiments.kit.words import as_percent, as_ratio, format_number

TECHNIQUE, COMPOSITE, TOTAL = "time_technique", "time_composite", "time_total"
"""The stages a timing claim compares: the backend's technique stages, its compositing loop, the whole frame."""

STRICTLY_ABOVE_ONE, STRICTLY_BELOW_ONE = float(np.nextafter(1.0, 2.0)), float(np.nextafter(1.0, 0.0))
"""The bounds of "strictly slower" and "strictly faster" ratios: the intervals' bounds are inclusive, and equal
times beat nothing."""


def with_interval(text, decision, show=as_ratio):
    """``"×1.12 (95 % CI ×1.08–×1.17)"``: ``text`` with the decision's interval (shown by ``show``), if any."""
    words = intervals.interval_words(decision, show)
    return f"{text} ({words})" if words else text


def decision_words(decision, show=as_ratio):
    """A decision's value (shown by ``show``) with its interval where it has one."""
    return with_interval(show(decision.value), decision, show)


def all_of(decisions, *, show=as_ratio, notes=None, what="", extra=""):
    """One result of labelled decisions that must all hold (:func:`~pipeline.experiments.kit.intervals.combine`).

    ``decisions`` maps a label (a scene, an image size) to its
    :class:`~pipeline.experiments.kit.intervals.Decision`. ``measured`` gives the deciding (worst)
    label's value after ``what``; the detail lists every label's value with its interval and its note
    from ``notes`` (counts, which do not depend on the machine), then ``extra``.

    Raises
    ------
    ValueError
        ``decisions`` is empty: nothing was measured, so nothing holds.
    """
    if not decisions:
        raise ValueError("nothing to judge" + (f" ({what.strip()})" if what.strip() else ""))
    combined = intervals.combine(decisions.values())
    worst = next(label for label, d in decisions.items()
                 if (d.value, d.interval, d.holds) == (combined.value, combined.interval, combined.holds))
    notes = notes or {}
    detail = "; ".join(f"{label}: {decision_words(d, show)}" + (f" ({notes[label]})" if notes.get(label) else "")
                       for label, d in decisions.items())
    return ClaimResult.decided(f"{what}{decision_words(combined, show)} ({worst})", combined,
                               detail + (f"; {extra}" if extra else ""))


def config_rows(frame, config, *, what="", **match):
    """The rows of configuration ``config`` (its ``config`` tag) matching the tags ``match``.

    Raises
    ------
    ValueError
        No successful run matches, naming ``config``, ``what`` it was for and ``match``.
    """
    rows = rows_matching(frame, config, config=config, **match)
    if rows.empty:
        raise ValueError(f"no successful {config} run" + (f" of {what}" if what else "")
                         + (f" for {match}" if match else ""))
    return rows


def median_time(frame, config, **match):
    """The median whole-frame time of ``config``'s rows matching ``match`` (its views), a point for a page or a
    claim's detail; ValueError naming the run that reported none (:func:`~.results.stage_time`)."""
    return float(np.median([stage_time(row) for _, row in config_rows(frame, config, **match).iterrows()]))


def point_speedup(frame, slow, fast, **match):
    """``median_time(slow) / median_time(fast)`` on the rows matching ``match``: a point, without the interval
    of :func:`time_ratio` or the draws of :func:`speedup`."""
    return median_time(frame, slow, **match) / median_time(frame, fast, **match)


def count_ratio(frame, slow, fast, column="count_samples", **match):
    """The ratio of a count (:func:`median_count` over the views) of ``slow`` and ``fast``; NaN where it was not
    counted."""
    top, bottom = (median_count(config_rows(frame, config, **match), column) for config in (slow, fast))
    return top / bottom if bottom else np.nan


def time_ratio(frame, slow, fast, *, resampler, at_least=None, at_most=None, column="time_total", select=config_rows,
               **match):
    """``time(slow) / time(fast)``, each the median over the matching views, judged with its bootstrap interval.

    ``select(frame, config, **match)`` picks each side's rows (:func:`config_rows` by default). Runs timed
    in one interleave group are resampled round by round (:mod:`~pipeline.experiments.kit.intervals`);
    ``resampler`` is shared by every ratio of one claim.
    """
    return intervals.ratio_decision(select(frame, slow, **match), select(frame, fast, **match), column=column,
                                    at_least=at_least, at_most=at_most, resampler=resampler)


def ratio_pair(top, bottom):
    """``(value, draws)`` of ``top / bottom``, each a ``(value, draws)`` pair (``draws`` ``None`` where either
    has none)."""
    return top[0] / bottom[0], None if top[1] is None or bottom[1] is None else top[1] / bottom[1]


def speedup(frame, slow, fast, *, resampler, column="time_total", select=config_rows, **match):
    """``(value, draws)`` of ``time(slow) / time(fast)``: each side the median of ``column`` over its rows
    (``select(frame, config, **match)``: the views), with its bootstrap draws; a pair for :func:`ratio_of_draws`."""
    return ratio_pair(*(statistic(select(frame, config, **match), column, resampler) for config in (slow, fast)))


def ratio_of_draws(top, bottom, **bounds):
    """A :class:`~pipeline.experiments.kit.intervals.Decision` on ``top / bottom``, each a ``(value, draws)`` pair
    (:func:`ratio_pair`) of frame times; ``draws`` ``None`` where no frames were kept: then it is inconclusive.
    Pairs from separate interleave groups were resampled independently, so the ratio's draws carry both spreads."""
    value, draws = ratio_pair(top, bottom)
    return intervals.timing_decision(value, draws, {}, **bounds)


def decided(value, draws, *, frames=None, at_least=None, at_most=None, centred=False):
    """A :class:`~pipeline.experiments.kit.intervals.Decision` of ``value`` with the interval of its bootstrap ``draws``.

    Parameters
    ----------
    value : float
    draws : numpy.ndarray or None
        The value's bootstrap draws (``None``: no frames were kept; a timing is then inconclusive).
    frames : dict, optional
        ``{arm: timed frames}`` where ``value`` is computed from frame times (:func:`~.intervals.frame_count`):
        too few in an arm leaves it inconclusive (:func:`~.intervals.timing_decision`). ``None``: a count or a
        metric, judged by its interval or, without one, its value.
    centred : bool
        Shift the draws by their bias (their mean less ``value``) first. A statistic of extremes (the largest
        change over a turn, a spread from slowest to fastest) gathers every draw's noise on one side, so its
        percentile interval sits above the value, even wholly above it.
    """
    if centred and draws is not None:
        finite = np.asarray(draws, float)[np.isfinite(draws)]
        draws = draws - (finite.mean() - value) if finite.size and np.isfinite(value) else draws
    return intervals.draws_decision(float(value), draws, frames, at_least=at_least, at_most=at_most)


def ratio(top, bottom, column, resampler, *, at_least=None, at_most=None, statistic="median", bottom_column=None):
    """The ratio of ``statistic`` of ``column`` over the rows ``top`` and ``bottom`` that measured it, decided with
    its interval (:func:`~pipeline.experiments.kit.intervals.ratio_decision`: too few frames, inconclusive).

    Raises
    ------
    ValueError
        Either side measured nothing, or the denominator's value is 0: the claim is not measurable.
    """
    bottom_column = bottom_column or column
    top, bottom = top[numeric(top, column).notna()], bottom[numeric(bottom, bottom_column).notna()]
    if top.empty or bottom.empty:
        raise ValueError(f"no run reported {column if top.empty else bottom_column}")
    if intervals.REDUCE[statistic](numeric(bottom, bottom_column).to_numpy(float)) == 0:  # its point, not its draws
        raise ValueError(f"{bottom_column} is 0")
    return intervals.ratio_decision(top, bottom, column=column, statistic=statistic, at_least=at_least,
                                    at_most=at_most, resampler=resampler, bottom_column=bottom_column)


def r_squared(x, draws):
    """R² of the least-squares line through ``x`` and each bootstrap draw (the rows of ``draws``), or ``None``.

    A draw that does not vary is fitted exactly (R² 1), as :func:`~.results.fit_line` fits a constant.
    """
    if draws is None:
        return None
    x = np.asarray(x, float)
    xc, yc = x - x.mean(), draws - draws.mean(axis=1, keepdims=True)
    total = (yc ** 2).sum(axis=1)
    explained = (yc @ xc) ** 2 / (xc ** 2).sum()
    return np.where(total > 0, explained / np.where(total > 0, total, 1.0), 1.0)


def median_count(rows, column):
    """The median over ``rows`` (the views) of a count: samples, fragments, rays; they do not depend on the machine.

    Rows that did not count it are left out; NaN where none did.

    Raises
    ------
    pipeline.experiments.kit.results.MissingColumn
        No run of the experiment reported ``column``: a claim that reads it is not measured.
    """
    return float(numeric(rows, column).median())


def counted(rows, column, what):
    """:func:`median_count` of ``column`` over ``rows``, failing closed: ValueError naming ``what`` where no row
    counted it (a claim that rests on it is then not measured, never judged on NaN)."""
    value = median_count(rows, column)
    if not np.isfinite(value):
        raise ValueError(f"{what} counted no {column.removeprefix('count_')}")
    return value


def worst_of(rows, column, by, *, lowest=False):
    """``(row, per_group)``: the deciding row of an all-of over values, the one of ``rows`` whose ``column`` is the
    largest (with ``lowest``, the smallest), and that extreme per group of ``by`` for the claim's detail."""
    groups = rows.groupby(by, sort=False)[column]
    if lowest:
        return rows.loc[rows[column].idxmin()], groups.min()
    return rows.loc[rows[column].idxmax()], groups.max()


def view_ratio(rows, top, bottom, resampler, *, key):
    """``(value, draws, views)``: the median over ``rows`` (views) of ``top`` over that of ``bottom``, two stages
    measured once per view and process (not per frame: nothing to resample within one), with draws that resample
    the views and, where several processes timed them (``once_<stage>``, :mod:`pipeline.collect`), each view's
    processes, the two stages of one process together; ``key`` names the rows' draws in ``resampler``.

    Raises
    ------
    ValueError
        A view lacks either stage's time or has a zero ``bottom``: the claim is not measured.
    """
    tops, bottoms = (numeric(rows, column).to_numpy(float) for column in (top, bottom))
    if not (np.isfinite(tops).all() and np.isfinite(bottoms).all() and (bottoms > 0).all()):
        raise ValueError(f"{key}: a view without its {top} and {bottom}")
    picks = resampler.indices(("views", key), len(rows))
    # Each view's time in a draw: the mean over its processes drawn with replacement, the same for both stages.
    per_process = [intervals.once_draws(rows, column, resampler) for column in (top, bottom)]
    if any(values is None for values in per_process):
        per_process = [np.broadcast_to(values, (resampler.draws, len(rows))) for values in (tops, bottoms)]
    tops_drawn, bottoms_drawn = (np.take_along_axis(values, picks, axis=1) for values in per_process)
    return (float(np.median(tops) / np.median(bottoms)),
            np.median(tops_drawn, axis=1) / np.median(bottoms_drawn, axis=1), len(rows))


def ratios_where_both(frame, scenes, top, bottom, *, what, describe=None, column=TOTAL, **bounds):
    """``top``'s ``column`` over ``bottom``'s (two configurations' test runs, each the median over its views) on
    each of ``scenes`` that both rendered, every one judged against ``bounds`` (:func:`all_of`); ``scenes`` a
    mapping gives each scene bounds of its own instead (``{scene: {"at_least": …, "at_most": …}}``: a paper's
    band per table row).

    A scene only one of them renders (a peer's limit on volumes, say) is not compared; ``what`` says the ratio in
    the detail, then ``describe(rows)`` what the compared rows record (the devices they ran on).

    Raises
    ------
    ValueError
        No scene of ``scenes`` was rendered by both: the claim is not measured.
    """
    resampler = intervals.Resampler()
    decisions, compared = {}, []
    per_scene = scenes if isinstance(scenes, Mapping) else dict.fromkeys(scenes, bounds)
    for name, scene_bounds in per_scene.items():
        pair = [measured(rows_matching(frame, name, scene=name, role="test", config=config), column)
                for config in (top, bottom)]
        if not any(part.empty for part in pair):
            decisions[name] = ratio(*pair, column, resampler, **scene_bounds)
            compared += pair
    if not decisions:
        raise ValueError(f"no scene of {', '.join(map(str, scenes))} rendered by both {top} and {bottom}")
    described = describe(pd.concat(compared)) if describe else ""
    return all_of(decisions, extra=what + (f"; {described}" if described else ""))


def measured(rows, column, missing=None):
    """The rows with a value in ``column``, read as numbers (:class:`~pipeline.experiments.kit.results.MissingColumn`
    if absent); where none has one and ``missing`` says what that means, ValueError saying it (fails closed)."""
    values = numeric(rows, column)
    if missing is not None and values.notna().sum() == 0:
        raise ValueError(missing)
    return rows.assign(**{column: values})[values.notna()]


def timed(frame, what, column, **match):
    """The rows of ``frame`` matching ``match`` that have a ``column`` time; ValueError naming ``what`` if none."""
    rows = measured(rows_matching(frame, what, **match), column)
    if rows.empty:
        raise ValueError(f"no {column} of {what}")
    return rows


def values(rows, column, resampler):
    """``(values, draws)``: each row's median ``column`` and its ``(DRAWS, rows)`` bootstrap draws (``None``
    without frames)."""
    rows = measured(rows, column)
    if rows.empty:
        raise ValueError(f"no run reported {column}")
    return numeric(rows, column).to_numpy(float), intervals.row_draws(rows, column, resampler)


def statistic(rows, column, resampler, reduce="median"):
    """``(value, draws)`` of ``reduce`` (a key of :data:`~pipeline.experiments.kit.intervals.REDUCE`) over the rows
    that measured ``column`` (:func:`~pipeline.experiments.kit.intervals.statistic_draws`); ValueError if none did."""
    rows = measured(rows, column)
    if rows.empty:
        raise ValueError(f"no run reported {column}")
    value = float(intervals.REDUCE[reduce](numeric(rows, column).to_numpy(float)))
    return value, intervals.statistic_draws(rows, column, reduce, resampler)


def line(rows, x, column, resampler, *, at_least):
    """``(slope, intercept, Decision on R²)`` of a least-squares line of ``column`` against the rows' column ``x``."""
    ys, draws = values(rows, column, resampler)
    rows = measured(rows, column)
    slope, intercept, r2 = fit_line(rows[x], ys)
    return slope, intercept, decided(r2, r_squared(rows[x].to_numpy(float), draws), at_least=at_least,
                                     frames=resampler.arms())


def r2_words(value):
    """``"R² 0.97"``."""
    return f"R² {format_number(value)}"


def labelled(decisions, show=as_ratio):
    """``"×1.12 (brain; 95 % CI ×1.08–×1.17), ×0.9 (head)"``: each decision's value, label and interval."""
    parts = []
    for label, decision in decisions.items():
        words = intervals.interval_words(decision, show)
        parts.append(f"{show(decision.value)} ({label}{'; ' + words if words else ''})")
    return ", ".join(parts)


def milliseconds(rows, column=TECHNIQUE):
    """``"1.23 ms"``: the median of ``column`` over the rows."""
    return f"{format_number(float(numeric(rows, column).median()) * 1e3)} ms"


def counts(rows, column, label="scene"):
    """``"C1: 1.05e+06, C8: 7.05e+06"``: a counter of each row (samples, fragments: they do not depend on the
    machine) for a claim's detail, beside its times; ``"n/a"`` where no run reported it."""
    if column not in rows:
        return "n/a"
    numbers = numeric(rows, column)
    names = [int(n) if isinstance(n, float) and n.is_integer() else n for n in rows[label]]  # 1000.0 read back
    return ", ".join(f"{name}: {format_number(value)}" for name, value in zip(names, numbers))


def starved(rows):
    """Why the parallel runs among ``rows`` were starved (their ``info_starved`` sentences), or ``""``."""
    if "info_starved" not in rows:
        return ""
    texts = [str(t) for t in rows["info_starved"] if isinstance(t, str) and t.strip()]
    return "; ".join(dict.fromkeys(texts))


def busy(rows):
    """``"workers busy 97 % at least"``: the least busy share over compositing of the parallel runs
    (``info_worker_busy``), or ``""``."""
    if "info_worker_busy" not in rows:
        return ""
    shares = numeric(rows, "info_worker_busy").dropna()
    return f"workers busy {as_percent(float(shares.min()))} at least" if not shares.empty else ""


def unless_starved(result, rows, *, holding_survives):
    """``result``, or inconclusive where a starved run among ``rows`` may have decided it.

    A parallel run whose workers had fewer free cores than threads (``info_starved``, from the machine's load
    over its frames) measured the machine rather than the technique. ``holding_survives``: the claim says a
    parallel run is fast enough, and starving it can only slow it, so a claim that holds anyway still holds;
    otherwise (comparisons among parallel runs, shares of work that follow which thread ran when) a starved run
    decides nothing either way.
    """
    why = starved(rows)
    if not why:
        return result
    detail = f"{result.detail}; starved: {why}"
    if result.holds is None or (result.holds and holding_survives):
        return replace(result, detail=detail)
    return replace(result, holds=None, inconclusive=True,
                   detail=detail + " (a verdict from a starved run is the machine's, not the technique's)")


def in_every_process(measured, holds_per_process, detail=""):
    """A :class:`ClaimResult` of a count a parallel run's scheduling shares out (which worker stole which task):
    it holds where it holds in every process that measured it, fails where it fails in every one, and is
    inconclusive otherwise.

    Such a count varies from process to process as a time does (two quiet smoke runs measured round robin with
    stealing's imbalance at 12.4 % and 27.3 %), so one process cannot decide it, as it cannot a timing claim.
    """
    holds = [bool(value) for value in holds_per_process]
    if len(holds) < 2:
        why = ("inconclusive: it rests on one process's count, and how a parallel run shares out its work varies "
               "between processes; two processes' records (replicates ≥ 2) would decide it")
    elif len(set(holds)) > 1:
        why = f"inconclusive: it holds in {sum(holds)} of the {len(holds)} processes that measured it"
    else:
        return ClaimResult(measured, holds[0], detail)
    return ClaimResult(measured, None, f"{detail}; {why}" if detail else why, inconclusive=True)


def summed(rows, column, resampler):
    """``(value, draws)``: each row's (view's) median ``column`` summed over ``rows``, with its bootstrap draws.

    Parameters
    ----------
    rows : pandas.DataFrame
        The views of one run (or of runs timed together), with ``column`` and, where timed, its frames.
    column : str
        A time column (``"time_draw"``).
    resampler : pipeline.experiments.kit.intervals.Resampler
        Shared by every pair of one claim, so that rows of one interleave group are resampled together.

    Returns
    -------
    tuple
        The sum, and the sums of the views' draws (``None`` without frames): a pair for :func:`ratio_pair`.
    """
    draws = intervals.row_draws(rows, column, resampler)
    return float(numeric(rows, column).sum()), None if draws is None else draws.sum(axis=1)


def image_pairs(frame, first, second, *, first_match=None, second_match=None):
    """``[(scene, view, row_first, row_second)]``: every scene and view that configurations ``first`` and ``second``
    both rendered to an EXR, for comparing their images.

    Parameters
    ----------
    frame : pandas.DataFrame
        An experiment's successful rows.
    first, second : str
        The configurations (``config`` tags), each selected by :func:`config_rows`.
    first_match, second_match : dict, optional
        More tags each side's rows must have (``{"order": "front-to-back"}``).

    Raises
    ------
    ValueError
        Either configuration has no run, or the two share no rendered view.
    """
    a = config_rows(frame, first, **(first_match or {}))
    b = config_rows(frame, second, **(second_match or {}))
    pairs = []
    for row in a.itertuples():
        match = b[(text_column(b, "scene") == str(row.scene)) & (text_column(b, "view") == str(row.view))]
        if not match.empty and file_exists(row.exr) and file_exists(match.exr.iloc[0]):
            pairs.append((row.scene, row.view, row, match.iloc[0]))
    if not pairs:
        raise ValueError(f"no view rendered by both {first} and {second}")
    return pairs


def counts_compared(labels, counts, *, fewer, measured, words, extra=""):
    """A count claim over ``labels`` (the scenes, say): one count below (or above) another on every label.

    Parameters
    ----------
    labels : iterable
        What the counts are compared over, in the order the detail lists them.
    counts : callable
        ``counts(label)``: ``(a, b)``, the label's two counts (samples, fragments: they do not depend on the
        machine), each validated (:func:`counted`).
    fewer : bool
        The claim holds where ``a < b`` on every label; ``False``: where ``a > b`` on every label.
    measured : callable
        ``measured(ratio, label)``: the result's ``measured``, from the deciding label's ``a / b`` (``inf`` where
        ``b`` is 0): the largest with ``fewer``, else the smallest.
    words : callable
        ``words(label, a, b)``: a label's counts in the detail, joined by ``"; "``; ``extra`` ends the detail.

    Returns
    -------
    ClaimResult
    """
    compared = [(a / b if b else np.inf, label, a, b) for label in labels for a, b in [counts(label)]]
    ratio, label, _, _ = (max if fewer else min)(compared)
    return ClaimResult(measured(ratio, label), all(a < b if fewer else a > b for _, _, a, b in compared),
                       "; ".join(words(label, a, b) for _, label, a, b in compared) + extra)


def worst_test_psnr(frame, configs, *, at_least):
    """The worst PSNR against the reference of the test rows of ``configs``: a paper's "every method renders the
    reference's image" claim.

    Parameters
    ----------
    frame : pandas.DataFrame
        A claim's rows, with the tags ``role``, ``config``, ``scene``, ``view`` and the column ``psnr``.
    configs : sequence of str
        The methods judged, in the order their worst values are listed in the detail.
    at_least : float
        The floor, in dB.

    Returns
    -------
    ClaimResult
        ``measured`` is the worst PSNR with its method, scene and view; the detail lists each method's worst.

    Raises
    ------
    ValueError
        No row has a PSNR, or a view of one lacks it (a missing comparison is "not measured", never left out of
        the worst).
    """
    tests = frame[(text_column(frame, "role") == "test") & text_column(frame, "config").isin(configs)]
    psnr = numeric(tests, "psnr")
    if psnr.notna().sum() == 0:
        raise ValueError("no PSNR against the reference")
    if psnr.isna().any():
        raise ValueError("no PSNR against the reference for " + ", ".join(
            f"{r.run} ({r.view})" for r in tests[psnr.isna()].itertuples()))
    worst = tests.loc[psnr.idxmin()]
    per_config = tests.assign(psnr=psnr).groupby("config").psnr.min()
    return ClaimResult(f"{format_number(psnr.min())} dB ({worst.config}, {worst.scene}, {worst.view})",
                       bool(psnr.min() >= at_least),
                       ", ".join(f"{c}: ≥ {format_number(per_config[c])} dB" for c in configs if c in per_config))
