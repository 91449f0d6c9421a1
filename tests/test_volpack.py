"""The ``volpack`` backend (VolPack through ctypes) against the reference renderer.

Skipped as a whole where the VolPack shared library is missing (``apt-get install libvolpack1``);
the probe's refusal is tested either way.
"""

import math

import numpy as np
import pytest

import datasets
import renderers
from core.camera import Camera
from core.errors import BackendUnavailableError, InputError, UnsupportedFeatureError
from core.scene import Scene, Shading, VolumeInstance
from core.transfer import GradientOpacity, TransferFunction
from core.volume import Volume
from renderers.volpack import library as vp
from renderers.volpack.renderer import VolPackRenderer, density_alpha_table, gradient_table

AVAILABLE, WHY = VolPackRenderer.probe()
needs_volpack = pytest.mark.skipif(not AVAILABLE, reason=WHY)

LINEAR = TransferFunction.from_points([(0, 1, 1, 1, 0), (1, 1, 1, 1, 1)], name="linear")


def psnr(reference, test):
    mse = float(np.mean((reference.astype(np.float64) - test) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(1 / mse)


def centroid(image):
    """Opacity-weighted (row, column) centroid in pixels."""
    weight = image[..., 3].astype(np.float64)
    rows, cols = np.mgrid[:image.shape[0], :image.shape[1]]
    return np.array([(weight * rows).sum(), (weight * cols).sum()]) / weight.sum()


@pytest.fixture(scope="module")
def reference():
    return renderers.get("reference")


def scene_of(volume, tf=LINEAR, *, gradient=None, size=48, shading="none", **camera):
    return Scene([VolumeInstance(volume, tf, gradient_opacity=gradient)], Camera(**camera),
                 width=size, height=size, shading=Shading(model=shading))


# -- probe and registry ------------------------------------------------------------------------

def test_probe_names_the_package_when_the_library_is_missing(monkeypatch):
    monkeypatch.setattr(vp, "_LIB", None)
    monkeypatch.setattr(vp, "LIBRARY_NAMES", ("libvolpack-does-not-exist.so.9",))
    monkeypatch.setattr(vp.ctypes.util, "find_library", lambda name: None)
    ok, reason = VolPackRenderer.probe()
    assert ok is False
    assert "apt-get install libvolpack1" in reason
    with pytest.raises(BackendUnavailableError, match="apt-get install libvolpack1"):
        renderers.get("volpack")


def test_registered_after_reference():
    names = renderers.names()
    assert "volpack" in names and names.index("volpack") > names.index("reference")
    assert renderers.backend_module("volpack") == "renderers.volpack.renderer"


# -- options -----------------------------------------------------------------------------------

@needs_volpack
@pytest.mark.parametrize("options, match", [
    ({"mode": "fast"}, "mode"),
    ({"opaque_threshold": 0.0}, "opaque_threshold"),
    ({"opaque_threshold": 1.5}, "opaque_threshold"),
    ({"opaque_threshold": "high"}, "opaque_threshold"),
    ({"min_opacity": 1.0}, "min_opacity"),
    ({"min_opacity": -0.1}, "min_opacity"),
    ({"octree_base_node_size": 3}, "power of two"),
    ({"octree_base_node_size": 1024}, "octree_base_node_size: expected an integer from 1 to 512, got 1024"),
    ({"octree_base_node_size": 0}, "octree_base_node_size"),
    ({"octree_threshold": -1}, "octree_threshold"),
    ({"octree_threshold": 256}, "octree_threshold"),
    ({"octree_threshold": True}, "octree_threshold"),
])
def test_bad_options_are_named(options, match):
    with pytest.raises(InputError, match=match):
        renderers.get("volpack", **options)


@needs_volpack
def test_unknown_option_lists_the_valid_ones():
    with pytest.raises(InputError, match="valid options: mode, opaque_threshold, min_opacity"):
        renderers.get("volpack", early_termination=False)


@needs_volpack
def test_options_and_environment_are_recorded():
    backend = renderers.get("volpack", mode="octree", opaque_threshold=1.0, min_opacity=0.0)
    assert backend.options == {"mode": "octree", "opaque_threshold": 1.0, "min_opacity": 0.0,
                               "octree_base_node_size": 4, "octree_threshold": 4}
    env = backend.environment()
    assert env["volpack_header_version"] == "1.1"
    assert env["volpack_threads"] == 1


# -- refusals ----------------------------------------------------------------------------------

def _small():
    data = np.zeros((8, 8, 8), np.uint8)
    data[2:6, 2:6, 2:6] = 200
    return Volume(data, name="small")


@needs_volpack
@pytest.mark.parametrize("make, feature", [
    (lambda v: scene_of(v, projection="perspective"), "projections"),
    (lambda v: Scene([VolumeInstance(v, LINEAR)], mode="mip", width=8, height=8), "modes"),
    (lambda v: Scene([VolumeInstance(v, LINEAR), VolumeInstance(v, LINEAR)], width=8, height=8), "2 volumes"),
    (lambda v: Scene([VolumeInstance(v, LINEAR, transform=np.diag([2.0, 1, 1, 1]))], width=8, height=8),
     "transforms"),
    (lambda v: scene_of(Volume(v.data, spacing=(1, 1, 2))), "anisotropic_spacing"),
])
def test_unsupported_features_are_refused_with_a_reason(make, feature):
    backend = renderers.get("volpack")
    scene = make(_small())
    with pytest.raises(UnsupportedFeatureError) as info:
        backend.render(scene)
    assert feature in str(info.value)
    assert backend.capabilities.reasons  # every missing capability has a stated reason
    for name in ("projections", "modes", "max_volumes", "transforms", "anisotropic_spacing", "camera_inside_volume"):
        assert backend.capabilities.reasons[name]


@needs_volpack
def test_eye_plane_inside_the_box_is_an_input_error():
    scene = scene_of(_small(), distance=2.0)
    with pytest.raises(InputError, match="camera distance"):
        renderers.get("volpack").render(scene)


@needs_volpack
def test_reference_step_with_gradient_opacity_is_refused():
    tf = TransferFunction(LINEAR.table, reference_step=0.5, name="half")
    scene = scene_of(_small(), tf, gradient=GradientOpacity(np.ones(8)))
    with pytest.raises(InputError, match="reference_step"):
        renderers.get("volpack").render(scene)


@needs_volpack
def test_volume_wider_than_volpack_allows_is_refused():
    scene = scene_of(Volume(np.zeros((1, 1, 1025), np.uint8)), size=8)
    with pytest.raises(InputError, match="1024"):
        renderers.get("volpack").render(scene)


# -- framing: VolPack's coordinates mapped onto our camera ----------------------------------------

VIEWS = [(0, 0), (30, 20), (120, -40), (200, 70), (-60, 10), (90, 0)]
"""Views covering all three of VolPack's principal axes and both slice orders."""


@needs_volpack
@pytest.mark.parametrize("azimuth, elevation", VIEWS)
def test_an_off_centre_voxel_lands_on_the_reference_pixel(reference, azimuth, elevation):
    backend = renderers.get("volpack", opaque_threshold=1.0, min_opacity=0.0)
    for x, y, z in [(5, 3, 2), (2, 7, 9), (6, 2, 4)]:
        data = np.zeros((12, 10, 8), np.uint8)  # nz, ny, nx: asymmetric box
        data[z, y, x] = 255
        scene = scene_of(Volume(data), azimuth=azimuth, elevation=elevation)
        expected = centroid(reference.render(scene).image)
        got = centroid(backend.render(scene).image)
        # measured: < 0.03 px; half a voxel (the lattice offset) is 1.5 px, half a pixel 0.5 px
        assert np.all(np.abs(got - expected) < 0.06), (x, y, z, got, expected)


@needs_volpack
def test_view_axis_follows_the_view():
    backend = renderers.get("volpack")
    axes = {}
    for azimuth, elevation in [(0, 0), (90, 0), (0, 80)]:
        axes[(azimuth, elevation)] = backend.render(scene_of(_small(), azimuth=azimuth, elevation=elevation,
                                                             up=(0, 1, 0) if elevation < 80 else (0, 0, -1))
                                                    ).counters["view_axis"]
    assert axes == {(0, 0): 2, (90, 0): 0, (0, 80): 1}


@needs_volpack
@pytest.mark.parametrize("azimuth", [0, 180])
def test_front_slab_hides_the_back_slab(azimuth):
    """Compositing order: the slab nearer the eye wins (azimuth 0 looks down −z: high z is nearer).

    Only VolPack is checked: the reference classifies after interpolation, so the rim of the
    dense slab passes through the other slab's densities and shows a thin shell of its colour.
    """
    data = np.zeros((16, 12, 12), np.uint8)
    data[3:7, 3:9, 3:9] = 100   # low z: behind at azimuth 0
    data[9:13, 3:9, 3:9] = 220  # high z: in front at azimuth 0
    tf = TransferFunction.from_points([(0, 0, 1, 0, 0), (80 / 255, 0, 1, 0, 0), (100 / 255, 0, 1, 0, 1),
                                       (170 / 255, 0, 1, 0, 1), (200 / 255, 1, 0, 0, 1), (1, 1, 0, 0, 1)])
    scene = scene_of(Volume(data), tf, azimuth=azimuth)
    got = renderers.get("volpack").render(scene).image[20:28, 20:28, :3].sum(axis=(0, 1))
    front = 0 if azimuth == 0 else 1  # red in front at azimuth 0, green at 180
    assert got[front] > 10 * got[1 - front]


# -- accuracy against the reference -------------------------------------------------------------

AGREEMENT = [
    # data set, size, preset, azimuth, elevation, shading, PSNR bound (measured value in the comment)
    ("sphere", 32, "opaque", 0, 0, "none", 28.5),       # 29.12 dB
    ("sphere", 32, "opaque", 30, 20, "none", 26.5),     # 27.29 dB
    ("ct_skull", 48, "volpack", 0, 0, "none", 26.5),    # 27.04 dB (density × gradient opacity)
    ("ct_skull", 48, "volpack", 30, 20, "none", 27.5),  # 28.08 dB
    ("ct_skull", 48, "isbvr", 30, 20, "phong", 34.5),   # 35.04 dB (colour varies: 4 materials)
    ("ct_skull", 48, "volpack", 30, 20, "phong", 30.3),  # 30.93 dB (constant colour: 1 material)
]


@needs_volpack
@pytest.mark.parametrize("name, size, preset, azimuth, elevation, shading, bound", AGREEMENT)
def test_agrees_with_the_reference(reference, name, size, preset, azimuth, elevation, shading, bound):
    volume = datasets.load(name, size=size, cache_dir=False)
    chosen = datasets.get(name).preset(preset)
    scene = scene_of(volume, chosen.transfer_function, gradient=chosen.gradient_opacity, size=64,
                     shading=shading, azimuth=azimuth, elevation=elevation)
    truth = reference.render(scene).image
    image = renderers.get("volpack").render(scene).image
    assert image.shape == (64, 64, 4) and image.dtype == np.float32
    assert psnr(truth, image) >= bound
    # the bound is tight enough to catch a framing mistake: one pixel off, or upside down
    assert psnr(truth, np.roll(image, 1, axis=1)) < bound
    assert psnr(truth, np.roll(image, 1, axis=0)) < bound
    if name != "sphere":
        assert psnr(truth, image[::-1]) < bound


@needs_volpack
def test_light_direction_is_in_view_space(reference):
    """A light from the right lights the right side in both renderers (not mirrored)."""
    volume = datasets.load("sphere", size=32, cache_dir=False)
    tf = datasets.get("sphere").preset("opaque").transfer_function
    light = Shading(model="phong", light_direction=(0.8, 0.3, 0.5))
    mirrored = Shading(model="phong", light_direction=(-0.8, -0.3, 0.5))
    base = Scene([VolumeInstance(volume, tf)], Camera(azimuth=30, elevation=20), width=48, height=48)
    truth = reference.render(base.__class__(base.volumes, base.camera, 48, 48, shading=light)).image
    backend = renderers.get("volpack")
    good = backend.render(base.__class__(base.volumes, base.camera, 48, 48, shading=light)).image
    bad = backend.render(base.__class__(base.volumes, base.camera, 48, 48, shading=mirrored)).image
    assert psnr(truth, good) > psnr(truth, bad) + 8


@needs_volpack
@pytest.mark.parametrize("azimuth, elevation", [(0, 0), (30, 20), (45, 35)])
def test_opacity_correction_of_a_homogeneous_cube(reference, azimuth, elevation):
    """Centre pixel of a uniform cube: 1 − (1 − α)^(L/Δ0) with VolPack's per-view correction."""
    alpha = 20 / 255
    volume = Volume(np.full((24, 24, 24), 20, np.uint8))
    scene = scene_of(volume, azimuth=azimuth, elevation=elevation, size=65)  # pixel 32 is centred
    direction = scene.camera.basis()[2]
    length = 24 / np.max(np.abs(direction))  # through the centre, face to face
    exact = 1 - (1 - alpha) ** length
    image = renderers.get("volpack", opaque_threshold=1.0, min_opacity=0.0).render(scene).image
    assert abs(image[32, 32, 3] - exact) < 3 / 255  # 8-bit opacity index and image
    assert abs(reference.render(scene).image[32, 32, 3] - exact) < 1e-4


def test_gradient_table_uses_volpack_scale():
    ramp = GradientOpacity.from_points([(0, 0), (1, 1)])
    table = gradient_table(ramp)
    assert table.shape == (vp.VP_GRAD_MAX + 1,)
    # index k stands for |∇s| in [k, k+1)/255; u = |∇s|/(√3/2), the interval's centre
    assert table[0] == pytest.approx(0.5 / (255 * np.sqrt(3) / 2), rel=1e-6)
    assert table[220] == pytest.approx(220.5 / (255 * np.sqrt(3) / 2), rel=1e-6)


def test_density_opacity_table_reads_the_transfer_function_at_v_over_255():
    # α = s: entry v holds α(v/255), so the last entry is the transfer function's value at 1.0
    table = density_alpha_table(LINEAR, 1.0, 1.0)
    assert table.shape == (vp.VP_SCALAR_MAX + 1,)
    assert table[0] == 0 and table[128] == pytest.approx(128 / 255, rel=1e-6) and table[255] == 1


@needs_volpack
@pytest.mark.parametrize("density, colour", [(0, (1, 0, 0)), (128, (0, 1, 0)), (255, (0, 0, 1))])
def test_a_density_gets_the_transfer_function_colour_at_its_value_over_255(density, colour):
    """The colour weights are indexed like the opacity table: density v takes the colour at s = v/255.

    The colour changes between adjacent table entries (127 | 128 and 254 | 255), so reading the table
    at v/256 instead would give a half-and-half mix at 128 and all but pure green at 255.
    """
    tf = TransferFunction.from_points([(0, 1, 0, 0, 0.5), (127 / 255, 1, 0, 0, 0.5), (128 / 255, 0, 1, 0, 0.5),
                                       (254 / 255, 0, 1, 0, 0.5), (1, 0, 0, 1, 0.5)])
    scene = scene_of(Volume(np.full((16, 16, 16), density, np.uint8)), tf, size=33)
    pixel = renderers.get("volpack", opaque_threshold=1.0, min_opacity=0.0).render(scene).image[16, 16]
    assert pixel[3] > 0.99  # 16 voxels of α = 0.5
    np.testing.assert_allclose(pixel[:3] / pixel[3], colour, atol=3 / 255)  # 8-bit image


# -- caching, modes, determinism ------------------------------------------------------------------

@needs_volpack
def test_preprocessing_is_cached_per_volume_and_classification():
    volume = datasets.load("ct_skull", size=32, cache_dir=False)
    preset = datasets.get("ct_skull").preset("volpack")
    scene = scene_of(volume, preset.transfer_function, gradient=preset.gradient_opacity, azimuth=30)
    backend = renderers.get("volpack")
    first = backend.render(scene)
    assert {"volume", "classify", "shade", "render", "total"} <= set(first.timings)
    assert first.counters["rle_bytes"] > 0 and first.counters["voxels"] == 32 ** 3
    second = backend.render(scene.with_camera(azimuth=60))
    assert "volume" not in second.timings and "classify" not in second.timings
    other = scene_of(volume, TransferFunction.ramp(0.3, 0.6), gradient=preset.gradient_opacity)
    third = backend.render(other)
    assert "classify" in third.timings and "volume" not in third.timings
    fourth = backend.render(scene_of(_small()))
    assert "volume" in fourth.timings and "classify" in fourth.timings


@needs_volpack
def test_octree_is_built_once_per_volume():
    volume = datasets.load("ct_skull", size=32, cache_dir=False)
    preset = datasets.get("ct_skull").preset("volpack")
    backend = renderers.get("volpack", mode="octree")
    first = backend.render(scene_of(volume, preset.transfer_function, gradient=preset.gradient_opacity))
    assert "octree" in first.timings and first.counters["octree_bytes"] > 0
    again = backend.render(scene_of(volume, TransferFunction.ramp(0.3, 0.6), gradient=preset.gradient_opacity))
    assert "octree" not in again.timings  # the octree holds field ranges, not opacities


@needs_volpack
def test_modes_agree_and_frames_are_bit_reproducible():
    volume = datasets.load("ct_skull", size=32, cache_dir=False)
    preset = datasets.get("ct_skull").preset("volpack")
    scene = scene_of(volume, preset.transfer_function, gradient=preset.gradient_opacity, shading="phong",
                     azimuth=30, elevation=20)
    images = {mode: renderers.get("volpack", mode=mode).render(scene).image for mode in ("rle", "octree", "raw")}
    # the octree skips only regions whose every voxel is at or below min_opacity: lossless
    assert np.array_equal(images["rle"], images["octree"])
    assert np.array_equal(images["rle"], images["raw"])
    backend = renderers.get("volpack")
    assert np.array_equal(backend.render(scene).image, backend.render(scene).image)
    assert np.array_equal(backend.render(scene).image, images["rle"])
    # a context reused across views and image sizes leaves nothing of the previous frame behind
    other = scene_of(volume, preset.transfer_function, gradient=preset.gradient_opacity, shading="phong",
                     azimuth=-70, elevation=10, size=40)
    backend.render(scene_of(volume, preset.transfer_function, gradient=preset.gradient_opacity, size=40))
    assert np.array_equal(backend.render(other).image, renderers.get("volpack").render(other).image)


@needs_volpack
def test_thresholds_change_the_image_as_documented():
    volume = Volume(np.full((16, 16, 16), 40, np.uint8))
    scene = scene_of(volume, size=32)
    alpha = 40 / 255  # per voxel, above 0.05
    full = renderers.get("volpack", opaque_threshold=1.0, min_opacity=0.0).render(scene).image
    skipped = renderers.get("volpack", opaque_threshold=1.0, min_opacity=alpha + 0.01).render(scene).image
    early = renderers.get("volpack", opaque_threshold=0.5, min_opacity=0.0).render(scene).image
    assert full[16, 16, 3] == pytest.approx(1 - (1 - alpha) ** 16, abs=3 / 255)
    assert skipped[..., 3].max() == 0  # every voxel at or below min_opacity is transparent
    assert 0.5 <= early[16, 16, 3] < full[16, 16, 3] - 0.1  # the ray stopped soon after 0.5


@needs_volpack
def test_reference_step_other_than_the_voxel_is_folded_into_the_table(reference):
    """α per Δ0 = ½ voxel: each voxel is two reference steps (1 − (1 − α)² per voxel)."""
    alpha = 20 / 255
    tf = TransferFunction(LINEAR.table, reference_step=0.5, name="half-voxel")
    scene = scene_of(Volume(np.full((16, 16, 16), 20, np.uint8)), tf, size=33)
    exact = 1 - (1 - alpha) ** (16 / 0.5)
    image = renderers.get("volpack", opaque_threshold=1.0, min_opacity=0.0).render(scene).image
    assert abs(image[16, 16, 3] - exact) < 3 / 255
    assert abs(reference.render(scene).image[16, 16, 3] - exact) < 1e-4
