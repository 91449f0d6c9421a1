"""Lens volumes (Ropinski et al. 2005) in ``vtk-gpu``: VTK's label map, cropping regions and clipping
planes against the reference's lens images, the lens's geometry in VTK's terms, and the refusals.

The geometry tests need no VTK; the rest is skipped where VTK cannot render offscreen here (as in
``tests/test_vtk.py``). Bounds are measured values (in the comments, VTK 9.7.2 on Mesa llvmpipe,
orthographic 48² views, early termination off) less a margin.
"""

import numpy as np
import pytest

import datasets
import renderers
from core.camera import Camera
from core.errors import InputError, UnsupportedFeatureError
from core.lens import Lens, LensAppearance
from core.mesh import Mesh
from core.scene import Scene, Shading, VolumeInstance, centering_transform
from core.transfer import GradientOpacity, TransferFunction
from core.volume import Volume
from pipeline.scene_io import rotation_matrix
from renderers.vtk import common
from renderers.vtk import gpu as vtk_gpu
from reports.metrics import psnr

AVAILABLE, WHY = common.offscreen_support()
needs_vtk = pytest.mark.skipif(not AVAILABLE, reason=f"VTK cannot render offscreen here: {WHY}")

METHODS = vtk_gpu.LENS_METHODS
CAMERA = Camera(azimuth=30.0, elevation=20.0)
LINEAR = TransferFunction.from_points([(0, 1, 1, 1, 0), (1, 1, 1, 1, 1)], name="linear")
OTHER = TransferFunction.ramp(0.3, 0.8, color=(0.2, 0.9, 0.4), alpha=0.6)
CLIP = LensAppearance("clip")
TINTED = LensAppearance("dvr", transfer_function=OTHER, opacity_scale=2.0)
CUBE = Volume(np.full((24, 24, 24), 6, np.uint8), name="medium")
"""A homogeneous medium, opacity 6/255 per voxel under :data:`LINEAR` (about 0.5 through the cube); box [-12, 12]³."""

# Lenses whose faces lie off the voxel grid, so that the label map's voxel edge shows.
SLAB = Lens("box", center=(10.3, 0.0, 0.0), size=(12.4, 40.0, 40.0), appearance=CLIP, name="slab")
"""Cuts the cube's +x face alone (x >= 4.1): every method renders it."""
INNER = Lens("box", center=(1.3, 2.4, 3.35), size=(10.4, 12.3, 8.2), appearance=CLIP, name="inner")
"""Inside the cube: cropping and the label map, not clipping planes."""


def cube(lens=None, *, volume=CUBE, transform=None, camera=CAMERA):
    return Scene([VolumeInstance(volume, LINEAR, transform=transform)], camera, width=48, height=48,
                 lenses=() if lens is None else [lens])


def skull(lens=None, *, gradient=None, shading="none"):
    volume = datasets.load("ct_skull", size=32, cache_dir=False)
    bone = datasets.get("ct_skull").preset("bone").transfer_function
    return Scene([VolumeInstance(volume, bone, gradient_opacity=gradient)], CAMERA, width=48, height=48,
                 shading=Shading(model=shading), lenses=() if lens is None else [lens])


def octahedron(scale):
    vertices = scale * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return Mesh(vertices, np.array(faces), name="octahedron")


@pytest.fixture(scope="module")
def reference():
    renderer = renderers.get("reference")
    return lambda scene: renderer.render(scene).image


@pytest.fixture(scope="module")
def vtk():
    """One accuracy-configured backend per lens method (no early termination), kept for the module."""
    backends = {method: renderers.get("vtk-gpu", early_termination=False, lens_method=method) for method in METHODS}
    yield backends
    for backend in backends.values():
        backend.close()


# ---------------------------------------------------------------------------------------------
# The option and the capabilities (no VTK needed)


def test_the_lens_method_option_and_the_capabilities():
    option = {row.name: row for row in vtk_gpu.VtkGpuRenderer.option_table}["lens_method"]
    assert option.default == "label-map" and option.choices == ("label-map", "cropping", "clipping-planes")
    with pytest.raises(InputError, match="vtk-gpu option lens_method"):
        vtk_gpu.VtkGpuRenderer(lens_method="segments")
    capabilities = vtk_gpu.VtkGpuRenderer.capabilities
    assert capabilities.lenses and all(method in capabilities.reasons["lenses"] for method in METHODS)
    cpu = renderers.backend_class("vtk-cpu").capabilities
    assert not cpu.lenses and "label-map" in cpu.reasons["lenses"]


# ---------------------------------------------------------------------------------------------
# The lens in VTK's terms (no VTK needed)


def test_the_label_map_marks_the_voxel_centres_inside_the_lens():
    instance = VolumeInstance(CUBE, LINEAR)
    # Voxel centres x = i − 11.5 of the centred cube: x in [4, 16] is i = 16..23.
    slab = vtk_gpu.lens_mask(Lens("box", center=(10.0, 0.0, 0.0), size=(12.0, 40.0, 40.0), appearance=CLIP), instance)
    expected = np.zeros((24, 24, 24), np.uint8)
    expected[:, :, 16:] = vtk_gpu.LENS_LABEL  # [z, y, x]
    assert slab.dtype == np.uint8 and np.array_equal(slab, expected)
    # A sphere of radius 1.2 on a voxel centre holds that centre and its six neighbours (√2 > 1.2).
    sphere = vtk_gpu.lens_mask(Lens("sphere", center=(0.5, 0.5, 0.5), radius=1.2, appearance=CLIP), instance)
    assert sphere.sum() == 7 * vtk_gpu.LENS_LABEL and sphere[12, 12, 12] == vtk_gpu.LENS_LABEL
    assert sphere[12, 12, 11] == sphere[12, 12, 13] == sphere[11, 12, 12] == vtk_gpu.LENS_LABEL
    # The mask follows the volume's placement: the volume and the slab turned together give the same mask.
    turn = rotation_matrix((1, 2, 3), 35)
    turned = VolumeInstance(CUBE, LINEAR, transform=turn @ centering_transform(CUBE))
    centre = (turn @ [10.0, 0.0, 0.0, 1.0])[:3]
    moved = Lens("box", center=centre, size=(12.0, 40.0, 40.0), transform=turn, appearance=CLIP)
    assert np.array_equal(vtk_gpu.lens_mask(moved, turned), expected)


def test_cropping_planes_are_the_box_lens_in_the_volumes_data_coordinates():
    # Data coordinates are the box [0, 24]³: world + 12.
    planes = vtk_gpu.cropping_planes(SLAB, VolumeInstance(CUBE, LINEAR))
    np.testing.assert_allclose(planes, (16.1, 28.5, -8.0, 32.0, -8.0, 32.0), atol=1e-12)
    turn = rotation_matrix((1, 2, 3), 35)
    turned = VolumeInstance(CUBE, LINEAR, transform=turn @ centering_transform(CUBE))
    moved = Lens("box", center=(turn @ [10.3, 0.0, 0.0, 1.0])[:3], size=SLAB.size, transform=turn, appearance=CLIP)
    np.testing.assert_allclose(vtk_gpu.cropping_planes(moved, turned), planes, atol=1e-9)
    with pytest.raises(UnsupportedFeatureError, match="rotated against volume 'medium'.*label-map"):
        vtk_gpu.cropping_planes(moved, VolumeInstance(CUBE, LINEAR))


@pytest.mark.parametrize("lens, normal, offset", [
    (SLAB, (-1, 0, 0), -4.1),  # its −x face at x = 4.1; kept: x < 4.1
    # A box turned 25° about z whose −x face alone crosses the cube: that face's plane, turned.
    (Lens("box", center=(30.0, 0.0, 0.0), size=(50.0, 80.0, 80.0), transform=rotation_matrix((0, 0, 1), 25),
          appearance=CLIP), (-np.cos(np.radians(25)), -np.sin(np.radians(25)), 0), 25 - 30 * np.cos(np.radians(25))),
    # Enclosing the cube: the kept side of any face is empty; beyond the cube's +x face: the whole cube is kept.
    (Lens("box", center=(0.0, 0.0, 0.0), size=(30.0, 30.0, 30.0), appearance=CLIP), (1, 0, 0), 15.0),
    (Lens("box", center=(20.0, 0.0, 0.0), size=(4.0, 4.0, 4.0), appearance=CLIP), (-1, 0, 0), -18.0),
])
def test_a_clipping_plane_is_the_face_that_alone_cuts_the_box(lens, normal, offset):
    found, c = vtk_gpu.clipping_plane(lens, VolumeInstance(CUBE, LINEAR))
    np.testing.assert_allclose(found, normal, atol=1e-12)
    assert c == pytest.approx(offset, abs=1e-9)


@pytest.mark.parametrize("lens, match", [
    (INNER, "more than one face"),
    (Lens("box", center=(12.0, 12.0, 0.0), size=(10.0, 10.0, 40.0), appearance=CLIP), "more than one face"),  # an edge
    (Lens("mesh", center=(0.0, 0.0, 0.0), mesh=octahedron(8.0), appearance=CLIP), "more than one face"),
    (Lens("sphere", center=(20.0, 0.0, 0.0), radius=10.0, appearance=CLIP), "sphere lens"),
])
def test_a_lens_no_one_face_of_which_cuts_the_box_has_no_clipping_plane(lens, match):
    with pytest.raises(UnsupportedFeatureError, match=f"{match}.*label-map"):
        vtk_gpu.clipping_plane(lens, VolumeInstance(CUBE, LINEAR))


# ---------------------------------------------------------------------------------------------
# Refusals, before any work


@needs_vtk
@pytest.mark.parametrize("method, lens, options, match", [
    ("cropping", Lens("box", center=(10.0, 0.0, 0.0), size=(12.0, 40.0, 40.0), transform=rotation_matrix((0, 0, 1), 10),
                      appearance=CLIP), {}, "rotated against volume"),
    ("cropping", Lens("sphere", center=(0.0, 0.0, 0.0), radius=5.0, appearance=CLIP), {}, "sphere lens"),
    ("cropping", Lens("box", center=(0.0, 0.0, 0.0), size=(8.0, 8.0, 8.0), appearance=TINTED), {}, "'dvr' appearance"),
    ("clipping-planes", Lens("sphere", center=(10.0, 0.0, 0.0), radius=5.0, appearance=CLIP), {}, "sphere lens"),
    ("clipping-planes", INNER, {}, "more than one face"),
    ("label-map", Lens("sphere", center=(0.0, 0.0, 0.0), radius=5.0, appearance=LensAppearance("mip")), {},
     "'mip' appearance"),
    ("label-map", Lens("sphere", center=(0.0, 0.0, 0.0), radius=5.0, appearance=LensAppearance("iso", isovalue=0.5)),
     {}, "'iso' appearance"),
    ("label-map", SLAB, {"depth_pass": True}, "depth pass"),
])
def test_unsupported_lens_scenes_are_refused_before_any_work(method, lens, options, match):
    with renderers.get("vtk-gpu", lens_method=method, **options) as backend:
        with pytest.raises(UnsupportedFeatureError, match=match) as info:
            backend.render(cube(lens))
        assert backend._pipeline is None  # nothing was built
        assert "use" in info.value.reason  # the fix is named


# ---------------------------------------------------------------------------------------------
# Against the reference


@needs_vtk
@pytest.mark.parametrize("method, lens, bound", [
    # Measured: cropping 55.9 dB, clipping planes 54.2 (their samples restart at the plane), label map 51.9
    # (the voxel edge); VTK without a lens 54.8 against the reference's no-lens image.
    ("cropping", SLAB, 52.0),
    ("clipping-planes", SLAB, 51.0),
    ("label-map", SLAB, 48.0),
    # Measured: cropping 55.0 dB, label map 46.7.
    ("cropping", INNER, 52.0),
    ("label-map", INNER, 43.0),
])
def test_a_clip_lens_over_a_homogeneous_medium_matches_the_reference(vtk, reference, method, lens, bound):
    backend = vtk[method]
    plain = backend.render(cube()).image  # first without the lens: the lens must rebuild the pipeline
    result = backend.render(cube(lens))
    truth = reference(cube(lens))
    assert psnr(truth, result.image) >= bound
    assert psnr(plain, result.image) < 35  # measured 20.2 (slab) and 31.2 (inner) dB: the lens shows
    assert result.info["lens_method"] == method and result.info["lens"] == "box clip"


@needs_vtk
def test_clipping_planes_render_a_turned_cutaway_that_cropping_cannot(vtk, reference):
    lens = Lens("box", center=(30.0, 0.0, 0.0), size=(50.0, 80.0, 80.0), transform=rotation_matrix((0, 0, 1), 25),
                appearance=CLIP)
    image = vtk["clipping-planes"].render(cube(lens)).image
    assert psnr(reference(cube(lens)), image) >= 51  # measured 55.0 dB (the label map: 47.3)
    assert psnr(vtk["clipping-planes"].render(cube()).image, image) < 25  # measured 19.3


@needs_vtk
def test_cropping_follows_a_turned_volume(vtk, reference):
    turn = rotation_matrix((1, 2, 3), 35)
    transform = turn @ centering_transform(CUBE)
    lens = Lens("box", center=(turn @ [10.3, 0.0, 0.0, 1.0])[:3], size=SLAB.size, transform=turn, appearance=CLIP)
    image = vtk["cropping"].render(cube(lens, transform=transform)).image
    assert psnr(reference(cube(lens, transform=transform)), image) >= 55  # measured 59.3 dB


@needs_vtk
@pytest.mark.parametrize("appearance, shading, bound", [
    # Measured: 33.5 dB unshaded, 35.1 with Phong, the error on the lens's rim, where the voxelised
    # lens (nearest voxel centre) and the exact one classify differently (VTK without a lens: 54.7, 45.8).
    (TINTED, "none", 31.0),
    (TINTED, "phong", 32.0),
    (CLIP, "none", 43.0),  # measured 46.4
])
def test_a_sphere_lens_on_a_phantom_by_the_label_map_matches_the_reference(vtk, reference, appearance, shading,
                                                                          bound):
    lens = Lens("sphere", center=(4.0, 2.0, 0.0), radius=9.0, appearance=appearance)
    image = vtk["label-map"].render(skull(lens, shading=shading)).image
    assert psnr(reference(skull(lens, shading=shading)), image) >= bound
    assert psnr(vtk["label-map"].render(skull(shading=shading)).image, image) < 30  # measured 19.3 to 26.0


@needs_vtk
@pytest.mark.parametrize("gradient, bound", [(None, 61.0), (GradientOpacity.from_points([(0, 0.2), (0.2, 1), (1, 1)]),
                                                          50.0)])
def test_the_label_tables_classify_as_the_lens_appearance(vtk, reference, gradient, bound):
    """A lens enclosing the volume has no rim: what is left is the label table (nearest-filtered in
    the scalar, opacity corrected by volbench) and the lens's gradient opacity."""
    appearance = LensAppearance("dvr", transfer_function=OTHER, gradient_opacity=gradient)
    lens = Lens("sphere", center=(0.0, 0.0, 0.0), radius=100.0, appearance=appearance)
    image = vtk["label-map"].render(skull(lens)).image
    assert psnr(reference(skull(lens)), image) >= bound  # measured 64.5 and 52.9 dB
