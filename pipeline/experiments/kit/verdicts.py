"""A claim's verdict: holds, fails, inconclusive, blocked or not measured, from the runs that did and did not happen.

A timing claim whose confidence interval straddles its bound is **inconclusive**
(:mod:`~pipeline.experiments.kit.intervals`): the frames taken cannot tell whether it holds. So is one
with no frames behind it or fewer than :data:`~pipeline.experiments.kit.intervals.MIN_FRAMES` in an arm
(:func:`~pipeline.experiments.kit.intervals.timing_decision`), and a missing value is "not measured"
(:func:`~pipeline.experiments.kit.intervals.decide` refuses NaN): judging fails closed.

A claim is checked on the successful runs of its experiment. Where runs that should have produced
measurements did not (they failed, their backend cannot run here, their data is absent:
:data:`core.outcomes.INCOMPLETE_CAUSES`), a check computed on the rest can give an answer the whole
data would not: ``kainz2009-table1``'s narrow-band claim read "fails, ×7.24" with every run and
"holds, ×1.26" once ``C8.tiled`` had failed. Such a claim is **blocked**, naming the runs it needs.
A run skipped because its backend lacks a feature the scene uses is a limit the experiment planned
for (the backend's capabilities say so), not a missing measurement.

Which runs a check needs is found by perturbation, so that no check has to declare its inputs: every
missing run is stood in for by rows that carry its tags, options and planned views, with extreme
measurements (every time, counter, statistic and image metric at a thousandth of the smallest value
seen and at a thousand times the largest). A check that reads such a run answers differently with
its stand-ins than without (or raises); a check that never selects it answers the same. The same test
decides, for the take-away sentences an experiment computes with its checks, whether the sentence can
be said (:func:`depends_on_missing`).
"""

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from core.outcomes import CAUSE_WORDS, INCOMPLETE_CAUSES, cause_of
from pipeline.experiments.kit.intervals import format_processes, parse_processes, processes_to_decide
from pipeline.experiments.kit.results import MissingColumn
from reports.metrics import METRIC_KEYS
from reports.takeaways import cell_text

VERDICTS = ("holds", "fails", "inconclusive", "blocked", "not measured")
"""Every verdict a claim can get, in the order the report counts them."""

MEASUREMENT_PREFIXES = ("time_", "count_", "info_", "stat_")
"""Columns a run's record measures (the rest describe the run or where it ran)."""

MEASUREMENT_COLUMNS = (*METRIC_KEYS, "diff_png", "png", "exr", "metrics_reason")
"""Per-view columns that only a rendered run has: its comparison with the reference and its images."""

ATTRIBUTE_EACH = 8
"""Up to this many missing runs of one backend are tested one by one to name the ones a check needs;
more are named as a group (a backend that did not run at all is one cause, not a hundred)."""


@dataclass(frozen=True)
class Missing:
    """Runs a verdict is blocked by: one run, or every missing run of a backend for one cause."""

    label: str
    backend: str
    cause: str
    runs: tuple

    whole_backend: bool = False

    def describe(self):
        """``"cl-tiled, which cannot run here (all 114 of its runs)"``, ``"run C8.tiled, which failed"``."""
        text = f"{self.label}, which {CAUSE_WORDS.get(self.cause, 'did not run')}"
        return text + (f" (all {len(self.runs)} of its runs)" if self.whole_backend else "")


def incomplete_runs(rows):
    """The rows of runs that should have produced measurements here and did not (one row per run)."""
    if rows.empty or "status" not in rows:
        return rows.iloc[:0]
    causes = [cause_of(status, cause) for status, cause in zip(rows.status, rows.get("cause", [""] * len(rows)))]
    cause = pd.Series(causes, index=rows.index)
    missing = rows[cause.isin(INCOMPLETE_CAUSES)].copy()
    missing["cause"] = cause[missing.index]
    return missing.drop_duplicates("run")


def _is_measurement(column):
    return column.startswith(MEASUREMENT_PREFIXES) or column in MEASUREMENT_COLUMNS


GENERIC_EXTREMES = (1e-6, 1e6)
"""Stand-in values of a measurement no successful run reported (the check asks for it by name)."""

IMAGE_COLUMNS = ("png", "exr", "diff_png")
"""Image paths: a stand-in points at a real image of another run (a check that compares images reads it)."""


def _extremes(ok):
    """``{column: (low, high)}`` stand-in values for every numeric measurement column of ``ok``."""
    out = {}
    for column in ok.columns:
        if not _is_measurement(column) or column in IMAGE_COLUMNS:
            continue
        values = pd.to_numeric(ok[column], errors="coerce")
        values = values[np.isfinite(values)]
        if values.empty:
            continue
        low, high = float(values.min()), float(values.max())
        spread = 1e3 * (high - low + abs(high) + 1.0)
        out[column] = (low / 1e3 if low > 0 else low - spread, high * 1e3 if high > 0 else high + spread)
    return out


def stand_ins(ok, missing, extremes, which):
    """Rows standing in for the ``missing`` runs: their own tags and options, extreme measurements.

    ``which`` is 0 for the low extremes and 1 for the high ones; ``extremes`` is
    ``{column: (low, high)}`` and may name columns no successful run has. Columns that describe where
    a run ran (environment, host) and image paths are copied from a successful run of the same
    backend where there is one.
    """
    rows = []
    for _, run in missing.iterrows():
        same_backend = ok[ok.backend == run.backend] if "backend" in ok else ok.iloc[:0]
        template = (same_backend if not same_backend.empty else ok).iloc[0].to_dict() if not ok.empty else {}
        own = {k: v for k, v in run.items() if not (isinstance(v, float) and np.isnan(v))}
        row = {**{k: v for k, v in template.items() if not _is_measurement(k) or k in IMAGE_COLUMNS}, **own,
               "status": "ok", "reason": "", "cause": ""}
        for column in {*template, *extremes}:
            if _is_measurement(column) and column not in IMAGE_COLUMNS:
                row[column] = extremes[column][which] if column in extremes else np.nan
        views = str(run.get("planned_views") or "").split(";")
        for view in [v for v in views if v] or [template.get("view", "")]:
            rows.append({**row, "view": view})
    frame = pd.DataFrame(rows)
    return frame.drop(columns=["planned_views"], errors="ignore")


def _answer(check, frame):
    """What ``check`` says of ``frame``, comparable across frames (an exception is an answer too)."""
    try:
        value = check(frame)
    except Exception as exc:  # noqa: BLE001 - a check that breaks on the stand-ins reads them
        return ("raised", type(exc).__name__, str(exc))
    if hasattr(value, "__dataclass_fields__"):
        return tuple(str(getattr(value, name)) for name in value.__dataclass_fields__)
    return repr(value)


def _asked_column(check, frame):
    """The column ``check`` asks for by name and ``frame`` lacks (``None`` when it asks for none)."""
    try:
        check(frame)
    except MissingColumn as exc:
        return exc.column
    except KeyError as exc:  # pandas: frame["name"]
        name = exc.args[0] if exc.args else None
        return name if isinstance(name, str) and name not in frame else None
    except Exception:  # noqa: BLE001 - any other answer is judged by _answer
        return None
    return None


def _reads(check, ok, missing, baseline, extremes):
    """Whether ``check`` answers differently once ``missing`` runs stand in with extreme values.

    A check that asks for a measurement only the missing runs would have reported (a counter only
    their backend makes) gets it in the stand-ins, and is asked again.
    """
    extremes = dict(extremes)
    for which in (0, 1):
        for _ in range(8):
            trial = pd.concat([ok, stand_ins(ok, missing, extremes, which)], ignore_index=True)
            asked = _asked_column(check, trial)
            if asked is None or asked in extremes or not _is_measurement(asked):
                break
            extremes[asked] = GENERIC_EXTREMES
        if _answer(check, trial) != baseline:
            return True
    return False


def depends_on_missing(check, rows):
    """The :class:`Missing` runs of ``rows`` that ``check`` would read; ``[]`` when it reads none.

    Parameters
    ----------
    check : callable
        ``check(frame)`` on the successful rows, as a claim's check (any return value; exceptions
        count as answers).
    rows : pandas.DataFrame
        Every row of the experiment, the runs that did not succeed included (one row each, with
        ``status``, ``cause`` and ``planned_views``).
    """
    missing = incomplete_runs(rows)
    if missing.empty:
        return []
    ok = rows[rows.status == "ok"].reset_index(drop=True)
    baseline = _answer(check, ok)
    extremes = _extremes(ok)
    if not _reads(check, ok, missing, baseline, extremes):
        return []
    found = []
    for (backend, cause), group in missing.groupby(["backend", "cause"], sort=True):
        if not _reads(check, ok, group, baseline, extremes):
            continue
        attempted = rows[rows.backend == backend].drop_duplicates("run")
        if len(group) == len(attempted):
            found.append(Missing(backend, backend, cause, tuple(group.run), whole_backend=True))
        elif len(group) > ATTRIBUTE_EACH:
            found.append(Missing(f"{len(group)} runs of {backend}", backend, cause, tuple(group.run)))
        else:
            needed = [run for _, run in group.iterrows()
                      if _reads(check, ok, group[group.run == run.run], baseline, extremes)]
            # Runs that matter only together (a ratio of two missing runs) are named together.
            for run in needed or [r for _, r in group.iterrows()]:
                found.append(Missing(f"run {run.run}", backend, cause, (run.run,)))
    if not found:  # several causes only together: name them all
        found = [Missing(f"run {run.run}", run.backend, run.cause, (run.run,)) for _, run in missing.iterrows()]
    return found


def blocked_detail(missing):
    """``"blocked: needs run C8.tiled, which failed"``-style text for a verdict's detail."""
    return "blocked: needs " + "; ".join(m.describe() for m in missing)


@dataclass(frozen=True)
class Verdict:
    """A claim checked: its verdict (one of :data:`VERDICTS`) with what was measured and why."""

    verdict: str
    measured: str
    holds: bool | None
    detail: str
    missing: tuple = ()
    interval: tuple | None = None
    margin: float | None = None
    disturbed_views: int = 0
    """How many disturbed views an inconclusive verdict rests on (0: none)."""
    frames: int | None = None
    """The timed frames behind the interval, in its thinnest arm (:attr:`ClaimResult.frames`)."""
    processes: int | None = None
    """The processes behind the interval: the fewest that timed any of the experiment's timed runs (``None``:
    no timed frames behind it)."""


TIMED_KINDS = ("timing", "cost model")
"""The kinds of claim (:data:`~pipeline.experiments.kit.model.CLAIM_KINDS`) whose intervals rest on timed frames."""


def fewest_processes(ok):
    """The fewest processes that timed any successful timed row of an experiment (``None``: none is timed)."""
    if "processes" not in ok:
        return None
    counts = pd.to_numeric(ok["processes"], errors="coerce").dropna()
    return int(counts.min()) if not counts.empty else None


DISTURBED_SPEED_UP = 10.0
"""How much faster a disturbed view's frames may have been on a quiet machine: a starved parallel run
was measured 26 times slower than on a quiet machine, a single-threaded one a few per cent."""

DISTURBED_TRIALS = 2
"""Perturbations tried besides every disturbed view at once: each gives every disturbed view a factor of
its own (seeded), since a disturbance slows two runs, even two timed together, by different amounts (a
starved parallel run's slowdown depends on how its work synchronises)."""


def disturbed_views(ok):
    """The successful rows whose timed frames were disturbed (``info_disturbed`` says why)."""
    if "info_disturbed" not in ok:
        return ok.iloc[:0]
    reasons = ok["info_disturbed"].fillna("").astype(str)
    return ok[reasons.str.strip() != ""]


def _sped_up(ok, index, factors):
    """``ok`` with the times and frames of the rows ``index`` divided by ``factors`` (one per row)."""
    frame = ok.copy()
    factors = pd.Series(factors, index=index, dtype=float)
    for column in frame.columns:
        if column.startswith("time_"):
            frame.loc[index, column] = pd.to_numeric(frame.loc[index, column], errors="coerce") / factors
        elif column.startswith("frames_"):
            frame.loc[index, column] = [
                format_processes([frames / factor for frames in parse_processes(text)])
                if isinstance(text, str) and text.strip() else text
                for text, factor in zip(frame.loc[index, column], factors)]
    return frame


def rests_on_disturbed(claim, ok, before=None):
    """The disturbed views ``claim``'s verdict rests on: ``[(run, view, reason)]``, empty if none.

    A verdict rests on them when its value moves with their times, shortened as they may have been on
    a quiet machine: every one :data:`DISTURBED_SPEED_UP` times shorter, then (:data:`DISTURBED_TRIALS`
    times) each by a factor of its own between 1 and that. The value, not only the verdict: a random
    change rarely restores what a disturbance broke (under a CPU hog the cubes' times fitted a line with
    R² 0.909 against 0.998 quiet, and no random speed-up of the disturbed cubes brought that back), so
    a verdict that reads disturbed times is not trusted. ``before`` is the claim's result on ``ok``
    where the caller has it.
    """
    disturbed = disturbed_views(ok)
    if disturbed.empty:
        return []
    before = before if before is not None else claim.evaluate(ok)
    rng = np.random.default_rng(len(disturbed))
    trials = [np.full(len(disturbed), DISTURBED_SPEED_UP)]
    trials += [np.exp(rng.uniform(0, np.log(DISTURBED_SPEED_UP), len(disturbed))) for _ in range(DISTURBED_TRIALS)]
    for factors in trials:
        after = claim.evaluate(_sped_up(ok, disturbed.index, factors))
        if (before.measured, before.holds, before.inconclusive) != (after.measured, after.holds, after.inconclusive):
            return [(row.run, row.get("view", ""), row.info_disturbed) for _, row in disturbed.iterrows()]
    return []


def disturbed_detail(views):
    """``"inconclusive: it rests on 3 views timed while the machine was disturbed (...)"``."""
    named = ", ".join(f"{run}/{view}" for run, view, _ in views[:3]) + (f" and {len(views) - 3} more" if len(views) > 3 else "")
    return (f"inconclusive: its verdict rests on {len(views)} view{'s' if len(views) != 1 else ''} timed while the "
            f"machine was disturbed ({named}: {views[0][2]})")


def unless_without_interval(claim, result):
    """``result``, or inconclusive where ``claim`` is a timing that ``result`` decides on point values alone.

    A time measured once, or a verdict read from the order of a few medians, says nothing of how the next
    run's frames fall: without an interval a timing claim cannot hold or fail.
    """
    if claim.kind != "timing" or result.holds is None or result.interval is not None:
        return result
    why = "inconclusive: a timing decided without an interval (no bootstrap over timed frames behind it)"
    return replace(result, holds=None, inconclusive=True,
                   detail=f"{result.detail}; {why}" if result.detail else why)


def unless_one_process(claim, result, processes):
    """``result``, or inconclusive where ``claim`` rests on timed frames that one process per run took.

    Frames within one process share what the next process does not (memory layout, compiled code, driver
    state, cache and clock history), so their interval is narrower than the spread between two runs of
    volbench: issue 23 measured ×2.23 and ×1.96 in two runs, each ±2 %. A run of one process cannot
    measure that spread, so it cannot widen its interval by it either, and must not decide.
    """
    if claim.kind not in TIMED_KINDS or result.holds is None or processes != 1:
        return result
    why = ("inconclusive: its interval rests on one process per run (the profile's replicates is 1), whose "
           "frames cannot show the spread between two processes; replicates ≥ 2 would decide it")
    return replace(result, holds=None, inconclusive=True,
                   detail=f"{result.detail}; {why}" if result.detail else why)


def judge(claim, rows):
    """The :class:`Verdict` of ``claim`` on an experiment's ``rows`` (every run, successful or not).

    A claim that would hold or fail differently had its disturbed views been quiet
    (:func:`rests_on_disturbed`) is inconclusive: a busy machine must not decide it. So is a timing claim
    whose check decided it without an interval (:func:`unless_without_interval`), or on the frames of one
    process per run (:func:`unless_one_process`).
    """
    ok = rows[rows.status == "ok"] if not rows.empty else rows
    result = unless_without_interval(claim, claim.evaluate(ok))
    # The raw check: Claim.evaluate turns a missing column into "not measurable", which would hide
    # the column a stand-in must supply.
    missing = depends_on_missing(claim.check, rows) if not rows.empty else []
    if missing:
        return Verdict("blocked", "", None, blocked_detail(missing), tuple(missing))
    processes = fewest_processes(ok) if result.interval is not None and claim.kind in TIMED_KINDS else None
    result = unless_one_process(claim, result, processes)
    if result.holds is not None and not ok.empty:
        views = rests_on_disturbed(claim, ok, before=result)
        if views:
            return Verdict("inconclusive", result.measured, None, f"{disturbed_detail(views)}; {result.detail}".rstrip("; "),
                           interval=result.interval, margin=result.margin, disturbed_views=len(views),
                           frames=result.frames, processes=processes)
    if result.inconclusive:
        return Verdict("inconclusive", result.measured, None, _with_processes_needed(result, processes),
                       interval=result.interval, margin=result.margin, frames=result.frames, processes=processes)
    if result.holds is None:
        return Verdict("not measured", result.measured, None, result.detail)
    return Verdict("holds" if result.holds else "fails", result.measured, bool(result.holds), result.detail,
                   interval=result.interval, margin=result.margin, frames=result.frames, processes=processes)


def _with_processes_needed(result, processes):
    """An inconclusive result's detail, ending with about how many processes per arm would decide it where its
    interval straddles the bound (:func:`~pipeline.experiments.kit.intervals.processes_to_decide`)."""
    if "inconclusive:" in result.detail:  # undecidable whatever the processes: too few frames, no interval
        return result.detail
    needed = processes_to_decide(result.value, result.interval, result.bound, processes)
    if needed is None or needed <= processes:
        return result.detail
    words = (f"its interval straddles the bound: about {needed} processes per arm (here {processes}) would decide it "
             "at the spread measured" if needed <= MORE_PROCESSES_SAID else
             f"its interval straddles the bound, and the value is too near it for more than {MORE_PROCESSES_SAID} "
             "processes per arm to decide it at the spread measured")
    return f"{result.detail}; {words}" if result.detail else words


MORE_PROCESSES_SAID = 100
"""Processes per arm above which "about N would decide it" is not worth saying: the value sits on its bound."""


VERDICT_WORDS = {"holds": "holds", "fails": "does not hold", "inconclusive": "inconclusive"}
"""How a take-away sentence says each verdict that was judged on measurements."""


def claim_sentences(judged):
    """A take-away sentence per claim that holds, fails or is inconclusive: statement, measurement, verdict, detail.

    ``judged`` is the experiment's rows of ``claims.csv`` (``statement``, ``measured``, ``verdict``,
    ``detail``): a page says what the claims table says, and judges nothing again. Blocked and
    unmeasured claims get no sentence: the claims table gives each its reason and the page's count of
    verdicts says how many there are.
    """
    sentences = []
    if judged is None:
        return sentences
    for claim in judged.to_dict("records"):
        word = VERDICT_WORDS.get(claim.get("verdict"))
        if word:
            detail = cell_text(claim.get("detail")).removeprefix("inconclusive: ")
            sentences.append(f"{claim['statement']}: {cell_text(claim.get('measured'))}, {word} ({detail}).")
    return sentences
