"""Pipeline-side inputs of the report: the record column, real-data provenance, planned papers."""

import json
from types import SimpleNamespace

import pytest

from pipeline import environment
from pipeline.experiments.planned import NEEDS, planned


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
    none = planned([], [])
    assert {row["paper"] for row in none} == set(NEEDS)
    lacroute = next(r for r in none if r["paper"] == "lacroute1995")
    assert lacroute["reason"] == "backend not implemented yet" and "shearwarp, volpack" in lacroute["needs"]
    with_backends = planned(["shearwarp", "volpack"], [])
    lacroute = next(r for r in with_backends if r["paper"] == "lacroute1995")
    assert lacroute["reason"] == "experiments not written yet"
    done = planned(["shearwarp", "volpack"], [SimpleNamespace(paper="lacroute1995")])
    assert "lacroute1995" not in {row["paper"] for row in done}


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
    own = set(tables[0].columns) - set(tables[1].columns)
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
