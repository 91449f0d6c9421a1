"""What did not run, said once: runs grouped by backend, cause and message; backends that made no frame.

A backend that cannot run on a machine fails or skips every one of its runs with the same message
(114 cl-tiled runs, each with PoCL's compiler error). The report states such a message once, with
the number of runs it stands for, and says plainly at the top which backends produced no frame here
and which papers are therefore not reproduced on this machine. Run outcomes come from the records
(``status``, ``cause``: :mod:`core.outcomes`), not from probing the machine that builds the report.
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
