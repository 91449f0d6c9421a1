"""lacroute1995-parallel: speed-up with workers, task assignments and task size (Ch. 6)."""

import json

import pytest

from pipeline.experiments.lacroute1995.parallel import worker_imbalance
from test_lacroute1995_package import check_report, evaluate, planned


def test_plan_sweeps_workers_then_schedules_and_task_sizes_at_the_most_workers():
    parallel = planned("lacroute1995-parallel", **{"lacroute1995-parallel": {"workers": [1, 2], "task_sizes": [1, 8, 64]}})
    assert {(r.options["workers"], r.options["schedule"], r.options["task_size"]) for r in parallel} >= {
        (1, "round-robin-steal", 8), (2, "contiguous", 8), (2, "round-robin-steal", 64)}


def test_worker_imbalance_reads_the_record(tmp_path):
    record = tmp_path / "run.json"
    record.write_text(json.dumps({"views": [{"view": "v", "info": {"worker_samples": [300, 100]}}]}))
    assert worker_imbalance(str(record), "v") == pytest.approx(0.5)
    with pytest.raises(ValueError):
        worker_imbalance(str(record), "other")


def _parallel_rows(t1=0.02, speedup=1.8, schedules=None, tasks=None, record=None):
    rows = [{"volume_size": 128, "workers": 1, "schedule": "round-robin-steal", "task_size": 8, "time_total": t1},
            {"volume_size": 128, "workers": 2, "schedule": "round-robin-steal", "task_size": 8,
             "time_total": t1 / speedup, "record": record, "view": "headline"}]
    for schedule, time in (schedules or {}).items():
        rows.append({"volume_size": 128, "workers": 2, "schedule": schedule, "task_size": 8, "time_total": time,
                     "record": record, "view": "headline"})
    for task, time in (tasks or {}).items():
        rows.append({"volume_size": 128, "workers": 2, "schedule": "round-robin-steal", "task_size": task,
                     "time_total": time})
    return rows


def test_parallel_claims(tmp_path):
    name = "lacroute1995-parallel"
    assert evaluate(name, "speed-up", _parallel_rows()).holds is True
    assert evaluate(name, "speed-up", _parallel_rows(speedup=1.1)).holds is False
    ordered = {"round-robin": 0.0115, "contiguous-steal": 0.012, "contiguous": 0.02}
    assert evaluate(name, "schedule-order", _parallel_rows(schedules=ordered)).holds is True
    assert evaluate(name, "schedule-order", _parallel_rows(schedules={**ordered, "contiguous": 0.009})).holds is False
    assert evaluate(name, "schedule-order", _parallel_rows()).holds is None
    assert evaluate(name, "task-size-u", _parallel_rows(tasks={1: 0.02, 64: 0.015})).holds is True
    assert evaluate(name, "task-size-u", _parallel_rows(tasks={1: 0.005, 64: 0.015})).holds is False
    record = tmp_path / "r.json"
    record.write_text(json.dumps({"views": [{"view": "headline", "info": {"worker_samples": [105, 95]}}]}))
    rows = _parallel_rows(schedules={"contiguous": 0.02}, record=str(record))
    assert evaluate(name, "load-imbalance", rows).holds is True
    assert evaluate(name, "imbalance-order", rows).holds is False  # both 5 %: contiguous not worse


def test_report_writes_its_charts(tmp_path):
    rows = _parallel_rows(schedules={"round-robin": 0.0115, "contiguous-steal": 0.012, "contiguous": 0.02},
                          tasks={1: 0.02, 64: 0.015})
    check_report(tmp_path, "lacroute1995-parallel", [{**row, "study": "workers"} for row in rows])
