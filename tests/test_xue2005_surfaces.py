"""``xue2005-surfaces``: what it plans and its claims on synthetic results.

Also the helpers ``test_xue2005_octree`` and ``test_xue2005_extraction`` share.
"""

import numpy as np
import pandas as pd
import pytest

import renderers
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kit import intervals
from reports.imageio import write_exr

NAME = "xue2005-surfaces"
NOISY = [1.0, 1.0, 3.0, 1.0, 3.0]
"""Frames whose resampled median is 1 or 3: against steady frames, a ratio whose interval spans ×1–×3."""


def with_isbvr(monkeypatch):
    """The registry with ``gl-isbvr``, whether or not its package is importable here."""
    monkeypatch.setattr(renderers, "BACKENDS", {"gl-isbvr": "renderers.gl.not_here:Isbvr", **renderers.BACKENDS})


def profile(scale="default", **settings):
    return Profile(name="t", scale=scale, volume_size=16, image_size=24, warmup=0, repeat=1,
                   experiments=["xue2005-surfaces", "xue2005-octree", "xue2005-extraction"], settings=settings)


def planned(experiment, scale="default", **settings):
    """The runs ``experiment`` plans at ``scale`` with its ``settings`` overridden."""
    chosen = profile(scale, **({experiment: settings} if settings else {}))
    return [r for r in experiments.plan(chosen).values() if r.experiment == experiment]


def evaluate(experiment, claim_id, rows):
    """The result of claim ``claim_id`` of ``experiment`` on ``rows`` (dicts, as the successful rows)."""
    claim = next(c for c in experiments.get(experiment).claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def frames(seconds, stage, group="g"):
    """Columns of a stage timed over the frames ``seconds`` in interleave ``group``."""
    return {f"time_{stage}": float(np.median(seconds)), f"frames_{stage}": intervals.format_frames(seconds),
            "interleave": group, "experiment": "x"}


def image(path, off_share=0.0, size=20, error=0.05):
    """An EXR at ``path``: a grey square with ``off_share`` of its pixels brighter by ``error``."""
    pixels = np.full((size, size, 4), 0.5, np.float32)
    flat = pixels.reshape(-1, 4)
    flat[:int(round(off_share * size * size)), :3] += error
    write_exr(str(path), pixels)
    return str(path)


def picture_rows(tmp_path, shares, *, match=None, scenes=("bonsai", "head")):
    """A Basic row and a row per ``shares`` key (its share of pixels off) for each scene, with images."""
    rows = []
    for scene in scenes:
        basic = f"{scene}.basic"
        rows.append({"scene": scene, "view": "headline", "run": basic, "variant": "basic", "config": "basic",
                     "reference": None, "exr": image(tmp_path / f"{basic}.exr")})
        for key, share in shares.items():
            run = f"{scene}.{key}"
            tags = match or {"variant": key, "config": "ess+ert"}
            rows.append({"scene": scene, "view": "headline", "run": run, "reference": basic,
                         "exr": image(tmp_path / f"{run}.exr", share), **tags})
    return rows


def test_plan_times_basic_with_each_surface_kind_per_scene(monkeypatch):
    with_isbvr(monkeypatch)
    runs = planned(NAME)
    groups = {}
    for run in runs:
        groups.setdefault(run.interleave, []).append(run)
    assert set(groups) == {"bonsai", "head"}
    for scene, members in groups.items():
        by = {r.tags["variant"]: r for r in members}
        assert set(by) == {"basic", "reduced", "coarse", "full"}
        assert by["basic"].options["zinit"] == "none" and by["basic"].reference is None
        for kind in ("reduced", "coarse", "full"):
            assert by[kind].options["zinit"] == "ess+ert" and by[kind].options["surfaces"] == kind
            assert by[kind].reference == by["basic"].id
        assert len({tuple(v["view"] for v in r.views) for r in members}) == 1, "views must pair"
        assert all(r.repeat >= 3 and r.warmup >= 1 for r in members)
    assert {r.scene["volumes"][0]["dataset"] for r in runs} == {"bonsai_like", "ct_skull"}
    assert {r.scene["volumes"][0]["preset"] for r in runs} == {"isbvr"}


def test_scales_set_sizes_and_views(monkeypatch):
    with_isbvr(monkeypatch)
    smoke, default, full = (planned(NAME, scale) for scale in ("smoke", "default", "full"))
    assert {(r.scene["volumes"][0]["size"], r.scene["width"], len(r.views)) for r in smoke} == {(32, 48, 1)}
    assert {(r.scene["volumes"][0]["size"], r.scene["width"], len(r.views)) for r in default} == {(128, 256, 3)}
    assert {(r.tags["size"], r.scene["width"]) for r in full} == {(256, 512)}
    assert [r.tags["scene"] for r in planned(NAME, scenes=["head"])] == ["head"] * 4


def test_the_cube_sets_must_render_basics_image(tmp_path):
    assert evaluate(NAME, "reduced-lossless", picture_rows(tmp_path, {"reduced": 0.0})).holds is True
    result = evaluate(NAME, "reduced-lossless", picture_rows(tmp_path, {"reduced": 0.01}))
    assert result.holds is False and "1 % of pixels off" in result.measured
    # 0.5 % of the pixels off by 2/255: over 50 dB, but more pixels off than lossless allows.
    speckled = picture_rows(tmp_path, {"reduced": 0.0})
    speckled[1]["exr"] = image(tmp_path / "speckled.exr", 0.005, error=2 / 255)
    result = evaluate(NAME, "reduced-lossless", speckled)
    assert result.holds is False
    assert result.measured == "66.4 dB (bonsai, headline); 0.5 % of pixels off by > 1/255 (bonsai, headline)"
    # Below 1/255 is not off, but it still lowers the PSNR under 50 dB when it covers the image.
    faint = picture_rows(tmp_path, {"reduced": 0.0})
    faint[1]["exr"] = image(tmp_path / "faint.exr", 1.0, error=0.003)
    assert evaluate(NAME, "reduced-lossless", faint).holds is True
    faint[1]["exr"] = image(tmp_path / "faint.exr", 1.0, error=0.0039)
    assert evaluate(NAME, "reduced-lossless", faint).holds is False


def test_coarse_surfaces_must_be_visibly_wrong_in_every_image(tmp_path):
    assert evaluate(NAME, "coarse-visibly-wrong", picture_rows(tmp_path, {"coarse": 0.05})).holds is True
    rows = picture_rows(tmp_path, {"coarse": 0.05})
    rows[-1]["exr"] = image(tmp_path / "almost.exr", 0.005)  # the head's image is nearly right
    result = evaluate(NAME, "coarse-visibly-wrong", rows)
    assert result.holds is False and "(head, headline)" in result.measured
    missing = picture_rows(tmp_path, {"coarse": 0.05})
    missing[-1]["reference"] = "head.other"
    assert evaluate(NAME, "coarse-visibly-wrong", missing).holds is None


def _counted(triangles, size=128):
    """Rows of both scenes with ``{variant: (Φ_t, Φ_p) triangles}``."""
    return [{"scene": scene, "view": "headline", "variant": variant, "size": size,
             "count_surface_triangles_t": t, "count_surface_triangles_p": p}
            for scene in ("bonsai", "head") for variant, (t, p) in triangles.items()]


def test_full_resolution_triangles_far_above_the_cube_sets():
    assert evaluate(NAME, "full-triangles", _counted({"full": (9e4, 2e4), "reduced": (2e3, 5e3)})).holds is True
    result = evaluate(NAME, "full-triangles", _counted({"full": (9e3, 2e3), "reduced": (2e3, 5e3)}))
    assert result.holds is False and result.measured == "×1.57 (bonsai)"


def test_a_million_triangles_is_judged_at_the_papers_size_only():
    small = evaluate(NAME, "full-million", _counted({"full": (3e5, 1e5)}))
    assert small.holds is None and small.measured == "not measured at 128³"
    assert "about 1.2e+06 at 256³" in small.detail
    assert evaluate(NAME, "full-million", _counted({"full": (1.2e6, 1e5)}, size=256)).holds is True
    assert evaluate(NAME, "full-million", _counted({"full": (7e5, 6e5)}, size=256)).holds is False


def _timed(stages, variants=("reduced",), scenes=("bonsai", "head"), views=("headline", "orbit000")):
    """Rows whose stages were timed over ``stages[variant][stage]`` (milliseconds), one group per scene."""
    rows = []
    for scene in scenes:
        for variant in variants:
            for view in views:
                row = {"scene": scene, "view": view, "variant": variant, "run": f"{scene}.{variant}",
                       "count_fragments": 100}
                for stage, ms in stages[variant].items():
                    row.update(frames([m * 1e-3 for m in ms], stage, group=scene))
                rows.append(row)
    return rows


def test_init_passes_small_beside_the_volume_pass_with_an_interval():
    steady = evaluate(NAME, "cube-init-small", _timed({"reduced": {"init": [1.0] * 5, "draw": [100.0] * 5}}))
    assert steady.holds is True and steady.interval == pytest.approx((0.01, 0.01))
    costly = evaluate(NAME, "cube-init-small", _timed({"reduced": {"init": [20.0] * 5, "draw": [100.0] * 5}}))
    assert costly.holds is False and costly.measured.startswith("T_a / T_m 0.2")
    # The init passes of some frames ten times slower: the interval straddles the bound.
    noisy = _timed({"reduced": {"init": [8.0 * f for f in NOISY], "draw": [100.0] * 5}})
    assert evaluate(NAME, "cube-init-small", noisy).inconclusive


def test_full_resolution_surfaces_erode_the_speed_up_when_slower():
    technique = {"basic": {"technique": [100.0] * 5}, "reduced": {"technique": [40.0] * 5, "init": [1.0] * 5,
                                                                   "draw": [39.0] * 5}}
    slower = _timed({**technique, "full": {"technique": [60.0] * 5, "init": [25.0] * 5, "draw": [35.0] * 5}},
                    variants=("basic", "reduced", "full"))
    result = evaluate(NAME, "full-erodes", slower)
    assert result.holds is True and result.measured.startswith("time full / cube sets ×1.5")
    assert "Basic / ESS+ERT ×2.5 (95 % CI ×2.5–×2.5) with the cube sets, ×1.67" in result.detail
    faster = _timed({**technique, "full": {"technique": [30.0] * 5, "init": [5.0] * 5, "draw": [25.0] * 5}},
                    variants=("basic", "reduced", "full"))
    assert evaluate(NAME, "full-erodes", faster).holds is False
    # The paper's statement is stronger: no speed-up over Basic is left. Slower than the cube sets is not
    # enough while the full surfaces still beat Basic (×1.67 here).
    paper = evaluate(NAME, "full-erodes-paper", slower)
    assert paper.holds is False and paper.measured.startswith("Basic / ESS+ERT with full-resolution surfaces ×1.67")
    offset = _timed({**technique, "full": {"technique": [120.0] * 5, "init": [60.0] * 5, "draw": [60.0] * 5}},
                    variants=("basic", "reduced", "full"))
    assert evaluate(NAME, "full-erodes-paper", offset).holds is True


def test_no_runs_without_the_isbvr_backend(monkeypatch):
    monkeypatch.setattr(renderers, "BACKENDS", {"reference": renderers.BACKENDS["reference"]})
    for name in (NAME, "xue2005-octree", "xue2005-extraction"):
        assert planned(name) == [], name
