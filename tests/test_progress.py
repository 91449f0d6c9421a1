"""``volbench run``'s progress line (pipeline.progress): the estimate, the line, the Snakemake logger plugin."""

import io
import logging

import pytest

from pipeline import progress


@pytest.fixture
def clock(monkeypatch):
    now = [100.0]
    monkeypatch.setattr(progress.time, "monotonic", lambda: now[0])
    return now


@pytest.mark.parametrize("seconds, words", [(42.4, "42 s"), (723, "12 min 03 s"), (3720, "1 h 02 min")])
def test_clock(seconds, words):
    assert progress.clock(seconds) == words


def test_the_estimate_weighs_each_render_by_its_views_and_runs_untimed_jobs_side_by_side(clock):
    progress.expect_renders({"r/a.json": (False, 1), "r/b.json": (True, 2), "r/c.json": (True, 4),
                             "r/d.json": (True, 6)})
    estimate = progress.Estimate(cores=2)
    estimate.plan({"render": 4, "evaluate": 2, "total": 6})
    assert estimate.planned == {"timed render": 3, "untimed render": 1, "evaluate": 2}
    assert estimate.seconds_left() is None  # nothing measured yet
    estimate.start(1, "render", ["r/a.json"])
    clock[0] += 4.0
    estimate.finish(1)
    assert estimate.timed_unmeasured()  # an untimed render says little about the timed ones
    estimate.start(2, "render_together_3", ["r/b.json"])
    clock[0] += 10.0
    estimate.finish(2)
    assert not estimate.timed_unmeasured()
    # Timed renders: 5 s a view so far; two to go, of the plan's mean 4 views; two evaluations at the
    # overall mean (7 s a job), two at a time.
    assert estimate.seconds_left() == pytest.approx(2 * 4 * 5.0 + 2 * 7.0 / 2)
    estimate.start(3, "render", ["r/c.json"])
    clock[0] += 4.0  # a running timed render of 4 views has about 16 s to go
    assert estimate.seconds_left() == pytest.approx(16.0 + 4 * 5.0 + 7.0)


def test_on_a_terminal_the_line_is_redrawn_in_place_and_messages_go_above_it():
    stream = io.StringIO()
    stream.isatty = lambda: True
    line = progress.ProgressLine(stream)
    line.show("volbench: 1 of 3 steps done")
    line.message("Error in rule render")
    line.show("volbench: 3 of 3 steps done", final=True)
    assert stream.getvalue() == ("\rvolbench: 1 of 3 steps done" + "\r" + " " * 27 + "\r" + "Error in rule render\n"
                                 + "volbench: 1 of 3 steps done" + "\rvolbench: 3 of 3 steps done\n")


def test_elsewhere_a_line_is_printed_at_most_every_minute_and_at_the_end(clock):
    stream = io.StringIO()
    line = progress.ProgressLine(stream)
    line.show("a")
    clock[0] += 10
    line.show("b")
    clock[0] += progress.PLAIN_EVERY
    line.show("c")
    line.show("d", final=True)
    assert stream.getvalue() == "a\nc\nd\n"


def test_the_text_says_what_is_done_elapsed_and_left():
    assert progress.progress_text(412, 976, 723, 540) == ("volbench: 412 of 976 steps done, 564 to go · 12 min 03 s "
                                                           "elapsed · about 9 min 00 s left")
    assert progress.progress_text(976, 976, 60, None).endswith("1 min 00 s elapsed")
    assert progress.progress_text(100, 976, 60, 540, floor=True).endswith(
        "· at least 9 min 00 s left (no timed render finished yet)")


@pytest.mark.parametrize("wildcards, output, experiment", [
    ({"experiment": "e1", "run": "r"}, ["results/runs/e1/r.json"], "e1"),
    ({}, ["results/runs/kainz2009-table1/a.json", "results/runs/kainz2009-table1/b.json"], "kainz2009-table1"),
    ({}, ["results/tables/xue2005-tf.csv", "results/claims/xue2005-tf.csv"], "xue2005-tf"),
    ({}, ["cache/abc.npy"], None),
])
def test_a_jobs_experiment_comes_from_its_wildcards_or_outputs(wildcards, output, experiment):
    assert progress.experiment_of(wildcards, output) == experiment


def test_the_plugin_turns_snakemakes_events_into_the_line_and_the_jobs_log(monkeypatch, capsys, tmp_path):
    from snakemake_interface_logger_plugins.common import LogEvent

    from pipeline import harness

    monkeypatch.setenv(harness.LOG_VARIABLE, str(tmp_path / "jobs.jsonl"))
    monkeypatch.setenv(harness.PIPELINE_RUN_VARIABLE, "run-7")
    progress.configure(cores=2)
    progress.register()
    from snakemake_interface_logger_plugins.registry import LoggerPluginRegistry

    handler = LoggerPluginRegistry().get_plugin(progress.PLUGIN).log_handler(None, None)
    handler.setFormatter(logging.Formatter("%(message)s"))

    def record(msg, level=logging.INFO, **extra):
        entry = logging.LogRecord("snakemake", level, __file__, 1, msg, None, None)
        entry.__dict__.update(extra)
        return entry

    handler.emit(record("Job stats", event=LogEvent.RUN_INFO, stats={"render": 1, "total": 1}))
    handler.emit(record(" Rule: render", event=LogEvent.JOB_INFO, jobid=1, rule_name="render_together_3",
                        output=["r/runs/e2/x.json"], wildcards={}))
    handler.emit(record("Select jobs to execute..."))
    handler.emit(record("MissingOutputException", level=logging.ERROR))
    handler.emit(record("", event=LogEvent.JOB_FINISHED, job_id=1))
    handler.emit(record("", event=LogEvent.PROGRESS, done=1, total=1))
    err = capsys.readouterr().err
    assert "MissingOutputException" in err and "Select jobs" not in err and "Rule: render" not in err
    assert "volbench: 1 of 1 steps done, 0 to go" in err
    line, = harness.read_log(tmp_path / "jobs.jsonl")
    assert (line["pipeline_run"], line["step"], line["experiment"], line["failed"]) == ("run-7", "render", "e2", False)
    assert line["ended"] >= line["started"]


def test_with_another_logger_on_the_console_the_plugin_only_writes_the_jobs_log():
    from snakemake_interface_logger_plugins.registry import LoggerPluginRegistry

    progress.configure(cores=2, console=False)
    try:
        progress.register()
        handler = LoggerPluginRegistry().get_plugin(progress.PLUGIN).log_handler(None, None)
        assert handler.writes_to_stream is False and handler.line is None
    finally:
        progress.configure(cores=None)
