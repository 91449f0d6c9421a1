"""What the harness itself costs (pipeline.harness): the jobs log and the account of a pipeline run's time."""

import json
import os

import pandas as pd
import pytest

from pipeline import harness


def test_a_job_line_names_its_pipeline_run_step_experiment_and_times(tmp_path):
    log = tmp_path / "harness" / "jobs.jsonl"
    harness.log_job(log, run="run-1", step="render", experiment="kruger2003-table1", started=5.0, ended=7.5)
    harness.log_job(log, run="run-1", step="report", experiment=None, started=8.0, ended=9.0, failed=True)
    first, second = harness.read_log(log)
    assert first == {"pipeline_run": "run-1", "kind": "job", "step": "render", "experiment": "kruger2003-table1",
                     "started": 5.0, "ended": 7.5, "failed": False}
    assert second["failed"] and second["experiment"] is None


def test_a_line_cut_short_by_a_kill_is_skipped(tmp_path):
    log = tmp_path / "jobs.jsonl"
    log.write_text('{"kind": "start", "pipeline_run": "a", "started": 1}\n{"kind": "jo')
    assert harness.read_log(log) == [{"kind": "start", "pipeline_run": "a", "started": 1}]
    assert harness.read_log(tmp_path / "none.jsonl") == []


def _log(run="r", started=1000.0):
    return [
        {"kind": "start", "pipeline_run": "old", "started": 10.0},
        {"kind": "start", "pipeline_run": run, "started": started},
        {"kind": "job", "pipeline_run": run, "step": "volume", "started": started + 1, "ended": started + 3},
        {"kind": "job", "pipeline_run": run, "step": "render", "experiment": "e1", "started": started + 3,
         "ended": started + 13},
        {"kind": "job", "pipeline_run": run, "step": "render", "experiment": "e1", "started": started + 14,
         "ended": started + 20},
        {"kind": "job", "pipeline_run": run, "step": "evaluate", "experiment": "e1", "started": started + 20,
         "ended": started + 22},
        {"kind": "job", "pipeline_run": "old", "step": "render", "experiment": "e1", "started": 11.0, "ended": 99.0},
        {"kind": "job", "pipeline_run": run, "step": "report", "started": started + 25, "ended": started + 27},
    ]


def _runs():
    return pd.DataFrame([
        # Two views of a group started in a new worker (its start-up is in both records: counted once).
        {"experiment": "e1", "harness_pipeline_run": "r", "harness_new": True, "harness_pid": 5,
         "harness_runs_before": 0, "harness_startup": 2.0, "info_timed_seconds": 4.0, "info_untimed_seconds": 1.0,
         "info_cold_seconds": 0.5, "info_rerun_seconds": None},
        {"experiment": "e1", "harness_pipeline_run": "r", "harness_new": True, "harness_pid": 5,
         "harness_runs_before": 0, "harness_startup": 2.0, "info_timed_seconds": 3.0, "info_untimed_seconds": 0.5,
         "info_cold_seconds": 0.25, "info_rerun_seconds": 1.5},
        # Rendered by an earlier pipeline run: costs this one nothing.
        {"experiment": "e1", "harness_pipeline_run": "old", "info_timed_seconds": 50.0},
    ])


def test_the_account_splits_each_experiments_wall_time_into_frames_and_overhead():
    account = harness.account(_log(), _runs(), run="r", now=1030.0)
    assert account["span"] == 30.0
    e1 = next(row for row in account["rows"] if row["name"] == "e1")
    assert e1["steps"] == 3 and e1["wall"] == pytest.approx(18.0)
    assert e1["timed"] == 7.0 and e1["untimed"] == 3.0  # warm-up and a view's discarded attempt
    assert e1["cold"] == 0.75 and e1["startup"] == 2.0
    assert e1["work"] == pytest.approx(2.0)  # its evaluation
    assert e1["overhead"] == pytest.approx(6.0)
    assert [row["name"] for row in account["rows"]] == ["e1", "phantoms", "collect and report"]
    # Jobs ran over 1..13, 14..22 and 25..27 of the 30 s: 8 s with no job.
    assert account["gaps"] == pytest.approx(8.0)
    assert account["timed_share"] == pytest.approx(7 / 30) and account["frames_share"] == pytest.approx(10 / 30)


def test_the_last_pipeline_run_logged_is_the_default_and_an_unknown_one_has_no_account():
    assert harness.account(_log(), _runs(), now=1030.0)["run"] == "r"
    assert harness.account(_log(), _runs(), run="never", now=1030.0) is None
    assert harness.account([], _runs()) is None


def test_a_pipeline_run_is_named_by_its_start_and_process():
    name = harness.new_pipeline_run()
    assert name.endswith(f"-{os.getpid()}") and name[:8].isdigit()
    assert harness.pipeline_run({harness.PIPELINE_RUN_VARIABLE: name}) == name
    assert harness.pipeline_run({}) is None


def test_log_start_writes_the_plan(tmp_path):
    log = tmp_path / "jobs.jsonl"
    harness.log_start(log, run="x", steps=12)
    assert json.loads(log.read_text())["planned_runs"] == 12


def test_the_appendix_shows_where_the_runs_time_went_and_how_quiet_the_timed_views_were(tmp_path):
    from pipeline.experiments.volbench.phantoms import PhantomGallery
    from reports.html import build_report

    runs = _runs().assign(run=["a", "b", "c"], status="ok", view="v", backend="reference", info_disturbed=["", "", "other work"],
                          rerun=["", "timed twice: ...", ""], info_untimed=False,
                          load_orchestrator_cores=[0.0, 0.01, None], load_foreign_cores=[0.02, 0.03, 0.9])
    account = harness.account(_log(), runs, run="r", now=1030.0)
    index = build_report(runs, pd.DataFrame(columns=["experiment", "claim", "holds"]), [PhantomGallery()],
                         results_dir=tmp_path, environment={}, harness=account)
    page = (index.parent / "appendix.html").read_text()
    assert "What the harness itself cost" in page
    assert "used at most 0.01 cores (median 0.01, over 2 views long enough to measure)" in page
    assert "1 view was disturbed when first timed and timed again; 1 is still disturbed" in page
    assert "took 0.5 minutes until its report: 23 % of that wall time went to timed frames and 33 % " in page
    # Wall, timed, untimed, evaluation, cold frames, worker start-up, the rest, and the share in frames.
    assert ("<td class=\"text\">e1</td><td>3</td><td>18</td><td>7</td><td>3</td><td>2</td><td>0.75</td><td>2</td>"
            "<td>3.25</td><td>56 %</td>") in page
