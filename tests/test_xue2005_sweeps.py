"""``xue2005-tf`` (E10): the transfer functions it plans and its claims on synthetic results.

Also the helpers ``test_xue2005_fuzziness`` shares.
"""

import numpy as np
import pandas as pd
import pytest

import renderers
from core.errors import InputError
from core.transfer import TransferFunction
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kit import intervals
from pipeline.experiments.xue2005.sweeps import PAPER_ISO, ramp_points, summary, sweep_pairs
from renderers.gl import isosurfaces

NAME = "xue2005-tf"

NOISY = [1.0, 1.0, 3.0, 1.0, 3.0]
"""Frame factors whose resampled median is 1 or 3: against steady frames, a ratio whose interval spans ×1–×3."""


def with_isbvr(monkeypatch):
    """The registry with ``gl-isbvr``, whether or not its package is importable here."""
    monkeypatch.setattr(renderers, "BACKENDS", {"gl-isbvr": "renderers.gl.not_here:Isbvr", **renderers.BACKENDS})


def planned(name, scale="default", **settings):
    profile = Profile(name="t", scale=scale, volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[name],
                      settings={name: settings} if settings else {})
    return [r for r in experiments.plan(profile).values() if r.experiment == name]


def timed(seconds, *, group, **row):
    """A successful row timed over the frames ``seconds`` (whole frames), in interleave ``group``."""
    return {"experiment": "x", "interleave": group, "view": "headline", "time_total": float(np.median(seconds)),
            "frames_total": intervals.format_frames(seconds), **row}


def evaluate(experiment, claim_id, rows):
    """The result of claim ``claim_id`` of ``experiment`` on ``rows`` (dicts, as the successful rows)."""
    claim = next(c for c in experiments.get(experiment).claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def mode_row(scene, tf, kind, config, ms, *, generated=1000, shaded=None, cubes_p=5, surface_p=10, iso=(50, 170)):
    """One mode of one transfer function: frames of ``ms`` milliseconds (a number: five steady frames)."""
    frames = [ms * 1e-3] * 5 if np.isscalar(ms) else [m * 1e-3 for m in ms]
    return timed(frames, group=f"{scene}.{tf}", run=f"{scene}.{tf}.{config}", scene=scene, tf=tf, kind=kind,
                 config=config, iso_t=iso[0], iso_p=iso[1], count_fragments_generated=generated,
                 count_fragments=generated if shaded is None else shaded, count_init_fragments=50, count_cubes_t=20,
                 count_cubes_p=cubes_p, count_surface_fragments_t=30, count_surface_fragments_p=surface_p,
                 count_surface_triangles_t=240, count_surface_triangles_p=120)


def ramps(speedups, scene="head"):
    """Basic at 10 ms and ESS+ERT at 10 / s ms for each speed-up ``s``, one iso_t each."""
    rows = []
    for k, s in enumerate(speedups):
        tf = f"t{10 * (k + 1)}-p170"
        rows += [mode_row(scene, tf, "ramp", "basic", 10.0, iso=(10 * (k + 1), 170)),
                 mode_row(scene, tf, "ramp", "ess+ert", 10.0 / s, shaded=round(1000 / s), iso=(10 * (k + 1), 170))]
    return rows


def controls(ratio=1.0, *, shaded=1000, frames=None):
    """The "neither" controls and the dense block: ESS+ERT at ``ratio`` times Basic's 10 ms."""
    rows = []
    for scene, tf, kind in (("head", "neither", "neither"), ("aneurysm", "neither", "neither"),
                            ("dense", "no_cue", "dense")):
        rows += [mode_row(scene, tf, kind, "basic", 10.0),
                 mode_row(scene, tf, kind, "ess+ert", frames or 10.0 * ratio, shaded=shaded, cubes_p=0, surface_p=0)]
    return rows


def never_opaque(ratio=1.0, *, cubes_p=0, frames=None):
    rows = []
    for scene in ("head", "aneurysm"):
        rows += [mode_row(scene, "never-opaque", "never-opaque", "basic", 10.0),
                 mode_row(scene, "never-opaque", "never-opaque", "ess", 5.0, shaded=400, cubes_p=0, surface_p=0),
                 mode_row(scene, "never-opaque", "never-opaque", "ess+ert", frames or 5.0 * ratio, shaded=400,
                          cubes_p=cubes_p, surface_p=0)]
    return rows


# -------------------------------------------------------------------------------------------- plan
def _analysis(points):
    return isosurfaces.analyse(TransferFunction.from_points(points["points"]).table[:, 3])


def test_every_transfer_function_is_one_group_with_basic_and_the_images_against_it(monkeypatch):
    with_isbvr(monkeypatch)
    runs = planned(NAME)
    groups = {}
    for run in runs:
        groups.setdefault(run.interleave, []).append(run)
        assert run.options["step_factor"] == 1.0 and run.repeat >= 3, run.id
        assert run.reference == (None if run.tags["config"] == "basic" else f"{run.interleave}.basic"), run.id
    configs = {group: sorted(r.tags["config"] for r in members) for group, members in groups.items()}
    assert configs["head.never-opaque"] == ["basic", "ess", "ess+ert"]
    assert configs["dense.no_cue"] == configs["head.neither"] == configs["aneurysm.t50-p150"] == ["basic", "ess+ert"]
    assert {r.tags["kind"] for r in runs} == {"ramp", "neither", "never-opaque", "dense"}
    for scene, (t, p) in PAPER_ISO.items():
        pairs = {(r.tags["iso_t"], r.tags["iso_p"]) for r in runs
                 if r.tags["scene"] == scene and r.tags["kind"] == "ramp"}
        assert (t, p) in pairs and all(a < b for a, b in pairs)
        assert {a for a, b in pairs if b == p} >= {10, 50, 120} and {b for a, b in pairs if a == t} >= {100, p, 240}
    # One TF per group, the same views in every run of a group.
    for members in groups.values():
        assert len({str(m.scene["volumes"]) for m in members}) == 1
        assert len({str(m.views) for m in members}) == 1


def test_the_transfer_functions_have_the_properties_their_kind_names(monkeypatch):
    with_isbvr(monkeypatch)
    for run in planned(NAME, scale="smoke"):
        volume = run.scene["volumes"][0]
        if run.tags["kind"] == "dense":
            assert volume == {"dataset": "fbm_control", "size": 32, "preset": "no_cue"}
            continue
        found = _analysis(volume["transfer_function"])
        expected = {"ramp": (True, True), "neither": (False, False), "never-opaque": (True, False)}[run.tags["kind"]]
        assert (found.has_empty, found.has_opaque) == expected, run.id
        if run.tags["kind"] == "ramp":  # opacity leaves 0 just above iso_t and reaches 1 at iso_p
            assert run.tags["iso_t"] / 255 <= found.iso_t <= (run.tags["iso_t"] + 1) / 255
            assert found.iso_p == pytest.approx(run.tags["iso_p"] / 255, abs=0.5 / 255)


def test_smoke_is_small_and_settings_are_checked(monkeypatch):
    with_isbvr(monkeypatch)
    smoke = planned(NAME, scale="smoke")
    assert len(smoke) <= 24 and {r.scene["width"] for r in smoke} == {48} and {len(r.views) for r in smoke} == {1}
    assert len({len(r.views) for r in planned(NAME, scale="full")} - {1}) == 1  # orbit views at paper scale
    with pytest.raises(InputError, match="grey levels"):
        planned(NAME, iso_t=[300])
    with pytest.raises(InputError, match="unknown"):
        planned(NAME, scenes=["bonsai"])
    with pytest.raises(InputError, match="iso_t < iso_p"):
        ramp_points("ct_skull", 170, 50)
    assert sweep_pairs("head", [10, 200], [40, 100]) == [(50.0, 170.0), (10.0, 170.0), (50.0, 100.0)]


# ------------------------------------------------------------------------------------------ claims
def test_iso_dependence_compares_the_best_and_the_worst_pair_of_each_scene():
    strong = ramps([1.2, 2.0, 3.0]) + ramps([1.0, 1.6], scene="aneurysm")
    result = evaluate(NAME, "iso-dependence", strong)
    assert result.holds is True and result.measured.startswith("best / worst pair's speed-up ×1.6 ")
    assert "head: best t30-p170 ×3" in result.detail and "worst t10-p170 ×1.2" in result.detail
    weak = ramps([1.2, 2.0, 3.0]) + ramps([1.0, 1.3], scene="aneurysm")
    assert evaluate(NAME, "iso-dependence", weak).holds is False
    noisy = ramps([1.0, 1.6], scene="aneurysm")
    noisy[-1] = mode_row("aneurysm", "t20-p170", "ramp", "ess+ert", [10.0 / 1.6 * f for f in NOISY],
                         iso=(20, 170))
    assert evaluate(NAME, "iso-dependence", noisy).inconclusive
    assert evaluate(NAME, "iso-dependence", ramps([2.0])).holds is None  # one pair: nothing to compare


def test_no_overhead_is_judged_in_the_band_on_every_control():
    assert evaluate(NAME, "no-overhead", controls(1.02)).holds is True
    slow = evaluate(NAME, "no-overhead", controls(1.1))
    assert slow.holds is False and "×1.1" in slow.measured
    assert evaluate(NAME, "no-overhead", controls(0.9)).holds is False  # faster is not "no overhead" either
    assert evaluate(NAME, "no-overhead", controls(frames=[10.0 * f for f in NOISY])).inconclusive


def test_nothing_culled_needs_every_fragment_shaded():
    assert evaluate(NAME, "nothing-culled", controls()).holds is True
    off = evaluate(NAME, "nothing-culled", controls(shaded=991))
    assert off.holds is False and off.measured.startswith("F − F'_c = 9 ")


def test_ert_without_an_opaque_region_must_cost_and_cull_nothing():
    assert evaluate(NAME, "ert-free-without-opaque", never_opaque()).holds is True
    assert evaluate(NAME, "ert-free-without-opaque", never_opaque(1.2)).holds is False
    drawn = evaluate(NAME, "ert-free-without-opaque", never_opaque(cubes_p=4))
    assert drawn.holds is False and "4 Φ_p cubes" in drawn.detail


def test_the_summary_has_each_transfer_function_with_its_interval_and_culled_fraction():
    table = summary(pd.DataFrame(ramps([2.0]) + controls(1.0, shaded=990)))
    assert list(table.tf) == ["t10-p170", "neither", "neither", "no_cue"]
    first = table.iloc[0]
    assert first.speedup == pytest.approx(2.0) and first.low == pytest.approx(2.0) and first.high == pytest.approx(2.0)
    assert first.alpha == pytest.approx(0.5) and first.phi == pytest.approx(0.04)
    assert table.alpha.iloc[1] == pytest.approx(0.01)
