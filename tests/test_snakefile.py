"""The Snakefile reruns what an edit or a failure makes stale, and nothing else (dry runs on a copy)."""

import json
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent

pytestmark = [pytest.mark.slow, pytest.mark.integration]


def _snakemake(tree, profile, *args):
    out = subprocess.run([sys.executable, "-m", "snakemake", "--cores", "1", "--snakefile", str(tree / "Snakefile"),
                          "--directory", str(tree), "--configfile", str(profile), *args],
                         capture_output=True, text=True, timeout=180)
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-3000:]
    return out.stdout + out.stderr


def _planned(tree, profile):
    """``{rule: job count}`` a dry run would execute."""
    text = _snakemake(tree, profile, "--dry-run", "--quiet", "rules")
    return {m[1]: int(m[2]) for m in re.finditer(r"^(\w+)\s+(\d+)$", text, re.M) if m[1] not in ("total", "all")}


@pytest.fixture(scope="module")
def finished_workflow(tmp_path_factory):
    """A copy of the workflow whose outputs all exist and are up to date (as after a finished run).

    Everything (code, profile, results, phantom cache, Snakemake's metadata) lives in one folder
    under paths relative to it, so a copy of the folder is as finished as the original: each test
    edits a copy of its own.
    """
    tree = tmp_path_factory.mktemp("finished") / "tree"
    for entry in ("core", "datasets", "renderers", "reports", "pipeline", "config"):
        shutil.copytree(ROOT / entry, tree / entry, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "Snakefile", tree / "Snakefile")
    profile = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    profile.update(results="results", cache="cache", experiments=["volbench-convergence"])
    (tree / "profile.yaml").write_text(yaml.safe_dump(profile))
    summary = _snakemake(tree, tree / "profile.yaml", "--summary")
    # Its table's rows (tab-separated, after the header), not Snakemake's log lines.
    for output in [line.split("\t")[0] for line in summary.splitlines() if "\t" in line][1:]:
        path = tree / output
        path.parent.mkdir(parents=True, exist_ok=True)
        if "/metrics/" in str(path):  # an experiment's metrics: a folder (directory output)
            path.mkdir(parents=True, exist_ok=True)
        else:
            path.write_text(json.dumps({"status": "ok"}) if "/runs/" in str(path) else "")
    _snakemake(tree, tree / "profile.yaml", "--touch", "--forceall")  # marks them finished, recording params (the code digests)
    assert _planned(tree, tree / "profile.yaml") == {}
    return tree


@pytest.fixture
def workflow(finished_workflow, tmp_path):
    """``(tree, profile, results)`` of a finished workflow of this test's own (times kept: Snakemake compares them)."""
    tree = shutil.copytree(finished_workflow, tmp_path / "tree", symlinks=True)
    return tree, tree / "profile.yaml", tree / "results"


def _edit(path):
    with open(path, "a") as f:
        f.write("\n# an edit that changes the code's digest\n")


def test_a_shared_module_edit_reruns_every_job_it_shapes(workflow):
    tree, profile, _ = workflow
    _edit(tree / "core" / "errors.py")  # every job's code imports it
    planned = _planned(tree, profile)
    assert {"volume", "phantoms", "environment", "render", "evaluate", "tabulate", "collect", "report"} <= set(planned)
    assert "Params have changed since last execution" in _snakemake(tree, profile, "--dry-run")


def test_a_metrics_edit_reruns_evaluation_but_no_render(workflow):
    tree, profile, _ = workflow
    _edit(tree / "reports" / "metrics.py")
    planned = _planned(tree, profile)
    # The phantoms list plans the experiments, whose classes (their pages too) use the metrics.
    assert set(planned) == {"evaluate", "phantoms", "tabulate", "collect", "report"}


def test_a_loader_edit_reruns_renders_and_a_backend_edit_only_its_renders(workflow):
    tree, profile, _ = workflow
    _edit(tree / "renderers" / "reference" / "raycast.py")
    planned = _planned(tree, profile)
    assert "render" in planned and "volume" not in planned and "environment" not in planned
    _snakemake(tree, profile, "--touch", "--forceall")
    _edit(tree / "datasets" / "loaders.py")
    planned = _planned(tree, profile)
    assert "render" in planned and "volume" in planned and "environment" not in planned


def test_a_failed_run_is_retried_on_the_next_run(workflow):
    tree, profile, results = workflow
    records = sorted((results / "runs").rglob("*.json"))
    failed = records[0]
    failed.write_text(json.dumps({"status": "failed", "reason": "exceeded the profile's render_time_limit of 1 s"}))
    _snakemake(tree, profile, "--touch", "--forceall")  # even as a finished output with current metadata ...
    assert _planned(tree, profile)["render"] == 1  # ... the failed run is planned again
    text = _snakemake(tree, profile, "--dry-run")
    assert f"output: {failed.relative_to(tree)}" in text and ".retry" in text
    failed.write_text(json.dumps({"status": "ok"}))  # the retry succeeded
    _snakemake(tree, profile, "--touch", "--forceall")
    assert _planned(tree, profile) == {}
    records[1].write_text(json.dumps({"status": "skipped", "reason": "backend unavailable"}))
    _snakemake(tree, profile, "--touch", "--forceall")
    assert _planned(tree, profile) == {}  # a skipped run cannot happen here: it is not retried


def test_the_slurm_profile_gives_each_render_a_node_its_runtime_and_a_gpu_where_it_needs_one(tmp_path):
    """A dry run through the SLURM workflow profile: per-job resources as the executor will see them."""
    import renderers
    from pipeline.experiments import Profile, plan

    profile = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    profile.update(results=str(tmp_path / "results"), cache=str(tmp_path / "cache"),
                   experiments=["volbench-convergence", "kruger2003-nocue"])
    profile_path = tmp_path / "profile.yaml"
    profile_path.write_text(yaml.safe_dump(profile))
    text = _snakemake(ROOT, profile_path, "--dry-run", "--workflow-profile", str(ROOT / "config" / "profiles" / "slurm"))
    runs = plan(Profile.from_mapping(profile))
    # (A dry run executes nothing, so it shows no job as local: tests/test_cluster.py checks that.)
    # Render and evaluate jobs run bundled per experiment, phantoms in one more bundle (cluster jobs).
    groups = {"volumes", "runs-volbench-convergence", "runs-kruger2003-nocue"}
    assert set(re.findall(r"Group job (\S+) ", text)) == groups
    # Each group is one connected piece of the job graph (inside a cluster job the plugin runs one
    # job step per piece, one after another): bundling one piece per cluster job changes nothing.
    pieces = _snakemake(ROOT, profile_path, "--dry-run", "--workflow-profile", str(ROOT / "config" / "profiles" / "slurm"),
                        "--group-components", "runs-{experiment}=1", "volumes=1")
    assert sorted(re.findall(r"Group job (\S+) ", pieces)) == sorted(groups)
    jobs = re.findall(r"^(?:localrule|rule) (\w+):\n(.*?)(?=^\S|\Z)", re.sub(r"^    ", "", text, flags=re.M), re.M | re.S)
    renders = [body for name, body in jobs if name == "render"]
    devices = set()
    for body in renders:
        run = runs["/".join(re.search(r"wildcards: experiment=(\S+), run=(\S+)", body).groups())]
        resources = dict(item.split("=", 1) for item in re.search(r"resources: (.*)", body)[1].split(", "))
        assert resources["slurm_extra"] == "--exclusive" and resources["mem_mb"] == "4000"
        assert int(resources["runtime"]) == math.ceil(profile["render_time_limit"] / 60) + 10
        uses_device = renderers.backend_module(run.backend).startswith(("renderers.gl", "renderers.cl", "renderers.vtk.gpu"))
        assert resources["gpu"] == str(int(uses_device)), run.key
        devices.add(uses_device)
    assert devices == {True, False}  # both kinds of render job were checked


def test_a_stale_lock_left_by_a_killed_run_is_removed_and_the_run_goes_on(workflow, monkeypatch, capsys):
    from pipeline import cli, launch

    tree, profile, results = workflow
    locks = tree / ".snakemake" / "locks"
    locks.mkdir(parents=True, exist_ok=True)
    # As a Snakemake killed with kill -9 leaves it: the next run would stop on it.
    (locks / "0.output.lock").write_text(f"{(results / 'runs.csv').relative_to(tree)}\n")
    monkeypatch.setattr(launch, "ROOT", tree)
    monkeypatch.setattr(launch, "compile_packages", lambda: None)
    assert cli.main(["run", "--profile", str(profile), "--cores", "1"]) == 0
    out = capsys.readouterr().out
    assert f"volbench: removed a stale Snakemake lock from {locks}" in out and "volbench: report at" in out
    assert not list(locks.glob("*.lock"))


def test_the_runs_of_an_interleave_group_are_one_render_job(tmp_path):
    """A dry run of a profile whose sweep runs share a group per scene: one job renders each group's runs."""
    from pipeline.experiments import Profile, plan

    tree = tmp_path / "tree"
    for entry in ("core", "datasets", "renderers", "reports", "pipeline", "config"):
        shutil.copytree(ROOT / entry, tree / entry, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "Snakefile", tree / "Snakefile")
    module = tree / "pipeline" / "experiments" / "volbench" / "convergence.py"
    sweep_tags = '"role": "sweep"}'  # the end of the sweep runs' tags, however the call is wrapped
    assert module.read_text().count(sweep_tags) == 1
    module.write_text(module.read_text().replace(sweep_tags, f"{sweep_tags}, interleave=scene_name"))
    profile = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    profile.update(results="results", cache="cache", experiments=["volbench-convergence"])
    (tree / "profile.yaml").write_text(yaml.safe_dump(profile))
    runs = plan(Profile.from_mapping(profile)).values()  # this checkout's plan: the same runs, ungrouped
    scenes = sorted({run.tags["scene"] for run in runs})
    assert len(scenes) > 1

    planned = _planned(tree, tree / "profile.yaml")
    together = {rule: count for rule, count in planned.items() if rule.startswith("render_together_")}
    assert len(together) == len(scenes) and set(together.values()) == {1}  # one job per group
    assert planned["render"] == sum(run.tags["role"] == "truth" for run in runs)  # the ungrouped runs, one job each
    # On a cluster each is a render job as any other: a node of its own, the time of all its runs.
    text = _snakemake(tree, tree / "profile.yaml", "--dry-run", "--workflow-profile", str(ROOT / "config" / "profiles" / "slurm"))
    jobs = dict(re.findall(r"rule (render_together_\w+):\n(.*?)(?=^\s*\[|^\S|\Z)", text, re.M | re.S))
    assert set(jobs) == set(together)
    outputs = {rule: re.search(r"output: (.*)", job)[1].split(", ") for rule, job in jobs.items()}
    groups = {scene: [f"results/runs/volbench-convergence/{run.id}.json" for run in runs
                      if run.tags["scene"] == scene and run.tags["role"] == "sweep"] for scene in scenes}
    assert sorted(outputs.values()) == sorted(groups.values())  # each group's runs are one job's outputs
    for rule in together:
        members = outputs[rule]
        resources = dict(item.split("=", 1) for item in re.search(r"resources: (.*)", jobs[rule])[1].split(", "))
        assert resources["slurm_extra"] == "--exclusive" and resources["mem_mb"] == "4000" and resources["gpu"] == "0"
        assert int(resources["runtime"]) == (math.ceil(profile["render_time_limit"] / 60) + 10) * len(members)


def test_timed_renders_take_every_core_and_untimed_work_one_and_goes_first(tmp_path):
    """A timed render job never shares the machine; untimed renders (truths) take a core each and run first."""
    from pipeline.experiments import Profile, plan

    profile = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    profile.update(results=str(tmp_path / "results"), cache=str(tmp_path / "cache"),
                   experiments=["volbench-convergence"])
    (tmp_path / "profile.yaml").write_text(yaml.safe_dump(profile))
    out = subprocess.run([sys.executable, "-m", "snakemake", "--dry-run", "--cores", "2", "--snakefile",
                          str(ROOT / "Snakefile"), "--directory", str(ROOT), "--configfile", str(tmp_path / "profile.yaml")],
                         capture_output=True, text=True, timeout=180)
    assert out.returncode == 0, out.stderr[-3000:]
    jobs = re.findall(r"rule (render\w*):\n(.*?)(?=^\s*\[|^\S|\Z)", out.stdout + out.stderr, re.M | re.S)
    runs = {run.id: run for run in plan(Profile.from_mapping(profile)).values()}
    assert len(jobs) == len(runs) and {run.timed for run in runs.values()} == {True, False}
    for _, job in jobs:
        run = runs[re.search(r"run=([^,\s]+)", job)[1]]
        threads = re.search(r"threads: (\d+)", job)
        assert (int(threads[1]) if threads else 1) == (2 if run.timed else 1), job
        assert int(re.search(r"priority: (\d+)", job)[1]) == (1 if run.timed else 2), job
