"""The smoke profile on a real SLURM cluster, through snakemake-executor-plugin-slurm.

A one-node SLURM (munged, slurmctld, slurmd: ``scripts/slurm-single-node``) is started here, and
the smoke profile runs on it with the project's workflow profile (``config/profiles/slurm``). Side
by side with it, the local smoke run is brought up to date (``volbench run --profile smoke`` into
``VOLBENCH_CLUSTER_BASELINE``, default ``results/smoke``: where ``make reproduce PROFILE=smoke``
writes; Snakemake reruns only what is stale, so after that command it has nothing to do), and the
two are compared:

- the same runs: the same (experiment, run, view) rows with the same status and the same values in
  every column but timings and durations, paths and the environment (date, host, device, SLURM job);
- the same images: bit-identical EXRs for the CPU backends, within :data:`DEVICE_TOLERANCE` for
  those that render through a device driver;
- the same claims: the same set, and the same outcome and measured value for each once the timings
  and the values the backends declare scheduling-dependent (``Renderer.scheduling_dependent``:
  counters in runs.csv, entries in the run records) are the local run's (a timing claim may flip
  with the machine's load, the others not);
- the same phantoms: generated afresh on the cluster, the same bytes (``volumes.csv`` digests).

It needs root and Debian's slurmctld, slurmd, slurm-client and munge (``make cluster-packages``);
without them it skips with the reason, unless ``VOLBENCH_REQUIRE_CLUSTER`` is set (``.ci/run`` sets
it), where a skip is a failure. ``VOLBENCH_CLUSTER_EXPERIMENTS`` (names, comma-separated) runs only
those experiments of the profile on the cluster, compared with the same experiments of the local run
(which is always the whole profile).
"""

import dataclasses
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import renderers
from pipeline.collect import claims_table
from pipeline.environment import SLURM_FACTS, host_environment
from pipeline.experiments import Profile, plan, selected
from pipeline.scene_io import phantom_requests
from reports.imageio import read_image

pytestmark = pytest.mark.cluster

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "slurm-single-node"
SLURM_TOOLS = ("munged", "slurmctld", "slurmd", "sbatch", "srun", "squeue", "scontrol")
CPU_BACKENDS = frozenset({"reference", "shearwarp", "volpack", "vtk-cpu"})
"""Backends whose images must be bit-identical between the two runs (same code, same CPU)."""
DEVICE_TOLERANCE = 1e-6
"""Largest difference of a pixel channel allowed for the other backends (OpenGL through Mesa's
llvmpipe, OpenCL through PoCL): they render deterministically on one machine in practice."""
PATH_COLUMNS = ("record", "png", "exr", "diff_png")
KEY = ["experiment", "run", "view"]


def unavailable(reason):
    """Skip with ``reason``, or fail where CI requires the cluster test to run."""
    if os.environ.get("VOLBENCH_REQUIRE_CLUSTER"):
        pytest.fail(f"VOLBENCH_REQUIRE_CLUSTER is set, but {reason}")
    pytest.skip(reason)


def experiments():
    """The names of the experiments both runs hold: the smoke profile's, or ``VOLBENCH_CLUSTER_EXPERIMENTS``."""
    names = [n.strip() for n in os.environ.get("VOLBENCH_CLUSTER_EXPERIMENTS", "").split(",") if n.strip()]
    profile = Profile.load(ROOT / "config" / "smoke.yaml")
    if names:
        profile = dataclasses.replace(profile, experiments=names)
    return selected(profile)


SLURM_OPTIONS = (
    "--workflow-profile", str(ROOT / "config" / "profiles" / "slurm"),
    # No accounting database here: no account to validate or guess.
    "--slurm-no-account",
    # Jobs take seconds here, not hours: poll SLURM every 2 s instead of the default 40 s
    # (still far below MinJobAge, which the plugin checks before it trusts squeue).
    "--slurm-init-seconds-before-status-checks", "2", "--seconds-between-status-checks", "2",
)
"""Snakemake options of the cluster run: the project's workflow profile and this test cluster's settings."""


@pytest.fixture(scope="module")
def slurm():
    if os.geteuid() != 0:
        unavailable("starting munged, slurmctld and slurmd needs root")
    missing = [tool for tool in SLURM_TOOLS if shutil.which(tool) is None]
    if missing:
        unavailable(f"SLURM is not installed ({', '.join(missing)} missing): make cluster-packages")
    started = subprocess.run([str(SCRIPT), "start"], capture_output=True, text=True, timeout=120)
    if started.returncode != 0:
        unavailable(f"SLURM did not start:\n{started.stdout}{started.stderr}")
    conf = subprocess.run([str(SCRIPT), "env"], capture_output=True, text=True, check=True).stdout
    yield {**os.environ, "SLURM_CONF": conf.strip().split("=", 1)[1]}
    subprocess.run([str(SCRIPT), "stop"], check=False, timeout=60)


def smoke_command(results, *options):
    """``volbench run`` of the smoke profile into ``results`` (then ``options``), on this machine's cores."""
    return [sys.executable, "-m", "pipeline.cli", "run", "--profile", "smoke", "--cores", str(os.cpu_count()),
            "--results", results, *options]


@pytest.fixture(scope="module")
def side_by_side(slurm, tmp_path_factory):
    """The smoke profile through the SLURM executor and, beside it, the local smoke run it is compared with.

    The cluster run writes its own results and phantoms (``VOLBENCH_CLUSTER_RESULTS``, default
    ``results/smoke-slurm``), afresh. The local run is ``volbench run --profile smoke`` into
    ``VOLBENCH_CLUSTER_BASELINE`` (default ``results/smoke``, where ``make reproduce PROFILE=smoke``
    writes): Snakemake reruns only what is stale there, so after that command it has nothing to do.
    What it does render shares the machine with the cluster's jobs, so its timings are not
    measurements; nothing here compares timings. The two run side by side because the cluster run
    leaves most of the machine idle between its SLURM jobs (one core of two, on this 2-core VM).
    Returns ``(local results, cluster results, cluster log)``.
    """
    baseline = os.environ.get("VOLBENCH_CLUSTER_BASELINE", "results/smoke")
    results = os.environ.get("VOLBENCH_CLUSTER_RESULTS", "results/smoke-slurm")
    shutil.rmtree(ROOT / results, ignore_errors=True)
    subset = [f"--experiment={e.name}" for e in experiments()] if os.environ.get("VOLBENCH_CLUSTER_EXPERIMENTS") else []
    commands = {
        # Generated on the cluster too, not taken from the local run.
        "SLURM": (smoke_command(results, "--cache", f"{results}/.volumes", *subset, "--", *SLURM_OPTIONS), slurm),
        # The whole profile, so that a subset on the cluster never leaves a partial local report.
        "local": (smoke_command(baseline), {k: v for k, v in os.environ.items() if k != "SLURM_CONF"}),
    }
    logs = tmp_path_factory.mktemp("logs")
    started = time.monotonic()
    processes, walls = {}, {}
    for name, (command, env) in commands.items():
        with (logs / f"{name}.log").open("w") as log:
            processes[name] = subprocess.Popen(command, cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT)
    while len(walls) < len(processes):
        for name, process in processes.items():
            if name not in walls and process.poll() is not None:
                walls[name] = time.monotonic() - started
                # .ci/run checks the local run's report on this line, while the cluster run goes on.
                print(f"\n{name} smoke run finished after {walls[name]:.0f} s (exit code {process.returncode})", flush=True)
                if process.returncode != 0:
                    for other in processes.values():
                        other.terminate()  # Snakemake cancels its SLURM jobs on SIGTERM
                    for other in processes.values():
                        other.wait()
                    log = (logs / f"{name}.log").read_text()
                    pytest.fail(f"the {name} smoke run failed after {walls[name]:.0f} s:\n{log[-6000:]}")
        time.sleep(1)
    log = (logs / "SLURM.log").read_text()
    submitted = log.count("has been submitted with SLURM jobid")
    print(f"\nside by side: local smoke run {walls['local']:.0f} s, SLURM smoke run {walls['SLURM']:.0f} s wall "
          f"({submitted} SLURM jobs, results in {results})")
    for folder in (baseline, results):
        assert (ROOT / folder / "runs.csv").is_file() and (ROOT / folder / "claims.csv").is_file(), folder
    return ROOT / baseline, ROOT / results, log


@pytest.fixture(scope="module")
def baseline(side_by_side):
    return side_by_side[0]


@pytest.fixture(scope="module")
def cluster_run(side_by_side):
    return side_by_side[1:]


def is_timing(column):
    """Timings (``time_*``) and durations (``*_seconds``: e.g. a phantom's generation time) differ run to run."""
    return column.startswith("time_") or column.endswith("_seconds")


def scheduling_dependent():
    """``{backend: names}``: each backend's counters and info entries that its scheduling decides."""
    return {name: tuple(renderers.backend_class(name).scheduling_dependent) for name in renderers.names()}


def scheduling_columns():
    """The runs.csv columns of :func:`scheduling_dependent` (``count_<name>``, ``info_<name>``)."""
    return {f"{kind}_{name}" for names in scheduling_dependent().values() for name in names for kind in ("count", "info")}


def environment_columns(frame):
    """The runs.csv columns that describe where a run ran, not what it rendered: the host's facts
    (``environment`` of each run record), the device's (``backend_environment``: e.g. PoCL sizes
    ``cl_global_mem_bytes`` by the memory free when it starts), the SLURM job's and the node."""
    columns = set(host_environment()) | set(SLURM_FACTS) | {"node"}
    for path in frame["record"].dropna().unique():
        record = json.loads((ROOT / path).read_text())
        columns |= set(record["environment"]) | set(record.get("backend_environment") or {})
    return columns


def non_timing_columns(frame):
    """Columns two runs must agree on: not timings, paths or the environment, nor the values
    that the backends' thread or work-item scheduling decides (:func:`scheduling_dependent`)."""
    excluded = environment_columns(frame) | set(PATH_COLUMNS) | scheduling_columns()
    return [c for c in frame.columns if not is_timing(c) and c not in excluded]


def with_local_scheduling(cluster, local, folder):
    """``cluster`` whose records hold the local records' scheduling-dependent entries (copies in ``folder``).

    Claims read some values from the run records (e.g. the shear-warp workers' shares); each view's
    entries named by its backend's ``scheduling_dependent`` are replaced, the rest is the cluster's.
    """
    dependent = scheduling_dependent()
    written = {}
    for index, row in cluster.iterrows():
        names = dependent.get(row["backend"], ())
        if not names or not isinstance(row["record"], str):
            continue
        if row["record"] not in written:
            record = json.loads((ROOT / row["record"]).read_text())
            theirs = {view["view"]: view for view in json.loads((ROOT / local.loc[index, "record"]).read_text())["views"]}
            for view in record["views"]:
                for part in ("counters", "info"):
                    source = theirs.get(view["view"], {}).get(part, {})
                    view.get(part, {}).update({name: source[name] for name in names if name in source})
            path = folder / row["experiment"] / Path(row["record"]).name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(record))
            written[row["record"]] = str(path)
        cluster.loc[index, "record"] = written[row["record"]]
    return cluster


def runs(folder):
    """``runs.csv`` of ``folder``: the rows of :func:`experiments`, in a stable order."""
    frame = pd.read_csv(folder / "runs.csv", low_memory=False)
    frame = frame[frame.experiment.isin([e.name for e in experiments()])].dropna(axis=1, how="all")
    frame["view"] = frame["view"].fillna("")
    return frame.sort_values(KEY).reset_index(drop=True)


def relative(paths, folder):
    return [os.path.relpath(ROOT / p, ROOT / folder) if isinstance(p, str) else p for p in paths]


def test_render_jobs_ran_as_slurm_jobs_on_the_node(cluster_run):
    results, log = cluster_run
    frame = runs(results)
    timed = frame[frame.status == "ok"]
    assert timed["slurm_job_id"].notna().all(), "a render ran outside a SLURM job"
    assert timed["node"].str.startswith("volbench/").all(), sorted(pd.unique(timed["node"]))
    # Phantoms, runs and comparisons go through sbatch; collect and report run where Snakemake runs.
    assert "has been submitted with SLURM jobid" in log
    assert "localrule collect:" in log and "localrule report:" in log


def test_the_same_runs_with_the_same_non_timing_values(cluster_run, baseline):
    results, _ = cluster_run
    local, cluster = runs(baseline), runs(results)
    assert local[KEY].values.tolist() == cluster[KEY].values.tolist()
    # Only a cluster run fills the SLURM columns (runs() drops the columns no row fills).
    assert set(local.columns) - set(SLURM_FACTS) == set(cluster.columns) - set(SLURM_FACTS)
    for column in PATH_COLUMNS:
        if column in local:
            assert relative(local[column], baseline) == relative(cluster[column], results), column
    device = ~local["backend"].isin(CPU_BACKENDS)
    for column in non_timing_columns(local):
        a, b = local[column], cluster[column]
        if pd.api.types.is_float_dtype(a) and pd.api.types.is_float_dtype(b):
            # Metrics of device renders follow their images' tolerance; the rest are exact.
            close = np.isclose(a, b, rtol=0, atol=0, equal_nan=True)
            close |= device & np.isclose(a, b, rtol=1e-4, atol=1e-6, equal_nan=True)
            assert close.all(), (column, local.loc[~close, KEY + [column]].to_dict("records"),
                                 cluster.loc[~close, [column]].to_dict("records"))
        else:
            differ = ~((a == b) | (a.isna() & b.isna()))
            assert not differ.any(), (column, local.loc[differ, KEY + [column]].to_dict("records"),
                                      cluster.loc[differ, [column]].to_dict("records"))


def test_the_same_images(cluster_run, baseline):
    results, _ = cluster_run
    local, cluster = runs(baseline), runs(results)
    rows = local[local.status == "ok"]
    assert not rows.empty
    worst = {}
    for index, row in rows.iterrows():
        a = read_image(ROOT / row["exr"])
        b = read_image(ROOT / cluster.loc[index, "exr"])
        assert a.shape == b.shape, row["exr"]
        if row["backend"] in CPU_BACKENDS:
            assert np.array_equal(a, b), f"{row['exr']}: a CPU backend's image differs on the cluster"
        else:
            difference = float(np.max(np.abs(a - b)))
            worst[row["backend"]] = max(worst.get(row["backend"], 0.0), difference)
            assert difference <= DEVICE_TOLERANCE, f"{row['exr']}: differs by {difference:g}"
    print(f"\nlargest pixel difference of device backends: {worst}")


def test_the_same_claims(cluster_run, baseline, tmp_path):
    results, _ = cluster_run
    names = [e.name for e in experiments()]
    local_claims, cluster_claims = (pd.read_csv(folder / "claims.csv") for folder in (baseline, results))
    local_claims, cluster_claims = (claims[claims.experiment.isin(names)].reset_index(drop=True)
                                    for claims in (local_claims, cluster_claims))
    claim_key = ["experiment", "claim", "statement", "expected"]
    assert local_claims[claim_key].values.tolist() == cluster_claims[claim_key].values.tolist()
    outcome = [claims["holds"].fillna("not measured").astype(str) for claims in (local_claims, cluster_claims)]
    flipped = local_claims.loc[outcome[0] != outcome[1], "claim"]
    print(f"\nclaims whose outcome differs with the cluster's timings: {sorted(flipped) or 'none'}")
    # With the local run's timings and scheduling-dependent values in place of the cluster's,
    # every claim must come out the same.
    local, cluster = runs(baseline), runs(results)
    timing = [c for c in local.columns if is_timing(c) or c in scheduling_columns()]
    cluster[timing] = local[timing]
    cluster = with_local_scheduling(cluster, local, tmp_path)
    expected, measured = claims_table(local, experiments()), claims_table(cluster, experiments())
    pd.testing.assert_frame_equal(expected, measured)


def test_the_same_phantoms(cluster_run, baseline):
    """Phantoms generated on the cluster (into their own cache) hold the local run's bytes."""
    results, _ = cluster_run
    names = {e.name for e in experiments()}
    profile = Profile.load(ROOT / "config" / "smoke.yaml")
    keys = set(phantom_requests([entry for run in plan(profile).values() if run.experiment in names
                                 for entry in run.volume_entries], size=profile.volume_size))
    local, cluster = (pd.read_csv(folder / "volumes.csv").set_index("key") for folder in (baseline, results))
    assert keys and keys <= set(cluster.index) and keys <= set(local.index)
    keys = sorted(keys)
    assert local.loc[keys, "sha256"].tolist() == cluster.loc[keys, "sha256"].tolist()


def test_stopping_slurm_leaves_nothing_that_slows_later_commands(slurm):
    """After ``stop``, SLURM's commands (and every Snakemake start, through the executor plugin's
    ``scontrol show config``) must not go looking for the stopped controller (9 s each here)."""
    subprocess.run([str(SCRIPT), "stop"], check=True, timeout=60)
    assert not Path("/run/slurm/conf/slurm.conf").exists()
    started = time.monotonic()
    subprocess.run(["scontrol", "show", "config"], capture_output=True, env={k: v for k, v in os.environ.items() if k != "SLURM_CONF"})
    assert time.monotonic() - started < 3
