"""What the harness itself costs: where a pipeline run's wall time went.

``volbench run`` names each pipeline run (:data:`PIPELINE_RUN_VARIABLE`) and its log
(:data:`LOG_VARIABLE`, ``<results>/harness/jobs.jsonl``): the run's start and plan first, then one line
per job, written by the process that runs Snakemake (:mod:`pipeline.progress`) from Snakemake's own
events, with its step, its experiment and when Snakemake started it and saw it finish (its process's
start, imports and Snakemake's bookkeeping included). A run's records carry what their frames took (``info.cold_seconds``,
``untimed_seconds``, ``timed_seconds``, ``rerun_seconds`` per view, :mod:`pipeline.timing`) and what
the process that rendered them cost to start (``harness``, :mod:`pipeline.workers`). From both,
:func:`account` makes the appendix's table: per experiment its jobs' wall time split into timed
frames, untimed frames (warm-up, preprocessing, single untimed frames, a disturbed view's discarded
attempt) and overhead (cold frames with their compilation, worker start-up, imports, I/O), and for the
whole run the share spent in frames. A Snakemake started by hand logs nothing.
"""

import json
import os
import socket
import time
from pathlib import Path

PIPELINE_RUN_VARIABLE = "VOLBENCH_PIPELINE_RUN"
"""Names the pipeline run a job belongs to (``volbench run`` sets it for Snakemake and its jobs)."""

LOG_VARIABLE = "VOLBENCH_HARNESS_LOG"
"""The path of the jobs log a job appends its line to."""

LOG_NAME = Path("harness") / "jobs.jsonl"
"""The jobs log under a results folder."""


def pipeline_run(environ=None):
    """The pipeline run this process belongs to, or ``None`` outside ``volbench run``."""
    return (os.environ if environ is None else environ).get(PIPELINE_RUN_VARIABLE) or None


def new_pipeline_run():
    """A name for a new pipeline run: its UTC start and the launching process, ``20261128T174100Z-1234``."""
    return f"{time.strftime('%Y%m%dT%H%M%SZ', time.gmtime())}-{os.getpid()}"


def log_path(results_dir):
    return Path(results_dir) / LOG_NAME


def append(path, entry):
    """Append one JSON line to the log at ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as f:
        f.write(json.dumps(entry, sort_keys=True) + "\n")


def log_job(path, *, run, step, experiment, started, ended, failed=False):
    """One job's line: its step (the rule's), experiment (or ``None``), start and end (seconds since the epoch)."""
    append(path, {"pipeline_run": run, "kind": "job", "step": step, "experiment": experiment, "started": started,
                  "ended": ended, "failed": failed})


def log_start(path, *, run, steps=None):
    """The pipeline run's first line: when it started, and how many runs its plan has."""
    append(path, {"pipeline_run": run, "kind": "start", "started": time.time(), "planned_runs": steps,
                  "host": socket.gethostname(), "pid": os.getpid()})


def read_log(path):
    """Every line of a jobs log (``[]`` where there is none); a line cut short by a kill is skipped."""
    try:
        lines = Path(path).read_text().splitlines()
    except OSError:
        return []
    entries = []
    for line in lines:
        try:
            entries.append(json.loads(line))
        except ValueError:
            continue
    return entries


STEP_GROUPS = {"render": "render", "evaluate": "evaluate", "tabulate": "tabulate"}
"""The steps whose time belongs to an experiment (the others are the run's own: phantoms, report)."""


def _union(intervals):
    """Seconds covered by at least one of ``[(start, end)]``."""
    covered, end_so_far = 0.0, None
    for start, end in sorted(intervals):
        if end_so_far is None or start > end_so_far:
            covered += end - start
            end_so_far = end
        elif end > end_so_far:
            covered += end - end_so_far
            end_so_far = end
    return covered


def account(entries, runs_df, *, run=None, now=None):
    """Where one pipeline run's time went: ``None`` without a logged run, else a dict for the report.

    Parameters
    ----------
    entries : list of dict
        The jobs log (:func:`read_log`).
    runs_df : pandas.DataFrame
        ``runs.csv``: its ``info_*_seconds`` and ``harness_*`` columns (rows of runs rendered by this
        pipeline run, ``harness_pipeline_run``).
    run : str, optional
        The pipeline run; ``None``: the last one logged.
    now : float, optional
        The end of the span (seconds since the epoch; ``None``: now, as the report job is the run's last).

    Returns
    -------
    dict
        ``run``, ``started``, ``span`` (seconds), ``rows`` (one per experiment, costliest first, then the
        run's own steps; each with ``steps``, ``wall``, ``timed``, ``untimed``, ``work`` (its evaluation
        and tables), ``cold``, ``startup`` and ``overhead``, the wall time in none of them),
        ``gaps`` (seconds no job ran: scheduling), ``timed``, ``untimed`` (whole run) and their shares.
    """
    import pandas as pd

    starts = [e for e in entries if e.get("kind") == "start"]
    if run is None:
        if not starts:
            return None
        run = starts[-1]["pipeline_run"]
    start = next((e for e in starts if e["pipeline_run"] == run), None)
    if start is None:
        return None
    jobs = [e for e in entries if e.get("kind") == "job" and e.get("pipeline_run") == run]
    end = time.time() if now is None else now
    span = max(end - start["started"], 1e-9)
    frames = _frames(runs_df, run)
    rows = {}
    for job in jobs:
        group = job.get("experiment") if job.get("step") in STEP_GROUPS and job.get("experiment") else None
        key = group or {"volume": "phantoms", "phantoms": "phantoms", "environment": "environment"}.get(
            job["step"], "collect and report")
        row = rows.setdefault(key, {"name": key, "experiment": bool(group), "steps": 0, "wall": 0.0, "work": 0.0})
        row["steps"] += 1
        row["wall"] += job["ended"] - job["started"]
        if job["step"] in ("evaluate", "tabulate"):
            row["work"] += job["ended"] - job["started"]
    for row in rows.values():
        done = frames.get(row["name"], {}) if row["experiment"] else {}
        for column in ("timed", "untimed", "cold", "startup"):
            row[column] = done.get(column, 0.0)
        row["overhead"] = max(0.0, row["wall"] - row["timed"] - row["untimed"] - row["work"])
        row["frames_share"] = (row["timed"] + row["untimed"]) / row["wall"] if row["wall"] > 0 else None
    # The experiments, costliest first; then the run's own steps.
    ordered = sorted(rows.values(), key=lambda r: (not r["experiment"], -r["wall"]))
    busy = _union([(job["started"], job["ended"]) for job in jobs])
    timed = sum(r["timed"] for r in rows.values())
    untimed = sum(r["untimed"] for r in rows.values())
    return {"run": run, "started": pd.Timestamp(start["started"], unit="s", tz="UTC").strftime("%Y-%m-%d %H:%M UTC"),
            "span": span, "rows": ordered, "gaps": max(0.0, span - busy), "timed": timed, "untimed": untimed,
            "timed_share": timed / span, "frames_share": (timed + untimed) / span,
            "wall": sum(r["wall"] for r in rows.values()), "planned_runs": start.get("planned_runs")}


def _frames(runs_df, run):
    """``{experiment: {"timed", "untimed", "cold", "startup"}}`` seconds of the runs rendered by pipeline ``run``."""
    import pandas as pd

    if runs_df is None or runs_df.empty or "harness_pipeline_run" not in runs_df:
        return {}
    rows = runs_df[runs_df["harness_pipeline_run"].astype(str) == str(run)]
    out = {}
    for experiment, group in rows.groupby("experiment"):
        def total(*columns):
            return float(sum(pd.to_numeric(group[c], errors="coerce").fillna(0).sum() for c in columns if c in group))

        # A worker's start-up is in every record of the group it started with: count each start once.
        started = group
        if "harness_new" in group:
            started = group[group["harness_new"].astype(str).str.lower() == "true"]
            started = started.drop_duplicates(subset=[c for c in ("harness_pid", "harness_runs_before") if c in group])
        startup = float(pd.to_numeric(started.get("harness_startup"), errors="coerce").fillna(0).sum()) \
            if "harness_startup" in started else 0.0
        out[experiment] = {"timed": total("info_timed_seconds"),
                           "untimed": total("info_untimed_seconds", "info_rerun_seconds"),
                           "cold": total("info_cold_seconds"), "startup": startup}
    return out
