"""Judging this paper's timing claims: like scopes, ratios and statistics with their intervals, starved runs.

Every timing claim of the package names the stage it compares (:data:`SCOPES`) and compares the same
stage on both sides. Its value gets a 95 % bootstrap interval from the runs' timed frames
(:mod:`pipeline.experiments.kit.intervals`), resampled round by round where the runs were timed
together (their ``interleave`` group); a claim over several scenes holds where every scene does,
fails where one fails and is inconclusive otherwise (:func:`~pipeline.experiments.kit.intervals.combine`).
Rows without frames (counts, results written before frames were kept) are judged on their values alone.

A parallel run whose workers had fewer free cores than threads (``info_starved``, from the machine's
load over its frames) measured the machine rather than the technique: :func:`unless_starved` turns the
verdicts such a run could have decided inconclusive, and says why.
"""

from dataclasses import replace

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import decided, r_squared
from pipeline.experiments.kit.pages import as_percent, as_ratio, format_number
from pipeline.experiments.kit.results import fit_line, numeric

TECHNIQUE, COMPOSITE, TOTAL = "time_technique", "time_composite", "time_total"

SCOPES = {TECHNIQUE: "technique (the backend's kernels or library calls: tables, compositing, warp)",
          COMPOSITE: "compositing loop (the composite stage)", TOTAL: "whole frame (Python and conversions included)"}
"""What each compared stage holds, for the claims' details."""


def measured(rows, column):
    """The rows with a value in ``column`` (:class:`~pipeline.experiments.kit.results.MissingColumn` if absent)."""
    return rows[numeric(rows, column).notna()]


def values(rows, column, resampler):
    """``(values, draws)``: each row's median ``column`` and its ``(DRAWS, rows)`` bootstrap draws (``None``
    without frames)."""
    rows = measured(rows, column)
    if rows.empty:
        raise ValueError(f"no run reported {column}")
    return numeric(rows, column).to_numpy(float), intervals.row_draws(rows, column, resampler)


def statistic(rows, column, resampler, reduce="median"):
    """``(value, draws)`` of ``reduce`` (a key of :data:`~pipeline.experiments.kit.intervals.REDUCE`) over the rows."""
    point, draws = values(rows, column, resampler)
    function = intervals.REDUCE[reduce]
    return float(function(point)), (None if draws is None else function(draws, axis=1))


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


def starved(rows):
    """Why the parallel runs among ``rows`` were starved (their ``info_starved`` sentences), or ``""``."""
    if "info_starved" not in rows:
        return ""
    texts = [str(t) for t in rows["info_starved"] if isinstance(t, str) and t.strip()]
    return "; ".join(dict.fromkeys(texts))


def busy(rows):
    """``"workers busy 97 %"``: the parallel runs' mean busy share over compositing (``info_worker_busy``), or ``""``."""
    if "info_worker_busy" not in rows:
        return ""
    shares = numeric(rows, "info_worker_busy").dropna()
    return f"workers busy {as_percent(float(shares.min()))} at least" if not shares.empty else ""


def unless_starved(result, rows, *, holding_survives):
    """``result``, or inconclusive where a starved run among ``rows`` may have decided it.

    ``holding_survives``: the claim says a parallel run is fast enough, and starving it can only slow
    it, so a claim that holds anyway still holds; otherwise (comparisons among parallel runs, shares
    of work that follow which thread ran when) a starved run decides nothing either way.
    """
    why = starved(rows)
    if not why:
        return result
    detail = f"{result.detail}; starved: {why}"
    if result.holds is None or (result.holds and holding_survives):
        return replace(result, detail=detail)
    return replace(result, holds=None, inconclusive=True,
                   detail=detail + " (a verdict from a starved run is the machine's, not the technique's)")

