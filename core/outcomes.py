"""How a run ended: the ``cause`` a run record gives when it produced no frame (CONVENTIONS, Results).

The pipeline writes it, the report and the claims read it: a run skipped because its backend lacks
a feature the scene uses is a limit the experiment planned for (the backend's capabilities say
so); every other cause means measurements the experiment expected are missing on this machine.
"""

CAUSES = {
    "": "the run succeeded",
    "unsupported": "the backend lacks a feature the scene uses (a planned limit, stated by its capabilities)",
    "unavailable": "the backend cannot run on this machine (its probe says why)",
    "no-data": "the data set is not on this machine",
    "error": "the run raised an error",
    "time-limit": "the run exceeded the profile's render_time_limit",
    "crash": "the render process died without a record",
}
"""A record's ``cause`` → what it means."""

INCOMPLETE_CAUSES = frozenset(CAUSES) - {"", "unsupported"}
"""Causes of runs that should have produced measurements here and did not."""

CAUSE_WORDS = {"unavailable": "cannot run here", "no-data": "has no data here", "error": "failed",
               "time-limit": "exceeded the time limit", "crash": "crashed", "unsupported": "lacks a feature"}
"""How a sentence says that a run (or a backend) ended with each cause."""


def cause_of(status, cause):
    """The cause of a record (``status``, ``cause``), also for records written before causes existed.

    Such a record's failure counts as an error and its skip as a planned limit.
    """
    cause = "" if cause is None or cause != cause else str(cause)  # NaN from a CSV
    if cause or status == "ok":
        return cause
    return "error" if status == "failed" else "unsupported"
