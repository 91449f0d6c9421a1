"""Tests of the experiments' kit (pipeline.experiments.kit): settings by scale, planning helpers, checks."""

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline.experiments.kit.checks import Band, Bound, Growth, Measure, Ratio
from pipeline.experiments.kit.intervals import format_frames
from pipeline.experiments.kit.judging import STRICTLY_ABOVE_ONE
from pipeline.experiments.kit.model import SIZES, Claim, Experiment, Paper, Profile, scaled
from pipeline.experiments.kit.pages import device_takeaways, gl_devices
from pipeline.experiments.kit.planning import listed, scene, truth_run
from pipeline.experiments.kit.results import nonempty


class Sweep(Experiment):
    name = "test-sweep"
    settings = frozenset({"counts", "image_size"})
    scales = {"smoke": {"counts": [1, 2]}, "full": {"counts": [1, 2, 4, 8], "image_size": 512}}


def test_an_experiment_takes_its_own_settings_for_the_profiles_scale_and_the_profile_overrides_them():
    sweep = Sweep()
    assert Profile(name="a", scale="smoke").setting(sweep, "counts", [1]) == [1, 2]
    assert Profile(name="b", scale="full").setting(sweep, "image_size", 64) == 512
    assert Profile(name="c", scale="default").setting(sweep, "counts", [1]) == [1]  # no default scale: the default
    overridden = Profile(name="d", scale="full", settings={"test-sweep": {"counts": [3]}})
    assert overridden.setting(sweep, "counts", [1]) == [3] and overridden.setting(sweep, "image_size", 64) == 512
    assert overridden.setting("test-sweep", "image_size", 64) == 64  # by name: the profile's overrides alone
    with pytest.raises(InputError, match="scale: expected one of smoke, default, full"):
        Profile(name="e", scale="huge")


def test_scaled_adds_an_experiments_own_settings_to_a_shared_base_at_each_scale():
    assert scaled() == SIZES and scaled() is not SIZES
    lens = scaled(smoke={"orbit": 0}, full={"image_size": 1024, "orbit": 2})
    assert lens == {"smoke": {"volume_size": 32, "image_size": 48, "orbit": 0}, "default": SIZES["default"],
                    "full": {"volume_size": 256, "image_size": 1024, "orbit": 2}}
    assert SIZES["full"] == {"volume_size": 256, "image_size": 512}  # the base is left as it was
    # A paper's own base, one scale of it extended, and a scale neither gives left out.
    assert scaled(base=lens, full={"scenes": ["skull"]})["full"] == {**lens["full"], "scenes": ["skull"]}
    assert scaled(base={"full": {"repeat": 15}}, smoke={"views": 1}) == {"smoke": {"views": 1}, "full": {"repeat": 15}}
    sweep = type("Lens", (Experiment,), {"name": "test-lens", "scales": lens})()
    assert Profile(name="f", scale="full").setting(sweep, "image_size", 64) == 1024
    assert Profile(name="d", scale="default").setting(sweep, "orbit", 1) == 1  # not set at that scale


def test_listed_names_the_unknown_values():
    profile = Profile(name="p", scale="smoke", settings={"test-sweep": {"counts": [1, 3]}})
    with pytest.raises(InputError, match=r"settings.test-sweep.counts: unknown \[3\]"):
        listed(profile, Sweep(), "counts", [1], known=(1, 2))


def test_a_paper_must_be_a_known_id():
    assert Paper("kainz2009", "cl-tiled", baselines=("gl-peel",)).backends == ("cl-tiled", "gl-peel")
    with pytest.raises(InputError, match="not in core.papers.PAPERS"):
        Paper("doe2024", "x")


def test_scenes_hold_only_what_they_use_and_truth_runs_are_one_untimed_reference_frame():
    plain = scene("s", 32, volumes=[{"dataset": "sphere"}])
    assert set(plain) == {"name", "width", "height", "mode", "shading", "volumes"} and plain["width"] == 32
    assert scene("s", 32, width=48, meshes=[{"generator": "cube"}], camera={"view_height": 2})["width"] == 48
    truth = truth_run("e", "s", plain, ({"view": "v"},), 0.125, {"scene": "s", "role": "test"}, config="reference")
    assert (truth.id, truth.backend, truth.warmup, truth.repeat) == ("s.truth", "reference", 0, 1)
    assert truth.tags == {"scene": "s", "role": "truth", "config": "reference"}
    assert truth.options == {"step_factor": 0.125}


def _times(**columns):
    return pd.DataFrame({"status": "ok", **columns})


def test_a_ratio_check_computes_its_verdict_and_words():
    df = _times(config=["rc", "rc", "rc-b"], time_total=[0.010, 0.012, 0.004])
    check = Ratio(Measure("RC", match={"config": "rc"}), Measure("RC-b", match={"config": "rc-b"}), at_least=2.5)
    result = check(df)  # times without their frames: measured, but nothing to decide them on
    assert (result.measured, result.holds, result.inconclusive) == ("×2.75", None, True)  # median 11 ms over 4 ms
    assert result.detail == "RC 11 ms, RC-b 4 ms; inconclusive: no timed frames behind RC, RC-b"
    assert check.expected == "RC / RC-b ≥ ×2.5"
    with pytest.raises(ValueError, match="no successful run of RC-b"):
        check(df[df.config == "rc"])


def test_bound_band_and_growth():
    df = _times(scene=["a", "b"], psnr=[41.0, 38.5])
    floor = Bound(Measure("the worst image", column="psnr", statistic="min", unit="dB"), at_least=40)
    assert (floor(df).measured, floor(df).holds, floor.expected) == ("38.5 dB", False, "the worst image ≥ 40 dB")
    named = Bound(Measure("the worst image", column="psnr", statistic="min", unit="dB", label="scene"), at_least=38)
    assert (named(df).measured, named(df).holds) == ("38.5 dB (b)", True)
    band = Band(Measure("fraction", column="psnr", statistic="max", unit=""), target=40, relative=0.01, absolute=2)
    assert band(df).holds is True and band.expected == "40 ± 2"
    sizes = _times(size=[32, 64, 128, 256], time_total=[1.0, 8.0, 64.0, 512.0])
    cubic = Growth(Measure("frame time"), "size", at_most=3.2)
    assert (cubic(sizes).measured, cubic(sizes).holds) == ("3", None)  # no frames: inconclusive
    framed = pd.DataFrame([_framed(t, size=n) for n, t in ((32, 1.0), (64, 8.0), (128, 64.0), (256, 512.0))])
    assert cubic(framed).measured.startswith("3 (95 % CI") and cubic(framed).holds is True
    short = framed.assign(frames_total=[format_frames([t] * 3) for t in framed.time_total])
    assert cubic(short).inconclusive and "size 32: 3 timed frames" in cubic(short).detail
    with pytest.raises(ValueError, match="need three values of size"):
        cubic(sizes.iloc[:2])


NOISE = 1 + 0.02 * np.random.default_rng(5).standard_normal(30)
"""Thirty frames' relative noise (2 %)."""


def _framed(seconds, **tags):
    """A row timed over thirty frames around ``seconds``: its median and its frames, as collect writes them."""
    frames = seconds * NOISE
    return {"status": "ok", "view": "front", **tags, "time_total": float(np.median(frames)),
            "frames_total": format_frames(frames)}


def test_a_ratio_on_timed_frames_has_an_interval_and_a_margin_and_may_be_inconclusive():
    df = pd.DataFrame([_framed(0.011, run="a", config="rc"), _framed(0.004, run="b", config="rc-b")])
    check = Ratio(Measure("RC", match={"config": "rc"}), Measure("RC-b", match={"config": "rc-b"}), at_least=2.5)
    result = check(df)
    low, high = result.interval
    assert 2.5 < low < 2.75 < high and result.holds is True and not result.inconclusive
    assert result.margin == pytest.approx(0.1, abs=0.01)
    assert result.measured == f"×2.75 (95 % CI ×{low:.3g}–×{high:.3g})"
    straddling = Ratio(check.numerator, check.denominator, at_least=2.75)(df)
    assert straddling.inconclusive and straddling.holds is None and straddling.interval == result.interval
    assert Ratio(check.numerator, check.denominator, at_least=3.0)(df).holds is False
    plain = check(df.drop(columns="frames_total"))  # results written before frames were kept: not decided
    assert (plain.measured, plain.holds, plain.interval, plain.inconclusive) == ("×2.75", None, None, True)
    # A tie does not make "faster": equal frames, timed together, fail a strict bound and hold an inclusive one.
    tie = pd.DataFrame([_framed(0.004, run="a", config="rc", interleave="g", experiment="x"),
                        _framed(0.004, run="b", config="rc-b", interleave="g", experiment="x")])
    assert Ratio(check.numerator, check.denominator, at_least=STRICTLY_ABOVE_ONE)(tie).holds is False
    assert Ratio(check.numerator, check.denominator, at_least=1.0)(tie).holds is True


def test_a_bound_on_a_time_has_an_interval_in_seconds():
    df = pd.DataFrame([_framed(0.010, scene="a"), _framed(0.012, scene="b")])
    ceiling = Bound(Measure("the slowest frame", statistic="max"), at_most=0.0125)
    result = ceiling(df)
    low, high = result.interval
    assert low < 0.012 < high < 0.0125 and result.holds is True
    assert result.margin == pytest.approx(0.04, abs=0.005)
    straddling = Bound(ceiling.measure, at_most=0.012)(df)
    assert straddling.inconclusive and straddling.holds is None
    psnr = Bound(Measure("the worst image", column="psnr", statistic="min", unit="dB"), at_least=40)
    assert psnr(df.assign(psnr=[41.0, 42.0])).interval is None  # a metric has no frames


def test_a_growth_exponent_on_timed_frames_has_an_interval():
    sizes = pd.DataFrame([_framed(1e-3 * (size / 32) ** 3, size=size) for size in (32, 64, 128, 256)])
    cubic = Growth(Measure("frame time"), "size", at_most=3.2)
    result = cubic(sizes)
    low, high = result.interval
    assert low < 3.0 < high < 3.2 and result.holds is True and result.margin == pytest.approx(0.2 / 3.2, abs=0.01)
    straddling = Growth(Measure("frame time"), "size", at_most=3.0)(sizes)
    assert straddling.inconclusive and straddling.holds is None
    assert Growth(Measure("frame time"), "size", at_least=3.5)(sizes).holds is False


def test_device_takeaways_name_the_devices_and_add_the_papers_note_for_a_cpu_rasterizer():
    rows = pd.DataFrame({"gl_renderer": ["llvmpipe", "llvmpipe", None], "vtk_gl_renderer": [None, None, "llvmpipe"],
                         "gl_software_rasterizer": [True, True, True]})
    assert list(gl_devices(rows)) == ["llvmpipe"] * 3
    assert device_takeaways(rows, software="only ratios count") == [
        "Frame times on this page were measured on llvmpipe, a CPU rasterizer: only ratios count."]
    mixed = rows.assign(gl_renderer=["llvmpipe", "NVIDIA H100", None], gl_software_rasterizer=[True, False, True])
    (sentence,) = device_takeaways(mixed, software="only ratios count")
    assert "NVIDIA H100" in sentence and "per device" in sentence and "only ratios" not in sentence
    assert device_takeaways(rows.iloc[:0], software="x") == []


def test_a_claim_knows_what_it_measures_from_its_check_or_declares_it():
    from pipeline.experiments import all_experiments
    from pipeline.experiments.kit.model import CLAIM_KINDS, Claim

    times = Ratio(Measure("RC", match={"config": "rc"}), Measure("RC-b", match={"config": "rc-b"}), at_least=1.5)
    assert Claim("faster", "RC-b is faster", times.expected, times).kind == "timing"
    psnr = Bound(Measure("the worst image", column="psnr", statistic="min", unit="dB"), at_least=40)
    assert Claim("accurate", "It is accurate", psnr.expected, psnr).kind == "accuracy"
    fragments = Bound(Measure("fragments", column="count_fragments_main", unit=""), at_most=10)
    assert Claim("few", "Few fragments", fragments.expected, fragments).kind == "count"
    with pytest.raises(ValueError, match="measures one kind"):
        Claim("mixed", "Mixed", "", Ratio(times.numerator, psnr.measure, at_least=1.0))
    # A check written by hand says what it measures; a typo is refused too.
    with pytest.raises(ValueError, match="'by-hand'.*kind=") as missing:
        Claim("by-hand", "A statement", "a bound", lambda df: None)
    assert "timing, count, accuracy, cost model" in str(missing.value)
    with pytest.raises(ValueError, match="'timings' is not one of"):
        Claim("typo", "A statement", "a bound", lambda df: None, kind="timings")
    assert Claim("by-hand", "A statement", "a bound", lambda df: None, kind="cost model").kind == "cost model"
    kinds = {claim.kind for experiment in all_experiments().values() for claim in experiment.claims}
    assert kinds == set(CLAIM_KINDS)


def test_with_ours_puts_our_target_right_after_the_papers_number_with_its_value_and_kind():
    paper_check = Ratio(Measure("RC", match={"config": "rc"}), Measure("RC-b", match={"config": "rc-b"}), at_least=3.0)
    ours_check = Ratio(paper_check.numerator, paper_check.denominator, at_least=1.0)
    twin = Claim("gain-paper", "RC-b is 3× faster (paper)", paper_check.expected, paper_check, paper_value="×3")
    paper, ours = twin.with_ours("RC-b is faster", ours_check.expected, ours_check, why="faster at all: another device")
    assert paper is twin and (paper.id, paper.target, paper.ours) == ("gain-paper", "paper", "")
    assert (ours.id, ours.statement, ours.check) == ("gain", "RC-b is faster", ours_check)
    assert ours.expected == "RC / RC-b ≥ ×1"
    assert (ours.target, ours.ours, ours.paper_value) == ("ours", "faster at all: another device", "×3")
    assert ours.kind == paper.kind == "timing"
    # Only the paper's number takes ours beside it: ours would have no twin named after it.
    for claim in (Claim("gain", "RC-b is faster", "", paper_check),
                  Claim("gain-paper", "RC-b is faster", "", paper_check, ours="why")):
        with pytest.raises(ValueError, match="'<id>-paper', takes ours"):
            claim.with_ours("x", "y", ours_check, why="z")


def test_nonempty_passes_what_was_found_and_names_what_was_not():
    rows = pd.DataFrame({"scene": ["foot"]})
    assert nonempty(rows, what="the foot") is rows
    assert nonempty(["foot"]) == ["foot"]
    with pytest.raises(ValueError, match="^no successful run of the foot at 512²$"):
        nonempty(rows.iloc[:0], what="the foot at 512²")
    with pytest.raises(ValueError, match="^no successful run$"):
        nonempty([])
