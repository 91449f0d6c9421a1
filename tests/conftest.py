"""What every test module shares."""

import pytest


@pytest.fixture(autouse=True)
def load_span_not_waited_for(monkeypatch):
    """Test frames are tiny: timing each view on until its load can be read (``pipeline.timing._unreadable``,
    half a second a view) would only slow the suite; ``tests/test_timing.py`` checks that rule itself."""
    from pipeline import timing

    monkeypatch.setattr(timing, "_unreadable", lambda start: False)
