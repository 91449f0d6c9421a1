"""Confidence intervals of timing claims, and the third verdict: a claim whose interval straddles its bound.

A run is timed in one or more processes (the profile's ``replicates``), each with its own warm-up and
frames: the process is the unit of replication, as in pyperf, since frames within one process share
what another does not (memory layout, compiled code, driver state, cache and clock history). A run's
time in the tables is the mean over its processes of each one's median frame; the frames themselves are
kept (``frames_<stage>``: the seconds of every timed frame, space-separated in the order they were
taken, one process after another separated by `` | ``).

A claim that rests on times gets an interval by the percentile bootstrap, as pyperf and hyperfine
summarise a benchmark by its distribution rather than one number, drawn in two stages: each draw
resamples the processes with replacement, then each process's frames, recomputes each run's time, the
claim's statistic over the runs it reads and then its value (a ratio, a share, a slope). Runs timed
together in one job (:attr:`~pipeline.experiments.kit.model.Run.interleave`) share their processes and
are resampled *by process and by round*: the same processes of A and B are drawn, and within one the
frames of one round of A and B together, so what slowed both (a process, a disturbance) cancels in
their ratio. With one process per run the interval covers its frames only, not the spread between two
runs of volbench, which one process cannot measure: such a timing claim is inconclusive
(:func:`~pipeline.experiments.kit.verdicts.unless_one_process`).

The verdict follows hyperfine's and asv's rule for "significantly different": a claim holds only when
its whole interval is on the holding side of the bound, fails when the whole interval is on the other
side, and is *inconclusive* otherwise. The draws are seeded, so the same frames give the same interval.
"""

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

DRAWS = 2000
"""Bootstrap resamples per interval: the 2.5 % and 97.5 % percentiles move by well under 1 % between seeds."""

LEVEL = 0.95
"""Coverage of the intervals claims report."""

MIN_FRAMES = 5
"""Timed frames an arm of a timing claim needs at least: with fewer, its interval is too coarse to decide (one
frame gives a zero-width interval, three resample to at most ten distinct medians), and the claim is
inconclusive."""

PROCESS_FRAMES = 3
"""Timed frames each process of a replicated run takes at least: its median must be one of its frames'."""

PROCESS_SEPARATOR = " | "
"""Between two processes' frames in a ``frames_<stage>`` cell."""

SEED = 20260125


def frames_column(column):
    """The column holding the frames of a time column (``time_total`` → ``frames_total``), or ``None``.

    Only per-frame times have frames: ``time_<stage>_min``/``_max`` (extremes) and derived columns do not.
    """
    if not column.startswith("time_") or column.endswith(("_min", "_max")):
        return None
    return "frames_" + column.removeprefix("time_")


def parse_processes(text):
    """The seconds of a ``frames_<stage>`` cell, one array per process (``None`` for an empty cell)."""
    if not isinstance(text, str) or not text.strip():
        return None
    return [np.array(part.split(), dtype=float) for part in text.split(PROCESS_SEPARATOR.strip())]


def parse_frames(text):
    """The seconds of a ``frames_<stage>`` cell, every process's frames together (``None`` for an empty cell)."""
    processes = parse_processes(text)
    return None if processes is None else np.concatenate(processes)


def format_frames(values):
    """``frames_<stage>``'s text for one process: every frame's seconds to 6 significant digits."""
    return " ".join(f"{v:.6g}" for v in values)


def format_processes(per_process):
    """``frames_<stage>``'s text for several processes' frames (:data:`PROCESS_SEPARATOR` between them)."""
    return PROCESS_SEPARATOR.join(format_frames(values) for values in per_process)


def process_time(per_process, reduce=np.median):
    """A run's time from its processes' frames: the mean of each process's ``reduce`` (median) frame."""
    return float(np.mean([reduce(values) for values in per_process]))


class Resampler:
    """Seeded bootstrap indices shared by runs timed together.

    ``indices(key, n)`` gives the ``(DRAWS, n)`` resample of ``n`` frames (or processes); rows with the
    same key (the same interleave group, view and process) and the same number of frames get the same
    indices, so their processes and, within one, their frames are drawn together round by round.
    """

    def __init__(self, draws=DRAWS, seed=SEED):
        self.draws = draws
        self._rng = np.random.default_rng(seed)
        self._cache = {}
        self.fewest = None
        """The fewest frames of any row resampled so far (``None``: none was)."""

    def indices(self, key, n):
        key = (key, n)
        if key not in self._cache:
            self._cache[key] = self._rng.integers(0, n, size=(self.draws, n))
        return self._cache[key]

    def saw(self, frames):
        """Note a row resampled with ``frames`` timed frames in all (over its processes)."""
        self.fewest = frames if self.fewest is None else min(self.fewest, frames)

    def arms(self):
        """``{"its thinnest run": frames}`` for :func:`timing_decision` (empty where nothing was resampled): what
        a value drawn with this resampler rests on, where its check does not name its arms."""
        return {"its thinnest run": self.fewest} if self.fewest is not None else {}


def _row_key(row, position):
    """Rows with one key are drawn together: the runs of one interleave group and view timed in the same processes
    (a group whose backends render through two OpenGL stacks is timed in a process per stack,
    :func:`pipeline.experiments.stack_parts`: those rows are drawn apart, as separate runs are)."""
    group = row.get("interleave") if hasattr(row, "get") else None
    if isinstance(group, str) and group:
        return ("group", row.get("experiment"), group, row.get("view"), _processes(row))
    return ("run", row.get("run"), row.get("view"), position)


def _processes(row):
    """The processes that timed a row, as recorded (``harness_pids`` of a replicated run, else ``harness_pid``;
    ``None`` for rows that do not say)."""
    for column in ("harness_pids", "harness_pid"):
        value = row.get(column)
        if isinstance(value, (list, tuple)) or (value is not None and not pd.isna(value)):
            return str(list(value) if isinstance(value, (list, tuple)) else value)
    return None


REDUCE = {"median": np.median, "min": np.min, "max": np.max, "mean": np.mean}


def row_draws(rows, column, resampler):
    """``(DRAWS, len(rows))``: each row's time (:func:`process_time`) of ``column`` in every draw, or ``None``.

    Each draw resamples a row's processes, then each process's frames (the first stage is skipped for a row
    of one process). ``None`` where any row has no frames for the column (a count, a metric, results
    written before frames were kept): such a claim is judged on its point value alone.
    """
    frames = frames_column(column)
    if frames is None or frames not in rows or rows.empty:
        return None
    out = np.empty((resampler.draws, len(rows)))
    for i, (index, row) in enumerate(rows.iterrows()):
        processes = parse_processes(row[frames])
        if processes is None or any(len(values) == 0 for values in processes):
            return None
        key = _row_key(row, index)
        resampler.saw(sum(map(len, processes)))
        medians = np.stack([np.median(values[resampler.indices(key if p == 0 else (key, p), len(values))], axis=1)
                            for p, values in enumerate(processes)])
        if len(processes) == 1:
            out[:, i] = medians[0]
        else:
            drawn = resampler.indices(("processes", key), len(processes)).T  # (processes, DRAWS)
            out[:, i] = medians[drawn, np.arange(resampler.draws)].mean(axis=0)
    return out


def once_draws(rows, column, resampler):
    """``(DRAWS, len(rows))``: each row's time of ``column``, a stage its processes timed once each (``once_<stage>``,
    preprocessing), in every draw, or ``None`` where a row has no such cell (one process, or an older record).

    The processes are drawn as :func:`row_draws` draws the same row's (the same indices): a ratio of a
    preprocessing stage to a frame time pairs each process's build with its own frames.
    """
    once = "once_" + column.removeprefix("time_")
    if once not in rows or rows.empty:
        return None
    out = np.empty((resampler.draws, len(rows)))
    for i, (index, row) in enumerate(rows.iterrows()):
        processes = parse_processes(row[once])
        if processes is None or len(processes) < 2 or any(len(values) != 1 for values in processes):
            return None
        values = np.concatenate(processes)
        drawn = resampler.indices(("processes", _row_key(row, index)), len(values))
        out[:, i] = values[drawn].mean(axis=1)
    return out


def frame_count(rows, column):
    """How many timed frames of ``column`` the rows hold together (0 where ``column`` is not a frame time)."""
    frames = frames_column(column)
    if frames is None or frames not in rows:
        return 0
    return int(sum(len(values) for values in map(parse_frames, rows[frames]) if values is not None))


def statistic_draws(rows, column, statistic, resampler):
    """``(DRAWS,)`` draws of ``statistic`` over the rows' median frames, or ``None`` (see :func:`row_draws`)."""
    per_row = row_draws(rows, column, resampler)
    if per_row is None:
        return None
    return REDUCE[statistic](per_row, axis=1)


def interval_of(draws, level=LEVEL):
    """The percentile interval ``(low, high)`` of bootstrap ``draws`` (``None`` passes through)."""
    if draws is None:
        return None
    draws = np.asarray(draws, float)
    draws = draws[np.isfinite(draws)]
    if draws.size == 0:
        return None
    tail = 100 * (1 - level) / 2
    low, high = np.percentile(draws, [tail, 100 - tail])
    return float(low), float(high)


@dataclass(frozen=True)
class Decision:
    """A value judged against a bound with its interval.

    ``holds`` is True or False when the interval (or, without one, the value) is wholly on one side,
    ``None`` when the interval straddles the bound (:attr:`inconclusive`). ``margin`` is the value's
    relative distance from the bound, positive on the holding side (+0.1: 10 % clear of it).
    """

    value: float
    interval: tuple | None
    holds: bool | None
    margin: float
    why: str = ""
    """Why a decision is inconclusive whatever its interval says (too few frames, no frames), or empty."""
    frames: int | None = None
    """The timed frames behind the interval in its thinnest arm (``None``: not a timing, or not counted)."""
    bound: float | None = None
    """The bound the decision turned on: the one its interval straddles, else the nearer one."""

    @property
    def inconclusive(self):
        return self.holds is None


def _margin(value, at_least, at_most):
    margins = []
    if at_least is not None:
        margins.append((value - at_least) / abs(at_least) if at_least else value)
    if at_most is not None:
        margins.append((at_most - value) / abs(at_most) if at_most else -value)
    return float(min(margins)) if margins else float("nan")


def decide(value, interval, *, at_least=None, at_most=None):
    """A :class:`Decision`: holds, fails or inconclusive from ``value``, its ``interval`` and the bounds.

    Raises
    ------
    ValueError
        ``value`` is not a number (a missing or uncounted measurement): the claim is not measured, never a
        verdict that a comparison with NaN would make.
    """
    def inside(v):
        return bool((at_least is None or v >= at_least) and (at_most is None or v <= at_most))

    value = float(value)  # a NumPy scalar's comparisons give numpy.bool_, which `is False` misses
    if np.isnan(value):
        raise ValueError("the measured value is missing (NaN): a measurement it rests on was not taken")
    margin = _margin(value, at_least, at_most)
    bounds = [bound for bound in (at_least, at_most) if bound is not None]
    nearest = min(bounds, key=lambda bound: abs(value - bound)) if bounds else None
    if interval is None:
        return Decision(value, None, inside(value), margin, bound=nearest)
    low, high = interval
    if inside(low) and inside(high):
        holds = True
    elif (at_least is not None and high < at_least) or (at_most is not None and low > at_most):
        holds = False
    else:
        holds = None
    straddled = [bound for bound in bounds if low <= bound <= high]
    return Decision(value, (low, high), holds, margin, bound=straddled[0] if straddled else nearest)


def processes_to_decide(value, interval, bound, processes):
    """About how many processes per arm would decide a value whose ``interval`` straddles ``bound``, as pyperf
    says how many more runs a benchmark needs: the interval's half-width towards the bound shrinks as one over
    the square root of the processes, and must fall below the value's distance from the bound. ``None`` where
    it cannot say (no interval or bound, the value on the bound).
    """
    if interval is None or bound is None or not processes or not np.isfinite(value) or value == bound:
        return None
    low, high = interval
    half = (value - low) if bound < value else (high - value)
    needed = processes * (half / abs(value - bound)) ** 2
    return int(np.ceil(needed)) if np.isfinite(needed) else None


def timing_decision(value, draws, arms, *, at_least=None, at_most=None):
    """A timing claim's :class:`Decision`: ``value`` with the interval of its bootstrap ``draws``, inconclusive
    where frames cannot decide it.

    ``arms`` maps each side's name to how many timed frames it rests on (:func:`frame_count`; empty where the
    caller's draws do not say). Without draws (a side kept no frames) or with fewer than :data:`MIN_FRAMES`
    frames in an arm the decision is inconclusive, saying why: a point value or a zero-width interval would
    decide it on nothing.
    """
    decision = decide(value, interval_of(draws), at_least=at_least, at_most=at_most)
    decision = replace(decision, frames=min(arms.values()) if arms else None)
    few = {arm: n for arm, n in arms.items() if n < MIN_FRAMES}
    if decision.interval is None and draws is not None and not any(n == 0 for n in arms.values()):
        why = "its draws give no finite interval (a zero denominator in every draw)"
    elif decision.interval is None:
        why = "no timed frames behind " + (", ".join(arm for arm, n in arms.items() if n == 0) or "its interval")
    elif few:
        why = "; ".join(f"{arm}: {n} timed frame{'s' * (n != 1)}" for arm, n in few.items()) + \
            f", fewer than {MIN_FRAMES}"
    else:
        return decision
    return replace(decision, holds=None, why=why)


def draws_decision(value, draws, arms, *, at_least=None, at_most=None):
    """``value`` judged with the interval of its bootstrap ``draws``: a frame time by :func:`timing_decision`
    (``arms``, each side's timed frames), a count or a metric (``arms`` ``None``: no frames) by :func:`decide`."""
    if arms is None:
        return decide(value, interval_of(draws), at_least=at_least, at_most=at_most)
    return timing_decision(value, draws, arms, at_least=at_least, at_most=at_most)


def combine(decisions):
    """Every one of several decisions ("every scene"): fails if one fails, inconclusive if one is, else holds.

    The combined margin is the smallest, the interval the one of the decision with that margin.
    """
    decisions = list(decisions)
    if not decisions:
        raise ValueError("no decisions to combine")
    worst = min(decisions, key=lambda d: d.margin if np.isfinite(d.margin) else np.inf)
    if any(d.holds is False for d in decisions):
        holds = False
        worst = min((d for d in decisions if d.holds is False), key=lambda d: d.margin)
    elif any(d.holds is None for d in decisions):
        holds = None
        worst = min((d for d in decisions if d.holds is None), key=lambda d: d.margin)
    else:
        holds = True
    return replace(worst, holds=holds)


def ratio_decision(top, bottom, *, column="time_total", statistic="median", at_least=None, at_most=None,
                   resampler=None, bottom_column=None):
    """The ratio of ``statistic`` of ``column`` over rows ``top`` and rows ``bottom``, judged with its interval.

    ``bottom_column`` (default ``column``) compares two stages (a share, one scope against another).
    Rows of one interleave group are resampled round by round (paired).
    """
    resampler = resampler or Resampler()
    bottom_column = bottom_column or column
    value = _point(top, column, statistic) / _point(bottom, bottom_column, statistic)
    a = statistic_draws(top, column, statistic, resampler)
    b = statistic_draws(bottom, bottom_column, statistic, resampler)
    draws = a / b if a is not None and b is not None else None
    arms = (None if frames_column(column) is None
            else {"numerator": frame_count(top, column), "denominator": frame_count(bottom, bottom_column)})
    return draws_decision(value, draws, arms, at_least=at_least, at_most=at_most)


def _point(rows, column, statistic):
    values = pd.to_numeric(rows[column], errors="coerce").dropna().to_numpy()
    if values.size == 0:
        raise ValueError(f"no {column} in the rows")
    return float(REDUCE[statistic](values))


def interval_words(decision, show):
    """``"95 % CI ×1.02–×1.09"``: a decision's interval in words (empty without one)."""
    if decision.interval is None:
        return ""
    low, high = decision.interval
    return f"95 % CI {show(low)}–{show(high)}"


def interval_or_nan(draws, level=LEVEL):
    """``(low, high)`` of bootstrap ``draws`` (:func:`interval_of`), NaNs where there are none, for a table's columns.

    Parameters
    ----------
    draws : numpy.ndarray or None
        Bootstrap draws of a value; ``None`` where no frames were kept.
    level : float
        The interval's coverage.

    Returns
    -------
    tuple of float
        The interval's ends, or ``(nan, nan)``.
    """
    interval = interval_of(draws, level)
    return interval if interval is not None else (np.nan, np.nan)
