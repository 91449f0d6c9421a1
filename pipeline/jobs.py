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
    record = execute_limited(run, profile=_profile(args.profile), device_environment=device_env)
    print(f"{run.key}: {record['status']} {record['reason']}".rstrip())


def evaluate(args):
    from pipeline.rendering import evaluate as evaluate_run

    evaluate_run(args.record, args.reference, args.output)


def collect(args):
    from pipeline.collect import collect as collect_results
    from pipeline.runner import run_record_path

    profile = _profile(args.profile)
    runs = plan(profile)
    records = [run_record_path(profile.results, run.experiment, run.id) for run in runs.values()]
    collect_results(records, selected(profile), results_dir=profile.results)


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
                         real_data=real_data_provenance(profile.real_data))
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
    p = steps.add_parser("evaluate", help="compare a run with its reference run")
    p.add_argument("--record", required=True)
    p.add_argument("--reference", required=True)
    p.add_argument("--output", required=True)
    p.set_defaults(func=evaluate)
    for name, func in (("collect", collect), ("report", report)):
        p = steps.add_parser(name)
        p.add_argument("--profile", required=True)
        p.set_defaults(func=func)
    args = parser.parse_args(argv)
    args.func(args)


if __name__ == "__main__":
    sys.exit(main())
