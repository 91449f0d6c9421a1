"""Take-away sentences computed from the results, so that a report's prose changes with its numbers.

Each function takes a small tidy :class:`pandas.DataFrame` (or the claims table) and returns a
list of sentences (possibly empty); nothing here is written by hand about particular results.
"""

import math

import numpy as np
import pandas as pd

__all__ = ["accuracy_failures", "claims", "fastest_at_accuracy", "number", "order_range", "problems",
           "ms"]

PSNR_GOOD = 40.0
"""dB: the accuracy the take-aways call "accurate" (the reference's own default-step target)."""


def number(value, digits=3):
    """A short number: 3 significant digits, ``n/a`` for missing, ``∞`` for infinity."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "n/a"
    value = float(value)
    if math.isinf(value):
        return "∞" if value > 0 else "−∞"
    return f"{value:.{digits}g}"


def ms(seconds):
    """Seconds as milliseconds with 3 significant digits (``1.73 ms``)."""
    return f"{number(float(seconds) * 1e3)} ms"


def _listing(items, limit=3):
    items = list(items)
    shown = "; ".join(items[:limit])
    return shown + (f"; and {len(items) - limit} more" if len(items) > limit else "")


def claims(table, *, limit=3):
    """One sentence on the claims: how many hold, which fail (measured against expected), which are
    inconclusive (a timing claim whose interval straddles its bound), how many are blocked by runs
    that did not happen and how many could not be measured.

    ``table`` has the columns of ``claims.csv`` (``statement``, ``expected``, ``measured``, ``verdict``;
    a table without ``verdict`` is read from ``holds``: True / False / None for not measured).
    """
    table = pd.DataFrame(table)
    if table.empty:
        return []
    if "verdict" in table:
        verdict = table.verdict.fillna("not measured")
    else:
        verdict = table.holds.map(lambda v: "holds" if v is True else "fails" if v is False else "not measured")
    good, bad, undecided = int((verdict == "holds").sum()), table[verdict == "fails"], table[verdict == "inconclusive"]
    blocked, unmeasured = int((verdict == "blocked").sum()), int((verdict == "not measured").sum())
    measured = good + len(bad) + len(undecided)
    sentence = f"{good} of {measured} measured claims hold" if measured else "No claim could be measured"
    for rows, words in ((bad, "failing"), (undecided, "inconclusive (the interval straddles the bound)")):
        if len(rows):
            sentence += f"; {words}: " + _listing(
                (f"{row.statement} (measured {row.measured}, expected {row.expected})" for row in rows.itertuples()),
                limit)
    if blocked:
        sentence += f"; {blocked} blocked by runs that did not happen here"
    if unmeasured:
        sentence += f"; {unmeasured} not measured"
    return [sentence + "."]


def fastest_at_accuracy(frame, *, psnr_min=PSNR_GOOD, scene_col="scene", label_col="technique",
                        time_col="time_total"):
    """Per scene, the fastest row whose PSNR reaches ``psnr_min`` (time in seconds).

    A scene where no row gets there gets a sentence naming its most accurate row instead.
    """
    rows = frame[np.isfinite(pd.to_numeric(frame[time_col], errors="coerce"))]
    sentences = []
    for scene, group in rows.groupby(scene_col, sort=True):
        accurate = group[group.psnr >= psnr_min]
        if not accurate.empty:
            best = accurate.loc[accurate[time_col].idxmin()]
            slowest = accurate.loc[accurate[time_col].idxmax()]
            sentence = (f"At ≥ {number(psnr_min)} dB PSNR the fastest setting on {scene} is "
                        f"{best[label_col]} at {ms(best[time_col])} ({number(best.psnr)} dB)")
            if slowest[time_col] > best[time_col]:
                sentence += f", {number(slowest[time_col] / best[time_col], 2)}× faster than the slowest that gets there"
            sentences.append(sentence + ".")
        elif group.psnr.notna().any():
            top = group.loc[group.psnr.idxmax()]
            sentences.append(f"On {scene} no setting reaches {number(psnr_min)} dB PSNR; the most accurate is "
                             f"{top[label_col]} at {number(top.psnr)} dB ({ms(top[time_col])}).")
    return sentences


def accuracy_failures(frame, *, psnr_min=PSNR_GOOD, scene_col="scene", label_col="technique"):
    """Where a setting falls below ``psnr_min``: one sentence listing them, worst first."""
    bad = frame[frame.psnr < psnr_min].sort_values("psnr")
    if bad.empty:
        if frame.psnr.notna().any():
            return [f"Every setting reaches {number(psnr_min)} dB PSNR on every scene "
                    f"(worst {number(frame.psnr.min())} dB)."]
        return []
    items = (f"{row[label_col]} on {row[scene_col]} ({number(row.psnr)} dB)" for _, row in bad.iterrows())
    return [f"Below {number(psnr_min)} dB PSNR (where a setting fails): {_listing(items, 4)}."]


def order_range(orders):
    """The observed orders of convergence ``{scene: order}`` as one sentence."""
    orders = {k: v for k, v in orders.items() if v is not None and np.isfinite(v)}
    if not orders:
        return []
    low, high = min(orders.values()), max(orders.values())
    span = number(low, 2) if number(low, 2) == number(high, 2) else f"{number(low, 2)}–{number(high, 2)}"
    detail = ", ".join(f"{scene} {number(order, 2)}" for scene, order in sorted(orders.items(), key=lambda kv: kv[1]))
    return [f"The error falls with the step at observed order {span} ({detail}); "
            f"order 1 halves the error with each halving of the step, order 2 quarters it."]


def problems(groups):
    """Runs that made no frame, as sentences: those that should have (failed, unavailable, no data),
    then the planned limits (a feature the backend lacks), each group of one message once.

    ``groups`` is :func:`reports.outcomes.problem_groups`' list.
    """
    sentences = []
    for planned, one, many in ((False, "run made no frame", "runs made no frame"),
                               (True, "run was skipped as a planned limit", "runs were skipped as planned limits")):
        chosen = [g for g in groups if g["planned"] == planned]
        if not chosen:
            continue
        count = sum(g["count"] for g in chosen)
        items = [f"{g['backend']} × {g['count']} ({', '.join(g['runs'][:2])}{' …' if g['count'] > 2 else ''}): "
                 f"{g['reason'] or 'no reason recorded'}" for g in chosen]
        sentences.append(f"{count} {one if count == 1 else many}: {_listing(items)}.")
    return sentences
