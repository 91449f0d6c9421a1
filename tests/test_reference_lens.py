"""The reference renderer's lens volumes against closed forms, the no-lens image and its exact modes.

Exactness notes. Samples stay on the no-lens lattice and each is classified by where it lies, so a
lens boundary is resolved to the step: a ray's counted path outside a clip lens differs from the
true one by at most half a step at each of the two lens boundaries inside the box, and over a
homogeneous medium of extinction ``σ`` the alpha ``1 − exp(−σL)`` is then within ``σ·Δ`` of the
closed form (a box face that cuts the lens is exact: the box's cut cells count their overlap).
"""

import numpy as np
import pytest

from core.camera import Camera
from core.errors import InputError
from core.lens import Lens, LensAppearance
from core.mesh import Mesh
from core.scene import Scene, Shading, VolumeInstance
from core.transfer import GradientOpacity, TransferFunction
from core.volume import Volume
from pipeline.scene_io import rotation_matrix
from renderers.reference import ReferenceRenderer
from renderers.reference import raycast

N = 16  # voxels a side; spacing 1, so the box is [-8, 8]³ in world units
ALPHA = 0.1
SIGMA = -np.log1p(-ALPHA)  # Δ0 = 1
CLIP = LensAppearance("clip")
ROTATION = rotation_matrix((1, 2, 3), 35)


def render(scene, **options):
    return ReferenceRenderer(depth=True, **options).render(scene)


def octahedron(scale):
    vertices = scale * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return Mesh(vertices, np.array(faces), name="octahedron")


def octahedron_planes(scale):
    normals = np.array([[a, b, c] for a in (1, -1) for b in (1, -1) for c in (1, -1)], float) / np.sqrt(3)
    return normals, np.full(8, scale / np.sqrt(3))


def smooth_volume(seed=0):
    rng = np.random.default_rng(seed)
    z, y, x = np.meshgrid(*(np.linspace(0, 1, N),) * 3, indexing="ij")
    field = 0.5 + 0.2 * np.sin(5 * x + rng.random()) * np.cos(4 * y) + 0.25 * z * np.sin(3 * z + 2 * x)
    return Volume(field.astype(np.float32))


def homogeneous(lens=None, *, camera=None, width=32, height=32):
    tf = TransferFunction.constant(color=(0.9, 0.5, 0.2), alpha=ALPHA)
    camera = camera or Camera(view_height=32.0, distance=60.0)
    return Scene([VolumeInstance(Volume(np.zeros((N, N, N), np.uint8)), tf)], camera=camera, width=width,
                 height=height, lenses=() if lens is None else [lens])


# ---------------------------------------------------------------------------------------------
# Independent intervals (numpy, the textbook formulas)


def slab_interval(o, d, lo, hi):
    """``[t0, t1]`` of rays in the box ``[lo, hi]`` (whole line); parallel rays by an inclusion test."""
    t0 = np.full(o.shape[:-1], -np.inf)
    t1 = np.full(o.shape[:-1], np.inf)
    for axis in range(3):
        p, q = o[..., axis], d[..., axis]
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (lo[axis] - p) / q, (hi[axis] - p) / q
        parallel = q == 0
        outside = parallel & ((p < lo[axis]) | (p > hi[axis]))
        t0 = np.where(parallel, np.where(outside, np.inf, t0), np.maximum(t0, np.minimum(ta, tb)))
        t1 = np.where(parallel, np.where(outside, -np.inf, t1), np.minimum(t1, np.maximum(ta, tb)))
    return t0, t1


def quadratic_interval(o, d, center, radius):
    f = o - center
    a = np.einsum("...i,...i", d, d)
    b = 2 * np.einsum("...i,...i", f, d)
    c = np.einsum("...i,...i", f, f) - radius ** 2
    disc = b * b - 4 * a * c
    root = np.sqrt(np.where(disc > 0, disc, np.nan))
    return (np.where(disc > 0, (-b - root) / (2 * a), np.inf), np.where(disc > 0, (-b + root) / (2 * a), -np.inf))


def rotated_box_interval(o, d, center, size, rotation):
    """A box of ``size`` turned by ``rotation`` about ``center``: rays carried into its frame by ``Rᵀ``."""
    r = rotation[:3, :3]
    return slab_interval((o - center) @ r, d @ r, -np.asarray(size) / 2, np.asarray(size) / 2)


def half_space_interval(o, d, normals, offsets):
    den = d @ normals.T
    num = offsets - o @ normals.T
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = num / den
    t0 = np.max(np.where(den < 0, ratio, -np.inf), axis=-1)
    t1 = np.min(np.where(den > 0, ratio, np.inf), axis=-1)
    missed = ((den == 0) & (num < 0)).any(axis=-1)
    return np.where(missed, np.inf, t0), np.where(missed, -np.inf, t1)


def outside_alpha(scene, lens_interval):
    """Beer–Lambert alpha over each pixel ray's path in the box (``t >= 0``) outside the lens."""
    origins, directions = scene.camera.rays(scene.width, scene.height)
    b0, b1 = slab_interval(origins, directions, np.full(3, -N / 2), np.full(3, N / 2))
    b0 = np.maximum(b0, 0.0)
    box = np.clip(b1 - b0, 0, None)
    l0, l1 = lens_interval(origins, directions)
    inside = np.clip(np.minimum(l1, b1) - np.maximum(l0, b0), 0, None)
    return -np.expm1(-SIGMA * (box - inside))


# ---------------------------------------------------------------------------------------------
# Intervals: the kernel against the closed forms


def test_a_sphere_lens_interval_is_the_quadratics_roots():
    rng = np.random.default_rng(1)
    o = rng.normal(scale=20, size=(500, 3))
    d = rng.normal(size=(500, 3))
    center, radius = np.array([1.0, -2.0, 3.0]), 15.0
    expected = np.array(quadratic_interval(o, d, center, radius)).T
    sphere = np.array([*center, radius])
    got = np.array([raycast.sphere_interval(oi, di, sphere) for oi, di in zip(o, d)])
    hit = np.isfinite(expected[:, 0])
    assert 50 < hit.sum() < 450
    np.testing.assert_allclose(got[hit], expected[hit], rtol=1e-10, atol=1e-10)
    assert (got[~hit, 0] == np.inf).all() and (got[~hit, 1] == -np.inf).all()
    # A tangent line (distance to the centre exactly r) is empty, never NaN.
    assert raycast.sphere_interval(np.array([3.0, 0, 10]), np.array([0.0, 0, -1]), np.array([0, 0, 0, 3.0])) == (
        np.inf, -np.inf)


def test_a_rotated_box_lens_interval_is_the_slab_test_in_its_frame():
    rng = np.random.default_rng(2)
    o = rng.normal(scale=6, size=(500, 3))
    d = rng.normal(size=(500, 3))
    lens = Lens("box", center=(2, -1, 0.5), size=(6, 10, 4), transform=ROTATION, appearance=CLIP)
    m = np.linalg.inv(lens.object_to_world())[:3]
    normals, offsets = lens.half_spaces()
    got = np.array([raycast.planes_interval(oi, di, m, normals, offsets) for oi, di in zip(o, d)])
    expected = np.array(rotated_box_interval(o, d, np.array(lens.center), lens.size, ROTATION)).T
    hit = expected[:, 0] < expected[:, 1]
    assert 50 < hit.sum() < 450
    np.testing.assert_allclose(got[hit], expected[hit], rtol=1e-11, atol=1e-11)
    assert (got[~hit, 0] >= got[~hit, 1]).all()


def test_a_convex_mesh_lens_is_the_same_half_spaces():
    rng = np.random.default_rng(3)
    o = rng.normal(scale=4, size=(500, 3))
    d = rng.normal(size=(500, 3))
    lens = Lens("mesh", center=(1, 1, 1), mesh=octahedron(5.0), appearance=CLIP)
    m = np.linalg.inv(lens.object_to_world())[:3]
    normals, offsets = lens.half_spaces()
    got = np.array([raycast.planes_interval(oi, di, m, normals, offsets) for oi, di in zip(o, d)])
    expected = np.array(half_space_interval(o - 1.0, d, *octahedron_planes(5.0))).T
    hit = expected[:, 0] < expected[:, 1]
    assert 50 < hit.sum() < 450
    np.testing.assert_allclose(got[hit], expected[hit], rtol=1e-12, atol=1e-12)
    assert (got[~hit, 0] >= got[~hit, 1]).all()


# ---------------------------------------------------------------------------------------------
# Clip lenses over a homogeneous medium: Beer–Lambert over the path outside the lens


PERSPECTIVE = Camera(projection="perspective", distance=30.0, fov_y=40.0)
CLIP_CASES = {
    "sphere partly outside the box": (Lens("sphere", center=(6, 1, 0), radius=5, appearance=CLIP), None,
                                      lambda o, d: quadratic_interval(o, d, np.array([6.0, 1, 0]), 5.0)),
    "rotated box": (Lens("box", center=(0, 0, 2), size=(8, 12, 6), transform=ROTATION, appearance=CLIP), None,
                    lambda o, d: rotated_box_interval(o, d, np.array([0.0, 0, 2]), (8, 12, 6), ROTATION)),
    "octahedron mesh": (Lens("mesh", center=(0, 0, 0), mesh=octahedron(7.0), appearance=CLIP), None,
                        lambda o, d: half_space_interval(o, d, *octahedron_planes(7.0))),
    "sphere enclosing the perspective camera": (
        Lens("sphere", center=(0, 0, 30), radius=25, appearance=CLIP), PERSPECTIVE,
        lambda o, d: quadratic_interval(o, d, np.array([0.0, 0, 30]), 25.0)),
    "grazing sphere (pixel centres on its silhouette)": (
        Lens("sphere", center=(0.5, 0.5, 0), radius=3, appearance=CLIP), None,
        lambda o, d: quadratic_interval(o, d, np.array([0.5, 0.5, 0]), 3.0)),
    "grazing box (pixel centres in its faces)": (
        Lens("box", center=(0.5, 0.5, 0), size=(6, 6, 6), appearance=CLIP), None,
        lambda o, d: slab_interval(o, d, np.array([-2.5, -2.5, -3]), np.array([3.5, 3.5, 3]))),
}


@pytest.mark.parametrize("case", CLIP_CASES)
def test_a_clip_lens_leaves_beer_lambert_over_the_path_outside_it(case):
    lens, camera, interval = CLIP_CASES[case]
    scene = homogeneous(lens, camera=camera)
    expected = outside_alpha(scene, interval)
    assert (expected < outside_alpha(scene, lambda o, d: (np.full(o.shape[:-1], np.inf),) * 2) - 0.05).any()
    for factor in (0.5, 0.0625):
        result = render(scene, step_factor=factor)
        image = result.image
        assert np.isfinite(image).all()
        step = result.info["step"]
        error = np.abs(image[..., 3].astype(float) - expected)
        assert error.max() <= SIGMA * step + 1e-6, (case, factor, error.max())
        colour = np.array([0.9, 0.5, 0.2])
        np.testing.assert_allclose(image[..., :3], image[..., 3:] * colour, atol=1e-6)


@pytest.mark.parametrize("center", [(0, 0, 20), (0, 0, -20), (20, 0, 0)], ids=["in front", "behind", "beside"])
def test_a_lens_outside_the_box_changes_nothing(center):
    lens = Lens("sphere", center=center, radius=5, appearance=CLIP)
    plain = render(homogeneous())
    lensed = render(homogeneous(lens))
    np.testing.assert_array_equal(lensed.image, plain.image)
    assert lensed.counters == plain.counters


def test_a_clip_lens_enclosing_the_volume_leaves_nothing():
    lens = Lens("box", center=(0, 0, 0), size=(17, 17, 17), appearance=CLIP)
    result = render(homogeneous(lens))
    assert not result.image.any() and result.counters["samples"] == 0
    assert result.counters["rays_hit"] == render(homogeneous()).counters["rays_hit"]


# ---------------------------------------------------------------------------------------------
# A lens with the outside appearance is no lens, bit for bit


def shaded_scene(lens=None, *, projection="perspective"):
    volume = smooth_volume()
    instance = VolumeInstance(volume, TransferFunction.ramp(0.4, 0.9, color=(0.8, 0.6, 0.3), alpha=0.4),
                              gradient_opacity=GradientOpacity.from_points([(0, 0.3), (0.5, 1), (1, 1)]))
    camera = Camera(azimuth=25, elevation=-15, projection=projection)
    return Scene([instance], camera=camera, width=40, height=32, shading=Shading(model="phong"),
                 lenses=() if lens is None else [lens])


SAME = {"sphere": dict(shape="sphere", center=(1, 2, 0), radius=5),
        "camera inside sphere": dict(shape="sphere", center=(0, 0, 0), radius=200),
        "rotated box": dict(shape="box", center=(0, -1, 1), size=(7, 9, 5), transform=ROTATION),
        "grazing box": dict(shape="box", center=(0, 0, 0), size=(16, 16, 16)),
        "octahedron": dict(shape="mesh", center=(-1, 0, 1), mesh=octahedron(6.0))}


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
@pytest.mark.parametrize("shape", SAME)
def test_a_lens_with_the_outside_appearance_gives_the_no_lens_image_bit_for_bit(shape, projection):
    plain_scene = shaded_scene(projection=projection)
    instance = plain_scene.volumes[0]
    # A copy of the table (not the same object): only the values may matter.
    tf = TransferFunction(instance.transfer_function.table.copy())
    same = LensAppearance("dvr", transfer_function=tf, gradient_opacity=instance.gradient_opacity)
    lensed = render(shaded_scene(Lens(appearance=same, **SAME[shape]), projection=projection))
    plain = render(plain_scene)
    assert plain.image[..., 3].max() > 0.5
    np.testing.assert_array_equal(lensed.image, plain.image)
    np.testing.assert_array_equal(lensed.info["depth"], plain.info["depth"])
    assert lensed.counters == plain.counters


def test_a_transparency_lens_changes_only_the_rays_through_it():
    scene = shaded_scene(projection="orthographic")
    instance = scene.volumes[0]
    center, radius = np.array([1.0, 2.0, 0.0]), 4.0
    faint = LensAppearance("dvr", transfer_function=instance.transfer_function,
                           gradient_opacity=instance.gradient_opacity, opacity_scale=0.2)
    lensed = render(shaded_scene(Lens("sphere", center=center, radius=radius, appearance=faint),
                                 projection="orthographic")).image
    plain = render(scene).image
    origins, directions = scene.camera.rays(scene.width, scene.height)
    t0, t1 = quadratic_interval(origins, directions, center, radius)
    missed = ~(t1 - t0 > 0)
    through = t1 - t0 > 4.0
    np.testing.assert_array_equal(lensed[missed], plain[missed])
    assert (lensed[through, 3] < plain[through, 3] - 0.01).mean() > 0.9


# ---------------------------------------------------------------------------------------------
# iso and mip inside a lens: exact, restricted to the lens segment


def ramp_along_z():
    """``s = (z_world + 7.5)/15``: the trilinear field is exact, ``s = 0.5`` on the plane ``z = 0``."""
    data = np.broadcast_to((np.arange(N, dtype=np.float32) / (N - 1))[:, None, None], (N, N, N))
    return Volume(np.ascontiguousarray(data))


TRANSPARENT = TransferFunction.constant(alpha=0.0)
IDENTITY = TransferFunction.from_points([(0, 0, 1, 0, 0), (1, 0, 1, 0, 1)])


def ramp_scene(lens, outside=TRANSPARENT, *, mode="dvr", shading="none", volume=None):
    instance = VolumeInstance(volume or ramp_along_z(), outside, isovalue=0.5)
    return Scene([instance], camera=Camera(view_height=32.0, distance=60.0), width=32, height=32, mode=mode,
                 shading=Shading(model=shading), lenses=() if lens is None else [lens])


def pixel_offsets(scene):
    origins, directions = scene.camera.rays(scene.width, scene.height)
    np.testing.assert_array_equal(directions, np.broadcast_to([0.0, 0.0, -1.0], directions.shape))
    return origins, np.hypot(origins[..., 0], origins[..., 1])


def test_an_iso_lens_finds_the_surface_inside_it_and_only_there():
    lens = Lens("sphere", center=(0, 0, 0), radius=4, appearance=LensAppearance("iso", isovalue=0.5,
                                                                                 transfer_function=IDENTITY))
    scene = ramp_scene(lens)
    origins, r = pixel_offsets(scene)
    result = render(scene)
    inside, outside = r < 3.9, r > 4.1
    assert inside.sum() > 20
    # The data are float32: 7/15 and 8/15 carry 3e-8 of rounding, 15 times that along z.
    np.testing.assert_allclose(result.info["depth"][inside], origins[inside, 2], rtol=0, atol=1e-6)
    assert (result.image[inside] == [0, 1, 0, 1]).all()
    assert not result.image[outside].any()
    # A lens that does not reach the plane z = 0 has no crossing in its segment.
    above = Lens("sphere", center=(0, 0, 5), radius=3, appearance=lens.appearance)
    assert not render(ramp_scene(above)).image.any()


def test_an_iso_lens_is_composited_behind_the_medium_in_front_and_hides_what_is_behind():
    red = TransferFunction.constant(color=(1, 0, 0), alpha=ALPHA)
    lens = Lens("box", center=(0, 0, -1), size=(8, 8, 4), appearance=LensAppearance("iso", isovalue=0.5,
                                                                                  transfer_function=IDENTITY))
    scene = ramp_scene(lens, red)
    origins, _ = pixel_offsets(scene)
    result = render(scene)
    image = result.image.astype(float)
    hit = (np.abs(origins[..., 0]) < 3.9) & (np.abs(origins[..., 1]) < 3.9)
    np.testing.assert_allclose(image[hit, 3], 1.0, atol=1e-6)
    # Red from the 7 units in front of the lens (box face z = 8 to lens face z = 1), none from the lens
    # segment before the surface at z = 0, then green.
    front = np.exp(-SIGMA * 7.0)
    assert np.abs(image[hit, 1] - front).max() <= SIGMA * result.info["step"] + 1e-6
    np.testing.assert_allclose(image[hit, 0] + image[hit, 1], 1.0, atol=1e-6)


@pytest.mark.parametrize("towards_camera", [True, False])
def test_a_mip_lens_takes_the_exact_maximum_of_its_segment(towards_camera):
    volume = ramp_along_z()
    if not towards_camera:
        volume = Volume(np.ascontiguousarray(volume.data[::-1]))
    lens = Lens("sphere", center=(0, 0, -2), radius=3, appearance=LensAppearance("mip", transfer_function=IDENTITY))
    scene = ramp_scene(lens, volume=volume)
    origins, r = pixel_offsets(scene)
    result = render(scene)
    inside = r < 2.9
    # The field is linear in z: the maximum is where the ray enters the lens (s grows towards the
    # camera) or leaves it (s grows away from it), not outside the lens segment.
    z = -2 + (1 if towards_camera else -1) * np.sqrt(9 - r[inside] ** 2)
    expected = (z + 7.5) / 15 if towards_camera else (7.5 - z) / 15
    np.testing.assert_allclose(result.image[inside, 3], expected, rtol=0, atol=1e-6)
    np.testing.assert_allclose(result.info["depth"][inside], origins[inside, 2] - z, rtol=0, atol=1e-9)
    assert not result.image[r > 3.1].any()


@pytest.mark.parametrize("mode", ["mip", "iso"])
def test_a_mip_or_iso_lens_enclosing_the_volume_is_that_mode_bit_for_bit(mode):
    volume = smooth_volume(seed=4)
    tf = TransferFunction.ramp(0.3, 0.9, color=(0.7, 0.8, 0.9))
    kwargs = {"isovalue": 0.55} if mode == "iso" else {}
    lens = Lens("sphere", center=(0, 0, 0), radius=100, appearance=LensAppearance(mode, transfer_function=tf,
                                                                                **kwargs))
    lensed = render(ramp_scene(lens, volume=volume, shading="phong"))
    plain_scene = Scene([VolumeInstance(volume, tf, isovalue=0.55)], camera=lensed_camera(lens, volume), width=32,
                        height=32, mode=mode, shading=Shading(model="phong"))
    plain = render(plain_scene)
    assert plain.image[..., 3].max() > 0.5
    np.testing.assert_array_equal(lensed.image, plain.image)
    np.testing.assert_array_equal(lensed.info["depth"], plain.info["depth"])


def lensed_camera(lens, volume):
    return ramp_scene(lens, volume=volume).camera


# ---------------------------------------------------------------------------------------------
# Refusals


def test_pre_classification_refuses_a_lens_scene():
    scene = homogeneous(Lens("sphere", center=(0, 0, 0), radius=3, appearance=CLIP))
    with pytest.raises(InputError, match="classification='pre'.*lens"):
        ReferenceRenderer(classification="pre").render(scene)


def test_the_reference_has_the_lens_capability():
    scene = homogeneous(Lens("sphere", center=(0, 0, 0), radius=3, appearance=CLIP))
    assert ReferenceRenderer.capabilities.lenses and ReferenceRenderer.capabilities.missing(scene) == []
    assert "lenses" not in ReferenceRenderer.capabilities.reasons


def test_the_work_estimate_adds_a_mip_or_iso_lens_walk_to_the_steps():
    renderer = ReferenceRenderer()
    plain = renderer.work(homogeneous())[0]
    assert renderer.work(homogeneous(Lens("sphere", center=(0, 0, 0), radius=3, appearance=CLIP)))[0] == plain
    mip = homogeneous(Lens("sphere", center=(0, 0, 0), radius=3, appearance=LensAppearance("mip")))
    assert renderer.work(mip)[0] == plain + 32 * 32 * (3 * N + 3)
