"""Timings grouped by node, and the warning a ratio between nodes carries."""

import pandas as pd
import pytest

from core.errors import InputError
from reports.nodes import node_warning, nodes_of, nodes_table

ROWS = pd.DataFrame([
    {"experiment": "e", "run": "a", "view": "v0", "status": "ok", "node": "lab/n1", "cpu_model": "CPU A",
     "cpu_cores": 32, "usable_cpus": 32, "memory_bytes": 64 * 1024 ** 3, "gl_renderer": "llvmpipe",
     "cl_device": None, "date": "2025-01-31 14:05"},
    {"experiment": "e", "run": "a", "view": "v1", "status": "ok", "node": "lab/n1", "cpu_model": "CPU A",
     "cpu_cores": 32, "usable_cpus": 32, "memory_bytes": 64 * 1024 ** 3, "gl_renderer": "llvmpipe",
     "cl_device": None, "date": "2025-01-31 14:09"},
    {"experiment": "e", "run": "b", "view": "v0", "status": "ok", "node": "laptop", "cpu_model": "CPU B",
     "cpu_cores": 8, "usable_cpus": 4, "memory_bytes": 16 * 1024 ** 3, "gl_renderer": None,
     "cl_device": "pthread", "date": "2025-02-01 09:00"},
    {"experiment": "f", "run": "c", "view": None, "status": "skipped", "node": "laptop", "cpu_model": "CPU B",
     "cpu_cores": 8, "usable_cpus": 4, "memory_bytes": 16 * 1024 ** 3, "gl_renderer": None,
     "cl_device": "pthread", "date": "2025-02-01 09:00"},
])


def test_a_ratio_within_one_node_carries_no_warning():
    assert node_warning(ROWS[ROWS.node == "lab/n1"]) == ""
    assert node_warning(ROWS.drop(columns="node")) == ""  # nothing recorded: nothing to say
    assert node_warning([]) == ""


def test_a_ratio_across_nodes_says_so_and_names_them():
    warning = node_warning(ROWS[ROWS.run.isin(["a", "b"])], what="the speed-up of b over a")
    assert warning.startswith("the speed-up of b over a compares timings measured on different nodes")
    assert "(lab/n1, laptop)" in warning
    assert node_warning(ROWS.to_dict("records")) == node_warning(ROWS)


def test_bad_input_is_named():
    with pytest.raises(InputError, match="rows"):
        nodes_of(42)
    with pytest.raises(InputError, match="what"):
        node_warning(ROWS, what="")


def test_nodes_table_groups_runs_by_node_with_their_hardware():
    table = {row["node"]: row for row in nodes_table(ROWS)}
    assert list(table) == ["lab/n1", "laptop"]
    assert table["lab/n1"]["cpu"] == "CPU A, 32 of 32 cores usable" and table["lab/n1"]["memory"] == "64.0 GiB"
    assert table["lab/n1"]["runs"] == 1 and table["lab/n1"]["dates"] == "2025-01-31 14:05 to 2025-01-31 14:09"
    assert table["laptop"]["cpu"] == "CPU B, 4 of 8 cores usable" and table["laptop"]["devices"] == "pthread"
    assert table["laptop"]["runs"] == 1 and table["laptop"]["experiments"] == 2
    assert nodes_table(pd.DataFrame()) == [] and nodes_table(ROWS.drop(columns="node")) == []
