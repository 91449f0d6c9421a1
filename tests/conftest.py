"""What every test module shares."""

import os
import tempfile

import pytest

# Numba's on-disk cache is not safe for two processes writing one function's entries at once: the index one writes
# can name a specialisation the other overwrote, and the next call fails ("can't unbox array from PyObject", seen in
# a fresh clone's `make test`). Each pytest-xdist worker compiles into a cache of its own; set before any test
# module imports Numba.
_WORKER = os.environ.get("PYTEST_XDIST_WORKER")
if _WORKER and "NUMBA_CACHE_DIR" not in os.environ:
    os.environ["NUMBA_CACHE_DIR"] = os.path.join(tempfile.gettempdir(), "volbench-numba", _WORKER)


@pytest.fixture(autouse=True)
def load_span_not_waited_for(monkeypatch):
    """Test frames are tiny: timing each view on until its load can be read (``pipeline.timing._unreadable``,
    half a second a view) would only slow the suite; ``tests/test_timing.py`` checks that rule itself."""
    from pipeline import timing

    monkeypatch.setattr(timing, "_unreadable", lambda start: False)
