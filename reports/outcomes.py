"""What did not run, said once: runs grouped by backend, cause and message; backends that made no frame.

A backend that cannot run on a machine fails or skips every one of its runs with the same message
(114 cl-tiled runs, each with PoCL's compiler error). The report states such a message once, with
the number of runs it stands for, and says plainly at the top which backends produced no frame here
and which papers are therefore not reproduced on this machine. Run outcomes come from the records
(``status``, ``cause``: :mod:`core.outcomes`), not from probing the machine that builds the report.

Timings that other work disturbed are said the same way: the views still disturbed after they were
timed again and the parallel runs that had fewer free cores than workers, one group per experiment
and cause (:func:`timing_disturbances`).
"""

import re

import pandas as pd

from core.outcomes import CAUSE_WORDS, INCOMPLETE_CAUSES, cause_of

_ADDRESS = re.compile(r"0x[0-9a-fA-F]{6,}")
_SPACE = re.compile(r"\s+")


def reason_key(reason):
    """``reason`` with what differs between runs of one fault removed (object addresses, spacing)."""
    if reason is None or (isinstance(reason, float) and reason != reason):
        return ""
    return _SPACE.sub(" ", _ADDRESS.sub("0x…", str(reason))).strip()


def per_run(runs_df):
    """One row per run of ``runs_df`` (tidy: one row per run and view) with its ``cause`` filled in."""
    if runs_df is None or runs_df.empty:
        return pd.DataFrame(columns=["experiment", "run", "backend", "status", "cause", "reason", "record"])
    runs = runs_df.drop_duplicates(["experiment", "run"]).copy()
    runs["cause"] = [cause_of(s, c) for s, c in zip(runs.status, runs.get("cause", pd.Series(index=runs.index)))]
    runs["reason"] = [reason_key(r) for r in runs.get("reason", pd.Series("", index=runs.index))]
    return runs


def problem_groups(runs):
    """The runs of ``runs`` (:func:`per_run`) that made no frame, grouped by backend, cause and message.

    Returns a list of ``{"backend", "status", "cause", "planned", "reason", "count", "runs", "records"}``,
    largest groups first; ``planned`` is true for a feature the backend lacks (a limit the experiment
    expects), false for a run that should have produced a frame here.
    """
    bad = runs[runs.status != "ok"]
    groups = []
    for (backend, status, cause, reason), group in bad.groupby(["backend", "status", "cause", "reason"], sort=False):
        groups.append({"backend": backend, "status": status, "cause": cause, "planned": cause not in INCOMPLETE_CAUSES,
                       "reason": reason, "count": len(group), "runs": list(group.run),
                       "records": list(group.get("record", pd.Series([None] * len(group))))})
    groups.sort(key=lambda g: (g["planned"], -g["count"], g["backend"]))
    return groups


def backend_outcomes(runs):
    """Per backend of ``runs`` (:func:`per_run`): its runs, those that made frames, and why the rest did not.

    Returns ``{backend: {"runs", "ok", "missing", "planned", "ran", "cause", "reason"}}``: ``missing``
    runs should have made frames here (:data:`core.outcomes.INCOMPLETE_CAUSES`), ``planned`` ones
    met a feature the backend lacks; ``ran`` is whether any run made a frame; ``cause`` and
    ``reason`` are those of the backend's largest group of missing runs.
    """
    out = {}
    for backend, group in runs.groupby("backend", sort=False):
        missing = group[group.cause.isin(INCOMPLETE_CAUSES)]
        top = missing.groupby(["cause", "reason"]).size().sort_values(ascending=False)
        cause, reason = top.index[0] if len(top) else ("", "")
        out[backend] = {"runs": len(group), "ok": int((group.status == "ok").sum()), "missing": len(missing),
                        "planned": int(((group.status != "ok") & ~group.cause.isin(INCOMPLETE_CAUSES)).sum()),
                        "ran": bool((group.status == "ok").any()), "cause": cause, "reason": reason}
    return out


def silent_backends(outcomes):
    """The backends of :func:`backend_outcomes` that made no frame although runs of theirs should have."""
    return {name: o for name, o in outcomes.items() if not o["ran"] and o["missing"]}


def did_not_run(name, outcome):
    """One sentence: ``"cl-tiled made no frame here (0 of 114 runs): it cannot run here: <message>"``."""
    words = CAUSE_WORDS.get(outcome["cause"], "did not run")
    # The registry's wording of an unavailable backend would say the same thing twice.
    reason = outcome["reason"].removeprefix(f"backend {name!r} is not available here: ")
    text = f"{name} made no frame here (0 of {outcome['runs']} runs): it {words}"
    return text + (f": {reason}" if reason else "")


# ------------------------------------------------------------------------------ disturbed timings
_NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?")


def _text(value):
    """A cell of ``runs.csv`` as text: ``""`` for an empty one (NaN once read back)."""
    if value is None or (isinstance(value, float) and value != value):
        return ""
    return str(value).strip()


def _span(numbers):
    """``"0.75–2.34"`` from the same number of several sentences, as written; one value when they agree."""
    low, high = min(numbers, key=float), max(numbers, key=float)
    return low if float(low) == float(high) else f"{low}–{high}"


def _cause_groups(rows, reasons, timed_twice):
    """``rows`` whose ``reasons`` are not empty, grouped by experiment and cause.

    A reason may join several causes with ``"; "`` (:func:`pipeline.disturbance.verdict`); they stay
    together, so that each view is listed once. Reasons differing only in their numbers are one, said
    with the range of each number (``"other work used 0.75–2.34 cores while it was timed"``).
    """
    groups = {}
    for index, reason in reasons.items():
        row = rows.loc[index]
        for cause in filter(None, ["; ".join(part.strip() for part in reason.split(";") if part.strip())]):
            key = (row["experiment"], tuple(_NUMBER.split(cause)))
            group = groups.setdefault(key, {"numbers": [], "runs": {}, "views": 0, "timed_twice": 0, "rows": []})
            group["numbers"].append(_NUMBER.findall(cause))
            group["views"] += 1
            group["timed_twice"] += bool(timed_twice[index])
            group["runs"].setdefault(row["run"], row.get("record"))
            group["rows"].append(index)
    out = []
    for (experiment, words), group in groups.items():
        spans = [_span(column) for column in zip(*group["numbers"])]
        cause = "".join(word + (spans[i] if i < len(spans) else "") for i, word in enumerate(words))
        out.append({"experiment": experiment, "cause": cause, "views": group["views"],
                    "timed_twice": group["timed_twice"], "runs": list(group["runs"]),
                    "records": list(group["runs"].values()), "rows": group["rows"]})
    out.sort(key=lambda g: (g["experiment"], -g["views"], g["cause"]))
    return out


def timing_disturbances(runs_df):
    """The timed views of ``runs_df`` (``runs.csv``) that were disturbed, and the parallel runs that were starved.

    The render job times a disturbed view again once and keeps the quieter attempt (``rerun`` says
    so); a view whose kept frames are still disturbed has its reason in ``info_disturbed``, and a
    parallel run that had fewer free cores than workers in ``info_starved``.

    Returns
    -------
    dict or None
        ``None`` for results written before disturbances were recorded (no ``info_disturbed``
        column). Otherwise ``"views"`` (how many views were timed: successful, not one untimed
        frame), ``"disturbed"`` and ``"starved"`` (groups: ``experiment``, ``cause`` with the range
        of its numbers, ``views``, ``timed_twice`` (views of the group that were timed again),
        ``runs``, ``records``, ``rows`` (the views' index labels); a starved group also has
        ``busy``, the workers' busy share in words, or ``""``) and ``"quiet_again"``
        (``{experiment: views}`` disturbed at first and quiet when timed again).
    """
    if runs_df is None or "info_disturbed" not in runs_df:
        return None
    rows = runs_df[runs_df["status"] == "ok"] if "status" in runs_df else runs_df

    def texts(column):
        return rows[column].map(_text) if column in rows else pd.Series("", index=rows.index, dtype=object)

    disturbed, starved, rerun = texts("info_disturbed"), texts("info_starved"), texts("rerun")
    starved_groups = _cause_groups(rows, starved[starved != ""], rerun)
    busy = pd.to_numeric(rows["info_worker_busy"], errors="coerce") if "info_worker_busy" in rows else None
    for group in starved_groups:
        shares = busy[group["rows"]].dropna() if busy is not None else ()
        group["busy"] = (f"workers busy {_span([f'{100 * v:.0f}' for v in shares])} % of the compositing"
                         if len(shares) else "")
    quiet = rows[(rerun != "") & (disturbed == "")]
    untimed = texts("info_untimed").astype(str).str.lower() == "true"
    # An untimed frame (a ground truth, an accuracy-only run) has no timing for a disturbance to spoil.
    return {"views": int((~untimed).sum()),
            "disturbed": _cause_groups(rows, disturbed[(disturbed != "") & ~untimed], rerun),
            "starved": starved_groups, "quiet_again": quiet.groupby("experiment", sort=True).size().to_dict()}


def disturbance_notice(disturbances):
    """One sentence for a page whose timed views include disturbed ones or starved runs, or ``""``.

    ``disturbances`` is :func:`timing_disturbances` of the page's rows.
    """
    if not disturbances:
        return ""
    views = len({i for g in disturbances["disturbed"] for i in g["rows"]})
    starved = len({(g["experiment"], run) for g in disturbances["starved"] for run in g["runs"]})
    parts = []
    if views:
        parts.append(f"{views} of the {disturbances['views']} timed views on this page "
                     f"{'was' if views == 1 else 'were'} disturbed while timed")
    if starved:
        parts.append(f"{starved} parallel {'run' if starved == 1 else 'runs'} had fewer free cores than workers")
    if not parts:
        return ""
    return " and ".join(parts) + ": their times and the intervals of the claims that read them are less certain."


def quiet_summary(runs_df):
    """How quiet the machine was while views were timed: a dict for the appendix, or ``None`` without timed views.

    ``views`` (timed views: successful, not one untimed frame), ``timed_twice`` (disturbed at first,
    timed again), ``disturbed`` (still disturbed in the timing kept), and over the timed views the
    CPU that volbench's own orchestration used (``orchestrator_max``, ``orchestrator_median``: cores,
    from each view's ``load_orchestrator_cores``; ``None`` where no view recorded it) and all other
    work (``foreign_median``).
    """
    if runs_df is None or runs_df.empty or "info_disturbed" not in runs_df:
        return None
    rows = runs_df[runs_df["status"] == "ok"] if "status" in runs_df else runs_df
    untimed = rows["info_untimed"].map(_text).astype(str).str.lower() == "true" if "info_untimed" in rows \
        else pd.Series(False, index=rows.index)
    rows = rows[~untimed]
    if rows.empty:
        return None

    def numbers(column):
        return pd.to_numeric(rows[column], errors="coerce").dropna() if column in rows else pd.Series(dtype=float)

    orchestrator, foreign = numbers("load_orchestrator_cores"), numbers("load_foreign_cores")
    rerun = rows["rerun"].map(_text) if "rerun" in rows else pd.Series("", index=rows.index)
    return {"views": len(rows), "timed_twice": int((rerun != "").sum()),
            "disturbed": int((rows["info_disturbed"].map(_text) != "").sum()),
            "orchestrator_views": len(orchestrator),
            "orchestrator_max": float(orchestrator.max()) if len(orchestrator) else None,
            "orchestrator_median": float(orchestrator.median()) if len(orchestrator) else None,
            "foreign_median": float(foreign.median()) if len(foreign) else None}
