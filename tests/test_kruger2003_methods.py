"""Krüger & Westermann 2003, the package: registration, what every experiment plans, the shared helpers.

Also the helpers the other ``test_kruger2003_*`` files share.
"""

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import renderers
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kit import intervals
from pipeline.experiments.kruger2003.methods import METHODS, method_runs
from pipeline.experiments.kruger2003.passes import M_VALUES
from pipeline.experiments.kruger2003.tables import TABLE1

ROOT = Path(__file__).resolve().parent.parent
NAMES = ("kruger2003-table1", "kruger2003-nocue", "kruger2003-passes", "kruger2003-stability", "kruger2003-occluder")


def with_gl_backends(monkeypatch):
    """The registry with the GL backends, whether or not their package is importable here."""
    monkeypatch.setattr(renderers, "BACKENDS", {"gl-raycast": "renderers.gl.not_here:RayCaster",
                                                "gl-slicer": "renderers.gl.not_here:Slicer", **renderers.BACKENDS})


def small_profile(scale="default", **settings):
    return Profile(name="t", scale=scale, volume_size=16, image_size=24, warmup=0, repeat=1, experiments=list(NAMES),
                   settings=settings)


def timed(seconds, *, group="", stage="total", **row):
    """A successful row whose ``stage`` was timed over the frames ``seconds``, in interleave ``group``."""
    return {**row, f"time_{stage}": float(np.median(seconds)), f"frames_{stage}": intervals.format_frames(seconds),
            "interleave": group, "experiment": "x"}


def five_frames(row, stage="total"):
    """``row`` with five timed frames of its ``time_<stage>`` (a timing claim needs five in an arm)."""
    return {**row, f"frames_{stage}": intervals.format_frames([row[f"time_{stage}"]] * 5)}


NOISY = [1.0, 1.0, 3.0, 1.0, 3.0]
"""Frames whose resampled median is 1 or 3: against steady frames, a ratio whose interval spans ×1–×3."""


def evaluate(experiment, claim_id, rows):
    """The result of claim ``claim_id`` of ``experiment`` on ``rows`` (dicts, as the successful rows)."""
    claim = next(c for c in experiments.get(experiment).claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def test_experiments_are_registered_with_the_paper():
    registry = experiments.all_experiments()
    for name in NAMES:
        experiment = registry[name]
        assert experiment.paper == "kruger2003" and experiment.title and experiment.description
        assert experiment.claims, name
    table = registry["kruger2003-table1"].paper_table()
    head = table[table["data set (paper)"] == "Head"].iloc[0]
    assert head["RC-b / RC"] == pytest.approx(23.4 / 4.8, abs=0.01)
    assert head["RC-b / SBVR"] == pytest.approx(3.3, abs=0.01)


def test_no_runs_without_the_gl_backends(monkeypatch):
    monkeypatch.setattr(renderers, "BACKENDS", {"reference": renderers.BACKENDS["reference"]})
    assert not [r for r in experiments.plan(small_profile()).values() if r.experiment.startswith("kruger2003")]


def test_plan_times_methods_and_renders_truth_once(monkeypatch):
    with_gl_backends(monkeypatch)
    runs = [r for r in experiments.plan(small_profile()).values() if r.experiment.startswith("kruger2003")]
    assert {r.experiment for r in runs} == set(NAMES)
    for run in runs:
        if run.backend == "reference":
            assert (run.warmup, run.repeat) == (0, 1), run.key
        else:
            assert run.warmup >= 1 and run.repeat >= 3, run.key
            assert "step_factor" in run.options, run.key
            # The occluder's plane hides the volume on purpose: those images have no truth.
            assert (run.reference is None) == (run.experiment == "kruger2003-occluder"), run.key
    table1 = [r for r in runs if r.experiment == "kruger2003-table1" and r.backend != "reference"]
    assert {r.tags["config"] for r in table1} == set(METHODS)
    assert {r.tags["scene"] for r in table1} == set(TABLE1)
    headline = table1[0].views[0]
    assert headline["view"] == "headline" and len(table1[0].views) == 3  # headline + 2 orbit views
    # One step for every method of a scene: the claims compare like with like.
    assert len({r.options["step_factor"] for r in table1}) == 1
    sweep = [r for r in runs if r.tags.get("part") == "m-sweep"]
    assert sorted(r.options["samples_per_pass"] for r in sweep) == list(M_VALUES)


def test_the_runs_a_timing_claim_compares_are_timed_together(monkeypatch):
    with_gl_backends(monkeypatch)
    runs = [r for r in experiments.plan(small_profile()).values() if r.experiment.startswith("kruger2003")]
    groups = {}
    for run in runs:
        if run.interleave:
            groups.setdefault((run.experiment, run.interleave), []).append(run)
    for (_, group), members in groups.items():
        assert all(m.backend != "reference" and m.repeat >= 3 for m in members), group
        assert len({tuple(v["view"] for v in m.views) for m in members}) == 1, f"{group}: views must pair"
    ids = {key: sorted(m.id for m in members) for key, members in groups.items()}
    for scene in TABLE1:  # Table 1's four methods per data set; ours and the peer alone
        assert ids["kruger2003-table1", scene] == sorted(f"{scene}.{c}" for c in ("sbvr", "rc", "rc-a", "rc-b"))
    assert ids["kruger2003-nocue", "no_cue"] == ["no_cue.rc", "no_cue.rc-a", "no_cue.rc-b"]
    assert ids["kruger2003-passes", "iso"] == ["foot-iso.rc-a", "foot.rc-a"]
    assert ids["kruger2003-passes", "m-sweep"] == sorted(f"foot.m{m}" for m in M_VALUES)
    assert ids["kruger2003-stability", "head.threshold"] == ["head.t0.8", "head.t0.9", "head.t0.95", "head.t0.99",
                                                             "head.t1"]
    assert {len(ids["kruger2003-occluder", c]) for c in ("rc", "rc-a")} == {5}
    assert len(groups) == len(TABLE1) + 1 + 2 + 4 + 2


def test_the_no_cue_control_is_seen_straight_at_a_face(monkeypatch):
    # From an oblique view rays through the cube's corners leave early and early termination culls them.
    with_gl_backends(monkeypatch)
    runs = [r for r in experiments.plan(small_profile()).values()
            if r.experiment in ("kruger2003-nocue", "kruger2003-occluder")]
    assert {(v["azimuth"], v["elevation"]) for r in runs for v in r.views} == {(0.0, 0.0)}


def test_profiles_name_only_known_settings_and_smoke_stays_small(monkeypatch):
    with_gl_backends(monkeypatch)
    for profile in ("smoke", "default", "full"):
        experiments.check_settings(Profile.load(ROOT / "config" / f"{profile}.yaml"))
    smoke = dataclasses.replace(Profile.load(ROOT / "config" / "smoke.yaml"), experiments=list(NAMES))
    smoke = list(experiments.plan(smoke).values())
    assert 0 < len(smoke) <= 48
    assert all(r.scene["width"] <= 64 for r in smoke)


def test_each_experiment_takes_its_own_smoke_settings_without_the_profiles(monkeypatch):
    with_gl_backends(monkeypatch)
    runs = [r for r in experiments.plan(small_profile("smoke")).values() if r.experiment.startswith("kruger2003")]
    assert {r.experiment for r in runs} == set(NAMES)
    assert {r.scene["width"] for r in runs} == {64}, "every experiment's smoke image_size"
    assert {r.scene["volumes"][0]["size"] for r in runs} == {32}, "every experiment's smoke volume_size"
    by = {name: [r for r in runs if r.experiment == name and r.backend != "reference"] for name in NAMES}
    assert {r.tags["scene"] for r in by["kruger2003-table1"]} == {"head"}
    assert {len(r.views) for r in by["kruger2003-table1"]} == {2}  # headline + one orbit view
    assert sorted(r.tags["m"] for r in by["kruger2003-passes"] if "m" in r.tags) == [2, 8, 32]
    assert {r.tags["value"] for r in by["kruger2003-stability"]} == {0.9, 1.0, 8, 16}
    assert {r.tags["fraction"] for r in by["kruger2003-occluder"]} == {0.0, 0.5, 1.0}


def test_a_method_whose_backend_is_not_registered_is_left_out(monkeypatch):
    monkeypatch.setattr(renderers, "BACKENDS", {"gl-raycast": "renderers.gl.not_here:RayCaster",
                                                "reference": renderers.BACKENDS["reference"]})
    runs = method_runs("x", "head", {"volumes": []}, ({"view": "headline"},), METHODS, 0.5, "head.truth",
                       {"scene": "head"}, {"warmup": 1, "repeat": 3})
    assert [r.tags["config"] for r in runs] == ["rc", "rc-a", "rc-b", "single-pass"]
    assert {r.reference for r in runs} == {"head.truth"} and {r.options["step_factor"] for r in runs} == {0.5}
