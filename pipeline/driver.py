"""The Snakemake that ``volbench run`` starts: Snakemake's own command line, in this process, with three changes.

``python -m pipeline.driver <snakemake arguments>`` parses its arguments as ``snakemake`` does and runs
the workflow through Snakemake's API (:func:`snakemake.cli.args_to_api`), with:

1. **No job-rate limiter** where the jobs run on this machine. Snakemake 9 ends every scheduler pass
   under a rate limit by starting a timer for another pass one timespan later, and every finished job
   adds such a pass that re-arms itself, so the passes multiply as a run goes on: in the default
   profile the main process took 0.85 of a core after 130 jobs, beside the timed renders. Without a
   limiter Snakemake's scheduler waits on a semaphore that only a finished job (or an error) releases:
   while a job runs it sleeps. Its command line cannot say "no limit" (``--max-jobs-per-timespan``
   always builds a limiter), so the parsed value is replaced here; a limit the user gives is kept,
   and other executors (a cluster's) keep Snakemake's default.
2. **The render service** (:mod:`pipeline.workers`) for local runs: render jobs hand their runs to
   warm worker processes instead of starting their own.
3. **One progress line** instead of Snakemake's account of every job (:mod:`pipeline.progress`),
   where the jobs run here and the command line chooses no ``--logger`` of its own nor ``--verbose``;
   Snakemake's full log is still written to ``.snakemake/log/``. A dry run and a cluster run show
   Snakemake's own output.
"""

import os
import sys
from pathlib import Path

NO_LIMIT_FLAGS = ("--max-jobs-per-timespan", "--max-jobs-per-second")
"""Snakemake's flags for a job-rate limit: given by the user, the limit is theirs."""


def _given(argv, flags):
    return any(arg == flag or arg.startswith(flag + "=") for arg in argv for flag in flags)


NOT_RUNNING = ("dryrun", "touch", "unlock", "summary", "detailed_summary", "list_rules", "list_target_rules",
               "list_input_changes", "list_params_changes", "list_untracked", "list_changes", "delete_all_output",
               "delete_temp_output", "cleanup_shadow", "filegraph", "d3dag", "dag", "rulegraph", "report",
               "lint", "cleanup_metadata", "list_conda_envs", "conda_cleanup_envs", "conda_create_envs_only",
               "containerize", "export_cwl", "generate_unit_tests", "archive")
"""Snakemake's options that make it list, mark or clean instead of running jobs (their output is the point)."""


def _local(args):
    """Whether this runs jobs, on this machine (Snakemake's local executor, none of :data:`NOT_RUNNING`)."""
    return (getattr(args, "executor", None) in (None, "local")
            and not any(getattr(args, name, None) for name in NOT_RUNNING))


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    from snakemake import cli

    from pipeline import progress, workers

    progress.register()
    try:
        parser, args = cli.parse_args(argv)
        if not _local(args):  # a dry run, a cluster: Snakemake as it is, with its own account of every job
            return 0 if cli.args_to_api(args, parser) else 1
        if not _given(argv, NO_LIMIT_FLAGS):
            args.max_jobs_per_timespan = None
            args.max_jobs_per_second = None
        # The plugin writes the jobs log either way; it owns the console unless another logger or --verbose does.
        progress.configure(cores=args.cores, console=not args.logger and not args.verbose)
        args.logger = [*args.logger, progress.PLUGIN]
        root = Path(args.directory or ".").resolve()
        with workers.RenderService(cores=args.cores or os.cpu_count() or 1, root=root,
                                   log_dir=root / ".snakemake" / "volbench-workers") as service:
            os.environ[workers.SERVICE_VARIABLE] = service.address
            return 0 if cli.args_to_api(args, parser) else 1
    except Exception as exc:  # as Snakemake's own main reports it
        from snakemake.exceptions import print_exception

        print_exception(exc)
        return 1


if __name__ == "__main__":
    sys.exit(main())
