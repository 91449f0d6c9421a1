"""Which node measured which timings: the report's grouping by node and the check every ratio makes.

A timing belongs to the machine that measured it. Results merged from several nodes or clusters
(and a host measured both inside and outside a SLURM job) share one ``runs.csv``, where the
``node`` column keeps them apart; a ratio between timings from two nodes compares the machines as
well as the techniques, so whatever computes one calls :func:`node_warning` on the rows it used
and shows the sentence it returns.
"""

import pandas as pd

from core.errors import InputError

GIB = 1024 ** 3


def _frame(rows, name):
    if isinstance(rows, pd.DataFrame):
        return rows
    if isinstance(rows, (str, bytes)) or not hasattr(rows, "__iter__"):
        raise InputError(f"{name}: expected a DataFrame or a list of row mappings, got {type(rows).__name__}")
    return pd.DataFrame(list(rows))


def nodes_of(rows):
    """The distinct nodes ``rows`` (``runs.csv`` rows) were measured on, sorted; rows naming none are left out."""
    frame = _frame(rows, "rows")
    if "node" not in frame:
        return []
    return sorted(str(node) for node in pd.unique(frame["node"].dropna()))


def node_warning(rows, *, what="this ratio"):
    """A sentence saying that ``rows`` came from different nodes, or ``""`` when they share one.

    Parameters
    ----------
    rows : pandas.DataFrame or iterable of mapping
        The rows (of ``runs.csv``) whose timings a ratio or comparison is computed from; the
        ``node`` column names where each was measured. Rows without one do not count.
    what : str
        What the caller computes, as the sentence's subject (``"the speed-up over VolPack"``).

    Returns
    -------
    str
        ``""`` for rows from one node (or none named); otherwise e.g. ``"this ratio compares
        timings measured on different nodes (a, b): it measures the machines as well as the
        techniques."``.
    """
    if not isinstance(what, str) or not what.strip():
        raise InputError(f"what: expected a non-empty description of the comparison, got {what!r}")
    nodes = nodes_of(rows)
    if len(nodes) < 2:
        return ""
    return (f"{what} compares timings measured on different nodes ({', '.join(nodes)}): "
            "it measures the machines as well as the techniques.")


def nodes_table(runs_df):
    """One row per node for the report's environment section: its hardware and what it measured.

    Returns
    -------
    list of dict
        ``node``, ``cpu`` (model, usable CPUs of the node's cores), ``memory``, ``devices`` (OpenGL
        renderer, OpenCL device), ``runs`` (runs with timings measured there), ``experiments`` and
        ``dates`` (first to last record date), sorted by node.
    """
    frame = _frame(runs_df, "runs_df")
    if frame.empty or "node" not in frame:
        return []
    table = []
    for node, group in frame.dropna(subset=["node"]).groupby("node", sort=True):
        first = group.iloc[0]

        def fact(column, rows=group, first=first):
            value = first.get(column) if column in rows else None
            return None if value is None or (isinstance(value, float) and pd.isna(value)) else value

        cores, usable = fact("cpu_cores"), fact("usable_cpus")
        cpu = str(fact("cpu_model") or "CPU not recorded")
        if cores is not None:
            cpu += f", {int(float(usable if usable is not None else cores))} of {int(float(cores))} cores usable"
        memory = fact("memory_bytes")
        devices = [str(v) for v in (fact("gl_renderer"), fact("cl_device")) if v is not None]
        timed = group[group["status"] == "ok"] if "status" in group else group
        dates = sorted(str(d) for d in pd.unique(group["date"].dropna())) if "date" in group else []
        table.append({
            "node": str(node), "cpu": cpu,
            "memory": f"{float(memory) / GIB:.1f} GiB" if memory is not None else "not recorded",
            "devices": ", ".join(devices) or "none recorded",
            "runs": int(timed.drop_duplicates(["experiment", "run"]).shape[0]) if not timed.empty else 0,
            "experiments": int(pd.unique(group["experiment"]).size) if "experiment" in group else 0,
            "dates": f"{dates[0]} to {dates[-1]}" if len(dates) > 1 else (dates[0] if dates else "not recorded"),
        })
    return table
