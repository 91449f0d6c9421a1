"""The reference renderer against closed-form answers (homogeneous media, MIP, isosurfaces, convergence).

Exactness notes. With a constant transfer function the medium is homogeneous whatever the
reconstruction, so box images are exact: the cells a box cuts count their overlap length, so a
ray with path length ``L`` has alpha ``1 − (1 − α)^(L/Δ0)`` = ``1 − exp(−σL)`` for any step. A
binary sphere is not exact: trilinear reconstruction of a sampled distance field has an
``O(h²)`` level set and the sharp step in the transfer function an ``O(Δ)`` chord error inside
the box, so the sphere test asserts the error shrinks with both. An L1 ball
(an octahedron centred on a voxel) is exact, because ``|x| + |y| + |z|`` is linear inside every
reconstruction cell when its kinks lie on voxel-centre planes.
"""

import math

import numpy as np
import pytest

from core.volume import Volume
from core.camera import Camera
from core.scene import Scene, Shading, VolumeInstance
from core.transfer import TransferFunction
from renderers.reference import ReferenceRenderer


def render(scene, **options):
    return ReferenceRenderer(**options).render(scene)


def box_path_lengths(origins, directions, half_extent):
    """Analytic path length of each ray (t >= 0) through the world box ``[-h, h]``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = (-half_extent - origins) / directions
        tb = (half_extent - origins) / directions
    near = np.nanmax(np.where(np.isfinite(ta), np.minimum(ta, tb), -np.inf), axis=-1)
    far = np.nanmin(np.where(np.isfinite(ta), np.maximum(ta, tb), np.inf), axis=-1)
    return np.clip(far - np.maximum(near, 0.0), 0.0, None)


# ---------------------------------------------------------------------------------------------
# Homogeneous boxes


def test_face_on_box_alpha_and_colour_are_exact():
    """Face-on: every covered pixel has A = 1 − exp(−σL) and C = c·A (emission–absorption slab)."""
    alpha, colour = 0.1, (0.9, 0.5, 0.2)
    volume = Volume(np.zeros((16, 16, 16), np.uint8), spacing=(1.0, 1.0, 1.5))  # depth L = 24
    tf = TransferFunction.constant(color=colour, alpha=alpha)
    scene = Scene([VolumeInstance(volume, tf)], camera=Camera(view_height=32.0, distance=60.0), width=32, height=32)
    sigma = -math.log(1 - alpha) / 1.0  # Δ0 = smallest spacing = 1
    expected = 1 - math.exp(-sigma * 24.0)
    covered = np.zeros((32, 32), bool)
    covered[8:24, 8:24] = True
    for factor in (1.0, 0.5, 0.3, 0.25):
        image = render(scene, step_factor=factor).image
        np.testing.assert_allclose(image[covered, 3], expected, rtol=0, atol=2e-7)
        np.testing.assert_allclose(image[covered, :3], np.outer(np.full(covered.sum(), expected), colour), atol=2e-7)
        assert not image[~covered].any()


def test_reference_step_of_the_transfer_function_is_honoured():
    """Table opacity per Δ0 = 0.5 doubles the optical depth of the same box."""
    table = np.tile(np.float32([1, 1, 1, 0.05]), (256, 1))
    volume = Volume(np.zeros((8, 8, 8), np.uint8))
    scene = Scene([VolumeInstance(volume, TransferFunction(table, reference_step=0.5))],
                  camera=Camera(view_height=16.0, distance=40.0), width=16, height=16)
    image = render(scene).image
    np.testing.assert_allclose(image[8, 8, 3], 1 - 0.95 ** (8 / 0.5), atol=2e-7)


def test_opacity_correction_uses_the_object_space_step_of_scaled_volumes():
    """Optical depth is counted in object units: a box scaled ×(2, 1, 3) keeps its 8-voxel depth."""
    alpha = 0.1
    volume = Volume(np.zeros((8, 8, 8), np.uint8))
    transform = np.diag([2.0, 1.0, 3.0, 1.0])
    transform[:3, 3] = (-8, -4, -12)
    scene = Scene([VolumeInstance(volume, TransferFunction.constant(alpha=alpha), transform=transform)],
                  camera=Camera(view_height=20.0, distance=60.0), width=20, height=20)
    for factor in (0.25, 1 / 3):
        image = render(scene, step_factor=factor).image
        np.testing.assert_allclose(image[10, 10, 3], 1 - (1 - alpha) ** 8, atol=2e-7)


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_oblique_box_alpha_is_exact_for_every_path_length(projection):
    """Path lengths that are no multiple of the step still give A = 1 − (1 − α)^(L/Δ0) and C = c·A.

    The float32 image holds the result to its rounding (relative 2⁻²⁴); the old lattice, which
    counted a cut cell as a whole step or none, was off by up to σΔ/2.
    """
    alpha, colour = 0.15, np.array([0.9, 0.5, 0.2])
    volume = Volume(np.zeros((20, 16, 12), np.uint8))
    tf = TransferFunction.constant(color=tuple(colour), alpha=alpha)
    camera = Camera(azimuth=25, elevation=15, view_height=36.0, distance=80.0, projection=projection, fov_y=26.0)
    scene = Scene([VolumeInstance(volume, tf)], camera=camera, width=40, height=40)
    origins, directions = scene.camera.rays(40, 40)
    lengths = box_path_lengths(origins, directions, np.array([6.0, 8.0, 10.0]))
    expected = 1 - (1 - float(tf.table[0, 3])) ** lengths  # Δ0 = 1; the table holds float32(α)
    covered = lengths > 0
    assert covered.sum() > 400  # the box covers a good part of the picture
    for factor in (2.0, 1.0, 0.7):
        fractions = lengths[covered] / factor % 1.0
        assert np.mean((fractions > 0.05) & (fractions < 0.95)) > 0.8  # mostly cut cells
        image = render(scene, step_factor=factor).image
        np.testing.assert_allclose(image[..., 3], expected, rtol=2e-7, atol=1e-12)
        np.testing.assert_allclose(image[..., :3], expected[..., None] * colour, rtol=2e-7, atol=1e-12)


def test_faint_oblique_box_is_exact_to_1e_9():
    """A faint medium keeps alpha near 0.01, where float32 resolves 1e-9: the kernel is that exact."""
    alpha = 0.001
    volume = Volume(np.zeros((12, 10, 14), np.uint8), spacing=(1.0, 1.5, 0.75))  # Δ0 = 0.75
    tf = TransferFunction.constant(alpha=alpha)
    scene = Scene([VolumeInstance(volume, tf)],
                  camera=Camera(azimuth=-35, elevation=40, view_height=28.0, distance=60.0), width=32, height=32)
    origins, directions = scene.camera.rays(32, 32)
    lengths = box_path_lengths(origins, directions, np.array([7.0, 7.5, 4.5]))
    expected = 1 - (1 - float(tf.table[0, 3])) ** (lengths / 0.75)  # the table holds float32(α)
    assert (lengths > 0).sum() > 300 and expected.max() < 0.03
    for factor in (2.0, 1.0):
        image = render(scene, step_factor=factor).image
        np.testing.assert_allclose(image[..., 3], expected, rtol=0, atol=1e-9)


def test_box_behind_a_gap_composites_front_to_back():
    """Two separate boxes on one ray: C = c1·A1 + (1 − A1)·c2·A2 on the shared lattice."""
    a1, a2 = 0.2, 0.3
    c1, c2 = np.array([1.0, 0.2, 0.1]), np.array([0.1, 0.3, 1.0])
    volume = Volume(np.zeros((6, 8, 8), np.uint8))
    near = np.eye(4)
    near[:3, 3] = (-4, -4, 5)  # z in [5, 11]
    far = np.eye(4)
    far[:3, 3] = (-4, -4, -9)  # z in [-9, -3]
    scene = Scene([VolumeInstance(volume, TransferFunction.constant(color=tuple(c1), alpha=a1), transform=near, name="near"),
                   VolumeInstance(volume, TransferFunction.constant(color=tuple(c2), alpha=a2), transform=far, name="far")],
                  camera=Camera(view_height=16.0, distance=40.0), width=16, height=16)
    image = render(scene).image
    A1, A2 = 1 - (1 - a1) ** 6, 1 - (1 - a2) ** 6
    expected = np.append(c1 * A1 + (1 - A1) * c2 * A2, A1 + (1 - A1) * A2)
    np.testing.assert_allclose(image[8, 8], expected, atol=1e-6)


def test_dvr_of_a_depth_ramp_equals_compositing_on_the_documented_cells():
    """Cells [kΔ, (k + 1)Δ] from the entry, the last cut by the exit face and sampled at its overlap's
    midpoint with α' for its length; clamp-to-edge linear reconstruction, TF lookup, C += (1 − A)α'c."""
    nz, step = 10, 0.3
    ramp = np.float32([0.05, 0.2, 0.9, 0.4, 0.6, 0.1, 0.75, 0.3, 0.95, 0.5])
    data = np.broadcast_to(ramp[:, None, None], (nz, 6, 6)).copy()
    tf = TransferFunction.from_points([(0, 0.9, 0.1, 0.1, 0.0), (0.5, 0.1, 0.9, 0.2, 0.3), (1, 0.2, 0.2, 1.0, 0.7)])
    volume = Volume(data, spacing=(1.0, 1.0, 0.8))  # Δ0 = 0.8, depth 8
    scene = Scene([VolumeInstance(volume, tf)], camera=Camera(view_height=12.0, distance=30.0), width=12, height=12)
    result = render(scene, step=step)
    # The ray enters at object z = 8 and walks down; voxel k sits at z = (k + ½)·0.8.
    starts = np.arange(math.ceil(8 / step)) * step  # 27 cells, the last [7.8, 8.1] cut to [7.8, 8]
    ends = np.minimum(starts + step, 8.0)
    t = (starts + ends) / 2
    rgba = tf.lookup(np.interp((8 - t) / 0.8 - 0.5, np.arange(nz), ramp.astype(np.float64)))
    corrected = 1 - (1 - rgba[:, 3]) ** ((ends - starts) / 0.8)
    colour, alpha = np.zeros(3), 0.0
    for a, c in zip(corrected, rgba[:, :3]):
        colour += (1 - alpha) * a * c
        alpha += (1 - alpha) * a
    np.testing.assert_allclose(result.image[6, 6], [*colour, alpha], rtol=2e-7, atol=1e-9)
    assert 0.3 < alpha < 0.99
    assert result.counters["samples"] == 36 * 27  # a 6 × 6 pixel face, 27 cells per ray


# ---------------------------------------------------------------------------------------------
# Sphere of constant extinction


def sphere_alpha_error(n, factor, radius=6.0, side=16.0, alpha=0.2):
    """Mean and interior-max |A − A_analytic| for a binary sphere sampled on n³ voxels."""
    h = side / n
    centres = (np.arange(n) + 0.5) * h - side / 2
    z, y, x = np.meshgrid(centres, centres, centres, indexing="ij")
    # A distance field, linear across the surface, classified by a sharp step at 0.5.
    data = (0.5 + (radius - np.sqrt(x * x + y * y + z * z)) / 20).astype(np.float32)
    table = TransferFunction.step(0.5, size=4096, alpha=alpha).table
    tf = TransferFunction(table, reference_step=1.0)
    scene = Scene([VolumeInstance(Volume(data, spacing=(h, h, h)), tf)],
                  camera=Camera(view_height=side, distance=50.0), width=32, height=32)
    image = render(scene, step_factor=factor).image
    origins, _ = scene.camera.rays(32, 32)
    d = np.hypot(origins[..., 0], origins[..., 1])
    chord = 2 * np.sqrt(np.clip(radius ** 2 - d ** 2, 0, None))
    error = np.abs(image[..., 3] - (1 - (1 - alpha) ** chord))
    return error.mean(), error[d < radius - 1].max()


def test_sphere_chord_error_shrinks_with_voxel_and_step():
    results = [sphere_alpha_error(n, 0.5) for n in (12, 24, 48)]
    means = [m for m, _ in results]
    assert means[1] < 0.7 * means[0] and means[2] < 0.7 * means[1], means
    assert means[2] < 0.003
    assert results[2][1] < 0.01  # away from the silhouette, where the chord's slope is unbounded
    finer_step, _ = sphere_alpha_error(24, 0.25)
    assert finer_step < means[1]


# ---------------------------------------------------------------------------------------------
# Maximum intensity projection


def blob_volume(n, centre, sigma, peak, dtype=np.float32):
    idx = np.arange(n)
    z, y, x = np.meshgrid(idx, idx, idx, indexing="ij")
    r2 = (x - centre[0]) ** 2 + (y - centre[1]) ** 2 + (z - centre[2]) ** 2
    return (peak * np.exp(-r2 / (2 * sigma ** 2))).astype(dtype)


def test_mip_equals_the_transfer_function_of_each_column_maximum():
    """Pixels on voxel columns and a lattice through voxel centres: MIP = TF(max of the column)."""
    n = 24
    data = blob_volume(n, (10, 13, 9), 3.5, 0.8) + blob_volume(n, (4, 4, 20), 2.0, 0.3)
    tf = TransferFunction.from_points([(0, 0.1, 0.2, 1.0, 0.0), (0.5, 0.2, 1.0, 0.3, 0.4), (1, 1.0, 0.3, 0.1, 0.9)])
    scene = Scene([VolumeInstance(Volume(data), tf)], camera=Camera(view_height=float(n), distance=60.0),
                  width=n, height=n, mode="mip")
    normalised = Volume(data).normalized(np.float64)
    column_max = normalised.max(axis=0)[::-1]  # image row 0 is the top, y = n − 1
    rgba = tf.lookup(column_max)
    expected = np.concatenate([rgba[..., :3] * rgba[..., 3:], rgba[..., 3:]], axis=-1)
    for factor in (1 / 3, 1.0):  # both lattices pass through every voxel centre
        image = render(scene, step_factor=factor).image
        np.testing.assert_allclose(image, expected, atol=1e-6)
    peak = tf.lookup(normalised.max())
    np.testing.assert_allclose(image[n - 1 - 13, 10], [*(peak[:3] * peak[3]), peak[3]], atol=1e-6)
    assert image[..., 3].max() == image[n - 1 - 13, 10, 3]


# ---------------------------------------------------------------------------------------------
# Convergence


def test_dvr_converges_as_the_step_shrinks():
    n = 24
    data = blob_volume(n, (11.3, 12.6, 10.8), 4.0, 1.0) + blob_volume(n, (6.5, 15.2, 14.0), 2.5, 0.6)
    tf = TransferFunction.from_points([(0, 0, 0, 1, 0), (0.15, 0.2, 0.4, 1.0, 0.0), (0.6, 1.0, 0.6, 0.2, 0.25),
                                       (1.0, 1.0, 1.0, 1.0, 0.6)])
    scene = Scene([VolumeInstance(Volume(np.clip(data, 0, 1)), tf)],
                  camera=Camera(azimuth=30, elevation=20, view_height=30.0, distance=80.0), width=32, height=32,
                  shading=Shading(model="phong"))
    reference = render(scene, step_factor=1 / 32).image
    errors = []
    for factor in (1.0, 0.5, 0.25, 0.125):
        image = render(scene, step_factor=factor).image
        errors.append(float(np.sqrt(np.mean((image - reference) ** 2))))
    ratios = [b / a for a, b in zip(errors, errors[1:])]
    assert all(r < 0.6 for r in ratios), (errors, ratios)  # at least first order (measured ≈ 0.25)
    assert errors[-1] < 0.2 * errors[0], errors
    assert reference[..., 3].max() > 0.5  # a non-trivial picture


def observed_order(factors, errors):
    """Least-squares slope of log(error) against log(step)."""
    return float(np.polyfit(np.log(factors), np.log(errors), 1)[0])


def test_whole_box_medium_converges_with_second_order():
    """A smooth semi-transparent field filling its box, seen obliquely: every ray enters and leaves
    through cut cells, which counted as a whole step or none used to leave an O(Δ) error."""
    n = 20
    z, y, x = np.meshgrid(*(np.arange(n) / n,) * 3, indexing="ij")
    data = (0.55 + 0.2 * np.sin(5.0 * x + 1.0) * np.cos(4.0 * y - 0.5) + 0.2 * np.sin(6.0 * z + 2.0 * x))
    tf = TransferFunction.from_points([(0, 0.1, 0.3, 1.0, 0.02), (0.5, 0.3, 0.9, 0.4, 0.08),
                                       (1.0, 1.0, 0.5, 0.2, 0.2)])
    scene = Scene([VolumeInstance(Volume(data.astype(np.float32)), tf)],
                  camera=Camera(azimuth=30, elevation=20, view_height=34.0, distance=80.0), width=32, height=32)
    truth = render(scene, step_factor=1 / 32).image.astype(np.float64)
    factors = (2.0, 1.0, 0.5, 0.25)
    errors = [float(np.sqrt(np.mean((render(scene, step_factor=f).image - truth) ** 2))) for f in factors]
    order = observed_order(factors, errors)
    assert order >= 1.7, (errors, order)
    assert all(b < a for a, b in zip(errors, errors[1:])), errors
    assert 0.3 < truth[..., 3].max() < 0.99  # semi-transparent


# ---------------------------------------------------------------------------------------------
# Isosurfaces


def l1_ball_scene(radius, camera, *, shading=Shading(), size=48):
    n = 32
    idx = np.arange(n) - 16.0  # voxel 16 (object 16.5) is the centre
    z, y, x = np.meshgrid(idx, idx, idx, indexing="ij")
    data = (np.abs(x) + np.abs(y) + np.abs(z)).astype(np.float32)
    volume = Volume(data, value_range=(0.0, 100.0))
    tf = TransferFunction.from_points([(0, 1.0, 0.2, 0.1, 1), (0.2, 0.1, 0.8, 0.3, 1), (1, 0.1, 0.1, 1.0, 1)])
    instance = VolumeInstance(volume, tf, isovalue=radius / 100.0, name="l1-ball")
    return Scene([instance], camera=camera, width=size, height=size, mode="iso", shading=shading), tf


def analytic_entry(origins, directions, centre, radius, near, far, step=0.01):
    """First t in [near, far] with |p − centre|₁ <= radius: dense march, then bisection (inf for misses)."""
    ts = np.arange(near, far, step)
    first = np.empty(origins.shape[:-1], np.int64)
    for row in range(origins.shape[0]):  # row by row keeps the march small in memory
        points = origins[row, :, None, :] + ts[:, None] * directions[row, :, None, :]
        inside = np.abs(points - centre).sum(axis=-1) <= radius
        first[row] = np.where(inside.any(axis=-1), inside.argmax(axis=-1), -1)
    lo = np.where(first > 0, ts[np.maximum(first - 1, 0)], np.inf)
    hi = lo + step
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        below = np.abs(origins + mid[..., None] * directions - centre).sum(axis=-1) <= radius
        hi = np.where(below, mid, hi)
        lo = np.where(below, lo, mid)
    return np.where(first > 0, 0.5 * (lo + hi), np.inf)


def test_iso_hits_an_l1_ball_exactly():
    radius = 10.0
    camera = Camera(azimuth=20, elevation=30, view_height=28.0, distance=60.0)
    scene, tf = l1_ball_scene(radius, camera)
    result = render(scene, depth=True)
    image, depth = result.image, result.info["depth"]
    hit = image[..., 3] == 1
    assert np.all(hit | (image[..., 3] == 0)) and not image[~hit].any()
    np.testing.assert_allclose(image[hit, :3], np.broadcast_to(tf.lookup(0.1)[:3], (hit.sum(), 3)), atol=1e-6)
    origins, directions = scene.camera.rays(48, 48)
    centre = np.zeros(3) + 0.5  # object 16.5 minus the centring offset 16
    points = origins + depth[..., None] * directions
    np.testing.assert_allclose(np.abs(points[hit] - centre).sum(axis=-1), radius, atol=1e-4)
    entry = analytic_entry(origins, directions, centre, radius, 40.0, 80.0)
    # Every ray that enters the ball by more than a step is a hit, at the analytic entry.
    deep = np.isfinite(entry) & (np.abs(origins + (entry + 1.0)[..., None] * directions - centre).sum(-1) < radius - 0.5)
    assert deep.sum() > 300 and hit[deep].all()
    assert np.isfinite(entry[hit]).all()
    np.testing.assert_allclose(depth[hit], entry[hit], atol=1e-3)
    assert np.isnan(depth[~hit]).all()


def test_iso_phong_on_a_flat_face_matches_the_formula():
    """Away from the kinks the octahedron's normal is (±1, ±1, ±1)/√3: |N·L| = |N·H| = 1/√3 head-on."""
    shading = Shading(model="phong", ambient=0.2, diffuse=0.6, specular=0.4, shininess=4.0)
    scene, tf = l1_ball_scene(10.0, Camera(view_height=28.0, distance=60.0), shading=shading)
    result = render(scene, depth=True)
    origins, directions = scene.camera.rays(48, 48)
    points = origins + result.info["depth"][..., None] * directions - 0.5
    flat = (result.image[..., 3] == 1) & np.all(np.abs(np.nan_to_num(points)) > 1.05, axis=-1)
    assert flat.sum() > 100
    cosine = 1 / math.sqrt(3)
    expected = np.clip(tf.lookup(0.1)[:3] * (0.2 + 0.6 * cosine) + 0.4 * cosine ** 4, 0, 1)
    np.testing.assert_allclose(result.image[flat, :3], np.broadcast_to(expected, (flat.sum(), 3)), atol=1e-5)


def test_iso_euclidean_sphere_radius():
    """Central ray exact (the field is |z| there); elsewhere the level set is within h²/(8R)."""
    n, radius = 32, 10.0
    idx = np.arange(n) - 16.0
    z, y, x = np.meshgrid(idx, idx, idx, indexing="ij")
    data = np.sqrt(x * x + y * y + z * z).astype(np.float32)
    instance = VolumeInstance(Volume(data, value_range=(0.0, 100.0)), TransferFunction.constant(alpha=1.0),
                              isovalue=radius / 100.0, name="sphere")
    scene = Scene([instance], camera=Camera(view_height=32.0, distance=100.0), width=32, height=32, mode="iso")
    result = render(scene, depth=True)
    depth = result.info["depth"]
    # Pixel (15, 16) looks down the voxel column through the centre at world (0.5, 0.5).
    assert abs(depth[15, 16] - (100.0 - (0.5 + radius))) < 1e-3
    origins, directions = scene.camera.rays(32, 32)
    hit = result.image[..., 3] == 1
    radii = np.linalg.norm(origins[hit] + depth[hit][:, None] * directions[hit] - 0.5, axis=-1)
    assert hit.sum() > 250
    assert np.abs(radii - radius).max() < 1.0 / (8 * radius)
