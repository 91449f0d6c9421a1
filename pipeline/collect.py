"""Run records → tidy tables: ``runs.csv`` (one row per run and view), per-experiment CSVs, claims.

Every row names its run's JSON record (``record``) and, per view, its images (``png``, ``exr``), so
the report can link each number to where it came from, and the node it was measured on (``node``:
see :func:`pipeline.environment.node_name`), so timings from several machines or clusters merged in
one table stay apart.
"""

import json
from pathlib import Path

import pandas as pd

from pipeline.environment import node_name
from pipeline.runner import metrics_record_path
from reports.metrics import METRIC_KEYS


def _flatten(prefix, mapping):
    return {f"{prefix}{key}": value for key, value in (mapping or {}).items()}


def rows_for(record_path, *, results_dir):
    """The tidy rows of one run record: one per view, or one row carrying the skip/failure reason."""
    record = json.loads(Path(record_path).read_text())
    metrics = {}
    metrics_path = metrics_record_path(results_dir, record["experiment"], record["run"])
    if record["reference"] is not None and metrics_path.exists():
        metrics = json.loads(metrics_path.read_text())
    base = {
        "experiment": record["experiment"], "run": record["run"], "backend": record["backend"],
        "status": record["status"], "reason": record["reason"], "reference": record["reference"],
        "spec_hash": record["spec_hash"], "record": str(record_path), **record["tags"],
        **_flatten("option_", record.get("options")),
        **_flatten("stat_", record.get("statistics")),
        **record["environment"], **(record.get("backend_environment") or {}),
        "node": node_name(record["environment"]),
    }
    if record["status"] != "ok":
        return [base]
    rows = []
    for view in record["views"]:
        row = {**base, "view": view["view"], "png": view["png"], "exr": view["exr"],
               **_flatten("time_", view["timings"]),
               **{f"time_{k}_min": v for k, v in view["timings_min"].items()},
               **{f"time_{k}_max": v for k, v in view["timings_max"].items()},
               **_flatten("count_", view["counters"]),
               **_flatten("info_", {k: v for k, v in view["info"].items() if not isinstance(v, (dict, list))})}
        view_metrics = metrics.get("views", {}).get(view["view"])
        if view_metrics:
            row.update({key: view_metrics.get(key) for key in (*METRIC_KEYS, "diff_png")})
        elif metrics.get("status") == "skipped":
            row["metrics_reason"] = metrics["reason"]
        rows.append(row)
    return rows


def collect(record_paths, experiments, *, results_dir):
    """Write ``runs.csv``, ``<experiment>.csv`` and ``claims.csv``; return ``(runs_df, claims_df)``."""
    results_dir = Path(results_dir)
    frame = pd.DataFrame([row for path in record_paths for row in rows_for(path, results_dir=results_dir)])
    frame.to_csv(results_dir / "runs.csv", index=False)
    for experiment in experiments:
        experiment_rows(frame, experiment).to_csv(results_dir / f"{experiment.name}.csv", index=False)
    claims = claims_table(frame, experiments)
    claims.to_csv(results_dir / "claims.csv", index=False)
    return frame, claims


def experiment_rows(frame, experiment):
    """The rows of ``frame`` (``runs.csv``) that belong to ``experiment``, without all-empty columns."""
    return frame[frame.experiment == experiment.name].dropna(axis=1, how="all")


def claims_table(frame, experiments):
    """Every claim of ``experiments`` checked on the successful rows of ``frame``: ``claims.csv``'s table."""
    claim_rows = []
    for experiment in experiments:
        part = experiment_rows(frame, experiment)
        ok = part[part.status == "ok"] if not part.empty else part
        for claim in experiment.claims:
            result = claim.evaluate(ok)
            claim_rows.append({
                "experiment": experiment.name, "paper": experiment.paper, "claim": claim.id,
                "statement": claim.statement, "expected": claim.expected, "measured": result.measured,
                "holds": result.holds, "detail": result.detail,
            })
    return pd.DataFrame(claim_rows, columns=["experiment", "paper", "claim", "statement", "expected",
                                             "measured", "holds", "detail"])
