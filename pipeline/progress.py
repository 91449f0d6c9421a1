"""``volbench run``'s console and jobs log: one progress line instead of Snakemake's account of every job.

A Snakemake logger plugin (registered in-process by :func:`register`, added to the loggers by
:mod:`pipeline.driver`) that

- writes each job's line to the pipeline run's jobs log (:func:`pipeline.harness.log_job`, where
  ``volbench run`` names one) from Snakemake's own events: when it started the job and when it saw it
  finish;
- where the console is its (:func:`configure`), keeps one line up to date: steps done and to go, the
  time elapsed and an estimate of the time left. Warnings and errors (a failed job with its log) are
  printed above the line as Snakemake formats them; everything else Snakemake says goes only to its
  log file (``.snakemake/log/``). On a terminal the line is redrawn in place; elsewhere (a CI log) it
  is printed at most every :data:`PLAIN_EVERY` seconds, and at the end.

The estimate comes from the plan and the times measured so far: Snakemake's count of the jobs each
rule still has to run, split for the renders into timed and untimed jobs by the plan the Snakefile
registers (:func:`expect_renders`), each job kind's mean wall time so far (a kind not seen yet takes
the mean of every job), and the cores (untimed jobs run side by side, a timed render alone). Until the
first timed render has finished, the line says the time left is a floor: the quick jobs that run first
(phantoms, volumes, the reference's renders) say little about a timed render's minutes.
"""

import logging
import sys
import time
from collections import defaultdict

PLUGIN = "volbench"
"""The logger plugin's name (``--logger volbench``)."""

PLAIN_EVERY = 60.0
"""Seconds between two progress lines where the console is not a terminal."""

_RENDER_KINDS = {}
"""``{output path: "timed" | "untimed"}`` of the plan's render jobs (:func:`expect_renders`)."""

_SETTINGS = {"cores": None, "console": True}
"""What the driver tells the plugin before Snakemake starts (:func:`configure`)."""


def configure(*, cores, console=True):
    """The cores Snakemake runs jobs on (the estimate runs untimed jobs side by side on them), and whether the
    console is the plugin's (else Snakemake's own output goes there and the plugin only writes the jobs log)."""
    _SETTINGS.update(cores=cores, console=console)


def experiment_of(wildcards, output):
    """The experiment a job works for, from its wildcards or its outputs (``.../runs/<experiment>/<run>.json``,
    ``.../metrics/<experiment>``, ``.../tables/<experiment>.csv``), or ``None``."""
    if isinstance(wildcards, dict) and wildcards.get("experiment"):
        return wildcards["experiment"]
    for path in [output] if isinstance(output, str) else list(output or ()):
        parts = str(path).split("/")
        for folder in ("runs", "metrics", "tables", "claims"):
            if folder in parts[:-1]:
                name = parts[parts.index(folder) + 1]
                return name.removesuffix(".csv") if folder in ("tables", "claims") else name
    return None


def expect_renders(jobs):
    """Tell the estimate about the plan's render jobs: ``{first output path: (timed, weight)}``.

    ``timed`` says whether the job's frames are timed, ``weight`` how much it renders (its runs' views).
    """
    _RENDER_KINDS.clear()
    _RENDER_KINDS.update({str(path): (f"{'timed' if timed else 'untimed'} render", float(weight))
                          for path, (timed, weight) in jobs.items()})


def clock(seconds):
    """``"1 h 02 min"``, ``"12 min 03 s"`` or ``"42 s"``."""
    seconds = int(round(seconds))
    if seconds >= 3600:
        return f"{seconds // 3600} h {seconds % 3600 // 60:02d} min"
    if seconds >= 60:
        return f"{seconds // 60} min {seconds % 60:02d} s"
    return f"{seconds} s"


def _family(rule):
    """The step a rule is: ``render`` for the render rules (an interleave group's have names of their own)."""
    return "render" if rule == "render" or rule.startswith("render_together") else rule


class Estimate:
    """The time left from the jobs still to run and the wall times of those done (see the module notes).

    A render job's time is taken as proportional to its weight (the views of its runs, from the plan):
    each kind's seconds per unit of weight so far, times the weight still to render; a kind not seen
    yet takes the mean seconds per job of every job.
    """

    def __init__(self, cores):
        self.cores = max(1, int(cores or 1))
        self.planned = {}                  # kind -> jobs Snakemake has to run
        self.finished = defaultdict(list)  # kind -> [(seconds, weight)]
        self.started = {}                  # job id -> (kind, weight, monotonic start)

    def plan(self, per_rule):
        planned = defaultdict(int)
        for rule, count in per_rule.items():
            if rule != "total":
                planned[_family(rule)] += int(count)
        renders = planned.pop("render", 0)
        if renders:
            kinds = [kind for kind, _ in _RENDER_KINDS.values()]
            timed_share = kinds.count("timed render") / len(kinds) if kinds else 1.0
            planned["timed render"] = round(renders * timed_share)
            planned["untimed render"] = renders - planned["timed render"]
        self.planned = dict(planned)

    def kind(self, rule, output):
        """``(kind, weight)`` of a job: its rule (weight 1), or for a render job its entry of :func:`expect_renders`."""
        if _family(rule) != "render":
            return rule, 1.0
        first = next(iter(output), None) if not isinstance(output, str) else output
        return _RENDER_KINDS.get(str(first), ("timed render", 1.0))

    def start(self, job, rule, output):
        self.started[job] = (*self.kind(rule, output), time.monotonic())

    def finish(self, job):
        kind, weight, began = self.started.pop(job, (None, None, None))
        if kind is not None:
            self.finished[kind].append((time.monotonic() - began, weight))

    def _mean_weight(self, kind):
        weights = [weight for k, weight in _RENDER_KINDS.values() if k == kind]
        return sum(weights) / len(weights) if weights else 1.0

    def timed_unmeasured(self):
        """Whether timed renders are still to run and none has finished: they are most of a run's time, and until
        one has, :meth:`seconds_left` prices them at the mean of the quick jobs done so far, so it is a floor."""
        return self.planned.get("timed render", 0) > 0 and not self.finished.get("timed render")

    def seconds_left(self):
        """Seconds still to go, or ``None`` before any job has finished."""
        every = [seconds for done in self.finished.values() for seconds, _ in done]
        if not every:
            return None
        per_job = sum(every) / len(every)

        def per_weight(kind, weight):
            done = self.finished.get(kind)
            if not done:
                return per_job
            return weight * sum(seconds for seconds, _ in done) / max(1e-9, sum(w for _, w in done))

        def alone(kind):  # untimed jobs take a core each and run side by side; a timed render takes every core
            return 1 if kind == "timed render" else self.cores

        running = defaultdict(int)
        left = 0.0
        for kind, weight, began in self.started.values():
            running[kind] += 1
            left += max(0.0, per_weight(kind, weight) - (time.monotonic() - began)) / alone(kind)
        for kind, planned in self.planned.items():
            remaining = max(0, planned - len(self.finished.get(kind, ())) - running[kind])
            left += remaining * per_weight(kind, self._mean_weight(kind)) / alone(kind)
        return left


class ProgressLine:
    """One line on ``stream``: redrawn in place on a terminal, printed now and then elsewhere."""

    def __init__(self, stream=None):
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.shown = ""
        self.last_plain = None

    def show(self, text, *, final=False):
        if self.tty:
            self.stream.write("\r" + text + " " * max(0, len(self.shown) - len(text)))
            if final:
                self.stream.write("\n")
                text = ""
        elif final or self.last_plain is None or time.monotonic() - self.last_plain >= PLAIN_EVERY:
            self.stream.write(text + "\n")
            self.last_plain = time.monotonic()
        self.stream.flush()
        self.shown = text

    def message(self, text):
        """A message above the line (the line is drawn again after it on a terminal)."""
        if self.tty and self.shown:
            self.stream.write("\r" + " " * len(self.shown) + "\r")
        self.stream.write(text.rstrip("\n") + "\n")
        if self.tty and self.shown:
            self.stream.write(self.shown)
        self.stream.flush()


def progress_text(done, total, elapsed, left, *, floor=False):
    """The progress line; ``floor``: ``left`` is a lower bound (:meth:`Estimate.timed_unmeasured`)."""
    text = f"volbench: {done} of {total} steps done, {total - done} to go · {clock(elapsed)} elapsed"
    if done < total:
        if left is None:
            text += " · time left: after the first step"
        elif floor:
            text += f" · at least {clock(left)} left (no timed render finished yet)"
        else:
            text += f" · about {clock(left)} left"
    return text


def _handler_class():
    from snakemake_interface_logger_plugins.base import LogHandlerBase
    from snakemake_interface_logger_plugins.common import LogEvent

    class ProgressHandler(LogHandlerBase):
        """Snakemake's log → :class:`ProgressLine` (see the module notes)."""

        def __post_init__(self):
            import os

            from pipeline import harness

            self.console = _SETTINGS["console"]
            self.line = ProgressLine() if self.console else None
            self.began = time.monotonic()
            self.estimate = Estimate(_SETTINGS["cores"] or _cores())
            self.done = self.total = 0
            self.log = os.environ.get(harness.LOG_VARIABLE)
            self.run = harness.pipeline_run()
            self.jobs = {}  # job id -> (step, experiment, start since the epoch)

        def emit(self, record):
            try:
                self._emit(record)
            except Exception:  # noqa: BLE001 - the console must never stop the workflow
                self.handleError(record)

        def _emit(self, record):
            event = getattr(record, "event", None)
            if event == LogEvent.RUN_INFO:
                self.estimate.plan(getattr(record, "stats", {}) or {})
                self.total = int((getattr(record, "stats", {}) or {}).get("total", 0))
            elif event == LogEvent.JOB_INFO:
                output = getattr(record, "output", ())
                self.estimate.start(record.jobid, record.rule_name, output)
                self.jobs[record.jobid] = (_family(record.rule_name),
                                           experiment_of(getattr(record, "wildcards", None), output), time.time())
            elif event == LogEvent.JOB_FINISHED:
                self.estimate.finish(record.job_id)
                self._log(record.job_id)
            elif event == LogEvent.JOB_ERROR:
                self.estimate.finish(getattr(record, "jobid", None))
                self._log(getattr(record, "jobid", None), failed=True)
                if self.console:
                    self.line.message(self.format(record))
            if not self.console:
                return
            if event == LogEvent.PROGRESS:
                self.done, self.total = record.done, record.total
                self.line.show(progress_text(self.done, self.total, time.monotonic() - self.began,
                                             self.estimate.seconds_left(), floor=self.estimate.timed_unmeasured()),
                               final=self.done >= self.total)
            elif (record.levelno >= logging.WARNING and event != LogEvent.JOB_ERROR
                  or event in (LogEvent.GROUP_ERROR, LogEvent.ERROR)
                  or str(record.msg).startswith(("Nothing to be done", "Complete log"))):
                self.line.message(self.format(record))

        def _log(self, job, failed=False):
            from pipeline import harness

            step, experiment, started = self.jobs.pop(job, (None, None, None))
            if self.log and step is not None:
                harness.log_job(self.log, run=self.run, step=step, experiment=experiment, started=started,
                                ended=time.time(), failed=failed)

        @property
        def writes_to_stream(self):
            return self.console

        @property
        def writes_to_file(self):
            return False

        @property
        def has_filter(self):
            return False

        @property
        def has_formatter(self):
            return False

        @property
        def needs_rulegraph(self):
            return False

    return ProgressHandler


def _cores():
    import os

    return os.cpu_count() or 1


def register():
    """Register the plugin with Snakemake's logger registry (in this process; no package to install)."""
    from snakemake_interface_logger_plugins.registry import LoggerPluginRegistry
    from snakemake_interface_logger_plugins.registry.plugin import Plugin

    registry = LoggerPluginRegistry()
    if PLUGIN not in registry.plugins:
        registry.plugins[PLUGIN] = Plugin(_name=PLUGIN, log_handler=_handler_class(), _logger_settings_cls=None)
