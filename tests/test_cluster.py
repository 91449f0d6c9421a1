"""The smoke profile on a real SLURM cluster, through snakemake-executor-plugin-slurm.

A one-node SLURM (munged, slurmctld, slurmd: ``scripts/slurm-single-node``) is started here, and
the smoke profile runs on it with the project's workflow profile (``config/profiles/slurm``). Side
by side with it, the local smoke run is brought up to date (``volbench run --profile smoke`` into
``VOLBENCH_CLUSTER_BASELINE``, default ``results/smoke``: where ``make reproduce PROFILE=smoke``
writes; Snakemake reruns only what is stale, so after that command it has nothing to do), and the
two are compared (:mod:`pipeline.compare`, which ``scripts/compare-results`` runs on any two folders):

- the same runs: the same (experiment, run, view) rows with the same status and the same values in
  every column but timings and durations, paths and the environment (date, host, device, SLURM job);
- the same images: bit-identical EXRs for the CPU backends, within
  :data:`pipeline.compare.DEVICE_TOLERANCE` for those that render through a device driver;
- the same claims: the same set with the same verdicts but for timing claims; and the same outcome
  and measured value for each once the timings and the values the backends declare
  scheduling-dependent (``Renderer.scheduling_dependent``: counters in runs.csv, entries in the run
  records) are the local run's (a timing claim may flip with the machine's load, the others not);
- the same phantoms: generated afresh on the cluster, the same bytes (``volumes.csv`` digests).

It needs root and Debian's slurmctld, slurmd, slurm-client and munge (``make cluster-packages``);
without them it skips with the reason, unless ``VOLBENCH_REQUIRE_CLUSTER`` is set (``.ci/run`` sets
it), where a skip is a failure. ``VOLBENCH_CLUSTER_EXPERIMENTS`` (names, comma-separated) runs only
those experiments of the profile on the cluster, compared with the same experiments of the local run
(which is always the whole profile).
"""

import dataclasses
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from pipeline import compare
from pipeline.collect import claims_table
from pipeline.experiments import Profile, plan, selected
from pipeline.scene_io import phantom_requests

pytestmark = pytest.mark.cluster

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "slurm-single-node"
SLURM_TOOLS = ("munged", "slurmctld", "slurmd", "sbatch", "srun", "squeue", "scontrol")


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


def names():
    """The names of :func:`experiments`."""
    return [e.name for e in experiments()]


def test_render_jobs_ran_as_slurm_jobs_on_the_node(cluster_run):
    results, log = cluster_run
    frame = compare.read_runs(results, experiments=names())
    timed = frame[frame.status == "ok"]
    assert timed["slurm_job_id"].notna().all(), "a render ran outside a SLURM job"
    assert timed["node"].str.startswith("volbench/").all(), sorted(pd.unique(timed["node"]))
    # Phantoms, runs and comparisons go through sbatch; collect and report run where Snakemake runs.
    assert "has been submitted with SLURM jobid" in log
    assert "localrule collect:" in log and "localrule report:" in log


def test_the_same_runs_with_the_same_non_timing_values(cluster_run, baseline):
    results, _ = cluster_run
    assert compare.run_differences(baseline, results, experiments=names()) == []


def test_the_same_images(cluster_run, baseline):
    results, _ = cluster_run
    assert (compare.read_runs(baseline, experiments=names()).status == "ok").any()
    assert compare.image_differences(baseline, results, experiments=names()) == []


def test_the_same_claims(cluster_run, baseline, tmp_path):
    results, _ = cluster_run
    assert compare.claim_differences(baseline, results, experiments=names()) == []
    # With the local run's timings and scheduling-dependent values in place of the cluster's,
    # every claim must come out the same, measured values and timing claims included.
    local, cluster = (compare.read_runs(folder, experiments=names()) for folder in (baseline, results))
    expected = claims_table(local, experiments())
    measured = compare.claims_with_values_of(cluster, local, experiments(), workdir=tmp_path)
    pd.testing.assert_frame_equal(expected, measured)


def test_the_same_phantoms(cluster_run, baseline):
    """Phantoms generated on the cluster (into their own cache) hold the local run's bytes."""
    results, _ = cluster_run
    profile = Profile.load(ROOT / "config" / "smoke.yaml")
    keys = set(phantom_requests([entry for run in plan(profile).values() if run.experiment in names()
                                 for entry in run.volume_entries], size=profile.volume_size))
    assert keys
    assert compare.phantom_differences(baseline, results, keys=keys) == []


def test_stopping_slurm_leaves_nothing_that_slows_later_commands(slurm):
    """After ``stop``, SLURM's commands (and every Snakemake start, through the executor plugin's
    ``scontrol show config``) must not go looking for the stopped controller (9 s each here)."""
    subprocess.run([str(SCRIPT), "stop"], check=True, timeout=60)
    assert not Path("/run/slurm/conf/slurm.conf").exists()
    started = time.monotonic()
    subprocess.run(["scontrol", "show", "config"], capture_output=True, env={k: v for k, v in os.environ.items() if k != "SLURM_CONF"})
    assert time.monotonic() - started < 3
