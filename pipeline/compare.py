"""Two results folders compared: the same runs, images, claims and phantoms, timings aside.

Two pipeline runs of the same code and profile must agree on everything but what the machine and
its scheduling decide: the cluster test (``tests/test_cluster.py``) compares a SLURM smoke run with
a local one, and ``scripts/compare-results A B`` any two folders (a smoke run before and after a
change that must not change results). Each ``*_differences`` function returns the differences it
finds, one sentence each: none, the folders agree.

Left out everywhere: timings and durations (``time_*``, ``frames_*``, ``*_seconds``, the frame counts and
load the timing harness recorded), the environment (host,
device, SLURM job, node: every column a record's ``environment`` or ``backend_environment`` names)
and the values the backends declare scheduling-dependent (``Renderer.scheduling_dependent``: the
order of threads or work-items decides them). Paths are compared relative to their results folder,
and read there: a folder can be moved or copied (``/work/baseline/smoke`` whose records say
``results/smoke/...``). Images of CPU backends must be bit-identical, those rendered through a
device driver (:func:`pipeline.environment.uses_device`) within :data:`DEVICE_TOLERANCE`, and so
their metrics within :data:`METRIC_TOLERANCE`. Claims must be the same and have the same verdicts,
but for the claims whose judgement reads timings or scheduling-dependent values
(:func:`varying_claims`: the timing claims). Those may change to or from inconclusive between two runs
(listed, with the share of claims that agree: :func:`verdict_changes`), but a timing claim that holds in
one run and fails in the other is a difference (:func:`timing_flips`): two runs of volbench must not
disagree on a decided verdict. Beside the verdicts, the two runs' intervals of each timing claim are set
against each other (:func:`interval_agreement`): about 95 % agree where the intervals cover the spread
between runs, far fewer where they cover the frames of one process only.
"""

import argparse
import io
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

import renderers
from core.errors import BackendUnavailableError, InputError
from pipeline.collect import claims_table, table_path
from pipeline.environment import SLURM_FACTS, uses_device
from reports.imageio import read_image

KEY = ["experiment", "run", "view"]
"""What names a row of ``runs.csv``: a run's view (``view`` empty for a run that made no frame)."""

PATH_COLUMNS = ("record", "png", "exr", "diff_png")
"""The columns of ``runs.csv`` that name files."""

DEVICE_TOLERANCE = 1e-6
"""The largest difference of a pixel channel allowed between two images of a device backend (OpenGL
through Mesa's llvmpipe, OpenCL through PoCL render deterministically on one machine in practice)."""

METRIC_TOLERANCE = {"rtol": 1e-4, "atol": 1e-6}
"""How far a metric of a device render may differ (:func:`numpy.isclose`): its image's tolerance."""

VARYING_FACTORS = (0.25, 4.0)
"""The range of the random factors :func:`varying_claims` multiplies each varying value by."""


TIMING_INFO = ("info_frames", "info_warmup", "info_settled", "info_first_frame", "info_disturbed", "info_starved",
               "info_preprocessing_frame", "rerun")
"""What the timing harness decides from the times themselves: how many frames the budget took, when the
warm-up settled, whether the machine was disturbed or a parallel run starved (:mod:`pipeline.timing`), and
what the process had compiled before (whether the cold frame was also the preprocessing frame)."""


def is_timing(column):
    """Timings (``time_*``, each frame's ``frames_*``, each process's time of a stage it timed once, ``once_*``),
    durations (``*_seconds``), the machine's load
    (``load_*``), what the timing harness decided from them (:data:`TIMING_INFO`) and what the harness
    cost (``harness_*``: which process rendered, its start-up, the pipeline run) and the spread of a view's times
    between and within its processes (``spread_*``) differ run to run."""
    return (column.startswith(("time_", "frames_", "once_", "load_", "harness_", "spread_"))
            or column.endswith("_seconds")
            or column in TIMING_INFO)


def scheduling_dependent():
    """``{backend: names}``: each backend's counters and info entries that its scheduling decides."""
    dependent = {}
    for name in renderers.names():
        try:
            dependent[name] = tuple(renderers.backend_class(name).scheduling_dependent)
        except BackendUnavailableError:  # not importable here: none of its runs rendered either
            dependent[name] = ()
    return dependent


def scheduling_columns():
    """The ``runs.csv`` columns of :func:`scheduling_dependent` (``count_<name>``, ``info_<name>``)."""
    return {f"{kind}_{name}" for names in scheduling_dependent().values() for name in names
            for kind in ("count", "info")}


def read_runs(folder, *, experiments=None):
    """``runs.csv`` of the results folder ``folder``, its paths made absolute under ``folder``.

    Only the rows of ``experiments`` (names; ``None``: all), without the columns none of them fills,
    sorted by :data:`KEY` (``view`` ``""`` where a run made no frame).
    """
    frame = pd.read_csv(results_file(folder, "runs.csv"), low_memory=False)
    if experiments is not None:
        frame = frame[frame.experiment.isin(list(experiments))]
    return _under(frame, Path(folder)).sort_values(KEY).reset_index(drop=True)


def _under(frame, folder):
    """``frame`` (rows of ``runs.csv`` or a table of it) without the columns it leaves empty, its paths under
    ``folder``."""
    frame = frame.dropna(axis=1, how="all").copy()
    frame["view"] = frame["view"].fillna("") if "view" in frame else ""
    # The records sit at <results>/runs/<experiment>/<run>.json: <results> is where the run wrote them.
    suffixes = "/runs/" + frame.experiment.astype(str) + "/" + frame.run.astype(str) + ".json"
    written = [record[:-len(suffix)] if isinstance(record, str) and record.endswith(suffix) else None
               for record, suffix in zip(frame.record, suffixes)]
    for column in [c for c in PATH_COLUMNS if c in frame]:
        frame[column] = [_moved(path, prefix, folder) for path, prefix in zip(frame[column], written)]
    return frame


def results_file(folder, name):
    """The file ``name`` (``runs.csv``, ``claims.csv``, ``volumes.csv``) of the results folder ``folder``.

    Raises
    ------
    InputError
        It is not there.
    """
    path = Path(folder) / name
    if not path.is_file():
        raise InputError(f"{folder}: no {name}; give the results folder of a finished pipeline run (results/<profile>)")
    return path


def _moved(path, written, folder):
    """``path`` (under the results folder ``written`` where the run wrote it) under ``folder``."""
    if not isinstance(path, str) or written is None or not path.startswith(written + "/"):
        return path
    return str(folder.resolve() / path[len(written) + 1:])


def environment_columns(frame):
    """The columns of ``frame`` (:func:`read_runs`) that describe where a run ran, not what it rendered:
    its record's ``environment`` and ``backend_environment`` (e.g. PoCL sizes ``cl_global_mem_bytes`` by
    the memory free when it starts), the SLURM job's and the node."""
    columns = set(SLURM_FACTS) | {"node"}
    for path in frame["record"].dropna().unique():
        record = json.loads(Path(path).read_text())
        columns |= set(record["environment"]) | set(record.get("backend_environment") or {})
    return columns


def compared_columns(frame):
    """The columns of ``frame`` two runs must agree on: not timings, paths or the environment, nor
    the values that the backends' thread or work-item scheduling decides."""
    left_out = environment_columns(frame) | set(PATH_COLUMNS) | scheduling_columns()
    return [column for column in frame.columns if not is_timing(column) and column not in left_out]


def run_differences(a, b, *, experiments=None):
    """How ``runs.csv`` of the results folders ``a`` and ``b`` differ: rows, compared columns and paths."""
    first, second = read_runs(a, experiments=experiments), read_runs(b, experiments=experiments)
    differences = _only_in([tuple(row) for row in first[KEY].values], [tuple(row) for row in second[KEY].values],
                           "runs.csv rows (experiment, run, view)", a, b)
    columns = {"a": compared_columns(first), "b": compared_columns(second)}
    # The rows both have, in the same order.
    both = first[KEY].merge(second[KEY])
    first, second = (frame.merge(both).reset_index(drop=True) for frame in (first, second))
    differences += _only_in(columns["a"], columns["b"], "runs.csv columns", a, b)
    device = first["backend"].map(uses_device)
    for column in [c for c in columns["a"] if c in columns["b"]]:
        x, y = first[column], second[column]
        if pd.api.types.is_float_dtype(x) and pd.api.types.is_float_dtype(y):
            same = np.isclose(x, y, rtol=0, atol=0, equal_nan=True)
            same |= device.to_numpy() & np.isclose(x, y, equal_nan=True, **METRIC_TOLERANCE)
        else:
            same = ((x == y) | (x.isna() & y.isna())).to_numpy()
        differences += _rows_differing(first, column, x, y, same)
    for column in [c for c in PATH_COLUMNS if c in first and c in second]:
        x, y = (frame[column].map(lambda path, folder=folder: _relative(path, folder))
                for frame, folder in ((first, a), (second, b)))
        differences += _rows_differing(first, f"{column} (relative to the folder)", x, y,
                                       ((x == y) | (x.isna() & y.isna())).to_numpy())
    return differences


def _relative(path, folder):
    """A path of a row as relative to its results folder (one elsewhere as it is)."""
    if isinstance(path, str) and Path(path).is_relative_to(Path(folder).resolve()):
        return Path(path).relative_to(Path(folder).resolve()).as_posix()
    return path


def _rows_differing(frame, column, x, y, same, shown=3):
    if same.all():
        return []
    rows = np.flatnonzero(~same)
    examples = "; ".join(f"{'/'.join(map(str, frame.loc[i, KEY]))}: {x.iloc[i]!r} vs {y.iloc[i]!r}"
                         for i in rows[:shown])
    more = f" (and {len(rows) - shown} more)" if len(rows) > shown else ""
    return [f"runs.csv {column} differs in {len(rows)} rows: {examples}{more}"]


def _only_in(first, second, what, a, b, shown=5):
    differences = []
    for ours, theirs, folder in ((first, second, a), (second, first, b)):
        items = sorted(set(ours) - set(theirs), key=str)
        if items:
            more = f" (and {len(items) - shown} more)" if len(items) > shown else ""
            differences.append(f"{what} only in {folder}: {', '.join(map(str, items[:shown]))}{more}")
    return differences


def image_differences(a, b, *, experiments=None, tolerance=DEVICE_TOLERANCE):
    """How the images (EXR) of the runs both folders made differ: CPU backends' must be bit-identical,
    device backends' (:func:`uses_device`) within ``tolerance`` per pixel channel."""
    first, second = read_runs(a, experiments=experiments), read_runs(b, experiments=experiments)
    other = second.set_index(KEY)
    differences = []
    for row in first[(first.status == "ok") & first.exr.notna()].itertuples(index=False):
        key = (row.experiment, row.run, row.view)
        if key not in other.index or not isinstance(other.loc[key, "exr"], str):
            continue  # a row one folder lacks is a run difference
        paths = (row.exr, other.loc[key, "exr"])
        missing = [path for path in paths if not Path(path).is_file()]
        if missing:
            differences.append(f"{'/'.join(key)}: image {missing[0]} is missing")
            continue
        x, y = (read_image(path) for path in paths)
        if x.shape != y.shape:
            differences.append(f"{'/'.join(key)}: images of {x.shape} and {y.shape} pixels")
        elif not uses_device(row.backend) and not np.array_equal(x, y, equal_nan=True):
            differences.append(f"{'/'.join(key)}: {row.backend} (a CPU backend) made different images")
        elif uses_device(row.backend) and float(np.nanmax(np.abs(x - y), initial=0.0)) > tolerance:
            differences.append(f"{'/'.join(key)}: {row.backend} images differ by up to "
                               f"{float(np.nanmax(np.abs(x - y))):g}, more than {tolerance:g}")
    return differences


def read_claims(folder, *, experiments=None):
    """``claims.csv`` of the results folder ``folder`` (the rows of ``experiments``; ``None``: all)."""
    claims = pd.read_csv(results_file(folder, "claims.csv"), dtype=str, keep_default_na=False)
    return claims if experiments is None else claims[claims.experiment.isin(list(experiments))]


DECIDED = ("holds", "fails")
"""The verdicts that decide a claim; a change between them is a flip."""


def verdict_changes(first, second):
    """Two ``claims.csv`` tables' verdicts side by side: one row per claim of either.

    Columns ``experiment``, ``claim``, ``verdict_a``, ``verdict_b``, ``measured_a``, ``measured_b`` (a claim
    one table lacks has verdict ``"absent"``) and ``change``: ``"same"``, ``"flipped"`` (holds ↔ fails),
    ``"to inconclusive"`` (decided in ``first``, inconclusive in ``second``), ``"from inconclusive"`` (the
    reverse) or ``"other"`` (blocked, not measured, absent).
    """
    keys = ["experiment", "claim"]
    both = first[keys + ["verdict", "measured"]].merge(second[keys + ["verdict", "measured"]], on=keys,
                                                       suffixes=("_a", "_b"), how="outer")
    both[["verdict_a", "verdict_b"]] = both[["verdict_a", "verdict_b"]].fillna("absent")

    def change(a, b):
        if a == b:
            return "same"
        if a in DECIDED and b in DECIDED:
            return "flipped"
        if a in DECIDED and b == "inconclusive":
            return "to inconclusive"
        if a == "inconclusive" and b in DECIDED:
            return "from inconclusive"
        return "other"

    both["change"] = [change(a, b) for a, b in zip(both.verdict_a, both.verdict_b)]
    return both


def agreement_words(changes, *, timing=()):
    """``"231 of 235 claims (98.3 %) have the same verdict; of the 103 that read timings, 99 (96.1 %)"``.

    ``changes`` is :func:`verdict_changes`' table, ``timing`` the ``(experiment, claim)`` pairs that read
    timings (:func:`varying_claims`). The share is of the claims both folders judged: a run of three experiments
    compared with a whole one agrees or not on those three, and the claims of one folder alone are counted apart
    (``"; 235 claims in one folder only"``)."""
    absent = (changes.verdict_a == "absent") | (changes.verdict_b == "absent")
    shared = changes[~absent]
    same = shared.change == "same"
    words = f"{int(same.sum())} of {len(shared)} claims ({_share(same)}) have the same verdict"
    timed = [(e, c) in set(timing) for e, c in zip(shared.experiment, shared.claim)]
    if any(timed):
        words += f"; of the {sum(timed)} that read timings, {int(same[timed].sum())} ({_share(same[timed])})"
    if absent.any():
        alone = int(absent.sum())
        words += f"; {alone} claim{'s' if alone > 1 else ''} in one folder only"
    return words


def _share(flags):
    return f"{100 * flags.mean():.1f} %" if len(flags) else "–"


def interval_agreement(first, second, *, timing):
    """Whether two runs' 95 % intervals of each timing claim agree with each other: one row per claim of
    ``timing`` that both ``claims.csv`` tables (``first``, ``second``) give an interval.

    Columns ``experiment``, ``claim``, ``interval_a``, ``interval_b`` (``(low, high)``), ``apart`` (the
    distance of their midpoints over the half-widths added in quadrature, each interval read as ±1.96
    standard errors) and ``agree`` (``apart`` ≤ 1.96: the two values are within what their intervals allow).
    Where each interval covers the spread between two runs of volbench, not only the frames of one, about
    95 % agree; the share of two quiet runs is what tells whether the intervals claim more precision than
    the runs show (issue 35: ×2.41, CI 2.19–2.82, against ×3.08, CI 2.73–3.34, apart 2.4).
    """
    keys = ["experiment", "claim"]
    columns = keys + ["interval_low", "interval_high"]
    if not all(column in table for table in (first, second) for column in columns):  # judged before intervals
        first = second = pd.DataFrame(columns=columns)
    both = first[columns].merge(second[columns], on=keys, suffixes=("_a", "_b"))
    both = both[[(e, c) in set(timing) for e, c in zip(both.experiment, both.claim)]]
    bounds = both[[f"interval_{end}_{side}" for side in "ab" for end in ("low", "high")]].apply(
        pd.to_numeric, errors="coerce")
    both = both[np.isfinite(bounds).all(axis=1).to_numpy()]
    bounds = bounds.loc[both.index]
    low_a, high_a, low_b, high_b = (bounds.iloc[:, i].to_numpy() for i in range(4))
    spread = np.hypot((high_a - low_a) / 2, (high_b - low_b) / 2)
    distance = np.abs((low_b + high_b) / 2 - (low_a + high_a) / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        apart = np.where(spread > 0, 1.96 * distance / spread, np.where(distance > 0, np.inf, 0.0))
    return pd.DataFrame({"experiment": both.experiment.to_numpy(), "claim": both.claim.to_numpy(),
                         "interval_a": list(zip(low_a, high_a)), "interval_b": list(zip(low_b, high_b)),
                         "apart": apart, "agree": apart <= 1.96})


def interval_words(agreement):
    """``"of the 140 timing claims both gave an interval, 132 (94.3 %) agree within their 95 % intervals
    (about 95 % where the intervals cover the spread between runs)"``, or ``""`` where none has two."""
    if agreement.empty:
        return ""
    return (f"of the {len(agreement)} timing claims both gave an interval, {int(agreement.agree.sum())} "
            f"({_share(agreement.agree)}) agree within their 95 % intervals (about 95 % where the intervals cover "
            "the spread between runs)")


def intervals_apart(agreement, a="A", b="B"):
    """One line per timing claim whose two intervals do not agree (:func:`interval_agreement`), widest apart first."""
    def text(interval):
        return f"{interval[0]:.4g}–{interval[1]:.4g}"
    return [f"intervals apart: {row.experiment}/{row.claim}: {text(row.interval_a)} in {a}, "
            f"{text(row.interval_b)} in {b} ({row.apart:.1f} apart)"
            for row in agreement[~agreement.agree].sort_values("apart", ascending=False).itertuples()]


def claim_differences(a, b, *, experiments=None, timing=None):
    """How the claims of ``a`` and ``b`` differ: the same claims (experiment, id, statement, expected),
    and the same verdict for each but those whose judgement reads timings or scheduling-dependent
    values in either folder (``timing``: :func:`timing_claims`, computed here when not given)."""
    first, second = read_claims(a, experiments=experiments), read_claims(b, experiments=experiments)
    key = ["experiment", "claim"]
    text = ["statement", "expected"]
    differences = _only_in([tuple(row) for row in first[key].values], [tuple(row) for row in second[key].values],
                           "claims (experiment, claim)", a, b)
    varying = timing_claims(a, b, experiments=experiments) if timing is None else timing
    merged = first.merge(second, on=key, suffixes=("_a", "_b"))
    for row in merged.itertuples(index=False):
        name = f"{row.experiment}/{row.claim}"
        for column in text:
            if getattr(row, f"{column}_a") != getattr(row, f"{column}_b"):
                differences.append(f"claim {name}: {column} {getattr(row, f'{column}_a')!r} in {a}, "
                                   f"{getattr(row, f'{column}_b')!r} in {b}")
        if (row.experiment, row.claim) not in varying and row.verdict_a != row.verdict_b:
            differences.append(f"claim {name}: {row.verdict_a} in {a}, {row.verdict_b} in {b}")
    return differences


def timing_claims(a, b, *, experiments=None):
    """The ``(experiment, claim)`` pairs whose judgement reads timings or scheduling-dependent values in the
    results folder ``a`` or ``b`` (:func:`varying_claims` of each, of the experiments both hold)."""
    first, second = read_claims(a, experiments=experiments), read_claims(b, experiments=experiments)
    names = sorted(set(first.experiment) & set(second.experiment))
    varying = set()
    with tempfile.TemporaryDirectory(prefix="volbench-compare-") as workdir:
        for index, folder in enumerate((a, b)):
            varying |= varying_claims(read_runs(folder, experiments=names), _experiments(names),
                                      workdir=Path(workdir) / str(index))
    return varying


def timing_flips(a, b, *, experiments=None, timing=None):
    """The timing claims (``timing``: :func:`timing_claims`) that hold in one folder and fail in the other,
    one sentence each with both measurements: what two runs of volbench must never disagree on."""
    timing = timing_claims(a, b, experiments=experiments) if timing is None else timing
    changes = verdict_changes(read_claims(a, experiments=experiments), read_claims(b, experiments=experiments))
    return [f"timing claim {row.experiment}/{row.claim} flipped: {row.verdict_a} in {a} ({row.measured_a}), "
            f"{row.verdict_b} in {b} ({row.measured_b})"
            for row in changes.itertuples() if row.change == "flipped" and (row.experiment, row.claim) in timing]


def _experiments(names):
    from pipeline.experiments import all_experiments

    registry = all_experiments()
    unknown = [name for name in names if name not in registry]
    if unknown:
        raise InputError(f"experiments {', '.join(unknown)}: volbench has no such experiment, so which of their "
                         "claims read timings cannot be told; compare results of experiments it has")
    return [registry[name] for name in names]


def varying_claims(frame, experiments, *, workdir, seeds=(1, 2)):
    """The ``(experiment, claim)`` pairs whose judgement reads values that differ run to run.

    A claim is judged on ``frame`` (:func:`read_runs`) as it is, then with every timing and
    scheduling-dependent value (the columns and the records' entries) multiplied by a factor of its
    own, drawn from :data:`VARYING_FACTORS` (once per seed): where its verdict, measured value or
    detail changes, it reads them. Random factors per value rather than one scale for all, so that a
    claim on a ratio of two timings is found too. Record copies are written under ``workdir``.
    """
    baseline = claims_table(frame, experiments).set_index(["experiment", "claim"])
    varying = set()
    for seed in seeds:
        rng = np.random.default_rng(seed)
        perturbed = with_varying_values(
            frame, Path(workdir) / f"seed{seed}",
            columns=lambda column, values: values * rng.uniform(*VARYING_FACTORS, len(values))
            if pd.api.types.is_numeric_dtype(values) else values,
            entries=lambda index, view, part, name, value: _scaled(value, rng))
        judged = claims_table(perturbed, experiments).set_index(["experiment", "claim"])
        for column in ("verdict", "measured", "detail"):
            changed = baseline[column].astype(str) != judged[column].astype(str)
            varying |= set(baseline.index[changed.to_numpy()])
    return varying


def _scaled(value, rng):
    if isinstance(value, list):
        return [_scaled(item, rng) for item in value]
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return value * rng.uniform(*VARYING_FACTORS)
    return value


def with_varying_values(frame, workdir, *, columns, entries):
    """``frame`` whose timing and scheduling-dependent values are replaced, with the records it names.

    ``columns(column, values)`` gives a timing or scheduling-dependent column's new values;
    ``entries(index, view, part, name, value)`` the new value of a scheduling-dependent entry of
    ``part`` (``"counters"`` or ``"info"``) of view ``view`` in the record of row ``index``: those
    records are rewritten under ``workdir`` and the rows name the copies.
    """
    frame = frame.copy()
    dependent = scheduling_dependent()
    for column in [c for c in frame.columns if is_timing(c) or c in scheduling_columns()]:
        frame[column] = columns(column, frame[column])
    copies = {}
    for index, row in frame.iterrows():
        names = dependent.get(row["backend"], ())
        if not names or not isinstance(row["record"], str):
            continue
        if row["record"] not in copies:
            record = json.loads(Path(row["record"]).read_text())
            for view in record.get("views", []):
                for part in ("counters", "info"):
                    values = view.get(part) or {}
                    for name in set(names) & set(values):
                        values[name] = entries(index, view["view"], part, name, values[name])
            copy = Path(workdir) / row["experiment"] / Path(row["record"]).name
            copy.parent.mkdir(parents=True, exist_ok=True)
            copy.write_text(json.dumps(record))
            copies[row["record"]] = str(copy)
        frame.loc[index, "record"] = copies[row["record"]]
    return frame


def claims_with_values_of(frame, source, experiments, *, workdir):
    """The claims of ``experiments`` judged on ``frame`` with ``source``'s timing and scheduling-dependent
    values (both :func:`read_runs` of the same runs, row for row): what two runs' claims must agree on.
    Record copies are written under ``workdir``."""
    sources = {}

    def entry(index, view, part, name, value):
        path = source.loc[index, "record"]
        if path not in sources:
            sources[path] = {v["view"]: v for v in json.loads(Path(path).read_text()).get("views", [])}
        return (sources[path].get(view, {}).get(part) or {}).get(name, value)

    # read_runs drops the columns no run filled, so one side may lack a column (no run starved or was
    # disturbed there) that the other fills: the result takes exactly source's, filled or not.
    varying = [c for c in source.columns if is_timing(c) or c in scheduling_columns()]
    frame = frame.assign(**{column: np.nan for column in varying if column not in frame})
    replaced = with_varying_values(frame, workdir, entries=entry,
                                   columns=lambda column, values: source[column] if column in source else np.nan)
    return claims_table(replaced, experiments)


def phantom_differences(a, b, *, keys=None):
    """How the phantoms both folders list (``volumes.csv``) differ: the same keys (``keys``: only these,
    which both must hold; ``None``: all) with the same SHA-256 of their data."""
    first, second = (pd.read_csv(results_file(folder, "volumes.csv"), dtype=str, keep_default_na=False).set_index("key")
                     for folder in (a, b))
    if keys is None:
        differences = _only_in(list(first.index), list(second.index), "phantoms", a, b)
        keys = sorted(set(first.index) & set(second.index))
    else:
        differences = [f"phantom {key} is not in {folder}/volumes.csv" for folder, table in ((a, first), (b, second))
                       for key in sorted(keys) if key not in table.index]
        keys = sorted(key for key in keys if key in first.index and key in second.index)
    differences += [f"phantom {key} ({first.loc[key, 'dataset']}): different data (SHA-256 "
                    f"{first.loc[key, 'sha256'][:12]}… in {a}, {second.loc[key, 'sha256'][:12]}… in {b})"
                    for key in keys if first.loc[key, "sha256"] != second.loc[key, "sha256"]]
    return differences


def rejudged_claims(folder):
    """The claims of the results folder ``folder`` judged again by this code on its runs; nothing is rendered.

    Each experiment is judged on its own table (``tables/<experiment>.csv``, the records and images it names),
    as the pipeline judged it: its rows in their order and their types as that table alone gives them (in
    ``runs.csv`` a tag such as ``task_size`` 8 reads 8.0 where other experiments leave it empty). Read back as
    :func:`read_claims` reads ``claims.csv``, so that the two compare cell by cell.
    """
    folder = Path(folder)
    tables = []
    for experiment in _experiments(list(dict.fromkeys(read_claims(folder).experiment))):
        path = table_path(folder, experiment.name)
        if not path.is_file():
            raise InputError(f"{folder}: no {path.relative_to(folder)}; give the results folder of a finished "
                             "pipeline run (results/<profile>)")
        judged = claims_table(_under(pd.read_csv(path, low_memory=False), folder), [experiment])
        tables.append(pd.read_csv(io.StringIO(judged.to_csv(index=False)), dtype=str, keep_default_na=False))
    return pd.concat(tables, ignore_index=True).fillna("")


def rejudge_differences(folder):
    """How judging the runs of ``folder`` again (:func:`rejudged_claims`) changes its claims: ``(changes,
    sentences)``, :func:`verdict_changes`' table of the written against the re-judged verdicts, and a sentence
    per changed cell of a claim (its verdict, measured value, interval, margin, expected text, detail, kind,
    paper value...) or per claim one side lacks. A change of code that must not change what a claim says
    (moving the judging helpers into the kit) re-judges a finished run with no sentence."""
    written, judged = read_claims(folder), rejudged_claims(folder)
    key = ["experiment", "claim"]
    sentences = _only_in([tuple(r) for r in written[key].values], [tuple(r) for r in judged[key].values],
                         "claims (experiment, claim)", f"{folder}/claims.csv", "its runs judged again")
    columns = [c for c in dict.fromkeys([*written.columns, *judged.columns]) if c not in key]
    merged = written.merge(judged, on=key, suffixes=("_written", "_judged"))
    for column in columns:
        mine, again = (merged.get(f"{column}_{side}", pd.Series("", index=merged.index))
                       for side in ("written", "judged"))
        for row, a, b in zip(merged.itertuples(index=False), mine, again):
            if a != b:
                sentences.append(f"claim {row.experiment}/{row.claim}: {column} {a!r} as written, {b!r} judged again")
    return verdict_changes(written, judged), sentences


def finished_runs(*folders):
    """Refuse (:class:`InputError`) a folder that is not a finished run's, before any comparison."""
    for folder in folders:
        for name in ("runs.csv", "claims.csv", "volumes.csv"):
            results_file(folder, name)


def differences(a, b, *, timing=None):
    """Every difference between the results folders ``a`` and ``b``: runs, images, claims (a timing claim
    that flipped between holds and fails included: :func:`timing_flips`), phantoms."""
    finished_runs(a, b)
    # Which claims read timings is found by judging every claim again on changed values: once, for both uses.
    timing = timing_claims(a, b) if timing is None else timing
    return [*run_differences(a, b), *image_differences(a, b), *claim_differences(a, b, timing=timing),
            *timing_flips(a, b, timing=timing), *phantom_differences(a, b)]


def main(argv=None):
    """``scripts/compare-results A B``: print the differences; exit 1 when there are any, 2 on bad input."""
    parser = argparse.ArgumentParser(prog="compare-results", description=__doc__.split("\n\n")[0])
    parser.add_argument("a", help="a results folder (results/<profile>)")
    parser.add_argument("b", nargs="?", help="the results folder to compare it with (not with --rejudge)")
    parser.add_argument("--rejudge", action="store_true",
                        help="judge A's claims again with this code from its runs (nothing rendered) and list every "
                             "claim whose row changes: for a change of code that must not change verdicts")
    args = parser.parse_args(argv)
    if args.rejudge != (args.b is None):
        parser.error("give two results folders, or one with --rejudge")
    if args.rejudge:
        return _rejudge(args.a)
    try:
        finished_runs(args.a, args.b)  # before the timing claims are judged, which reads the folders
        timing = timing_claims(args.a, args.b)
        found = differences(args.a, args.b, timing=timing)
    except InputError as exc:
        print(f"compare-results: {exc}", file=sys.stderr)
        return 2
    for difference in found:
        print(difference)
    changes = verdict_changes(read_claims(args.a), read_claims(args.b))
    moved = changes[changes.change.isin(["to inconclusive", "from inconclusive"])]
    for row in moved.itertuples():
        print(f"changed {row.change}: {row.experiment}/{row.claim}: {row.verdict_a} in {args.a} ({row.measured_a}), "
              f"{row.verdict_b} in {args.b} ({row.measured_b})")
    print(f"verdicts: {agreement_words(changes, timing=timing)}; {len(moved)} changed to or from inconclusive")
    agreement = interval_agreement(read_claims(args.a), read_claims(args.b), timing=timing)
    for line in intervals_apart(agreement, args.a, args.b):
        print(line)
    if not agreement.empty:
        print(f"intervals: {interval_words(agreement)}")
    print(f"{len(found)} differences" if found else
          f"{args.a} and {args.b}: the same runs, images, claims (no timing claim flipped) and phantoms")
    return 1 if found else 0


def _rejudge(folder):
    try:
        finished_runs(folder)
        changes, found = rejudge_differences(folder)
    except InputError as exc:
        print(f"compare-results: {exc}", file=sys.stderr)
        return 2
    for sentence in found:
        print(sentence)
    flipped = int((changes.change == "flipped").sum())
    print(f"verdicts as written against judged again: {agreement_words(changes)}; {flipped} flipped between holds "
          "and fails")
    print(f"{len(found)} differences" if found else f"{folder}: every claim judged again as written")
    return 1 if found else 0


if __name__ == "__main__":
    raise SystemExit(main())
