# volbench workflow: phantoms → one job per run (images + JSON record) → metrics against each run's
# reference → tidy CSV → HTML report.
#
#   snakemake --cores 2 --configfile config/default.yaml        (what `make reproduce` runs)
#   snakemake -n --configfile config/full.yaml                   (dry run: list the jobs)
#   snakemake --executor slurm --jobs 64 --configfile config/full.yaml   (a cluster, via the plugin)
#
# A render job lists its backend's source files as inputs, so editing one backend reruns only its
# jobs; its params carry the run's spec hash, so changing a run's scene or options reruns that run.
import dataclasses
import json
import sys
from pathlib import Path

sys.path.insert(0, workflow.basedir)

import datasets
import renderers
from pipeline.experiments import Profile, plan
from pipeline.scene_io import dataset_arguments

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
PROFILE_JSON = json.dumps(dataclasses.asdict(PROFILE), sort_keys=True)
ROOT = Path(workflow.basedir)

wildcard_constraints:
    experiment="[A-Za-z0-9._+-]+",
    run="[A-Za-z0-9._+-]+",
    key="[A-Za-z0-9._+-]+",


def volume_requests(run):
    """``{cache_key: request}`` for the generated phantoms a run's scene uses."""
    requests = {}
    for entry in [*run.scene["volumes"], *([run.statistics] if run.statistics else [])]:
        if "dataset" not in entry or datasets.get(entry["dataset"]).kind != "phantom":
            continue
        kwargs = dataset_arguments(entry, size=PROFILE.volume_size)
        requests[datasets.cache_key(entry["dataset"], **kwargs)] = {"dataset": entry["dataset"], "kwargs": kwargs}
    return requests


VOLUMES = {key: request for run in RUNS.values() for key, request in volume_requests(run).items()}


def backend_sources(backend):
    package = ROOT / renderers.backend_module(backend).replace(".", "/")
    return sorted(str(p.relative_to(ROOT)) for p in [*package.rglob("*.py"), *(ROOT / "renderers" / "base").glob("*.py")])


def run_of(wildcards):
    return RUNS[f"{wildcards.experiment}/{wildcards.run}"]


def record(run):
    return f"{R}/runs/{run.experiment}/{run.id}.json"


def metrics(run):
    return f"{R}/metrics/{run.experiment}/{run.id}.json"


rule all:
    input:
        f"{R}/report/index.html",


rule volume:
    output:
        f"{CACHE}/{{key}}.npy",
    params:
        request=lambda w: json.dumps(VOLUMES[w.key]),
    shell:
        "{PY} -m pipeline.jobs volume --request {params.request:q} --cache {CACHE}"


rule environment:
    output:
        f"{R}/environment.json",
    shell:
        "{PY} -m pipeline.jobs environment --output {output}"


# Render jobs take every core: timings are taken with nothing else running beside them.
rule render:
    input:
        volumes=lambda w: [f"{CACHE}/{key}.npy" for key in volume_requests(run_of(w))],
        code=lambda w: backend_sources(run_of(w).backend),
        environment=f"{R}/environment.json",
    output:
        f"{R}/runs/{{experiment}}/{{run}}.json",
    params:
        run=lambda w: json.dumps(run_of(w).as_dict()),
        spec_hash=lambda w: run_of(w).spec_hash(),
    threads: workflow.cores
    shell:
        "NUMBA_NUM_THREADS={threads} {PY} -m pipeline.jobs render --run {params.run:q}"
        " --profile {PROFILE_JSON:q} --device-env {input.environment}"


rule evaluate:
    input:
        record=f"{R}/runs/{{experiment}}/{{run}}.json",
        reference=lambda w: record(RUNS[f"{w.experiment}/{run_of(w).reference}"]),
    output:
        f"{R}/metrics/{{experiment}}/{{run}}.json",
    shell:
        "{PY} -m pipeline.jobs evaluate --record {input.record} --reference {input.reference} --output {output}"


rule collect:
    input:
        records=[record(run) for run in RUNS.values()],
        metrics=[metrics(run) for run in RUNS.values() if run.reference is not None],
    output:
        f"{R}/runs.csv",
        f"{R}/claims.csv",
    shell:
        "{PY} -m pipeline.jobs collect --profile {PROFILE_JSON:q}"


rule report:
    input:
        f"{R}/runs.csv",
        f"{R}/claims.csv",
        f"{R}/environment.json",
    output:
        f"{R}/report/index.html",
    shell:
        "{PY} -m pipeline.jobs report --profile {PROFILE_JSON:q}"
