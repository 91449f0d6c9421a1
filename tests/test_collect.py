"""Pipeline-side inputs of the report: the record column, real-data provenance, planned papers."""

import json
from types import SimpleNamespace

import pytest

from pipeline import environment
from pipeline.experiments import papers
from pipeline.experiments.planned import planned


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """The report tests' results folder (records, metrics, CSVs as collect writes them), read-only here."""
    from test_reports_html import synthetic_results

    return synthetic_results(tmp_path_factory.mktemp("synthetic"))


def test_runs_csv_rows_link_their_record(synthetic):
    runs_df, _claims, _experiments, results = synthetic
    assert runs_df.record.notna().all()
    for row in runs_df.drop_duplicates("run").itertuples():
        assert json.loads(open(row.record).read())["run"] == row.run


def test_planned_papers_disappear_as_backends_and_experiments_land():
    import dataclasses

    lacroute = papers()["lacroute1995"]
    none = planned([], papers().values())
    assert {row["paper"] for row in none} == {p for p, paper in papers().items() if paper.technique}
    row = next(r for r in none if r["paper"] == "lacroute1995")
    assert row["reason"] == "backend not implemented yet" and "shearwarp, volpack" in row["needs"]
    without_experiments = dataclasses.replace(lacroute, experiments=())
    row = next(r for r in planned(["shearwarp", "volpack"], [without_experiments]))
    assert row["reason"] == "experiments not written yet"
    assert planned(["shearwarp", "volpack"], [lacroute]) == []
    assert planned([], [papers()["volbench"]]) == []  # the project's own studies need no paper's backend


def test_real_data_provenance_reads_the_manifest_and_sources(tmp_path):
    (tmp_path / "volumes.json").write_text(json.dumps({
        "_about": "comment", "cthead": {"file": "cthead_2x2x2_uint8.raw", "dims": [2, 2, 2], "dtype": "uint8",
                                        "modality": "CT head"}}))
    (tmp_path / "SOURCES.md").write_text(
        "| file | dims | source repo @ commit : path | licence |\n|---|---|---|---|\n"
        "| `cthead_2x2x2_uint8.raw` | 2×2×2 | someone/repo @ `abc` : data/cthead | MIT |\n")
    facts = environment.real_data_provenance(tmp_path)
    assert facts["folder"] == str(tmp_path) and facts["error"] == ""
    cthead = facts["datasets"][0]
    assert cthead["name"] == "cthead" and cthead["modality"] == "CT head"
    assert cthead["source"] == "someone/repo @ abc : data/cthead. MIT"
    missing = environment.real_data_provenance(tmp_path / "nowhere")
    assert "does not exist" in missing["error"]
    assert {d["name"] for d in missing["datasets"]} <= {"brainsmall"}  # VolPack's example, if Debian has it


def test_host_environment_records_date_memory_and_numba_threads():
    env = environment.host_environment()
    assert env["memory_bytes"] > 0 and env["numba_threads"] >= 1 and len(env["date"]) == 16


def test_every_row_names_the_node_that_measured_it(synthetic):
    runs_df, *_ = synthetic
    assert (runs_df["node"] == "test").all()  # the synthetic records' host, outside SLURM


def test_claims_table_is_what_collect_writes(synthetic):
    import pandas as pd

    from pipeline.collect import claims_table

    runs_df, claims_df, experiments, results = synthetic
    written = pd.read_csv(results / "claims.csv")
    recomputed = claims_table(runs_df, experiments)
    assert recomputed[["experiment", "claim", "measured"]].values.tolist() == \
        written[["experiment", "claim", "measured"]].fillna("").values.tolist()


def test_runs_and_claims_csv_are_the_experiments_tables_as_written(synthetic):
    import pandas as pd

    from pipeline.collect import claims_path, table_path

    runs_df, _claims, experiments, results = synthetic
    tables = [pd.read_csv(table_path(results, e.name), dtype=str, keep_default_na=False) for e in experiments]
    assert sum(map(len, tables)) == len(runs_df) and len(experiments) > 1
    # Text in, text out: every cell of runs.csv is its experiment's table's cell, blank where it has no column.
    merged = pd.read_csv(results / "runs.csv", dtype=str, keep_default_na=False)
    assert merged.equals(pd.concat(tables, ignore_index=True).fillna("")[merged.columns])
    own = set(tables[0].columns) - set().union(*(t.columns for t in tables[1:]))
    assert own and (merged.loc[len(tables[0]):, sorted(own)] == "").all().all()
    claims = pd.concat([pd.read_csv(claims_path(results, e.name), dtype=str, keep_default_na=False) for e in experiments],
                       ignore_index=True)
    assert pd.read_csv(results / "claims.csv", dtype=str, keep_default_na=False).equals(claims)


def test_phantom_manifest_digests_the_stored_bytes_and_names_a_missing_phantom(tmp_path):
    import hashlib

    import pytest

    import datasets
    from pipeline.collect import phantom_manifest
    from pipeline.scene_io import phantom_requests

    entries = [{"dataset": "sphere", "seed": 10}, {"dataset": "ct_skull"}, {"dataset": "sphere", "seed": 3},
               {"dataset": "sphere", "seed": 10}, {"dataset": "sphere", "seed": 2}]
    requests = phantom_requests(entries, size=8)
    assert len(requests) == 4  # one request per distinct phantom
    for request in requests.values():
        datasets.load(request["dataset"], cache_dir=tmp_path, **request["kwargs"])
    table = phantom_manifest(requests, cache_dir=tmp_path)
    # Listed by data set, then by seed as a number; types by name, as people read them.
    assert list(zip(table.dataset, table.seed)) == [("ct_skull", 0), ("sphere", 2), ("sphere", 3), ("sphere", 10)]
    assert set(table.dtype) == {"uint8"}
    manifest = table.set_index("key")
    for key, request in requests.items():
        stored = hashlib.sha256((tmp_path / f"{key}.npy").read_bytes())
        if manifest.loc[key, "labels"]:
            stored.update((tmp_path / f"{key}.labels.npy").read_bytes())
        assert manifest.loc[key, "sha256"] == stored.hexdigest() and manifest.loc[key, "dataset"] == request["dataset"]
    assert manifest.loc[datasets.cache_key("sphere", size=8, seed=3), "seed"] == 3
    (tmp_path / f"{datasets.cache_key('ct_skull', size=8, seed=0)}.npy").unlink()
    with pytest.raises(FileNotFoundError, match="ct_skull.*not in the cache"):
        phantom_manifest(requests, cache_dir=tmp_path)


def _tables(results, rows):
    """``tables/<e>.csv`` and ``claims/<e>.csv`` for ``{experiment: [(run, date), ...]}``, as tabulate writes them."""
    import pandas as pd

    from pipeline.collect import claims_path, table_path

    for name, runs in rows.items():
        for path_of, frame in ((table_path, pd.DataFrame([{"experiment": name, "run": run, "date": date} for run, date in runs])),
                               (claims_path, pd.DataFrame([{"experiment": name, "claim": "c", "holds": True}]))):
            path_of(results, name).parent.mkdir(parents=True, exist_ok=True)
            frame.to_csv(path_of(results, name), index=False)


def test_a_run_of_some_experiments_keeps_the_others_tables_and_drops_those_of_removed_ones(tmp_path):
    import pandas as pd

    from pipeline.collect import merge

    known = [SimpleNamespace(name=name) for name in ("c2002-third", "a2000-first", "b2001-second")]  # registry order
    _tables(tmp_path, {"a2000-first": [("r1", "2026-01-02 10:00")], "b2001-second": [("r2", "2026-01-05 09:00")],
                       "c2002-third": [("r3", "2026-01-01 08:00")], "gone1999-renamed": [("r4", "2025-12-01 07:00")]})
    earlier, dropped = merge([known[2]], results_dir=tmp_path, known=known)  # volbench run --experiment b2001-second
    assert (earlier, dropped) == (["c2002-third", "a2000-first"], ["gone1999-renamed"])
    runs = pd.read_csv(tmp_path / "runs.csv")
    assert list(runs.experiment) == ["c2002-third", "a2000-first", "b2001-second"]
    assert list(pd.read_csv(tmp_path / "claims.csv").experiment) == list(runs.experiment)
    assert merge([known[2]], results_dir=tmp_path) == ([], [])  # without the registry: this run's tables only
    assert list(pd.read_csv(tmp_path / "runs.csv").experiment) == ["b2001-second"]


def test_the_report_shows_earlier_runs_experiments_with_their_dates_and_the_dropped_tables(tmp_path):
    import pandas as pd

    from pipeline.jobs import report_contents

    registry = {name: SimpleNamespace(name=name) for name in ("a2000-first", "b2001-second", "c2002-third")}
    _tables(tmp_path, {"gone1999-renamed": [("r4", "2025-12-01 07:00")], "b2001-second": [("r2", "2026-01-05 09:00")]})
    runs = pd.DataFrame({"experiment": ["a2000-first", "a2000-first", "b2001-second", "c2002-third"],
                         "date": ["2026-01-02 10:00", "2026-01-02 10:40", "2026-01-05 09:00", None]})
    claims = pd.DataFrame({"experiment": ["a2000-first", "b2001-second", "c2002-third"]})
    shown, notices = report_contents(runs, claims, [registry["b2001-second"]], registry, tmp_path)
    assert [e.name for e in shown] == ["a2000-first", "b2001-second", "c2002-third"]
    assert notices[0] == ("Not all of this report comes from its last pipeline run: the results of 2 experiments are "
                          "from earlier runs (measured, UTC): a2000-first (2026-01-02 10:00 to 2026-01-02 10:40), "
                          "c2002-third (date not recorded).")
    assert notices[1].startswith("Left out: the results of gone1999-renamed, which volbench no longer has")
    assert report_contents(runs, claims, list(registry.values()), registry, tmp_path / "other") == (list(registry.values()), [])
    # Many earlier experiments (one rerun after a whole profile): the notice names the last run's instead.
    many = {f"e{i}-x": SimpleNamespace(name=f"e{i}-x") for i in range(5)}
    runs = pd.DataFrame({"experiment": list(many), "date": [f"2026-01-0{i + 1} 10:00" for i in range(5)]})
    _, notices = report_contents(runs, pd.DataFrame({"experiment": list(many)}), [many["e4-x"]], many,
                                 tmp_path / "other")
    assert notices == ["Not all of this report comes from its last pipeline run: that run made e4-x; the results of "
                       "the other 4 experiments are from earlier runs (measured 2026-01-01 10:00 to 2026-01-04 "
                       "10:00, UTC; each run's date is in runs.csv)."]


def test_a_views_frames_load_and_second_timing_are_columns_of_its_row(tmp_path):
    from pipeline.collect import rows_for
    from pipeline.experiments import Run
    from pipeline.records import new_record, run_record_path, write_json

    run = Run("e", "a", "reference", {"volumes": [{"dataset": "sphere"}]}, ({"view": "front"},), interleave="g")
    record = new_record(run, {})
    load = {"seconds": 1.2, "foreign_cores": 0.7, "own_cores": 1.0, "steal_share": 0.0, "waited_share": 0.2,
            "load_average": 1.5, "elapsed": 1.0}
    record["views"] = [{"view": "front", "png": "front.png", "exr": "front.exr", "timings": {"total": 0.0011},
                        "timings_min": {"total": 0.001}, "timings_max": {"total": 0.0012}, "counters": {},
                        "info": {"frames": 3, "load": load, "disturbed": "other work used 0.70 cores while it was timed"},
                        "frames": {"total": [0.001, 0.0012, 0.0011]},
                        "rerun": {"first": "other work used 1.20 cores while it was timed",
                                  "second": "other work used 0.70 cores while it was timed", "kept": "second"}}]
    path = run_record_path(tmp_path, "e", "a")
    write_json(path, record)
    (row,) = rows_for(path, results_dir=tmp_path)
    assert row["interleave"] == "g" and row["frames_total"] == "0.001 0.0012 0.0011"
    assert {k: v for k, v in row.items() if k.startswith("load_")} == {
        "load_foreign_cores": 0.7, "load_steal_share": 0.0, "load_waited_share": 0.2, "load_average": 1.5}
    assert row["info_disturbed"] == "other work used 0.70 cores while it was timed" and row["info_frames"] == 3
    assert row["rerun"] == ("timed twice: other work used 1.20 cores while it was timed; the second too: "
                            "other work used 0.70 cores while it was timed; kept the second")
    record["views"][0]["rerun"] = {"first": "3 of 10 frames took over 3× the median", "second": "", "kept": "second"}
    record["views"][0]["frames"] = {}
    record["interleave"] = None
    write_json(path, record)
    (row,) = rows_for(path, results_dir=tmp_path)
    assert row["rerun"] == "timed twice: 3 of 10 frames took over 3× the median; the second was quiet; kept the second"
    assert row["interleave"] == "" and not any(k.startswith("frames_") for k in row)


def test_a_run_timed_in_two_processes_keeps_each_ones_frames_and_names_the_disturbed_one(tmp_path):
    """merge_processes: each process's frames apart, the time the mean of their medians, the harness's seconds
    added, a disturbance and a failure named by process; the row counts the processes and keeps each one's time of
    a stage it timed once (``once_<stage>``)."""
    import copy

    from pipeline.collect import rows_for
    from pipeline.experiments import Run
    from pipeline.experiments.kit import intervals
    from pipeline.records import merge_processes, new_record, run_record_path, write_json

    run = Run("e", "a", "reference", {"volumes": [{"dataset": "sphere"}]}, ({"view": "front"},), replicates=2)
    attempts = []
    for pid, frames, disturbed, first in ((11, [0.001, 0.003, 0.002], "", 0.1),
                                          (12, [0.004, 0.006, 0.005], "a burst", 0.3)):
        record = new_record(run, {})
        record["harness"] = {"process": "worker", "pid": pid, "new": pid == 12, "startup": 1.5, "seconds": 2.0}
        record["views"] = [{"view": "front", "png": "front.png", "exr": "front.exr",
                            "timings": {"total": sorted(frames)[1], "first_frame": first},
                            "timings_min": {"total": min(frames)}, "timings_max": {"total": max(frames)},
                            "counters": {"samples": 7}, "frames": {"total": frames},
                            "info": {"frames": 3, "timed_seconds": sum(frames), "disturbed": disturbed}}]
        attempts.append(record)
    merged = merge_processes(attempts)
    view = merged["views"][0]
    assert [p["pid"] for p in view["processes"]] == [11, 12]
    assert view["timings"] == {"total": pytest.approx(0.0035), "first_frame": pytest.approx(0.2)}
    assert (view["timings_min"], view["timings_max"]) == ({"total": 0.001}, {"total": 0.006})
    assert view["info"]["frames"] == 6 and view["info"]["disturbed"] == "process 2: a burst"
    # Each process's own info (how it shared out its work), the harness's seconds summed above.
    assert [p["info"] for p in view["processes"]] == [{"disturbed": ""}, {"disturbed": "a burst"}]
    assert merged["harness"]["seconds"] == 4.0 and merged["harness"]["startup"] == 1.5
    assert merged["harness"]["pids"] == [11, 12] and merged["harness"]["processes"] == 2
    path = run_record_path(tmp_path, "e", "a")
    write_json(path, merged)
    (row,) = rows_for(path, results_dir=tmp_path)
    assert row["frames_total"] == "0.001 0.003 0.002 | 0.004 0.006 0.005" and row["processes"] == 2
    assert row["once_first_frame"] == "0.1 | 0.3" and "once_total" not in row
    assert row["time_total"] == pytest.approx(intervals.process_time(intervals.parse_processes(row["frames_total"])))
    failed = copy.deepcopy(attempts[1])
    failed.update(status="failed", reason="RuntimeError: lost the context")
    merged = merge_processes([attempts[0], failed], planned=3)
    assert merged["reason"] == "process 2 of 3: RuntimeError: lost the context"


def test_claims_table_gives_each_timing_claim_its_interval_and_margin():
    import numpy as np
    import pandas as pd

    from pipeline.collect import CLAIM_COLUMNS, claims_table
    from pipeline.experiments import Claim, Experiment
    from pipeline.experiments.kit.checks import Bound, Measure, Ratio
    from pipeline.experiments.kit.intervals import format_frames

    slow, fast = Measure("slow", match={"config": "slow"}), Measure("fast", match={"config": "fast"})

    class Speed(Experiment):
        name = "test-speed"
        claims = (Claim("faster", "fast is faster", "≥ ×1.5", Ratio(slow, fast, at_least=1.5)),
                  Claim("twice", "fast is twice as fast", "≥ ×2", Ratio(slow, fast, at_least=2.0)),
                  Claim("sharp", "fast is sharp", "≥ 40 dB", Bound(Measure("fast", match={"config": "fast"},
                                                                           column="psnr", unit="dB"), at_least=40)))

    noise = 1 + 0.02 * np.random.default_rng(3).standard_normal(30)
    frame = pd.DataFrame([{"experiment": "test-speed", "run": config, "view": "front", "status": "ok",
                           "config": config, "time_total": float(np.median(seconds * noise)),
                           "frames_total": format_frames(seconds * noise), "psnr": 42.0}
                          for config, seconds in (("slow", 0.004), ("fast", 0.002))])
    table = claims_table(frame, [Speed()])
    assert list(table.columns) == CLAIM_COLUMNS
    table = table.set_index("claim")
    assert table.loc["faster", "verdict"] == "holds" and 1.5 < table.loc["faster", "interval_low"] < 2.0
    assert table.loc["faster", "interval_high"] > 2.0 and table.loc["faster", "margin"] == pytest.approx(1 / 3)
    assert table.loc["twice", "verdict"] == "inconclusive" and table.loc["twice", "holds"] is None
    assert table.loc["twice", "interval_low"] < 2.0 < table.loc["twice", "interval_high"]
    # A metric has no frames: a point verdict, with its margin and no interval.
    assert table.loc["sharp", "verdict"] == "holds" and table.loc["sharp", "margin"] == pytest.approx(0.05)
    assert np.isnan(table.loc["sharp", "interval_low"]) and np.isnan(table.loc["sharp", "interval_high"])
