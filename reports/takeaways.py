"""Take-away sentences computed from the results, so that a report's prose changes with its numbers.

Each function takes a small tidy :class:`pandas.DataFrame` (or the claims table) and returns a
list of sentences (possibly empty); nothing here is written by hand about particular results.
"""

import html
import math
import re

import numpy as np
import pandas as pd
from markupsafe import Markup

__all__ = ["ACCURACY_FAILURE", "FAILING_CLAIM", "SHOWN", "Takeaway", "accuracy_failures", "change_words", "claims",
           "db_words", "fastest_at_accuracy", "likely_cause", "ms", "number", "order_range", "problems", "ranked",
           "rst_inline", "setting_words"]

PSNR_GOOD = 40.0
"""dB: the accuracy the take-aways call "accurate" (the reference's own default-step target)."""

FAILING_CLAIM, ACCURACY_FAILURE = 0, 1
"""Importance of a :class:`Takeaway`, most important first; a plain sentence comes after both."""


class Takeaway(str):
    """A take-away sentence that knows its importance (:data:`FAILING_CLAIM`, :data:`ACCURACY_FAILURE`).

    It is a ``str``, so it joins, deduplicates and renders like any sentence; ``takeaways.html``
    shows the most important first and folds all but five.
    """

    def __new__(cls, text, importance):
        sentence = super().__new__(cls, text)
        sentence.importance = importance
        return sentence

    def __reduce__(self):  # pickled with its importance (the report builds its pages in several processes)
        return type(self), (str(self), self.importance)


SHOWN = 5
"""Take-aways a page shows; the rest are folded (``takeaways.html``)."""


def ranked(sentences):
    """``sentences`` without repeats, most important first (:class:`Takeaway`; a plain sentence after both
    kinds), each level in its given order."""
    unique = list(dict.fromkeys(sentences))
    return sorted(unique, key=lambda sentence: getattr(sentence, "importance", ACCURACY_FAILURE + 1))


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


CHANGE_AS_PERCENT = 1.5
"""A ratio within this factor of 1 is said as a per cent change ("8.7 % faster"), beyond it as a
factor ("×14.9 slower"): a per cent of a large change ("1390 % slower") is hard to read."""


def change_words(ratio, *, faster="faster", slower="slower", same="no different"):
    """A ratio of two measurements (new / old: a time ratio) in words with the right sign.

    Parameters
    ----------
    ratio : float
        The measurement over the one it is compared with; above 1 says ``slower``, below 1 ``faster``.
    faster, slower : str, optional
        The words for a ratio below and above 1 (``"less"`` / ``"more"`` for counts).
    same : str, optional
        What a ratio that rounds to no change says.

    Returns
    -------
    str
        ``"8.7 % faster"`` (ratio 0.913: 8.7 % less time), ``"×14.9 slower"`` (ratio 14.9),
        ``"×14.9 faster"`` (ratio 0.0672); a factor from :data:`CHANGE_AS_PERCENT` on.

    Examples
    --------
    >>> change_words(0.9131), change_words(14.9), change_words(0.0672), change_words(1.2, slower="more")
    ('8.69 % faster', '×14.9 slower', '×14.9 faster', '20 % more')
    """
    ratio = float(ratio)
    if not math.isfinite(ratio) or ratio <= 0:
        raise ValueError(f"change_words: the ratio must be a positive finite number, got {ratio!r}")
    word = slower if ratio > 1 else faster
    factor = max(ratio, 1 / ratio)
    if factor >= CHANGE_AS_PERCENT:
        return f"×{number(factor)} {word}"
    percent = number(abs(ratio - 1) * 100)
    return same if float(percent) == 0 else f"{percent} % {word}"


def db_words(difference, *, more="more", less="less", same="no different"):
    """A difference of two values in dB in words with the right sign: ``"2 dB less"``, ``"1.99 dB more"``.

    ``difference`` is the value minus the one it is compared with; ``more`` and ``less`` are the words
    for a positive and a negative one (``"higher"`` / ``"lower"``).

    >>> db_words(-1.99), db_words(0.5, more="higher", less="lower")
    ('1.99 dB less', '0.5 dB higher')
    """
    difference = float(difference)
    if not math.isfinite(difference):
        raise ValueError(f"db_words: the difference must be a finite number of dB, got {difference!r}")
    shown = number(abs(difference))
    return same if float(shown) == 0 else f"{shown} dB {more if difference > 0 else less}"


SETTING_NAMES = {"step_factor": ("step", " voxel")}
"""Option names read differently from their key, with the unit after the value."""


def setting_words(setting):
    """A backend's options as a reader says them: ``"min_opacity=0.0,opaque_threshold=0.999"`` →
    ``"min opacity 0, opaque threshold 0.999"``, ``"step_factor=0.5"`` → ``"step 0.5 voxel"``.

    Text that is not ``key=value`` pairs (``"default"``, ``"truth"``) comes back unchanged;
    numbers are shortened (:func:`number`), ``True``/``False`` read ``on``/``off``.
    """
    text = "" if setting is None or (isinstance(setting, float) and math.isnan(setting)) else str(setting)
    pairs = [part.partition("=") for part in text.split(",")]
    if not text or not all(sep and key.strip() for key, sep, _ in pairs):
        return text
    words = []
    for key, _, value in pairs:
        key, value = key.strip(), value.strip()
        name, unit = SETTING_NAMES.get(key, (key.replace("_", " "), ""))
        try:
            value = number(float(value))
        except ValueError:
            value = {"True": "on", "False": "off"}.get(value, value)
        words.append(f"{name} {value}{unit}")
    return ", ".join(words)


_SETTING_IN_LABEL = re.compile(r"\(([^()=]+=[^()]*)\)")


def _label(text):
    """A label with its ``(key=value,...)`` settings in words: ``"vtk-cpu (step 0.5 voxel)"``."""
    return _SETTING_IN_LABEL.sub(lambda m: f"({setting_words(m.group(1))})", str(text))


_LITERAL = re.compile(r"``(.+?)``")


def rst_inline(text):
    """reStructuredText's inline ````literals```` as ``<code>``, everything else escaped: HTML to show."""
    parts = _LITERAL.split("" if text is None else str(text))
    # split() alternates text and the literals' contents: odd indices are the literals.
    return Markup("".join(f"<code>{html.escape(part)}</code>" if i % 2 else html.escape(part)
                          for i, part in enumerate(parts)))


def _listing(items, limit=3):
    items = list(items)
    shown = "; ".join(items[:limit])
    return shown + (f"; and {len(items) - limit} more" if len(items) > limit else "")


EVIDENCE_COLUMNS = ("disturbed_views", "software_rasterizer", "stand_in")
"""The columns of ``claims.csv`` :func:`likely_cause` reads besides the interval: how many disturbed views
the verdict rests on, the CPU rasterizer that timed the claim's GL runs (empty: none), the phantoms
standing in for the paper's scans (empty: none)."""


def cell_text(value):
    """A cell of a results table as text: ``""`` for an empty one (``None``, or NaN once read back)."""
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else str(value)


def likely_cause(claim):
    """Why a claim fails or is inconclusive, as far as its row of ``claims.csv`` shows.

    ``claim`` is a mapping (a row) with ``verdict``, ``interval_low``/``interval_high`` and the
    :data:`EVIDENCE_COLUMNS`. In this order: **timing noise** (its verdict rests on views timed while
    the machine was disturbed, or its interval straddles the bound), **llvmpipe** (a timing claim whose
    GL runs a CPU rasterizer timed), **stand-in data** (it reads a phantom standing in for the paper's
    scan; a timing claim only), otherwise **a real discrepancy**; **cause not determined** where a column it needs is absent.
    """
    timing = pd.notna(claim.get("interval_low")) and pd.notna(claim.get("interval_high"))
    disturbed = pd.to_numeric(pd.Series([claim.get("disturbed_views")]), errors="coerce").iloc[0]
    if pd.notna(disturbed) and disturbed > 0:
        return f"timing noise ({int(disturbed)} of its views timed while the machine was disturbed)"
    if claim.get("verdict") == "inconclusive" and timing:
        return "timing noise (its 95 % interval straddles the bound)"
    if not all(column in claim for column in EVIDENCE_COLUMNS):
        return "cause not determined"
    if timing and cell_text(claim.get("software_rasterizer")):
        return f"llvmpipe (GL frames timed on {cell_text(claim['software_rasterizer'])}, a CPU rasterizer)"
    # A phantom changes how much a technique saves (its empty space, its opacity), not whether two
    # renderers of the same phantom agree: only a timing claim is put down to the stand-in.
    if timing and cell_text(claim.get("stand_in")):
        return f"stand-in data ({cell_text(claim['stand_in'])})"
    return "a real discrepancy"


def claims(table, *, limit=3):
    """Take-aways on the claims: a count of the verdicts, then each failing claim (measured against
    expected) with its likely cause (:func:`likely_cause`), then the inconclusive ones with theirs.

    ``table`` has the columns of ``claims.csv`` (``statement``, ``expected``, ``measured``, ``verdict``;
    a table without ``verdict`` is read from ``holds``: True / False / None for not measured). Failing
    claims are :data:`FAILING_CLAIM` take-aways; ``limit`` inconclusive ones are named, the rest counted.
    """
    table = pd.DataFrame(table)
    if table.empty:
        return []
    if "verdict" in table:
        verdict = table.verdict.fillna("not measured")
    else:
        verdict = table.holds.map(lambda v: "holds" if v is True else "fails" if v is False else "not measured")
    table = table.assign(verdict=verdict)
    good, bad, undecided = int((verdict == "holds").sum()), table[verdict == "fails"], table[verdict == "inconclusive"]
    blocked, unmeasured = int((verdict == "blocked").sum()), int((verdict == "not measured").sum())
    measured = good + len(bad) + len(undecided)
    sentence = f"{good} of {measured} measured claims hold" if measured else "No claim could be measured"
    for count, words in ((len(bad), "fail"), (len(undecided), "inconclusive"), (blocked, "blocked by runs that did "
                                                                                 "not happen here"),
                         (unmeasured, "not measured")):
        if count:
            sentence += f"; {count} {words}"
    out = [Takeaway(sentence + ".", FAILING_CLAIM) if len(bad) else sentence + "."]
    # A target of ours that fails beside its paper claim failing too is one failure: said once, with the paper's.
    def twin(row):
        return (row.get("experiment"), cell_text(row.get("paper_value")))

    failing = bad.to_dict("records")
    ours_too = ({twin(row) for row in failing if row.get("target") == "ours"}
                & {twin(row) for row in failing if row.get("target") == "paper" and twin(row)[1]})
    for row in failing:
        if row.get("target") == "ours" and twin(row) in ours_too:
            continue
        also = "; our own looser target fails too" if row.get("target") == "paper" and twin(row) in ours_too else ""
        out.append(Takeaway(f"Fails: {row['statement']} (measured {row['measured']}, expected {row['expected']}{also}); "
                            f"likely cause: {likely_cause(row)}.", FAILING_CLAIM))
    if len(undecided):
        causes = pd.Series([likely_cause(row).partition(" (")[0] for row in undecided.to_dict("records")])
        counted = ", ".join(f"{cause} × {n}" for cause, n in causes.value_counts().items())
        out.append(f"Inconclusive ({counted}): " + _listing(
            (f"{row.statement} (measured {row.measured}, expected {row.expected})" for row in undecided.itertuples()),
            limit) + ".")
    return out


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
                        f"{_label(best[label_col])} at {ms(best[time_col])} ({number(best.psnr)} dB)")
            if slowest[time_col] > best[time_col]:
                sentence += (f", {change_words(best[time_col] / slowest[time_col])} than the slowest that gets there")
            sentences.append(sentence + ".")
        elif group.psnr.notna().any():
            top = group.loc[group.psnr.idxmax()]
            sentences.append(f"On {scene} no setting reaches {number(psnr_min)} dB PSNR; the most accurate is "
                             f"{_label(top[label_col])} at {number(top.psnr)} dB ({ms(top[time_col])}).")
    return sentences


def accuracy_failures(frame, *, psnr_min=PSNR_GOOD, scene_col="scene", label_col="technique"):
    """Where a setting falls below ``psnr_min``: one sentence listing them, worst first."""
    bad = frame[frame.psnr < psnr_min].sort_values("psnr")
    if bad.empty:
        if frame.psnr.notna().any():
            return [f"Every setting reaches {number(psnr_min)} dB PSNR on every scene "
                    f"(worst {number(frame.psnr.min())} dB)."]
        return []
    items = (f"{_label(row[label_col])} on {row[scene_col]} ({number(row.psnr)} dB)" for _, row in bad.iterrows())
    return [Takeaway(f"Below {number(psnr_min)} dB PSNR (where a setting fails): {_listing(items, 4)}.",
                     ACCURACY_FAILURE)]


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
