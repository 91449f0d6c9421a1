"""Run records → tidy tables: ``runs.csv`` (one row per run and view), per-experiment CSVs, claims.

Two steps, so each experiment's tables are made beside its runs (one Snakemake job per experiment,
in the experiment's job group: on a cluster, in the same job as its renders) and only the
concatenation waits for every experiment: :func:`tabulate` writes one experiment's rows
(``tables/<experiment>.csv``) and checks its claims (``claims/<experiment>.csv``); :func:`merge`
concatenates them into ``runs.csv`` and ``claims.csv``.

Every row names its run's JSON record (``record``) and, per view, its images (``png``, ``exr``), so
the report can link each number to where it came from, and the node it was measured on (``node``:
see :func:`pipeline.environment.node_name`), so timings from several machines or clusters merged in
one table stay apart.
"""

import hashlib
import json
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.environment import node_name
from pipeline.experiments.kit.intervals import format_frames, format_processes
from pipeline.experiments.kit.results import compact
from pipeline.records import metrics_record_path
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
        "status": record["status"], "reason": record["reason"], "cause": record.get("cause", ""),
        "reference": record["reference"],
        "spec_hash": record["spec_hash"], "record": str(record_path), "interleave": record.get("interleave") or "",
        **record["tags"],
        **_flatten("option_", record.get("options")),
        **_flatten("stat_", record.get("statistics")),
        **record["environment"], **(record.get("backend_environment") or {}),
        "node": node_name(record["environment"]),
        **_flatten("harness_", record.get("harness")),
    }
    if record["status"] != "ok":
        # The views it would have rendered, so that a claim can be judged without this run.
        return [{**base, "planned_views": ";".join(record.get("planned_views", []))}]
    rows = []
    for view in record["views"]:
        row = {**base, "view": view["view"], "png": view["png"], "exr": view["exr"],
               **_flatten("time_", view["timings"]),
               **{f"time_{k}_min": v for k, v in view["timings_min"].items()},
               **{f"time_{k}_max": v for k, v in view["timings_max"].items()},
               **_flatten("count_", view["counters"]),
               **_flatten("info_", {k: v for k, v in view["info"].items() if not isinstance(v, (dict, list))}),
               **_frames_cells(view),
               **{f"load_{k.removeprefix('load_')}": v for k, v in (view["info"].get("load") or {}).items()
                  if k in ("foreign_cores", "job_foreign_cores", "steal_share", "waited_share", "load_average",
                           "orchestrator_cores")},
               "rerun": _rerun_words(view.get("rerun"))}
        view_metrics = metrics.get("views", {}).get(view["view"])
        if view_metrics:
            row.update({key: view_metrics.get(key) for key in (*METRIC_KEYS, "diff_png")})
        elif metrics.get("status") in ("skipped", "failed"):
            row["metrics_reason"] = metrics["reason"]
        rows.append(row)
    return rows


def _frames_cells(view):
    """``{frames_<stage>: text}`` of a view: every timed frame, each process's apart
    (:data:`~pipeline.experiments.kit.intervals.PROCESS_SEPARATOR`); ``processes``, how many timed it (``None``
    for a view not timed: one untimed frame); and for a view of several, how its total time varied between
    them and within them (:func:`process_spreads`) and ``once_<stage>``, each process's time of a stage it timed
    once rather than per frame (preprocessing), so that a claim on that stage can resample the processes."""
    processes = view.get("processes")
    if not processes:
        timed = bool(view.get("frames")) and not view.get("info", {}).get("untimed")
        return {**{f"frames_{stage}": format_frames(values) for stage, values in (view.get("frames") or {}).items()},
                "processes": 1 if timed else None}
    stages = dict.fromkeys(stage for process in processes for stage in process["frames"])
    once = [stage for stage in dict.fromkeys(stage for process in processes for stage in process["timings"])
            if stage not in stages and all(stage in process["timings"] for process in processes)]
    return {**{f"frames_{stage}": format_processes([process["frames"].get(stage, []) for process in processes])
               for stage in stages}, "processes": len(processes),
            **{f"once_{stage}": format_processes([[process["timings"][stage]] for process in processes])
               for stage in once},
            **process_spreads([process["frames"].get("total") or [] for process in processes])}


def process_spreads(per_process):
    """``{"spread_between", "spread_within"}`` of a view's total frame time in several processes (empty where a
    process has none): the range of the processes' medians over their mean, and the median over the processes
    of their frames' interquartile range over their median. The appendix sets one beside the other per backend:
    a between-process spread above the within-process one is what an interval over one process's frames misses.
    """
    if len(per_process) < 2 or any(len(frames) == 0 for frames in per_process):
        return {}
    medians = np.array([np.median(frames) for frames in per_process])
    within = [np.subtract(*np.percentile(frames, [75, 25])) / np.median(frames) for frames in per_process]
    return {"spread_between": float(np.ptp(medians) / medians.mean()), "spread_within": float(np.median(within))}


def _rerun_words(rerun):
    """What a view's second timing says (``""`` when it was timed once): why, and which attempt was kept."""
    if not rerun:
        return ""
    kept = "kept the second" if rerun.get("kept") == "second" else "kept the first (quieter)"
    still = f"; the second too: {rerun['second']}" if rerun.get("second") else "; the second was quiet"
    return f"timed twice: {rerun.get('first')}{still}; {kept}"


def table_path(results_dir, experiment_name):
    """``results/tables/<experiment>.csv``: the experiment's rows of ``runs.csv``."""
    return Path(results_dir) / "tables" / f"{experiment_name}.csv"


def claims_path(results_dir, experiment_name):
    """``results/claims/<experiment>.csv``: the experiment's rows of ``claims.csv``."""
    return Path(results_dir) / "claims" / f"{experiment_name}.csv"


def tabulate(record_paths, experiment, *, results_dir):
    """One experiment's run records → its table and its checked claims; return ``(rows, claims)``.

    Parameters
    ----------
    record_paths : list of path
        The experiment's run records (``runs/<experiment>/<run>.json``); their metrics records are
        read from beside them in ``results_dir``.
    experiment : Experiment
    results_dir : path
        Where :func:`table_path` and :func:`claims_path` are written.
    """
    frame = compact(pd.DataFrame([row for path in record_paths for row in rows_for(path, results_dir=results_dir)]))
    rows = experiment_rows(frame, experiment)
    claims = claims_table(rows, [experiment])
    for path, table in ((table_path(results_dir, experiment.name), rows),
                        (claims_path(results_dir, experiment.name), claims)):
        path.parent.mkdir(parents=True, exist_ok=True)
        table.to_csv(path, index=False)
    return rows, claims


def merge(experiments, *, results_dir, known=None):
    """Concatenate the experiments' tables and claims (from :func:`tabulate`) into ``runs.csv`` and ``claims.csv``.

    The tables are read as text and written back unchanged (a column one experiment lacks is left
    empty in its rows), so no value is re-typed on the way.

    Parameters
    ----------
    experiments : list of Experiment
        The experiments of this pipeline run; their tables must exist.
    results_dir : path
    known : list of Experiment, optional
        Every experiment volbench has (``experiments`` among them), in registry order. Given, the
        tables that earlier pipeline runs left in ``results_dir`` for the other known experiments
        are merged too (a run of one experiment, ``volbench run --experiment X``, must not drop the
        rest of the profile's results), every table in registry order; tables named after no
        known experiment (one since removed or renamed) are left out.

    Returns
    -------
    earlier : list of str
        The experiments merged from earlier runs' tables.
    dropped : list of str
        The names of the tables left out.
    """
    results_dir = Path(results_dir)
    names = [experiment.name for experiment in experiments]
    earlier, dropped = [], []
    if known is not None:
        known_names = [experiment.name for experiment in known]
        present = {path.stem for path in (results_dir / "tables").glob("*.csv")}
        earlier = [name for name in known_names if name in present and name not in names]
        dropped = sorted(present - set(known_names))
        names = [name for name in known_names if name in names or name in earlier]
    for output, path_of in (("runs.csv", table_path), ("claims.csv", claims_path)):
        parts = [_read_text(path_of(results_dir, name)) for name in names
                 if name not in earlier or path_of(results_dir, name).is_file()]
        pd.concat(parts, ignore_index=True).to_csv(results_dir / output, index=False)
    return earlier, dropped


def _read_text(path):
    try:
        return pd.read_csv(path, dtype=str, keep_default_na=False)
    except pd.errors.EmptyDataError:  # an experiment without runs writes no columns
        return pd.DataFrame()


def collect(record_paths, experiments, *, results_dir):
    """:func:`tabulate` every experiment (its records among ``record_paths``), then :func:`merge`.

    What the workflow's tabulate and collect jobs do, in one call; returns the concatenated
    ``(runs, claims)`` tables as computed (before they are written as text).
    """
    record_paths = [Path(p) for p in record_paths]
    tables = [tabulate([p for p in record_paths if p.parent.name == experiment.name], experiment,
                       results_dir=results_dir) for experiment in experiments]
    merge(experiments, results_dir=results_dir)
    return (pd.concat([rows for rows, _ in tables], ignore_index=True),
            pd.concat([claims for _, claims in tables], ignore_index=True))


def phantom_manifest(requests, *, cache_dir):
    """One row per generated phantom: its request, what was stored and a digest of the stored bytes.

    ``requests`` is ``{cache key: {"dataset", "kwargs"}}`` (:func:`pipeline.scene_io.phantom_requests`);
    every one must already be in ``cache_dir``. The digest (SHA-256 of the ``.npy`` file, and of
    the labels file where there is one) lets two runs, on two machines or a cluster, show that they
    rendered bit-identical phantoms; the key only names the request.
    """
    cache_dir = Path(cache_dir)
    rows = []
    for key, request in requests.items():
        data = cache_dir / f"{key}.npy"
        if not data.is_file():
            raise FileNotFoundError(f"phantom {key} ({request['dataset']}) is not in the cache {cache_dir}: "
                                    "generate it first (the workflow's volume job)")
        stored = json.loads((cache_dir / f"{key}.json").read_text())
        digest = hashlib.sha256(data.read_bytes())
        labels = cache_dir / f"{key}.labels.npy"
        if stored["labels"]:
            digest.update(labels.read_bytes())
        kwargs = dict(request["kwargs"])
        rows.append({
            "key": key, "dataset": request["dataset"], "size": kwargs.pop("size", None), "seed": kwargs.pop("seed", None),
            "params": json.dumps(kwargs, sort_keys=True), "shape": "×".join(map(str, stored["shape"])),
            "dtype": np.dtype(stored["dtype"]).name, "labels": stored["labels"],
            "bytes": data.stat().st_size + (labels.stat().st_size if stored["labels"] else 0),
            "generation_seconds": stored["meta"].get("generation_seconds"), "sha256": digest.hexdigest(),
        })
    rows.sort(key=lambda row: (row["dataset"], row["size"] or 0, row["seed"] or 0, row["params"]))
    return pd.DataFrame(rows, columns=["key", "dataset", "size", "seed", "params", "shape", "dtype", "labels", "bytes",
                                       "generation_seconds", "sha256"])


def experiment_rows(frame, experiment):
    """The rows of ``frame`` (``runs.csv``) that belong to ``experiment``, without all-empty columns."""
    if frame.empty:
        return frame
    return frame[frame.experiment == experiment.name].dropna(axis=1, how="all")


def claims_table(frame, experiments):
    """Every claim of ``experiments`` judged on ``frame``'s rows: ``claims.csv``'s table.

    Each claim is checked on the successful rows and gets a verdict (:mod:`pipeline.experiments.kit.verdicts`):
    ``blocked`` where it would read runs that should have happened here and did not.
    """
    from pipeline.experiments.kit.pages import claim_evidence
    from pipeline.experiments.kit.verdicts import judge

    # One block per dtype: pandas.read_csv of runs.csv gives one per column (hundreds), and every
    # column a claim adds to such a frame would warn that it is fragmented.
    frame = frame.copy()
    claim_rows = []
    for experiment in experiments:
        part = experiment_rows(frame, experiment)
        for claim in experiment.claims:
            verdict = judge(claim, part)
            claim_rows.append({
                "experiment": experiment.name, "paper": experiment.paper, "claim": claim.id, "kind": claim.kind,
                "statement": claim.statement, "target": claim.target, "paper_value": claim.paper_value,
                "ours": claim.ours, "expected": claim.expected, "measured": verdict.measured,
                "holds": verdict.holds, "verdict": verdict.verdict, "detail": verdict.detail,
                "interval_low": verdict.interval[0] if verdict.interval else None,
                "interval_high": verdict.interval[1] if verdict.interval else None, "frames": verdict.frames,
                "processes": verdict.processes, "margin": verdict.margin, **claim_evidence(verdict, part),
            })
    return pd.DataFrame(claim_rows, columns=CLAIM_COLUMNS)


CLAIM_COLUMNS = ["experiment", "paper", "claim", "kind", "statement", "target", "paper_value", "ours", "expected",
                 "measured", "holds", "verdict", "detail", "interval_low", "interval_high", "frames", "processes",
                 "margin", "disturbed_views", "software_rasterizer", "stand_in"]
"""The columns of ``claims.csv``: ``kind`` is what the claim measures (timing, count, accuracy or cost model:
:data:`~pipeline.experiments.kit.model.CLAIM_KINDS`), ``target`` is ``paper`` (the paper's statement) or ``ours``
(our own target beside it, ``ours`` saying why), ``paper_value`` the paper's number the claim judges where it has one;
``interval_low``/``interval_high`` bound the 95 % interval of the measured value
where it rests on timed frames (in the value's unit: a ratio, seconds), ``frames`` how many timed frames it rests
on in its thinnest arm, ``processes`` in how many processes they were timed (the fewest of the experiment's
timed runs; with one, the interval cannot show the spread between two runs), ``margin`` is its relative distance
from the bound, positive on the holding side (the worst row's, for a claim over several); the last three are
what a failing claim's likely cause is read from (:func:`pipeline.experiments.kit.pages.claim_evidence`)."""
