"""``volbench run``: the pipeline through Snakemake, checked before it starts and reported after it ends.

Before Snakemake starts, the profile with every override (``--experiment``, ``--results``, ``--cache``,
``-- --config KEY=VALUE``) is loaded and checked, the run is planned (an unknown experiment or
setting stops here), its folders are checked writable and a stale Snakemake lock is removed. After
it ends, the runs that failed are summed up by cause and the exit status says so, and an earlier
report the run did not replace is marked as such (:mod:`reports.notices`).
"""

import dataclasses
import datetime
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import psutil

from core.errors import InputError, VolbenchError
from pipeline.disturbance import DRIVER, is_orchestrator

ROOT = Path(__file__).resolve().parent.parent

PACKAGES = ("core", "datasets", "renderers", "reports", "pipeline")
"""The project's packages: every job of the workflow imports some of them."""


def compile_packages():
    """Write the bytecode of :data:`PACKAGES` where it is missing or stale.

    Every Snakemake job is a fresh interpreter that imports these modules; where Python may not
    write bytecode itself (``PYTHONDONTWRITEBYTECODE``, a read-only checkout) each job would compile
    them again, about 0.2 s a job.
    """
    import compileall

    for package in PACKAGES:
        compileall.compile_dir(ROOT / package, quiet=1)


RUN_NOTICE = "unfinished"
"""The kind of notice (:mod:`reports.notices`) that ``volbench run`` puts on a report its pipeline
run did not replace."""

LOCKS = Path(".snakemake") / "locks"
"""Where Snakemake locks the files of a run in its working directory (here, the project)."""

RUN_FILES = Path(".snakemake") / "volbench-runs"
"""One file per ``volbench run`` going on in the project (host, pid, start, command), so that a
run on another machine of a shared file system counts as live (:func:`_check_lock`)."""


def _profile_file(name):
    """The file ``--profile`` names: a path (it has a suffix), or a name under ``config/``."""
    path = Path(name)
    if not path.suffix:
        path = ROOT / "config" / f"{name}.yaml"
    if not path.is_file():
        raise VolbenchError(f"profile {name!r}: no file {path}; see config/ for the profiles")
    return path


def _config_items(args, extra):
    """``(items, extra)``: the ``KEY=VALUE`` items of Snakemake's ``--config``, and ``extra`` without them.

    The items are ours (``--experiment``, ``--results``, ``--cache``) then the user's (after
    ``--config`` among the arguments after ``--``), so the user's win, as they did on one
    ``--config``: Snakemake keeps only the last ``--config`` of its command line.
    """
    if any(arg.startswith("--configfile") for arg in extra):
        raise VolbenchError("--configfile after '--': give the profile with --profile and change single values "
                            "with -- --config KEY=VALUE, so that volbench checks them before Snakemake starts")
    items = [f"experiments={json.dumps(args.experiment)}"] if args.experiment else []
    items += [f"{key}={value}" for key, value in (("results", args.results), ("cache", args.cache)) if value]
    if "--config" in extra:
        at = len(extra) - extra[::-1].index("--config")
        end = next((i for i in range(at, len(extra)) if extra[i].startswith("-")), len(extra))
        items += extra[at:end]
        extra = extra[:at - 1] + extra[end:]
    return items, extra


def _run_profile(path, items):
    """The profile Snakemake will run: the file's, with the ``--config`` items applied as Snakemake applies them."""
    from pipeline.experiments import Profile

    try:
        profile = Profile.load(path)
    except InputError as exc:  # the file's own errors name it; the values' name the profile
        raise InputError(str(exc) if str(path) in str(exc) else f"{path}: {exc}") from None
    if not items:
        return profile
    from snakemake.cli import parse_config
    from snakemake.utils import update_config

    try:
        overrides = parse_config(items)
    except ValueError as exc:
        raise VolbenchError(f"--config {' '.join(items)}: {exc}") from None
    mapping = dataclasses.asdict(profile)
    update_config(mapping, overrides)
    try:
        return Profile.from_mapping(mapping)
    except InputError as exc:
        raise InputError(f"{path} with --config {' '.join(items)}: {exc}") from None


def _check_folders(profile):
    """Refuse a results or cache folder that cannot be written, and a real-data folder that does not exist.

    The paths are the project's (Snakemake's working directory), as every job reads them.
    """
    for key in ("results", "cache"):
        folder = ROOT / getattr(profile, key)
        try:
            folder.mkdir(parents=True, exist_ok=True)
            tempfile.TemporaryFile(dir=folder).close()
        except OSError as exc:
            raise VolbenchError(f"profile {profile.name!r} {key}: cannot write to {folder} ({exc.strerror or exc}); "
                                f"give a folder you can write with --{key} or in the profile") from None
    if profile.real_data is not None and not (ROOT / profile.real_data).is_dir():
        raise VolbenchError(f"profile {profile.name!r} real_data: no folder {ROOT / profile.real_data}; give the folder "
                            "of the real scans, or null to read $VOLBENCH_REAL_DATA or ../shared/data/real")


def _workdir(argv, cwd):
    """The folder a Snakemake command line works in (its ``--directory``, else ``cwd``); ``None`` where unknown."""
    given = None
    for i, arg in enumerate(argv):
        if arg in ("--directory", "-d") and i + 1 < len(argv):
            given = argv[i + 1]
        elif arg.startswith("--directory="):
            given = arg.split("=", 1)[1]
    if given is not None and Path(given).is_absolute():
        return Path(given).resolve()
    if cwd is None:  # another user's process
        return None
    return (Path(cwd) / (given or ".")).resolve()


def snakemake_processes(directory):
    """The Snakemake processes of this machine that work in ``directory``, as :class:`psutil.Process` es.

    One whose folder cannot be told (another user's process, with a relative ``--directory`` or
    none) is listed too: it may work there.
    """
    directory = Path(directory).resolve()
    found = []
    for process in psutil.process_iter(["cmdline", "cwd", "create_time"]):
        argv = process.info["cmdline"] or []
        if process.pid != os.getpid() and is_orchestrator(argv) and _workdir(argv, process.info["cwd"]) in (directory, None):
            found.append(process)
    return found


def _runs_elsewhere():
    """``[(run file, its content)]`` of the ``volbench run`` s of other machines in the project (:data:`RUN_FILES`).

    Whether those are still going cannot be told from here. The files of this machine's runs are
    left to :func:`snakemake_processes`; those of runs that were killed are removed.
    """
    host = socket.gethostname()
    found = []
    for path in sorted((ROOT / RUN_FILES).glob("*.json")):
        try:
            run = json.loads(path.read_text())
        except (OSError, ValueError):  # removed or being written right now
            continue
        if run["host"] != host:
            found.append((path, run))
        elif not psutil.pid_exists(run["pid"]):
            path.unlink(missing_ok=True)
    return found


def _locked_paths(locks, *, profile, runs):
    """The paths in Snakemake's lock files that the run of ``profile``'s ``runs`` would read or write.

    As Snakemake decides: a run stops on a path another run writes (an output lock) that it reads
    or writes, and on a path another run reads (an input lock) that it writes. This run reads and
    writes everything in its results folder, reads its phantoms and writes those that are missing.
    """
    from pipeline.scene_io import phantom_requests

    results = os.path.normpath(ROOT / profile.results)
    requests = phantom_requests([entry for run in runs.values() for entry in run.volume_entries], size=profile.volume_size)
    phantoms = {os.path.normpath(ROOT / profile.cache / f"{key}.npy") for key in requests}
    held = []
    for lock in locks:
        writes = lock.name.endswith(".output.lock")
        for name in filter(None, map(str.strip, lock.read_text().splitlines())):
            path = os.path.normpath(ROOT / name)
            if (path == results or path.startswith(results + os.sep)
                    or (path in phantoms and (writes or not os.path.exists(path)))):
                held.append(name)
    return held


def _check_lock(unlock, *, dry_run, profile, runs):
    """Before Snakemake starts: remove a stale lock, or stop on a live run's lock that covers this run's files.

    Snakemake locks a run's files (:data:`LOCKS`) and removes the lock when it ends; a Snakemake
    that is killed (``kill -9``, a power loss) leaves it, and every later run stops on it. The lock
    does not say whose it is, so it counts as stale only when no Snakemake works in the project:
    none on this machine (:func:`snakemake_processes`) and no ``volbench run`` of another machine
    (:func:`_runs_elsewhere`). A stale lock is removed with Snakemake's ``unlock`` command (a dry
    run only says that the run will). A live run's lock stays: where it covers files of this run
    (:func:`_locked_paths`), this stops with an error naming the processes; elsewhere (two
    profiles side by side) Snakemake runs beside it.
    """
    locks = sorted((ROOT / LOCKS).glob("*.lock"))
    if not locks:
        return
    live = [f"pid {p.pid} ({' '.join(p.info['cmdline'])[:300]}, started "
            f"{datetime.datetime.fromtimestamp(p.info['create_time']):%Y-%m-%d %H:%M})" for p in snakemake_processes(ROOT)]
    elsewhere = [f"a volbench run on {run['host']} (pid {run['pid']}, started {run['started']}; if it is not running "
                 f"any more, delete {path})" for path, run in _runs_elsewhere()]
    if not live and not elsewhere:
        if dry_run:
            print(f"volbench: {ROOT / LOCKS} holds a stale lock (no Snakemake runs in {ROOT}: a run was killed); "
                  "volbench run without --dry-run removes it", flush=True)
            return
        unlocked = subprocess.run(unlock, capture_output=True, text=True)
        if unlocked.returncode != 0:
            raise VolbenchError(f"cannot remove the stale Snakemake lock in {ROOT / LOCKS} ({' '.join(unlock)}):\n"
                                f"{(unlocked.stdout + unlocked.stderr)[-2000:]}")
        print(f"volbench: removed a stale Snakemake lock from {ROOT / LOCKS}: no Snakemake runs in {ROOT}, "
              "so a run was killed before it could remove it", flush=True)
        return
    held = _locked_paths(locks, profile=profile, runs=runs)
    if held:
        raise VolbenchError(
            f"another Snakemake run holds files of this run in {ROOT} (locked in {ROOT / LOCKS}: {held[0]}"
            f"{f' and {len(held) - 1} more' if len(held) > 1 else ''}); running there: {'; '.join(live + elsewhere)}. "
            "Wait for it to finish, or stop it (kill PID) and run this command again: volbench then removes "
            "its stale lock")


def _failed_runs(runs, results):
    """``[(record path, record)]`` of the runs of this plan whose record under ``results`` says ``failed``.

    A record of another plan of a run (its spec hash differs) is not this run's; a run without a
    record did not happen (the pipeline stopped first).
    """
    from pipeline.records import run_record_path

    failed = []
    for run in runs.values():
        path = run_record_path(results, run.experiment, run.id)
        try:
            record = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if record.get("status") == "failed" and record.get("spec_hash") == run.spec_hash():
            failed.append((path, record))
    return failed


def failure_summary(failed, *, planned, results):
    """The lines ``volbench run`` prints for the failed runs of :func:`_failed_runs`: one per cause."""
    from core.outcomes import CAUSES, cause_of

    by_cause = {}
    for path, record in failed:
        by_cause.setdefault(cause_of(record["status"], record.get("cause")), []).append((path, record))
    lines = [f"{len(failed)} of {planned} runs failed; their records are under {Path(results) / 'runs'}:"]
    for cause, items in sorted(by_cause.items(), key=lambda item: -len(item[1])):
        path, record = items[0]
        reason = (str(record.get("reason") or "no reason recorded").splitlines() or [""])[0][:300]
        lines.append(f"  {len(items)} {cause} ({CAUSES.get(cause, 'an unknown cause')}), e.g. "
                     f"{path.relative_to(Path(results) / 'runs')}: {reason}")
    return lines


def _failed_jobs(log):
    """How many jobs Snakemake's ``log`` reports as failed."""
    return sum(line.startswith("Error in rule ") for line in log.read_text(errors="replace").splitlines())


def _exit_status(returncode):
    """A child's return code as this process's exit status (128 + N for a child killed by signal N, as shells say)."""
    return 128 - returncode if returncode < 0 else returncode


def _run_snakemake(command, *, runs, results):
    """Run the pipeline; then say what failed, mark a report this run did not replace, and return the exit status.

    The status is Snakemake's where it failed (the report, from an earlier run, then says so at the
    top: :func:`reports.notices.mark_report`), else 1 where a run of this plan failed, else 0. The
    pipeline run gets a name and a harness log (:mod:`pipeline.harness`) that its jobs append to.
    """
    from pipeline import harness
    from reports.notices import mark_report, unmark_report

    pipeline_run = harness.new_pipeline_run()
    log = harness.log_path(results)
    harness.log_start(log, run=pipeline_run, steps=len(runs))
    environment = {**os.environ, harness.PIPELINE_RUN_VARIABLE: pipeline_run, harness.LOG_VARIABLE: str(log)}
    started = datetime.datetime.now(datetime.timezone.utc)
    logs = ROOT / ".snakemake" / "log"
    before = set(logs.glob("*.snakemake.log"))
    run_file = ROOT / RUN_FILES / f"{socket.gethostname()}.{os.getpid()}.json"
    run_file.parent.mkdir(parents=True, exist_ok=True)
    run_file.write_text(json.dumps({"host": socket.gethostname(), "pid": os.getpid(),
                                    "started": f"{started:%Y-%m-%d %H:%M} UTC", "command": command}))
    process = None

    def forward(signum, frame):
        # SIGTERM (a batch system's or a test's stop) goes to Snakemake, which then stops its jobs
        # (cancels its SLURM jobs) and removes its lock; by default it would end this process
        # alone and leave Snakemake running.
        if process is not None:
            process.send_signal(signum)

    previous = signal.signal(signal.SIGTERM, forward)
    try:
        process = subprocess.Popen(command, env=environment)
        try:
            returncode = process.wait()
        except KeyboardInterrupt:
            # Ctrl-C reached Snakemake too: it stops its jobs and removes its lock, unless it is
            # killed first (as subprocess.run does after 0.25 s), which would leave the lock behind.
            process.wait()
            raise
    finally:
        signal.signal(signal.SIGTERM, previous)
        run_file.unlink(missing_ok=True)
    report = results / "report"
    if returncode == 0:
        unmark_report(report, kind=RUN_NOTICE)  # a notice a stopped run put there is past: the report is current
        print(f"volbench: report at {report / 'index.html'}")
    else:
        log = min(set(logs.glob("*.snakemake.log")) - before, default=None)
        jobs = _failed_jobs(log) if log else 0
        what = f"{jobs} job{'s' if jobs != 1 else ''} failed" if jobs else f"Snakemake stopped with exit code {returncode}"
        where = f"Snakemake's log: {log}" if log else "see Snakemake's output"
        marked = mark_report(report, f"This report was written before the pipeline run started "
                                     f"{started:%Y-%m-%d %H:%M} UTC, which did not finish: {what} ({where}). "
                                     "It does not show that run's results.", kind=RUN_NOTICE)
        print(f"volbench: the pipeline did not finish: {what} ({where})", file=sys.stderr)
        if marked:
            print(f"volbench: {report / 'index.html'} is from an earlier run; its pages now say so at the top",
                  file=sys.stderr)
    failed = _failed_runs(runs, results)
    for line in failure_summary(failed, planned=len(runs), results=results) if failed else ():
        print(f"volbench: {line}", file=sys.stderr)
    return _exit_status(returncode) or (1 if failed else 0)


def run(args):
    """``volbench run``: check the profile and its overrides, then run the workflow; return the exit status.

    ``args`` has the command's options: ``profile``, ``experiment``, ``results``, ``cache``,
    ``cores``, ``dry_run`` and ``snakemake_args``.
    """
    from pipeline.experiments import plan

    profile_path = _profile_file(args.profile)
    items, extra = _config_items(args, list(args.snakemake_args))
    profile = _run_profile(profile_path, items)
    runs = plan(profile)  # an unknown experiment or setting stops here, before Snakemake starts
    _check_folders(profile)
    workflow = ["--snakefile", str(ROOT / "Snakefile"), "--directory", str(ROOT),
                "--configfile", str(profile_path.resolve())]
    config = ["--config", *items] if items else []
    _check_lock([sys.executable, "-m", "snakemake", *workflow, "--cores", "1", "--unlock", *config],
                dry_run=args.dry_run, profile=profile, runs=runs)
    compile_packages()
    # Snakemake through the driver: no job-rate limiter (its scheduler sleeps while a job runs), the
    # render service's warm workers, one progress line (pipeline.driver).
    command = [sys.executable, "-m", DRIVER, *workflow, "--cores", str(args.cores), "--rerun-incomplete",
               # A failed job stops only the jobs that need its output; the others go on, and
               # volbench run then says what failed (_run_snakemake).
               "--keep-going",
               # The greedy scheduler: the default (an integer program solved after every job) only
               # pays where temporary files must be deleted early, and this workflow has none; with
               # hundreds of small jobs its solves take CPU between the renders.
               "--scheduler", "greedy",
               *(["--dry-run"] if args.dry_run else []), *extra, *config]
    print("volbench:", " ".join(command), flush=True)
    if args.dry_run:
        return _exit_status(subprocess.run(command).returncode)
    return _run_snakemake(command, runs=runs, results=Path(os.path.normpath(ROOT / profile.results)))
