"""Judging claims: the helpers every paper's claims use, written once.

A claim's check reads the experiment's successful rows and returns a
:class:`~pipeline.experiments.kit.model.ClaimResult`. What the papers' checks share is here, with one
rule each: the rows of one configuration (:func:`config_rows`), the ratio of two configurations' frame
times with its bootstrap interval (:func:`time_ratio`, :func:`ratio_of_draws`), a machine-independent
count over the views (:func:`median_count`), a value decided with the interval of its draws (:func:`decided`,
:func:`ratio`, :func:`r_squared` of a fitted line), a value with its interval in words (:func:`with_interval`)
and several labelled decisions that must all hold (:func:`all_of`), phrased one way on every page:
``measured`` is the deciding (worst) label's value and interval, named; the detail lists every label.

Judging imports no page code (:mod:`.pages` imports this module's words, not the other way round).
"""

import numpy as np

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.model import ClaimResult
from pipeline.experiments.kit.results import numeric, rows_matching
from pipeline.experiments.kit.words import as_ratio

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


def time_ratio(frame, slow, fast, *, resampler, at_least=None, at_most=None, column="time_total", select=config_rows,
               **match):
    """``time(slow) / time(fast)``, each the median over the matching views, judged with its bootstrap interval.

    ``select(frame, config, **match)`` picks each side's rows (:func:`config_rows` by default). Runs timed
    in one interleave group are resampled round by round (:mod:`~pipeline.experiments.kit.intervals`);
    ``resampler`` is shared by every ratio of one claim.
    """
    return intervals.ratio_decision(select(frame, slow, **match), select(frame, fast, **match), column=column,
                                    at_least=at_least, at_most=at_most, resampler=resampler)


def ratio_of_draws(top, bottom, **bounds):
    """A :class:`~pipeline.experiments.kit.intervals.Decision` on ``top / bottom``, each a ``(value, draws)`` pair
    of frame times (``draws`` ``None`` where no frames were kept: then the decision is inconclusive)."""
    draws = top[1] / bottom[1] if top[1] is not None and bottom[1] is not None else None
    return intervals.timing_decision(top[0] / bottom[0], draws, {}, **bounds)


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
