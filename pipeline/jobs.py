"""Entry points of the Snakemake jobs (``python -m pipeline.jobs <step> ...``).

Each step is one small, separately restartable unit of the workflow; the Snakefile passes it
everything it needs on the command line, so a job runs the same on this machine or on a cluster
node through an executor plugin. Each step imports what it uses only: a render job that hands its
runs to the render service (:mod:`pipeline.workers`) starts, waits and ends without loading NumPy.
"""

import argparse
import dataclasses
import json
import sys
from pathlib import Path


def parse_profile(text):
    from pipeline.experiments import Profile

    return Profile.from_json(text)


def volume(args):
    if _served(args):
        return
    import datasets

    request = json.loads(args.request)
    datasets.load(request["dataset"], cache_dir=args.cache, **request["kwargs"])


def environment(args):
    from pipeline.environment import host_environment, probe_devices
    from pipeline.records import write_json

    write_json(args.output, {**host_environment(), **probe_devices()})


def render(args):
    """Render one run, or (``--run`` a JSON list) the runs of one interleave group timed together.

    Where ``volbench run`` runs a render service on this machine (:mod:`pipeline.workers`), a warm
    worker renders the runs and this job only waits; else the job renders them in a child process of
    its own under the profile's time limit. A timed run of ``replicates`` > 1 is rendered that many times,
    each time in a process that has not rendered it before, its group's order reversed every other time,
    and its record keeps every process's frames (:func:`pipeline.records.merge_processes`). A group whose
    backends render through different OpenGL stacks comes as its parts (``--run`` a list of lists,
    :func:`pipeline.experiments.stack_parts`): each part is timed in processes of its own, one part after
    the other in each replicate, never in a process another part used in that replicate. Either way a
    run that failed is named on the output (Snakemake's log); a run that rendered or was skipped, as
    planned, says nothing.
    """
    from pipeline import workers

    runs = json.loads(args.run)
    runs = runs if isinstance(runs, list) else [runs]
    parts = runs if runs and isinstance(runs[0], list) else [runs]
    everything = [run for part in parts for run in part]
    replicates = max(int(run.get("replicates", 1)) for run in everything)
    separate = replicates > 1 or len(parts) > 1
    attempts, used = [], {index: [] for index in range(len(parts))}
    for replicate in range(replicates):
        # Alternate the order between processes: the first arm of a round (or part) is not always the same one.
        order = range(len(parts)) if replicate % 2 == 0 else reversed(range(len(parts)))
        outcomes, here, attempt = [], [], {}
        for index in order:
            part = parts[index] if replicate % 2 == 0 else parts[index][::-1]
            outcomes += _render_once(args, json.dumps(part), workers, avoid=used[index] + here, own_process=separate)
            if separate:
                records = _read_records(args.profile, part)
                attempt.update(records)
                pids = [(record.get("harness") or {}).get("pid") for record in records.values() if record]
                used[index] += pids
                here += pids
        if replicates > 1:
            attempts.append(attempt)
        if any(outcome["status"] == "failed" for outcome in outcomes):
            break
    if replicates > 1:
        outcomes = _merge_attempts(args.profile, everything, attempts, replicates)
    for outcome in outcomes:
        if outcome["status"] == "failed":
            print(f"{outcome['key']}: failed: {(outcome['reason'].splitlines() or [''])[0]}".rstrip())


def _render_once(args, runs_json, workers, *, avoid, own_process):
    """Render the runs of ``runs_json`` once: by the render service where one answers (in a worker none of
    whose process ids is in ``avoid``), else in a child process of this job's (always one where
    ``own_process``). Their outcomes."""
    address = workers.service_address()
    if address is not None:
        try:
            return workers.request_render(address, runs=runs_json, profile=args.profile, device_env=args.device_env,
                                          threads=args.threads, avoid=avoid)
        except workers.ServiceUnavailable as exc:
            print(f"volbench: {exc}; this job renders in a process of its own", file=sys.stderr)
    from pipeline import disturbance
    from pipeline.execution import execute_together_limited
    from pipeline.experiments import Run

    runs = Run.list_from_json(runs_json)
    device_env = json.loads(Path(args.device_env).read_text()) if args.device_env else {}
    device_env = {k: v for k, v in device_env.items() if k.startswith(("gl_", "cl_"))}
    disturbance.watch(disturbance.orchestrator_pids())
    # This process has only parsed its arguments: a forked child needs no fresh interpreter.
    records = execute_together_limited(runs, profile=parse_profile(args.profile), device_environment=device_env,
                                       start_method="fork", own_process=own_process)
    return [{"key": run.key, "status": record["status"], "reason": record["reason"]}
            for run, record in zip(runs, records)]


def _record_path(profile_json, run):
    from pipeline.records import run_record_path

    return run_record_path(json.loads(profile_json)["results"], run["experiment"], run["id"])


def _read_records(profile_json, runs):
    """``{run id: record}`` of the runs as their last process left them (``None`` where it wrote none)."""
    out = {}
    for run in runs:
        path = _record_path(profile_json, run)
        out[run["id"]] = json.loads(path.read_text()) if path.is_file() else None
    return out


def _merge_attempts(profile_json, runs, attempts, replicates):
    """Write each run's record merged over its processes' (:func:`pipeline.records.merge_processes`); the outcomes."""
    from pipeline.records import merge_processes, write_json

    outcomes = []
    for run in runs:
        records = [attempt[run["id"]] for attempt in attempts if attempt.get(run["id"]) is not None]
        key = f"{run['experiment']}/{run['id']}"
        if not records:
            outcomes.append({"key": key, "status": "failed", "reason": "no process wrote its record"})
            continue
        record = merge_processes(records, planned=replicates)
        if record["status"] == "ok" and len(records) < len(attempts):  # a process died before writing it
            record.update(status="failed", cause="error",
                          reason=f"{len(attempts) - len(records)} of its processes wrote no record")
        write_json(_record_path(profile_json, run), record)
        outcomes.append({"key": key, "status": record["status"], "reason": record["reason"]})
    return outcomes


def evaluate(args):
    """Compare every run of one experiment that has a reference with it, one run after another.

    One process for the experiment rather than one per run: a comparison of small images takes
    milliseconds and a process start a second.
    """
    if _served(args):
        return
    from pipeline.rendering import evaluate as evaluate_run

    pairs = json.loads(args.pairs)
    for record, reference, output in pairs:
        metrics = evaluate_run(record, reference, output)
        if metrics["status"] == "failed":
            reason = (metrics["reason"].splitlines() or [""])[0]
            print(f"{metrics['experiment']}/{metrics['run']}: metrics failed: {reason}", flush=True)


def phantoms(args):
    from pipeline.collect import phantom_manifest
    from pipeline.experiments import plan
    from pipeline.scene_io import phantom_requests

    profile = parse_profile(args.profile)
    requests = phantom_requests([entry for run in plan(profile).values() for entry in run.volume_entries],
                                size=profile.volume_size)
    phantom_manifest(requests, cache_dir=profile.cache).to_csv(args.output, index=False)


def tabulate(args):
    if _served(args):
        return
    from core.errors import InputError
    from pipeline.collect import tabulate as tabulate_experiment
    from pipeline.experiments import selected
    from pipeline.records import run_record_path

    profile = parse_profile(args.profile)
    experiment = next((e for e in selected(profile) if e.name == args.experiment), None)
    if experiment is None:
        raise InputError(f"experiment {args.experiment!r} is not in profile {profile.name!r}; "
                         f"it has {', '.join(e.name for e in selected(profile))}")
    # Its own runs only: planning the whole profile (checked when the workflow started) took most of the job.
    records = [run_record_path(profile.results, run.experiment, run.id) for run in experiment.runs(profile)]
    tabulate_experiment(records, experiment, results_dir=profile.results)


def collect(args):
    from pipeline.collect import merge
    from pipeline.experiments import all_experiments, selected

    profile = parse_profile(args.profile)
    earlier, dropped = merge(selected(profile), results_dir=profile.results, known=list(all_experiments().values()))
    if earlier:
        print(f"merged the tables of {len(earlier)} experiments from earlier runs: {', '.join(earlier)}")
    if dropped:
        print(f"left out the tables of experiments volbench no longer has: {', '.join(dropped)}")


EARLIER_NAMED = 3
"""Up to this many experiments from earlier pipeline runs, the notice names each with its dates."""


def _span(dates):
    """``"d"`` or ``"d0 to d1"`` of sorted dates; ``"date not recorded"`` without any."""
    if not dates:
        return "date not recorded"
    return dates[0] if dates[0] == dates[-1] else f"{dates[0]} to {dates[-1]}"


def report_contents(runs_df, claims_df, this_run, registry, results_dir):
    """``(experiments, notices)``: what a report shows, and what its pages say first where that mixes pipeline runs.

    ``runs.csv`` holds this pipeline run's experiments (``this_run``) and those earlier runs left
    (:func:`pipeline.collect.merge`, after ``volbench run --experiment X``): the report shows
    them all, in registry order, and says which come from earlier runs, when they were measured
    (``runs.csv``'s ``date``, UTC), and which tables were left out because their experiment is gone.
    """
    present = set(runs_df.get("experiment", ())) | set(claims_df.get("experiment", ()))
    this_names = {experiment.name for experiment in this_run}
    shown = [experiment for name, experiment in registry.items() if name in this_names or name in present]
    earlier, all_dates = [], []
    for name in (experiment.name for experiment in shown if experiment.name not in this_names):
        dates = sorted(map(str, runs_df.loc[runs_df.experiment == name, "date"].dropna().unique())) \
            if "date" in runs_df else []
        all_dates += dates
        earlier.append(f"{name} ({_span(dates)})")
    notices = []
    if len(earlier) > EARLIER_NAMED:
        # Many earlier experiments (one rerun after a whole profile): name what the last run made instead.
        last = ", ".join(sorted(this_names & present)) or "nothing shown here"
        notices.append(f"Not all of this report comes from its last pipeline run: that run made {last}; the "
                       f"results of the other {len(earlier)} experiments are from earlier runs (measured "
                       f"{_span(sorted(all_dates))}, UTC; each run's date is in runs.csv).")
    elif earlier:
        notices.append(f"Not all of this report comes from its last pipeline run: the results of {len(earlier)} "
                       f"experiments are from earlier runs (measured, UTC): {', '.join(earlier)}.")
    dropped = sorted(path.stem for path in (Path(results_dir) / "tables").glob("*.csv") if path.stem not in registry)
    if dropped:
        notices.append(f"Left out: the results of {', '.join(dropped)}, which volbench no longer has (removed or "
                       f"renamed); delete their CSV files in {Path(results_dir) / 'tables'} and "
                       f"{Path(results_dir) / 'claims'} to stop this notice.")
    return shown, notices


def report(args):
    import pandas as pd

    import renderers
    from pipeline.environment import real_data_provenance
    from pipeline.experiments import all_experiments, papers, selected
    from pipeline.experiments.planned import planned, techniques
    from reports.html import build_report

    profile = parse_profile(args.profile)
    results = Path(profile.results)
    from pipeline.experiments.kit.results import compact

    runs_df = compact(pd.read_csv(results / "runs.csv", low_memory=False))
    claims_df = pd.read_csv(results / "claims.csv")
    claims_df["holds"] = claims_df["holds"].map({True: True, False: False, "True": True, "False": False})
    claims_df[["measured", "detail"]] = claims_df[["measured", "detail"]].fillna("")
    environment_ = json.loads((results / "environment.json").read_text())
    environment_["profile"] = json.dumps(dataclasses.asdict(profile), sort_keys=True)
    backends = [{"name": b.name, "available": b.available, "reason": b.reason or "", "description": b.description}
                for b in renderers.available()]
    registry = all_experiments()
    experiments, notices = report_contents(runs_df, claims_df, selected(profile), registry, results)
    from pipeline import harness

    account = harness.account(harness.read_log(harness.log_path(results)), runs_df, run=harness.pipeline_run())
    index = build_report(runs_df, claims_df, experiments, results_dir=results, environment=environment_,
                         backends=backends, planned=planned(renderers.names(), papers().values()), notices=notices,
                         real_data=real_data_provenance(profile.real_data),
                         phantoms=pd.read_csv(results / "volumes.csv", dtype={"params": str}),
                         techniques=techniques(papers().values()), harness=account)
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
    p.add_argument("--threads", type=int, default=1, help="the cores Snakemake gave the job")
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
    args.argv = sys.argv[1:] if argv is None else list(argv)
    args.func(args)


def _served(args):
    """Whether a warm worker of ``volbench run``'s render service ran this step (:mod:`pipeline.workers`; its
    output printed, its failure raised): the phantom, comparison and table steps cost less than the
    imports of a process of their own."""
    from pipeline import workers

    address = workers.service_address()
    if address is None:
        return False
    try:
        status, output = workers.request_step(address, args.argv)
    except workers.ServiceUnavailable as exc:
        print(f"volbench: {exc}; this job runs in a process of its own", file=sys.stderr)
        return False
    sys.stdout.write(output)
    if status:
        raise SystemExit(status)
    return True


if __name__ == "__main__":
    sys.exit(main())
