"""Entry points of the Snakemake jobs (``python -m pipeline.jobs <step> ...``).

Each step is one small, separately restartable unit of the workflow; the Snakefile passes it
everything it needs on the command line, so a job runs the same on this machine or on a cluster
node through an executor plugin.
"""

import argparse
import dataclasses
import json
import sys
from pathlib import Path

from core.errors import InputError
from pipeline.experiments import Profile, Run, plan, selected


def _profile(text):
    return Profile.from_mapping(json.loads(text))


def volume(args):
    import datasets

    request = json.loads(args.request)
    datasets.load(request["dataset"], cache_dir=args.cache, **request["kwargs"])


def environment(args):
    from pipeline.environment import host_environment, probe_devices
    from pipeline.runner import write_json

    write_json(args.output, {**host_environment(), **probe_devices()})


def render(args):
    from pipeline.runner import execute_limited

    fields = json.loads(args.run)
    run = Run(**{**fields, "views": tuple(fields["views"])})
    device_env = json.loads(Path(args.device_env).read_text()) if args.device_env else {}
    device_env = {k: v for k, v in device_env.items() if k.startswith(("gl_", "cl_"))}
    # This process has only parsed its arguments: a forked child needs no fresh interpreter.
    record = execute_limited(run, profile=_profile(args.profile), device_environment=device_env, start_method="fork")
    print(f"{run.key}: {record['status']} {record['reason']}".rstrip())


def evaluate(args):
    """Compare every run of one experiment that has a reference with it, one run after another.

    One process for the experiment rather than one per run: a comparison of small images takes
    milliseconds and a process start a second.
    """
    from pipeline.rendering import evaluate as evaluate_run

    pairs = json.loads(args.pairs)
    for done, (record, reference, output) in enumerate(pairs, 1):
        metrics = evaluate_run(record, reference, output)
        print(f"evaluated {done}/{len(pairs)}: {metrics['experiment']}/{metrics['run']} {metrics['status']}", flush=True)


def phantoms(args):
    from pipeline.collect import phantom_manifest
    from pipeline.scene_io import phantom_requests

    profile = _profile(args.profile)
    requests = phantom_requests([entry for run in plan(profile).values() for entry in run.volume_entries],
                                size=profile.volume_size)
    phantom_manifest(requests, cache_dir=profile.cache).to_csv(args.output, index=False)


def tabulate(args):
    from pipeline.collect import tabulate as tabulate_experiment
    from pipeline.runner import run_record_path

    profile = _profile(args.profile)
    experiment = next((e for e in selected(profile) if e.name == args.experiment), None)
    if experiment is None:
        raise InputError(f"experiment {args.experiment!r} is not in profile {profile.name!r}; "
                         f"it has {', '.join(e.name for e in selected(profile))}")
    records = [run_record_path(profile.results, run.experiment, run.id)
               for run in plan(profile).values() if run.experiment == experiment.name]
    tabulate_experiment(records, experiment, results_dir=profile.results)


def collect(args):
    from pipeline.collect import merge

    profile = _profile(args.profile)
    merge(selected(profile), results_dir=profile.results)


def report(args):
    import pandas as pd

    import renderers
    from pipeline.environment import real_data_provenance
    from pipeline.experiments import all_experiments
    from pipeline.experiments.planned import planned
    from reports.html import build_report

    profile = _profile(args.profile)
    results = Path(profile.results)
    runs_df = pd.read_csv(results / "runs.csv", low_memory=False)
    claims_df = pd.read_csv(results / "claims.csv")
    claims_df["holds"] = claims_df["holds"].map({True: True, False: False, "True": True, "False": False})
    claims_df[["measured", "detail"]] = claims_df[["measured", "detail"]].fillna("")
    environment_ = json.loads((results / "environment.json").read_text())
    environment_["profile"] = json.dumps(dataclasses.asdict(profile), sort_keys=True)
    backends = [{"name": b.name, "available": b.available, "reason": b.reason or "", "description": b.description}
                for b in renderers.available()]
    index = build_report(runs_df, claims_df, selected(profile), results_dir=results, environment=environment_,
                         backends=backends, planned=planned(renderers.names(), all_experiments().values()),
                         real_data=real_data_provenance(profile.real_data),
                         phantoms=pd.read_csv(results / "volumes.csv", dtype={"params": str}))
    print(f"volbench report: {index.resolve()}")


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m pipeline.jobs", description=__doc__)
    steps = parser.add_subparsers(dest="step", required=True)
    p = steps.add_parser("volume", help="generate and cache one phantom")
    p.add_argument("--request", required=True)
    p.add_argument("--cache", required=True)
    p.set_defaults(func=volume)
    p = steps.add_parser("environment", help="record the host and its OpenGL/OpenCL devices")
    p.add_argument("--output", required=True)
    p.set_defaults(func=environment)
    p = steps.add_parser("render", help="execute one run")
    p.add_argument("--run", required=True)
    p.add_argument("--profile", required=True)
    p.add_argument("--device-env")
    p.set_defaults(func=render)
    p = steps.add_parser("evaluate", help="compare runs with their reference runs")
    p.add_argument("--pairs", required=True, help="JSON list of [run record, reference record, metrics output]")
    p.set_defaults(func=evaluate)
    p = steps.add_parser("phantoms", help="list the profile's generated phantoms with digests of their data")
    p.add_argument("--profile", required=True)
    p.add_argument("--output", required=True)
    p.set_defaults(func=phantoms)
    p = steps.add_parser("tabulate", help="one experiment's runs → its table and its checked claims")
    p.add_argument("--profile", required=True)
    p.add_argument("--experiment", required=True)
    p.set_defaults(func=tabulate)
    for name, func, text in (("collect", collect, "concatenate the experiments' tables into runs.csv and claims.csv"),
                             ("report", report, "write the HTML report")):
        p = steps.add_parser(name, help=text)
        p.add_argument("--profile", required=True)
        p.set_defaults(func=func)
    args = parser.parse_args(argv)
    args.func(args)


if __name__ == "__main__":
    sys.exit(main())
