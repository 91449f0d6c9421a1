import shutil
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


def test_a_second_quiet_run_reports_agreement_and_a_replication_flip_exits_3(tmp_path, monkeypatch, capsys):
    verdicts = {"quiet": {"a": "holds", "b": "holds", "c": "fails"},
                "loaded": {"a": "inconclusive", "b": "holds", "c": "fails"},
                "quiet-again": {"a": "holds", "b": "fails", "c": "inconclusive"}}
    ran = []

    def run(profile, selection, results, cores):
        ran.append(results.name)
        results.mkdir(parents=True)
        claims = _claims(verdicts[results.name.split("-", 1)[1]]).assign(experiment="lacroute1995-volpack")
        low = 1.0 if results.name.endswith("again") else 1.5  # a's intervals in the two quiet runs do not agree
        claims.assign(kind=["timing", "count", "timing"], interval_low=[low, None, 2.0],
                      interval_high=[low + 0.2, None, 2.2]).to_csv(results / "claims.csv", index=False)
        return 0

    monkeypatch.setattr(noise, "_volbench_run", run)
    args = ["--profile", "smoke", "--experiment", "lacroute1995-volpack", "--prefix", str(tmp_path / "n")]
    assert noise.main(args) == 3  # only the two quiet runs disagree on b
    assert ran == ["n-quiet", "n-loaded", "n-quiet-again"]
    out = capsys.readouterr().out
    assert ("two quiet runs: 1 of 3 claims (33.3 %) have the same verdict; of the 2 that read timings, 1 (50.0 %)"
            in out)
    assert "lacroute1995-volpack b: holds (x) → fails (x) [flipped]" in out
    assert ("two quiet runs' intervals: of the 2 timing claims both gave an interval, 1 (50.0 %) agree within their "
            "95 % intervals" in out)
    assert "  intervals apart: lacroute1995-volpack/a: 1.5–1.7 in the first, 1–1.2 in the second (6.9 apart)" in out
    assert pd.read_csv(tmp_path / "n-replication.csv").set_index("claim").change.to_dict() == {
        "a": "same", "b": "flipped", "c": "to inconclusive"}
    verdicts["loaded"]["b"] = "fails"  # a flip under load is the harness's failure, whatever the quiet runs say
    for name in ran:
        shutil.rmtree(tmp_path / name)
    assert noise.main(args) == 1
    ran.clear()
    assert noise.main([*args, "--prefix", str(tmp_path / "one"), "--quiet-runs", "1"]) == 1
    assert ran == ["one-quiet", "one-loaded"]
