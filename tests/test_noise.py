import time

import pandas as pd
import pytest

from core.errors import InputError
from pipeline import noise
from pipeline.disturbance import snapshot


def _claims(verdicts):
    return pd.DataFrame([{"experiment": "e", "claim": claim, "verdict": verdict, "measured": "x"}
                         for claim, verdict in verdicts.items()])


def test_only_holds_to_fails_or_back_is_a_flip():
    quiet = _claims({"a": "holds", "b": "fails", "c": "holds", "d": "inconclusive", "e": "blocked", "f": "holds"})
    loaded = _claims({"a": "fails", "b": "holds", "c": "inconclusive", "d": "holds", "e": "blocked", "f": "holds"})
    change = noise.flips(quiet, loaded).set_index("claim").change.to_dict()
    assert change == {"a": "flipped", "b": "flipped", "c": "inconclusive under load", "d": "decided under load",
                      "e": "same", "f": "same"}


def test_a_claim_missing_from_one_run_is_not_a_flip():
    change = noise.flips(_claims({"a": "holds"}), _claims({"b": "holds"})).set_index("claim").change
    assert set(change) == {"other"}


def test_the_hog_loads_the_machine_and_stops():
    start = snapshot()
    with noise.cpu_hog(1) as hogs:
        time.sleep(1.0)
        end = snapshot()
        assert all(h.is_alive() for h in hogs)
    assert all(not h.is_alive() for h in hogs)
    # One busy process: about one core of work besides this (sleeping) process.
    assert (end.busy - start.busy) - (end.own - start.own) >= 50  # ticks of 10 ms over one second


def test_selection_errors_name_the_fix():
    with pytest.raises(InputError, match="--paper 'nosuch'"):
        noise.experiments_of(["nosuch"], [], "smoke")
    with pytest.raises(InputError, match="--paper P or --experiment E"):
        noise.experiments_of([], [], "smoke")
    assert "lacroute1995-volpack" in noise.experiments_of(["lacroute1995"], [], "smoke")
