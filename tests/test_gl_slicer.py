"""The OpenGL slicer (view-aligned 3D-texture slicing, SBVR): slice geometry, images against the
reference, compositing orders, perspective spacing, contributing fragments, caching, options."""

import numpy as np
import pytest

import renderers
from core.camera import Camera
from core.errors import InputError, UnsupportedFeatureError
from core.scene import Scene, Shading, VolumeInstance
from core.transfer import TransferFunction
from core.volume import Volume
from renderers.gl import context
from renderers.gl.slicer import GLSlicerRenderer, slice_polygons
from renderers.gl.view import make_view, ray_lengths
from reports.metrics import psnr

GL_OK, GL_REASON = context.probe()
needs_gl = pytest.mark.skipif(not GL_OK, reason=f"no OpenGL 4.3 context through EGL here: {GL_REASON}")


def blob(n=36, seed=0):
    """A smooth blob with internal structure, zero at the box faces (as in test_gl_raycast)."""
    z, y, x = np.meshgrid(*(np.arange(n) + 0.5,) * 3, indexing="ij")
    r = np.sqrt((x - n / 2) ** 2 + (y - n / 2) ** 2 + (z - n / 2) ** 2)
    field = np.clip(1 - r / (0.42 * n), 0, 1)
    phase = np.random.default_rng(seed).uniform(0, 6, 3)
    field = np.clip(field + 0.15 * np.sin(x / 3 + phase[0]) * np.cos(y / 4 + phase[1]) * (field > 0), 0, 1)
    return Volume((field * 255).astype(np.uint8), name="blob")


SMOOTH = TransferFunction.from_points([(0, 1, 0.5, 0.2, 0), (0.15, 1, 0.5, 0.2, 0), (0.5, 0.3, 0.8, 1, 0.5),
                                       (1, 1, 1, 1, 0.9)], name="smooth")


def scene_of(volume, tf=SMOOTH, *, size=48, shading="none", mode="dvr", **camera):
    camera = {"azimuth": 30.0, "elevation": 20.0, **camera}
    return Scene((VolumeInstance(volume, tf),), camera=Camera(**camera), width=size, height=size,
                 shading=Shading(model=shading), mode=mode)


def reference(scene, step_factor=0.5):
    return renderers.get("reference", step_factor=step_factor).render(scene).image


@pytest.fixture(scope="module")
def volume():
    return blob()


def test_registered_with_its_options_and_sweep(volume):
    assert renderers.backend_module("gl-slicer") == "renderers.gl.slicer"
    backend = GLSlicerRenderer(order="front-to-back")
    assert backend.options["order"] == "front-to-back" and backend.options["step_factor"] == 0.5
    assert 1 <= len(GLSlicerRenderer.quality_sweep) <= 4
    for options, match in [({"order": "random"}, "order"), ({"step_factor": -1}, "step_factor"),
                           ({"count_contributing": "yes"}, "count_contributing"), ({"timing": "never"}, "timing")]:
        with pytest.raises(InputError, match=f"gl-slicer option {match}"):
            GLSlicerRenderer(**options)
    with pytest.raises(UnsupportedFeatureError, match="iSBVR"):
        backend.render(scene_of(volume, mode="iso"))
    for feature in ("modes", "max_volumes", "gradient_opacity", "meshes", "lenses"):
        assert GLSlicerRenderer.capabilities.reasons[feature]


def test_slices_are_the_planes_cut_with_the_box():
    volume = Volume(np.zeros((10, 12, 16), np.uint8))
    head_on = scene_of(volume, azimuth=0.0, elevation=0.0)
    view = make_view(head_on, 0.5)
    forward = -np.asarray(head_on.camera.basis()[2])
    triangles, depths = slice_polygons(view.model, head_on.camera.eye, forward, view.near, 0.5)
    assert len(depths) == 20 and np.allclose(np.diff(depths), 0.5)
    assert triangles.shape == (40, 3, 3)  # a square per slice, two triangles
    assert np.allclose(triangles[:2, :, 2], 1 - 0.25 / 10)  # the nearest slice, a quarter voxel inside the +z face
    oblique = scene_of(volume, azimuth=37.0, elevation=24.0)
    view = make_view(oblique, 0.5)
    forward = -np.asarray(oblique.camera.basis()[2])
    triangles, depths = slice_polygons(view.model, oblique.camera.eye, forward, view.near, 0.5)
    # The slices' areas add up to the box volume (midpoint rule of the cross-section area).
    world = triangles @ view.model[:3, :3].T
    areas = 0.5 * np.linalg.norm(np.cross(world[:, 1] - world[:, 0], world[:, 2] - world[:, 0]), axis=1)
    assert areas.sum() * 0.5 == pytest.approx(16 * 12 * 10, rel=2e-3)
    in_plane = (world - oblique.camera.eye) @ forward
    assert np.allclose(in_plane.std(axis=1), 0, atol=1e-5)  # each triangle lies in one slice plane


@needs_gl
@pytest.mark.parametrize("shading", ["none", "phong"])
def test_orthographic_slicing_matches_the_reference(volume, shading):
    scene = scene_of(volume, shading=shading)
    truth = reference(scene)
    images = [GLSlicerRenderer(order=order).render(scene).image for order in ("back-to-front", "front-to-back")]
    assert psnr(truth, images[0]) >= 50.0
    np.testing.assert_allclose(images[0], images[1], atol=2e-6)


@needs_gl
def test_a_sharp_classification_is_as_accurate_as_the_reference_at_the_same_step():
    """With a bone edge the slices sit elsewhere on each ray than the reference's samples; against a
    converged image both are as far off."""
    import datasets

    volume = datasets.load("ct_skull", size=40, seed=0)
    scene = scene_of(volume, datasets.preset("ct_skull", "bone").transfer_function, shading="phong")
    converged = reference(scene, step_factor=1 / 8)
    same_step = reference(scene)
    image = GLSlicerRenderer().render(scene).image
    assert psnr(same_step, image) >= 35.0
    assert psnr(converged, image) >= psnr(converged, same_step) - 1.5


@needs_gl
def test_a_homogeneous_box_has_the_exact_optical_depth_away_from_its_silhouette():
    volume = Volume(np.full((14, 18, 22), 200, np.uint8), spacing=(1.0, 0.8, 1.3))
    alpha = 0.08
    for projection in ("orthographic", "perspective"):
        scene = scene_of(volume, TransferFunction.constant(alpha=alpha), size=40, projection=projection)
        lengths = ray_lengths(scene)
        expected = 1 - (1 - alpha) ** (lengths / 0.8)
        image = GLSlicerRenderer().render(scene).image
        # Rays longer than two slice spacings cross at least one slice and count their length exactly.
        inside = lengths > 2 * 0.4 / 0.9
        assert np.abs(image[..., 3][inside] - expected[inside]).max() < 1e-4


@needs_gl
def test_perspective_slices_are_spaced_d_over_cos_theta(volume):
    """Planar slices: the method's step grows towards the image corners; opacity follows it."""
    scene = scene_of(volume, projection="perspective", shading="phong", fov_y=40.0)
    truth = reference(scene)
    assert psnr(truth, GLSlicerRenderer().render(scene).image) >= 55.0


@needs_gl
def test_camera_inside_the_volume(volume):
    scene = scene_of(volume, projection="perspective", distance=6.0, fov_y=70.0)
    assert scene.camera_inside_volume()
    assert psnr(reference(scene), GLSlicerRenderer().render(scene).image) >= 50.0


@needs_gl
def test_mip(volume):
    scene = scene_of(volume, mode="mip")
    result = GLSlicerRenderer().render(scene)
    assert psnr(reference(scene), result.image) >= 55.0
    assert "fragments_contributing" not in result.counters


@needs_gl
def test_counters_fragments_and_contributing_fraction(volume):
    head_on = scene_of(volume, azimuth=0.0, elevation=0.0, size=36)
    scene = Scene(head_on.volumes, camera=Camera(view_height=36.0), width=36, height=36)  # one pixel per voxel
    result = GLSlicerRenderer().render(scene)
    assert result.counters["slices"] == 72 and result.counters["triangles"] == 144
    assert result.counters["fragments"] == 72 * 36 * 36 == result.counters["samples"]
    assert result.info["fragments_walked"] == result.counters["fragments"]
    oblique = GLSlicerRenderer().render(scene_of(volume))
    assert oblique.info["fragments_walked"] == pytest.approx(oblique.counters["fragments"], rel=1e-3)
    contributing = oblique.counters["fragments_contributing"]
    assert 0 < contributing < 0.3 * oblique.counters["fragments"]
    opaque = TransferFunction.from_points([(0, 1, 1, 1, 0), (0.3, 1, 1, 1, 0), (0.4, 1, 1, 1, 1), (1, 1, 1, 1, 1)])
    hidden = GLSlicerRenderer().render(scene_of(volume, opaque)).counters["fragments_contributing"]
    assert hidden < contributing / 2  # an opaque surface hides everything behind it
    assert "count_contributing" in oblique.timings and "count_contributing" not in GLSlicerRenderer(
        count_contributing=False).render(scene_of(volume)).timings


@needs_gl
def test_timings_and_caching(volume):
    backend = GLSlicerRenderer()
    scene = scene_of(volume, shading="phong", size=32)
    first = backend.render(scene)
    assert set(first.info["uploaded"]) == {"volume", "gradients", "transfer_function"}
    second = backend.render(scene)
    assert second.info["uploaded"] == [] and "upload" not in second.timings
    assert {"slices", "draw", "resolve", "readback", "total"} <= set(second.timings)
    assert second.timings["total"] > 0 and second.timings["draw"] > 0
    assert np.array_equal(first.image, second.image)
    bigger = backend.render(scene_of(volume, shading="phong", size=40))  # new targets, same textures
    assert bigger.image.shape == (40, 40, 4) and bigger.info["uploaded"] == []
    backend.close()


def test_a_step_finer_than_float32_resolves_is_refused():
    with pytest.raises(InputError, match=r"gl-slicer option step_factor: 1e-05 is finer than .* use step_factor ≥"):
        renderers.get("gl-slicer", step_factor=1e-5)


@needs_gl
def test_more_slices_than_this_machine_can_build_are_refused_before_any_work(volume, monkeypatch):
    import core.resources

    from renderers.gl.slicer import GLSlicerRenderer

    monkeypatch.setattr(core.resources, "memory_limit", lambda: 2 ** 20)
    with pytest.raises(InputError, match=r"gl-slicer: scene 'scene' at step_factor 0.01 needs 15.2 MiB \(up to 6237 slices "
                                         r"across the box's 62.4 diagonal × 2560 bytes\), this machine has 1 MiB; use a "
                                         r"larger step_factor"):
        GLSlicerRenderer(step_factor=0.01).check(scene_of(volume))
    GLSlicerRenderer(step_factor=0.5).check(scene_of(volume))
