"""The OpenGL ray caster (Krüger & Westermann 2003): images against the reference for every variant
and mode, early termination within its bound, conservative empty-space skipping, pass counts,
the min–max grid and CT table, caching, options and capabilities."""

import math

import numpy as np
import pytest

import renderers
from core.camera import Camera
from core.errors import InputError, UnsupportedFeatureError
from core.scene import Scene, Shading, VolumeInstance
from core.transfer import GradientOpacity, TransferFunction
from core.volume import Volume
from renderers.gl import context, emptyspace
from renderers.gl.raycast import GLRaycastRenderer
from renderers.gl.view import ray_lengths
from reports.metrics import psnr

GL_OK, GL_REASON = context.probe()
needs_gl = pytest.mark.skipif(not GL_OK, reason=f"no OpenGL 4.3 context through EGL here: {GL_REASON}")


def blob(n=36, seed=0, dtype=np.uint8):
    """A smooth blob with internal structure, zero at the box faces."""
    z, y, x = np.meshgrid(*(np.arange(n) + 0.5,) * 3, indexing="ij")
    r = np.sqrt((x - n / 2) ** 2 + (y - n / 2) ** 2 + (z - n / 2) ** 2)
    field = np.clip(1 - r / (0.42 * n), 0, 1)
    phase = np.random.default_rng(seed).uniform(0, 6, 3)
    field = np.clip(field + 0.15 * np.sin(x / 3 + phase[0]) * np.cos(y / 4 + phase[1]) * (field > 0), 0, 1)
    if dtype == np.float32:
        return Volume((np.round(field * 255) / 255).astype(np.float32), name="blob-f32")
    return Volume((field * 255).astype(np.uint8), name="blob")


SMOOTH = TransferFunction.from_points([(0, 1, 0.5, 0.2, 0), (0.15, 1, 0.5, 0.2, 0), (0.5, 0.3, 0.8, 1, 0.5),
                                       (1, 1, 1, 1, 0.9)], name="smooth")
OPAQUE = TransferFunction.from_points([(0, 1, 1, 1, 0), (0.3, 1, 0.8, 0.6, 0), (0.45, 1, 0.8, 0.6, 1), (1, 1, 1, 1, 1)],
                                      name="opaque")


def scene_of(volume, tf=SMOOTH, *, size=48, shading="none", mode="dvr", **camera):
    camera = {"azimuth": 30.0, "elevation": 20.0, **camera}
    return Scene((VolumeInstance(volume, tf, isovalue=0.45),), camera=Camera(**camera), width=size, height=size,
                 shading=Shading(model=shading), mode=mode)


@pytest.fixture(scope="module")
def volume():
    return blob()


@pytest.fixture(scope="module")
def truth():
    """The reference image of a scene at the GL default step (cached per scene)."""
    cache = {}

    def render(scene, step_factor=0.5):
        key = (id(scene), step_factor)
        if key not in cache:
            cache[key] = (scene, renderers.get("reference", step_factor=step_factor).render(scene).image)
        return cache[key][1]

    return render


# ---------------------------------------------------------------------------------------------
# Options, registry, capabilities (no GL needed)


def test_registered_with_its_options_and_sweep():
    assert renderers.backend_module("gl-raycast") == "renderers.gl.raycast"
    backend = GLRaycastRenderer(variant="rc-a", samples_per_pass=4)
    assert backend.options["variant"] == "rc-a" and backend.options["samples_per_pass"] == 4
    assert backend.options["opaque_threshold"] == 0.95 and backend.options["block_size"] == 8
    sweep = GLRaycastRenderer.quality_sweep_for("dvr")
    steps = [s["step_factor"] for s in sweep if "step_factor" in s]
    assert len(steps) >= 2 and steps == sorted(steps, reverse=True)
    # Every speed–accuracy option of the caster appears, each once; the iso hit's only where it changes something.
    swept = {name for options in sweep for name in options}
    assert swept == {"step_factor", "opaque_threshold", "samples_per_pass", "block_size"} and len(sweep) <= 8
    iso = GLRaycastRenderer.quality_sweep_for("iso")
    assert iso[:len(sweep)] == sweep and {name for options in iso for name in options} - swept == {"iso_hit",
                                                                                                   "iso_refine"}
    sweep = iso
    for options in sweep:
        GLRaycastRenderer(**options)


@pytest.mark.parametrize("options, match", [
    ({"variant": "rc-c"}, "variant"), ({"step_factor": 0}, "step_factor"), ({"step_factor": "fine"}, "step_factor"),
    ({"samples_per_pass": 0}, "samples_per_pass"), ({"samples_per_pass": 2.5}, "samples_per_pass"),
    ({"opaque_threshold": 0.0}, "opaque_threshold"), ({"opaque_threshold": 1.5}, "opaque_threshold"),
    ({"block_size": 0}, "block_size"), ({"min_opacity": 1.0}, "min_opacity"), ({"min_opacity": -0.1}, "min_opacity"),
    ({"iso_refine": -1}, "iso_refine"), ({"iso_refine": 40}, "iso_refine"), ({"timing": "wallclock"}, "timing"),
    ({"occluder": 1.5}, "occluder"), ({"region_order": "sideways"}, "region_order"),
])
def test_bad_options_name_the_option(options, match):
    with pytest.raises(InputError, match=f"gl-raycast option {match}"):
        GLRaycastRenderer(**options)
    with pytest.raises(InputError):
        renderers.get("gl-raycast", **options)


def test_capabilities_say_why_features_are_missing(volume):
    caps = GLRaycastRenderer.capabilities
    assert caps.modes == {"dvr", "mip", "iso"} and caps.projections == {"orthographic", "perspective"}
    assert caps.camera_inside_volume and caps.transforms
    for feature in ("max_volumes", "gradient_opacity", "meshes", "lenses"):
        assert caps.reasons[feature]
    backend = GLRaycastRenderer()
    with pytest.raises(UnsupportedFeatureError, match="one volume"):
        backend.render(Scene((VolumeInstance(volume, SMOOTH), VolumeInstance(volume, SMOOTH))))
    with pytest.raises(UnsupportedFeatureError, match="gradient"):
        backend.render(Scene((VolumeInstance(volume, SMOOTH, gradient_opacity=GradientOpacity.from_points(
            [(0, 0), (1, 1)])),)))


# ---------------------------------------------------------------------------------------------
# Min–max grid and CT table (NumPy)


def trilinear(data, points):
    """Trilinear, clamp-to-edge, cell-centred samples of ``data`` [z, y, x] at voxel coordinates (x, y, z)."""
    shape = np.array(data.shape[::-1])
    u = np.clip(points, 0, shape - 1)
    i0 = np.minimum(np.floor(u).astype(int), shape - 2)
    f = u - i0
    out = 0.0
    for corner in np.ndindex(2, 2, 2):
        c = np.array(corner)
        w = np.prod(np.where(c, f, 1 - f), axis=-1)
        idx = i0 + c
        out = out + w * data[idx[:, 2], idx[:, 1], idx[:, 0]]
    return out


@pytest.mark.parametrize("shape, block_size, blocks", [((13, 17, 21), 8, (2, 3, 3)), ((13, 17, 21), 5, (3, 4, 5)),
                                                       ((1, 6, 9), 4, (1, 2, 3)), ((4, 3, 5), 1, (4, 3, 5))])
def test_block_ranges_hold_every_voxel_of_the_block_and_its_apron(shape, block_size, blocks):
    rng = np.random.default_rng(1)
    field = rng.random(shape).astype(np.float32)
    grid = emptyspace.block_minmax(field, block_size)
    assert grid.shape == blocks + (2,)
    for bz, by, bx in np.ndindex(grid.shape[:3]):
        region = field[max(bz * block_size - 1, 0):(bz + 1) * block_size + 1,
                       max(by * block_size - 1, 0):(by + 1) * block_size + 1,
                       max(bx * block_size - 1, 0):(bx + 1) * block_size + 1]
        lo, hi = grid[bz, by, bx]
        assert lo <= region.min() * 255 <= lo + 1 and hi - 1 <= region.max() * 255 <= hi


def test_ct_table_matches_a_brute_force_search():
    alpha = np.zeros(256)
    alpha[[40, 41, 200]] = 0.3
    alpha[120] = 0.01
    table = emptyspace.visibility_table(alpha, 0.0)
    for lo, hi in [(0, 39), (0, 40), (42, 119), (42, 120), (121, 199), (121, 200), (201, 255), (41, 41), (10, 250)]:
        touched = alpha[lo:hi + 1]  # the entries a scalar in [lo/255, hi/255] blends with non-zero weights
        assert table[hi, lo] == int((touched > 0).any()), (lo, hi)
    assert emptyspace.visibility_table(alpha, 0.05)[121, 119] == 0  # 0.01 <= min_opacity: empty
    assert emptyspace.visibility_table(alpha, 0.0)[121, 119] == 1


@pytest.mark.parametrize("size", [64, 1000])
@pytest.mark.parametrize("min_opacity", [0.0, 0.2])
def test_ct_table_at_other_table_sizes_matches_its_definition(size, min_opacity):
    """Tables of N != 256 entries (levels fall between entries, or several entries per level)."""
    rng = np.random.default_rng(size)
    alpha = np.where(rng.random(size) < 0.1, rng.choice([0.1, 0.5], size), 0.0)
    table = emptyspace.visibility_table(alpha, min_opacity)
    # Entry i, at s = i/(N - 1), has a non-zero weight for (i - 1)/(N - 1) < s < (i + 1)/(N - 1): a
    # scalar in [lo/255, hi/255] can blend with it when i - 1 < hi/255·(N - 1) and i + 1 > lo/255·(N - 1),
    # compared in integers so that no rounding enters the expectation.
    entries = np.flatnonzero(alpha > min_opacity)
    level = np.arange(emptyspace.LEVELS)[:, None]
    below_max = 255 * (entries - 1) < level * (size - 1)  # [hi, entry]
    above_min = 255 * (entries + 1) > level * (size - 1)  # [lo, entry]
    expected = (below_max[:, None, :] & above_min[None, :, :]).any(axis=2) | (level.T > level)
    assert 0 < expected.sum() < expected.size
    np.testing.assert_array_equal(table, expected.astype(np.uint8))


def test_blocks_called_empty_hold_no_visible_sample():
    """Conservative: trilinear samples anywhere in the cells of an empty block classify to α = 0."""
    rng = np.random.default_rng(2)
    data = (rng.random((24, 24, 24)) < 0.0005) * rng.integers(150, 256, (24, 24, 24))
    data = data.astype(np.uint8)
    volume = Volume(data)
    tf = TransferFunction.ramp(0.55, 0.7)
    field = volume.normalized()
    grid = emptyspace.block_minmax(field, 8)
    table = emptyspace.visibility_table(tf.table[:, 3], 0.0)
    empty = table[grid[..., 1], grid[..., 0]] == 0
    assert 0 < empty.sum() < empty.size
    for bz, by, bx in zip(*np.nonzero(empty)):
        # Cells of voxels 8b … 8b+7: voxel coordinates [8b − ½, 8b + 7.5).
        points = np.array([bx, by, bz]) * 8 - 0.5 + rng.random((4000, 3)) * 8
        assert tf.lookup(trilinear(field, points))[:, 3].max() == 0


# ---------------------------------------------------------------------------------------------
# Images against the reference


@needs_gl
@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
@pytest.mark.parametrize("shading", ["none", "phong"])
def test_every_variant_matches_the_reference(volume, truth, projection, shading):
    scene = scene_of(volume, shading=shading, projection=projection)
    ref = truth(scene)
    images = {}
    for variant in ("rc", "rc-a", "rc-b", "single-pass"):
        images[variant] = GLRaycastRenderer(variant=variant).render(scene).image
        assert images[variant].shape == ref.shape and images[variant].dtype == np.float32
    assert psnr(ref, images["rc"]) >= 55.0
    assert psnr(ref, GLRaycastRenderer(variant="single-pass", opaque_threshold=1.0).render(scene).image) >= 55.0
    # Early termination: within its bound 1 − T of the full integral. RC-a stops at the end of the
    # pass in which a ray passed T (up to M − 1 samples later), the single pass at once.
    for variant in ("rc-a", "single-pass"):
        assert np.abs(images[variant] - images["rc"]).max() <= 0.05 + 1e-4
    assert psnr(ref, images["rc-a"]) >= 44.0 and psnr(ref, images["single-pass"]) >= 38.0
    # Conservative empty-space skipping changes no pixel.
    assert np.array_equal(images["rc-b"], images["rc-a"])


@needs_gl
def test_an_opaque_phantom_matches_and_culls(truth):
    import datasets

    volume = datasets.load("ct_skull", size=40, seed=0)
    preset = datasets.preset("ct_skull", "bone")
    scene = scene_of(volume, preset.transfer_function, shading="phong")
    ref = truth(scene)
    results = {v: GLRaycastRenderer(variant=v).render(scene) for v in ("rc", "rc-a", "rc-b")}
    assert psnr(ref, results["rc"].image) >= 45.0 and psnr(ref, results["rc-b"].image) >= 40.0
    assert np.array_equal(results["rc-a"].image, results["rc-b"].image)
    main = {v: r.counters["fragments_main"] for v, r in results.items()}
    assert main["rc-b"] < main["rc-a"] < main["rc"]


@needs_gl
def test_camera_inside_the_volume(volume, truth):
    scene = scene_of(volume, projection="perspective", distance=6.0, fov_y=70.0, shading="phong")
    assert scene.camera_inside_volume()
    ref = truth(scene)
    for variant in ("rc", "single-pass"):
        assert psnr(ref, GLRaycastRenderer(variant=variant, opaque_threshold=1.0).render(scene).image) >= 50.0


@needs_gl
def test_homogeneous_box_has_the_exact_optical_depth(truth):
    """Partial last cells count their own length, so every ray's opacity is 1 − (1 − α)^(L/Δ0)."""
    volume = Volume(np.full((14, 18, 22), 200, np.uint8), spacing=(1.0, 0.8, 1.3))
    scene = scene_of(volume, TransferFunction.constant(alpha=0.08, color=(0.8, 0.6, 0.4)), size=40)
    lengths = ray_lengths(scene)
    expected = 1 - (1 - 0.08) ** (lengths / 0.8)
    for variant in ("rc", "single-pass"):
        image = GLRaycastRenderer(variant=variant, opaque_threshold=1.0).render(scene).image
        inside = lengths > 0.05
        assert np.abs(image[..., 3][inside] - expected[inside]).max() < 2e-4
        assert np.abs(image[..., 3][lengths == 0]).max() == 0


@needs_gl
@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_sampled_iso_surfaces_match_the_exact_reference(truth, projection):
    """The paper's sampled hit (the exact one: tests/test_gl_isocells.py). 8-bit textures are filtered with 8-bit
    weights here, which moves a few grazing hits; float32 does not."""
    exact = blob(dtype=np.float32)
    scene = scene_of(exact, shading="phong", mode="iso", projection=projection)
    ref = truth(scene)
    for variant in ("rc", "rc-b", "single-pass"):
        assert psnr(ref, GLRaycastRenderer(variant=variant, iso_hit="sampled").render(scene).image) >= 55.0
    # The paper's unrefined hit.
    assert psnr(ref, GLRaycastRenderer(iso_hit="sampled", iso_refine=0).render(scene).image) >= 45.0
    eight_bit = scene_of(blob(), shading="phong", mode="iso", projection=projection)
    image = GLRaycastRenderer(iso_hit="sampled").render(eight_bit).image
    wrong = np.abs(image - truth(eight_bit)).max(axis=-1) > 0.1
    assert wrong.mean() < 0.005


@needs_gl
def test_mip_matches_the_reference(volume, truth):
    scene = scene_of(volume, mode="mip")
    ref = truth(scene)
    for variant in ("rc", "rc-b", "single-pass"):
        result = GLRaycastRenderer(variant=variant).render(scene)
        assert psnr(ref, result.image) >= 55.0
    assert result.info["empty_space_skipping"] is False


@needs_gl
def test_transforms_and_anisotropic_spacing(volume, truth):
    aniso = Volume(volume.data, spacing=(1.0, 0.8, 1.5), name="aniso")
    mirror = np.diag([-1.0, 1.2, 0.9, 1.0])
    mirror[:3, 3] = (10.0, -20.0, 5.0)
    for projection in ("orthographic", "perspective"):
        scene = Scene((VolumeInstance(aniso, SMOOTH, transform=mirror),), width=40, height=40,
                      camera=Camera(azimuth=30, elevation=20, projection=projection), shading=Shading(model="phong"))
        assert psnr(truth(scene), GLRaycastRenderer(variant="rc").render(scene).image) >= 55.0


# ---------------------------------------------------------------------------------------------
# Passes, culling, counters


@needs_gl
@pytest.mark.parametrize("samples_per_pass", [8, 3])
def test_main_passes_are_the_longest_ray_over_m(volume, samples_per_pass):
    head_on = scene_of(volume, azimuth=0.0, elevation=0.0, size=32)
    oblique = scene_of(volume, size=32)
    for scene, steps in ((head_on, 36 / 0.5), (oblique, None)):
        if steps is None:
            steps = math.ceil(ray_lengths(scene).max() / 0.5 - 1e-3)
        for variant in ("rc", "rc-a", "rc-b"):
            result = GLRaycastRenderer(variant=variant, samples_per_pass=samples_per_pass).render(scene)
            passes = math.ceil(steps / samples_per_pass)
            assert result.counters["passes_main"] == passes and result.info["longest_ray_steps"] == steps
            assert result.counters["passes_intermediate"] == (0 if variant == "rc" else passes - 1)
            assert len(result.info["fragments_per_main_pass"]) == passes
            assert result.counters["samples"] == samples_per_pass * result.counters["fragments_main"]


@needs_gl
def test_early_z_culls_finished_rays(volume):
    scene = scene_of(volume, OPAQUE, size=40)
    rc = GLRaycastRenderer(variant="rc").render(scene)
    rca = GLRaycastRenderer(variant="rc-a").render(scene)
    rays = rc.counters["rays"]
    assert rays > 0 and rc.info["fragments_per_main_pass"] == [rays] * rc.counters["passes_main"]
    per_pass = rca.info["fragments_per_main_pass"]
    assert per_pass[0] == rays and all(a >= b for a, b in zip(per_pass, per_pass[1:])) and per_pass[-1] < rays // 4
    assert rca.counters["fragments_culled"] == rca.counters["passes_main"] * rays - rca.counters["fragments_main"]
    assert rca.counters["fragments_intermediate"] == rays * rca.counters["passes_intermediate"]
    assert rc.counters["fragments_culled"] == 0
    np.testing.assert_allclose(rca.image, rc.image, atol=0.05 + 1e-4)


@needs_gl
@pytest.mark.parametrize("variant", ["rc", "rc-b"])
def test_the_occluder_hides_its_part_of_the_footprint_and_culls_its_rays(volume, variant):
    scene = scene_of(volume, size=40)
    clear = GLRaycastRenderer(variant=variant).render(scene)
    rays, passes = clear.counters["rays"], clear.counters["passes_main"]
    covered = {}
    for fraction in (0.0, 0.5, 1.0):
        result = GLRaycastRenderer(variant=variant, occluder=fraction).render(scene)
        occluded = result.counters.get("rays_occluded", 0)
        covered[fraction] = occluded
        # No main-pass fragment of an occluded ray survives early-z, in any pass.
        assert max(result.info["fragments_per_main_pass"]) <= rays - occluded
        if variant == "rc":
            assert result.counters["fragments_main"] == passes * (rays - occluded)
        hidden = result.image[..., 3] == 1.0
        grey = np.all(np.isclose(result.image[hidden], [0.5, 0.5, 0.5, 1.0]), axis=-1)
        assert grey.sum() >= occluded  # every occluded ray shows the plane, nothing of the volume
        visible = ~np.all(np.isclose(result.image, [0.5, 0.5, 0.5, 1.0]), axis=-1)
        np.testing.assert_array_equal(result.image[visible], clear.image[visible])
    assert covered[0.0] == 0 and 0.3 * rays < covered[0.5] < 0.7 * rays and covered[1.0] == rays
    with pytest.raises(InputError, match="occluder"):
        GLRaycastRenderer(variant=variant, occluder=0.5).render(scene_of(volume, size=16, mode="mip"))


@needs_gl
def test_the_single_pass_variant_takes_an_occluder_only_with_a_lens(volume):
    # Without a lens it has no pass after which early-z could cull (with one: test_gl_raycast_lens).
    with pytest.raises(InputError, match="occluder.*multi-pass variant.*or a lens scene"):
        GLRaycastRenderer(variant="single-pass", occluder=0.5).render(scene_of(volume, size=16))


@needs_gl
@pytest.mark.parametrize("block_size", [8, 4, 5])
@pytest.mark.parametrize("mode", ["dvr", "iso"])
def test_empty_space_skipping_is_conservative(block_size, mode):
    """Small bright features straddling block faces, edges and corners: no visible block is ever skipped."""
    data = np.zeros((32, 32, 32), np.uint8)
    rng = np.random.default_rng(3)
    for _ in range(16):
        # Per axis: two voxels either side of a block face, or anywhere.
        start = [block_size * rng.integers(1, 32 // block_size) - 1 if rng.random() < 0.7 else rng.integers(0, 31)
                 for _ in range(3)]
        data[start[2]:start[2] + 2, start[1]:start[1] + 2, start[0]:start[0] + 2] = rng.integers(200, 256)
    volume = Volume(data, name="sparse")
    tf = TransferFunction.ramp(0.6, 0.75, color=(1.0, 0.7, 0.4), alpha=0.9)
    for azimuth, elevation in ((30, 20), (0, 0), (45, 35.26)):
        scene = Scene((VolumeInstance(volume, tf, isovalue=0.3),), mode=mode, width=40, height=40,
                      camera=Camera(azimuth=azimuth, elevation=elevation), shading=Shading(model="phong"))
        rca = GLRaycastRenderer(variant="rc-a", samples_per_pass=4).render(scene)
        rcb = GLRaycastRenderer(variant="rc-b", samples_per_pass=4, block_size=block_size).render(scene)
        assert rca.image.max() > 0.5
        assert np.array_equal(rcb.image, rca.image)
        assert rcb.counters["fragments_main"] < rca.counters["fragments_main"]  # something was skipped


@needs_gl
def test_single_pass_counts_the_samples_it_takes(volume):
    scene = scene_of(volume, size=40)
    reference = renderers.get("reference", step_factor=0.5).render(scene)
    full = GLRaycastRenderer(variant="single-pass", opaque_threshold=1.0).render(scene)
    assert full.counters["rays"] == full.counters["fragments_main"] == reference.counters["rays_hit"]
    assert full.counters["samples"] == pytest.approx(reference.counters["samples"], rel=2e-3)
    opaque = scene_of(volume, OPAQUE, size=40)
    stopped = GLRaycastRenderer(variant="single-pass").render(opaque)
    assert stopped.counters["samples"] < 0.9 * GLRaycastRenderer(variant="single-pass", opaque_threshold=1.0).render(
        opaque).counters["samples"]


@needs_gl
def test_timings_counters_and_info_are_stable(volume):
    stages = {"setup", "main", "intermediate", "resolve", "readback", "total"}
    counters = {"rays", "fragments_main", "fragments_intermediate", "fragments_culled", "passes_main",
                "passes_intermediate", "samples"}
    for variant in ("rc", "rc-a", "rc-b", "single-pass"):
        for timing in ("finish", "query"):
            backend = GLRaycastRenderer(variant=variant, timing=timing)
            backend.render(scene_of(volume, size=32))
            result = backend.render(scene_of(volume, size=32))
            assert set(result.timings) == stages and set(result.counters) == counters
            assert result.timings["total"] > 0 and result.timings["main"] > 0
            assert result.info["timing"] == timing
            assert backend.options["effective_step"] == pytest.approx(0.5)
    if context.is_software(context.shared_context()):
        assert GLRaycastRenderer().timing_method == "finish"
    assert set(GLRaycastRenderer().environment()) >= {"gl_renderer", "gl_version", "gl_max_3d_texture_size"}


# ---------------------------------------------------------------------------------------------
# Caching, errors


@needs_gl
def test_uploads_are_cached_and_a_new_transfer_function_rebuilds_the_ct_table(volume, monkeypatch):
    from renderers.gl import resources

    monkeypatch.setattr(resources, "_derived", type(resources._derived)())  # what other tests derived from it
    backend = GLRaycastRenderer(variant="rc-b")
    scene = scene_of(volume, shading="phong", size=32)
    first = backend.render(scene)
    assert set(first.info["uploaded"]) == {"volume", "gradients", "transfer_function", "minmax", "ct_table"}
    assert {"upload", "gradients", "minmax", "ct_table"} <= set(first.timings)
    second = backend.render(scene)
    assert second.info["uploaded"] == [] and "upload" not in second.timings
    assert np.array_equal(first.image, second.image)
    recoloured = backend.render(scene_of(volume, OPAQUE, shading="phong", size=32))
    assert recoloured.info["uploaded"] == ["transfer_function", "ct_table"] and "ct_table" in recoloured.timings
    assert recoloured.counters["fragments_main"] != second.counters["fragments_main"]
    assert backend.render(scene).info["uploaded"] == []  # both classifications stay cached
    backend.close()
    assert backend.render(scene).info["uploaded"] != []


@needs_gl
def test_scalar_formats_follow_the_dtype_and_value_range(volume, truth):
    cases = [(volume, "R8"), (Volume(volume.data.astype(np.uint16) * 40, value_range=(0, 20000)), "R16"),
             (Volume(volume.data.astype(np.uint16) * 40, value_range=(0, 8000)), "R32F (normalised"),
             (blob(dtype=np.float32), "R32F")]
    for vol, expected in cases:
        scene = scene_of(vol, size=32)
        result = GLRaycastRenderer(variant="rc").render(scene)
        assert result.info["scalar_format"].startswith(expected)
        assert psnr(truth(scene), result.image) >= 55.0


@needs_gl
def test_errors_before_any_work(volume, monkeypatch):
    no_iso = Scene((VolumeInstance(volume, SMOOTH),), mode="iso")
    with pytest.raises(InputError, match="isovalue"):
        GLRaycastRenderer().render(no_iso)
    monkeypatch.setattr(context, "max_3d_texture_size", lambda ctx: 16)
    with pytest.raises(InputError, match="GL_MAX_3D_TEXTURE_SIZE 16"):
        GLRaycastRenderer().render(scene_of(volume))


# -- sizes refused before any work ---------------------------------------------------------------

def test_a_sample_count_beyond_the_shaders_int_is_refused():
    with pytest.raises(InputError, match=r"^gl-raycast option samples_per_pass: expected an integer from 1 to "
                                         r"2147483647, got 2147483648$"):
        GLRaycastRenderer(samples_per_pass=2 ** 31)
    assert GLRaycastRenderer(samples_per_pass=2 ** 31 - 1).samples_per_pass == 2 ** 31 - 1


def test_a_step_finer_than_float32_resolves_is_refused():
    with pytest.raises(InputError, match=r"gl-raycast option step_factor: 1e-05 is finer than .* use step_factor ≥"):
        GLRaycastRenderer(step_factor=1e-5)


@needs_gl
def test_a_block_grid_that_only_pads_or_does_not_fit_is_refused_before_any_work(volume, monkeypatch):
    import core.resources

    with pytest.raises(InputError, match=r"block_size: 100000 is larger than volume 'blob' \(36×36×36\), so one block "
                                         r"covers it and the rest is padding; use block_size ≤ 36"):
        GLRaycastRenderer(block_size=100000).check(scene_of(volume))
    GLRaycastRenderer(block_size=100000, variant="rc").check(scene_of(volume))  # no block grid
    GLRaycastRenderer(block_size=36).check(scene_of(volume))
    monkeypatch.setattr(core.resources, "memory_limit", lambda: 2 ** 20)
    with pytest.raises(InputError, match=r"block_size 35 needs 2.02 MiB \(volume 'blob' \(36×36×36\) padded to whole "
                                         r"blocks, 343000 float32 voxels, and four float32 copies of it\)"):
        GLRaycastRenderer(block_size=35).check(scene_of(volume))


@needs_gl
def test_an_image_larger_than_the_contexts_render_targets_is_unsupported(volume):
    from renderers.gl import context as gl_context

    info = gl_context.shared_context().info
    most = min(int(info["GL_MAX_TEXTURE_SIZE"]), *map(int, info["GL_MAX_VIEWPORT_DIMS"]))
    wide = Scene((VolumeInstance(volume, SMOOTH),), width=most + 1, height=1)
    with pytest.raises(UnsupportedFeatureError, match=rf"a {most + 1}×1 image: .* renders at most {most}×{most} pixels"):
        GLRaycastRenderer().check(wide)
    GLRaycastRenderer().check(Scene((VolumeInstance(volume, SMOOTH),), width=most, height=1))
