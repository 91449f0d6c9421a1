# volbench workflow: phantoms → one job per run (images + JSON record) → per experiment, metrics of
# each run against its reference and the experiment's table and claims → tidy CSV → HTML report.
#
#   volbench run --profile default                                (what `make reproduce` runs: this
#                                                                 workflow through pipeline.driver)
#   snakemake --cores 2 --configfile config/default.yaml         (by hand: every render job a process)
#   snakemake -n --configfile config/full.yaml                   (dry run: list the jobs)
#   snakemake --workflow-profile config/profiles/slurm --cores 32 --configfile config/full.yaml
#                                                                (a SLURM cluster, via the executor plugin)
#
# Cluster resources. The workflow profile (config/profiles/slurm) gives every rule its SLURM
# resources; what depends on the run is set here: a render job's wall time follows the profile's
# render_time_limit (so SLURM never kills a run that volbench would record as failed), and a render
# job whose backend draws on a device (OpenGL, OpenCL) asks for one `gpu`. collect and report read
# every record and are quick, so they run where Snakemake runs (localrules).
#
# Reruns. Every job carries, as the param `code`, a content digest of all the code that shapes its
# output (pipeline.digests.job_code_digest: its entry in pipeline/jobs.py, the project modules that
# imports, directly or through others, their packages' data files such as templates and kernels,
# and a render job's backend package), so with Snakemake's default `params` rerun trigger an edit to
# any of it reruns exactly the jobs it shapes (and, through their outputs, the jobs downstream),
# while editing one backend reruns only its jobs. Digests, not the files as inputs: a checkout that
# changes no byte reruns nothing. A render job's params also carry the run's spec hash, so changing
# a run's scene or options reruns that run.
#
# Failed runs are retried: a run that raised or hit the profile's render_time_limit is recorded as
# failed (the report lists it) and its job succeeds, so the pipeline goes on. Each render job takes a
# retry marker (results/.retry/...) as an input, which the workflow rewrites at start-up: dated now
# and naming the record when the run's record is failed, or names an image that is missing or does
# not match the digest the record carries (a damaged run), empty and dated 1970 otherwise
# (pipeline.digests.mark_retry). So the next run (and a dry run) reruns exactly the failed and damaged
# runs, and a failed record is never kept as a finished output; it stays until its retry replaces it.
# (Both rely on Snakemake's default rerun triggers; `--rerun-triggers mtime` would turn the code
# digests off.)
import dataclasses
import json
import math
import sys
from pathlib import Path

sys.path.insert(0, workflow.basedir)

import datasets
from pipeline import digests, progress
from pipeline.environment import uses_device
from pipeline.experiments import Profile, plan, selected, stack_parts
from pipeline.scene_io import phantom_requests

import yaml

# The default profile applies only when no --configfile is given: Snakemake would deep-merge a
# `configfile:` directive with the user's profile instead of replacing it.
if not config:
    config.update(yaml.safe_load((Path(workflow.basedir) / "config" / "default.yaml").read_text()))

PROFILE = Profile.from_mapping(dict(config))
RUNS = plan(PROFILE)
R = PROFILE.results
CACHE = PROFILE.cache
PY = sys.executable
CODE = {rule: digests.job_code_digest(rule)
        for rule in ("volume", "phantoms", "environment", "evaluate", "tabulate", "collect", "report")}
BACKEND_CODE = {backend: digests.job_code_digest("render", backend=backend)
                for backend in sorted({run.backend for run in RUNS.values()})}
# Only the Snakemake a user starts marks the retries; the ones it spawns to run a job (a cluster job,
# a job step of a group) need the markers' paths only, and must not re-date them mid-run.
_retry_marker = digests.mark_retry if workflow.is_main_process else digests.retry_marker_path
RETRY = {key: str(_retry_marker(R, run.experiment, run.id)) for key, run in RUNS.items()}
PROFILE_JSON = json.dumps(dataclasses.asdict(PROFILE), sort_keys=True)
ROOT = Path(workflow.basedir)

# Backends that render on a device: their render jobs ask for one `gpu` on a cluster.
RENDER_RESOURCES = {
    "gpu": lambda w: int(uses_device(run_of(w).backend)),
}

# Cores and order. A timed render job takes every core, so nothing else runs beside its timed frames;
# on this machine an untimed one (a ground truth, a picture, the atlas's single frames) takes one, so
# untimed work runs side by side (on a cluster every render has a node of its own). Untimed renders go first (priority 2), then
# the timed ones (1), then the evaluations and tables (0), which wait for every run of their experiment.
UNTIMED_PRIORITY, TIMED_PRIORITY = 2, 1


def render_threads(runs):
    """The threads of a render job, a function of its wildcards: the executor is known only then."""
    def threads(wildcards):
        # On a cluster every render job has a node of its own (--exclusive) and asks for all its
        # cores: an experiment's jobs are one cluster job (a group), which asks for its widest layer
        # of jobs that could run side by side, and two one-core renders would ask one node for two
        # devices. (A dry run shows this machine's threads.)
        if not workflow.local_exec or any(run.timed for run in runs):
            return workflow.cores
        return 1
    return threads


def render_priority(runs):
    return TIMED_PRIORITY if any(run.timed for run in runs) else UNTIMED_PRIORITY
if PROFILE.render_time_limit is not None:
    # Minutes: the run's limit plus ten for start-up and writing the images and the record.
    RENDER_RESOURCES["runtime"] = math.ceil(PROFILE.render_time_limit / 60) + 10

localrules: all, collect, report

# Job groups (they take effect only off this machine, e.g. through the SLURM executor): every render
# and evaluate job of one experiment, and its tabulate job, are one group, and the workflow profile
# bundles each group's jobs into a single cluster job (`group-components`), so an experiment's runs
# are timed on one node one after another (their ratios compare like with like) and a profile of
# hundreds of small runs costs tens of cluster jobs, not hundreds. Phantom generation (the volume
# jobs and the phantoms list) is one more group. Each group is one connected piece of the job graph
# (tabulate reads every run of its experiment; the phantoms list every volume) because inside a
# cluster job the SLURM plugin starts one job step, with its own Snakemake, per connected piece, one
# piece after another: connected, a group costs one step and runs its jobs in parallel where their
# threads allow.
RUN_GROUP = "runs-{experiment}"
VOLUME_GROUP = "volumes"

wildcard_constraints:
    experiment="[A-Za-z0-9._+-]+",
    run="[A-Za-z0-9._+-]+",
    key="[A-Za-z0-9._+-]+",


def volume_requests(run):
    """``{cache_key: request}`` for the generated phantoms a run's scene uses."""
    return phantom_requests(run.volume_entries, size=PROFILE.volume_size)


VOLUMES = phantom_requests([entry for run in RUNS.values() for entry in run.volume_entries], size=PROFILE.volume_size)
EXPERIMENT_RUNS = {experiment.name: [run for run in RUNS.values() if run.experiment == experiment.name]
                   for experiment in selected(PROFILE)}


def run_of(wildcards):
    return RUNS[f"{wildcards.experiment}/{wildcards.run}"]


def record(run):
    return f"{R}/runs/{run.experiment}/{run.id}.json"




def metrics(run):
    return f"{R}/metrics/{run.experiment}/{run.id}.json"


# Per experiment, its runs that have a reference: [run record, reference record, metrics record].
EVALUATIONS = {name: [[record(run), record(RUNS[f"{name}/{run.reference}"]), metrics(run)]
                      for run in runs if run.reference is not None]
               for name, runs in EXPERIMENT_RUNS.items()}


rule all:
    input:
        f"{R}/report/index.html",


rule volume:
    output:
        f"{CACHE}/{{key}}.npy",
    group: VOLUME_GROUP
    params:
        request=lambda w: json.dumps(VOLUMES[w.key]),
        code=CODE["volume"],
    shell:
        "{PY} -m pipeline.jobs volume --request {params.request:q} --cache {CACHE}"


# The digests of every phantom the profile generated, for the report (and so the phantoms are one
# connected group: see the groups above).
rule phantoms:
    input:
        [f"{CACHE}/{key}.npy" for key in VOLUMES],
    output:
        f"{R}/volumes.csv",
    group: VOLUME_GROUP
    params:
        code=CODE["phantoms"],
    shell:
        "{PY} -m pipeline.jobs phantoms --profile {PROFILE_JSON:q} --output {output}"


rule environment:
    output:
        f"{R}/environment.json",
    params:
        code=CODE["environment"],
    shell:
        "{PY} -m pipeline.jobs environment --output {output}"


# Timed render jobs take every core (on a cluster: `--cores` per job, on a node of their own; see the
# workflow profile): timings are taken with nothing else running beside them. Where `volbench run`
# runs the workflow on this machine, a render job hands its runs to a warm worker process of the
# render service (pipeline.workers) and waits; elsewhere it renders in a process of its own.
#
# Runs of one experiment with the same `interleave` name are one job, made by a rule of their own
# (explicit outputs: Snakemake prefers it to `render`'s pattern): their frames alternate view by view,
# so a claim comparing them takes its ratio under the same conditions (pipeline.timing.measure_together).
# A group whose backends render through different OpenGL stacks goes to its job as its parts, each timed
# in processes of its own (pipeline.experiments.stack_parts).
INTERLEAVED = {}
for _run in RUNS.values():
    if _run.interleave:
        INTERLEAVED.setdefault((_run.experiment, _run.interleave), []).append(_run)

# The progress line's estimate weighs each render job by what it renders (pipeline.progress).
if workflow.is_main_process:
    _grouped = {run.key for members in INTERLEAVED.values() for run in members}
    progress.expect_renders({
        **{record(members[0]): (any(m.timed for m in members), sum(len(m.views) for m in members))
           for members in INTERLEAVED.values()},
        **{record(run): (run.timed, len(run.views)) for run in RUNS.values() if run.key not in _grouped}})

# Short rule names: a cluster job's name joins the names of every rule of its group. With names made
# of the experiment and group, kruger2003-stability's (four groups) was cut short with "...", and
# its SLURM job was never submitted: the workflow waited for it. The runs are in the rule's outputs.
for _index, ((_experiment, _group), _members) in enumerate(INTERLEAVED.items()):
    _name = f"render_together_{_index}"
    _parts = [[member.as_dict() for member in part] for part in stack_parts(_members)]
    _runs_json = json.dumps(_parts[0] if len(_parts) == 1 else _parts)
    rule:
        name: _name
        input:
            volumes=sorted({f"{CACHE}/{key}.npy" for member in _members for key in volume_requests(member)}),
            environment=f"{R}/environment.json",
            retry=[RETRY[member.key] for member in _members],
        output:
            [record(member) for member in _members],
        group: RUN_GROUP.format(experiment=_experiment)
        params:
            runs=_runs_json,
            spec_hash=[member.spec_hash() for member in _members],
            code=sorted({BACKEND_CODE[member.backend] for member in _members}),
        threads: render_threads(_members)
        priority: render_priority(_members)
        resources:
            gpu=int(any(uses_device(member.backend) for member in _members)),
            **({"runtime": RENDER_RESOURCES["runtime"] * len(_members)} if "runtime" in RENDER_RESOURCES else {}),
        shell:
            "NUMBA_NUM_THREADS={threads} {PY} -m pipeline.jobs render --run {params.runs:q}"
            " --profile {PROFILE_JSON:q} --device-env {input.environment} --threads {threads}"
    # What a workflow profile sets for `render` (on a cluster: a node of its own, its memory) holds for
    # these render jobs too: `set-resources` names rules, and these rules' names are made here.
    _set = workflow.resource_settings.overwrite_resources
    for _resources in (_set.get("render"), _set.get(_name)):
        workflow.get_rule(_name).resources.update(_resources or {})


rule render:
    input:
        volumes=lambda w: [f"{CACHE}/{key}.npy" for key in volume_requests(run_of(w))],
        environment=f"{R}/environment.json",
        retry=lambda w: RETRY[f"{w.experiment}/{w.run}"],
    output:
        f"{R}/runs/{{experiment}}/{{run}}.json",
    group: RUN_GROUP
    params:
        run=lambda w: json.dumps(run_of(w).as_dict()),
        spec_hash=lambda w: run_of(w).spec_hash(),
        code=lambda w: BACKEND_CODE[run_of(w).backend],
    threads: lambda w: render_threads([run_of(w)])(w)
    priority: lambda w: render_priority([run_of(w)])
    resources:
        **RENDER_RESOURCES,
    shell:
        "NUMBA_NUM_THREADS={threads} {PY} -m pipeline.jobs render --run {params.run:q}"
        " --profile {PROFILE_JSON:q} --device-env {input.environment} --threads {threads}"


# One job compares every run of an experiment that has a reference with it (a comparison of small
# images takes milliseconds, a job's start a second): results/metrics/<experiment>/<run>.json and
# the difference images beside each. Any render of the experiment recomputes all its metrics.
rule evaluate:
    input:
        lambda w: sorted({path for pair in EVALUATIONS[w.experiment] for path in pair[:2]}),
    output:
        directory(f"{R}/metrics/{{experiment}}"),
    group: RUN_GROUP
    params:
        pairs=lambda w: json.dumps(EVALUATIONS[w.experiment]),
        code=CODE["evaluate"],
    shell:
        "{PY} -m pipeline.jobs evaluate --pairs {params.pairs:q}"


# An experiment's table and claims are made in its group, beside its runs: on a cluster, in the
# same job (and they join the group's jobs into one: see the groups above).
rule tabulate:
    input:
        records=lambda w: [record(run) for run in EXPERIMENT_RUNS[w.experiment]],
        metrics=lambda w: [f"{R}/metrics/{w.experiment}"] if EVALUATIONS[w.experiment] else [],
    output:
        f"{R}/tables/{{experiment}}.csv",
        f"{R}/claims/{{experiment}}.csv",
    group: RUN_GROUP
    params:
        code=CODE["tabulate"],
    shell:
        "{PY} -m pipeline.jobs tabulate --profile {PROFILE_JSON:q} --experiment {wildcards.experiment}"


# runs.csv and claims.csv also keep the tables that earlier pipeline runs left for the profile's
# other experiments (after `volbench run --experiment X`), and the report shows them with a notice
# (pipeline.collect.merge, pipeline.jobs.report_contents); the experiments of this run are a param,
# so running another set of them rewrites both.
rule collect:
    input:
        tables=[f"{R}/tables/{name}.csv" for name in EXPERIMENT_RUNS],
        claims=[f"{R}/claims/{name}.csv" for name in EXPERIMENT_RUNS],
    output:
        f"{R}/runs.csv",
        f"{R}/claims.csv",
    params:
        experiments=sorted(EXPERIMENT_RUNS),
        code=CODE["collect"],
    shell:
        "{PY} -m pipeline.jobs collect --profile {PROFILE_JSON:q}"


rule report:
    input:
        f"{R}/runs.csv",
        f"{R}/claims.csv",
        f"{R}/environment.json",
        f"{R}/volumes.csv",
    output:
        f"{R}/report/index.html",
    params:
        experiments=sorted(EXPERIMENT_RUNS),
        code=CODE["report"],
    # It draws its pages' charts on every core it has (reports.html); nothing else is left to run beside it.
    threads: workflow.cores
    shell:
        "{PY} -m pipeline.jobs report --profile {PROFILE_JSON:q}"
