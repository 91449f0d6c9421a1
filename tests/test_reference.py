"""The reference renderer: options, results, multiple volumes, cameras, shading, errors."""

import math
import sys

import numba
import numpy as np
import pytest

import renderers
from core.volume import Volume
from core.camera import Camera
from core.errors import InputError
from core.scene import Scene, Shading, VolumeInstance, centering_transform
from core.transfer import GradientOpacity, TransferFunction
from renderers.reference import ReferenceRenderer
from renderers.reference.renderer import normalised_scalars


def render(scene, **options):
    return ReferenceRenderer(**options).render(scene)


def smooth_field(shape, seed=0):
    """A smooth random float32 field in [0, 1] (sum of a few Gaussians), indexed [z, y, x]."""
    rng = np.random.default_rng(seed)
    nz, ny, nx = shape
    z, y, x = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    field = np.zeros(shape)
    for _ in range(6):
        cx, cy, cz = rng.uniform(0.2, 0.8, 3) * (nx, ny, nz)
        width = rng.uniform(2.0, 4.0)
        field += rng.uniform(0.3, 1.0) * np.exp(-((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) / (2 * width ** 2))
    return (field / field.max()).astype(np.float32)


RAMP = TransferFunction.from_points([(0, 0.2, 0.3, 1.0, 0.0), (0.2, 0.2, 0.6, 1.0, 0.0), (0.6, 1.0, 0.7, 0.3, 0.3),
                                     (1.0, 1.0, 1.0, 1.0, 0.8)], name="ramp")


def translation(offset):
    matrix = np.eye(4)
    matrix[:3, 3] = offset
    return matrix


# ---------------------------------------------------------------------------------------------
# Registry, options, result record


def test_registry_builds_the_reference_and_probe_succeeds():
    assert ReferenceRenderer.probe() == (True, "")
    backend = renderers.get("reference", step_factor=0.5)
    assert isinstance(backend, ReferenceRenderer) and backend.name == "reference"
    row = {info.name: info for info in renderers.available()}["reference"]
    assert row.available and row.capabilities is ReferenceRenderer.capabilities


def test_probe_reports_a_missing_numba(monkeypatch):
    monkeypatch.setitem(sys.modules, "numba", None)  # makes `import numba` raise ImportError
    ok, reason = ReferenceRenderer.probe()
    assert not ok and "numba" in reason


@pytest.mark.parametrize("options", [
    {"step_factor": 0}, {"step_factor": -0.25}, {"step_factor": float("nan")}, {"step_factor": float("inf")},
    {"step_factor": "fine"}, {"step": 0.0}, {"step": float("nan")}, {"depth": "yes"}, {"classification": "late"},
])
def test_bad_options_raise_input_error_naming_the_option(options):
    with pytest.raises(InputError, match=next(iter(options))):
        ReferenceRenderer(**options)


def test_counters_timings_and_effective_step():
    volume = Volume(np.zeros((8, 8, 8), np.uint8), spacing=(2.0, 0.5, 1.0))
    scene = Scene([VolumeInstance(volume, TransferFunction.constant(alpha=0.1))],
                  camera=Camera(view_height=32.0, distance=50.0), width=32, height=32)
    backend = ReferenceRenderer()
    assert backend.options["effective_step"] is None
    result = backend.render(scene)
    step = 0.25 * 0.5  # a quarter of the smallest world voxel edge
    assert result.info["step"] == step and backend.options["effective_step"] == step
    assert backend.options["step_factor"] == 0.25 and backend.options["step"] is None
    covered = int((result.image[..., 3] > 0).sum())
    assert covered == 16 * 4  # 16 × 4 world units of box, one pixel per unit
    assert result.counters == {"rays": 32 * 32, "rays_hit": covered, "samples": covered * int(8 / step),
                               "early_terminations": 0}
    assert set(result.timings) == {"prepare", "render", "total"}
    assert all(v >= 0 for v in result.timings.values())
    assert result.timings["total"] >= result.timings["render"] + result.timings["prepare"] - 1e-9
    absolute = ReferenceRenderer(step=0.2, step_factor=0.9).render(scene)
    assert absolute.info["step"] == 0.2 and absolute.counters["samples"] == covered * 40
    assert "depth" not in result.info
    # The first sample sits half a step behind the entry face z = 4 (eye at z = 50).
    depth = ReferenceRenderer(depth=True).render(scene).info["depth"]
    np.testing.assert_allclose(depth[result.image[..., 3] > 0], 46 + step / 2, rtol=0, atol=1e-12)
    assert np.isnan(depth[result.image[..., 3] == 0]).all()


def test_world_step_accounts_for_scaled_transforms():
    volume = Volume(np.zeros((4, 4, 4), np.uint8))
    scaled = np.diag([3.0, 2.0, 4.0, 1.0])
    scene = Scene([VolumeInstance(volume, TransferFunction.constant(alpha=0.1), transform=scaled)])
    assert ReferenceRenderer().world_step(scene) == 0.25 * 2.0


def test_normalised_scalars_are_cached_per_volume():
    volume = Volume(np.arange(64, dtype=np.uint16).reshape(4, 4, 4), value_range=(10, 50))
    first = normalised_scalars(volume)
    assert normalised_scalars(volume) is first
    np.testing.assert_array_equal(first, volume.normalized().ravel())


def test_renders_are_bit_reproducible_across_runs_and_thread_counts():
    volume = Volume(smooth_field((20, 18, 16)), spacing=(1.0, 1.2, 0.9))
    scene = Scene([VolumeInstance(volume, RAMP, gradient_opacity=GradientOpacity.from_points([(0, 0.3), (1, 1)]))],
                  camera=Camera(azimuth=35, elevation=-20, projection="perspective"), width=40, height=40,
                  shading=Shading(model="phong"))
    first = render(scene).image
    second = render(scene).image
    assert first.tobytes() == second.tobytes()
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        single = render(scene).image
    finally:
        numba.set_num_threads(threads)
    assert single.tobytes() == first.tobytes()
    assert first[..., 3].max() > 0.3


# ---------------------------------------------------------------------------------------------
# Capabilities and errors


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
@pytest.mark.parametrize("mode", ["dvr", "mip", "iso"])
def test_capabilities_cover_every_projection_and_mode(projection, mode):
    volume = Volume(smooth_field((12, 10, 8)), spacing=(1.0, 2.0, 1.0))
    instances = [VolumeInstance(volume, RAMP, isovalue=0.5, gradient_opacity=GradientOpacity(np.ones(4)), name=f"v{i}",
                                transform=translation((i, 0, 0)) @ centering_transform(volume)) for i in range(3)]
    scene = Scene(instances, camera=Camera(projection=projection), mode=mode, shading=Shading(model="phong"),
                  width=16, height=16)
    assert ReferenceRenderer.capabilities.missing(scene) == []
    assert render(scene).image.shape == (16, 16, 4)
    assert ReferenceRenderer.capabilities.meshes and ReferenceRenderer.capabilities.lenses


def test_iso_without_isovalue_names_the_instance():
    volume = Volume(smooth_field((8, 8, 8)))
    scene = Scene([VolumeInstance(volume, RAMP, isovalue=0.3, name="has-one"),
                   VolumeInstance(volume, RAMP, name="lacks-one")], mode="iso")
    with pytest.raises(InputError, match="lacks-one"):
        render(scene)


def test_render_rejects_a_non_scene():
    with pytest.raises(InputError, match="Scene"):
        ReferenceRenderer().render("scene.yaml")


# ---------------------------------------------------------------------------------------------
# Pre-classification (the thesis's comparison caster)


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_pre_classification_equals_post_for_a_linear_transfer_function(projection):
    """Interpolation commutes with a linear classification: α = s, one colour, unshaded."""
    volume = Volume(smooth_field((12, 14, 16), seed=5))
    linear = TransferFunction.from_points([(0.0, 0.9, 0.6, 0.3, 0.0), (1.0, 0.9, 0.6, 0.3, 1.0)], name="linear")
    scene = Scene([VolumeInstance(volume, linear)], width=24, height=24,
                  camera=Camera(azimuth=30, elevation=20, view_height=30.0, distance=60.0, projection=projection))
    post = render(scene, step_factor=0.5)
    pre = render(scene, step_factor=0.5, classification="pre")
    assert pre.info["classification"] == "pre" and post.info["classification"] == "post"
    assert post.image[..., 3].max() > 0.3
    np.testing.assert_allclose(pre.image, post.image, atol=2e-6)


def test_pre_classification_blurs_a_step_transfer_function():
    """A step classified per voxel is interpolated between voxels: a ramp where post-classification is sharp."""
    data = np.zeros((1, 1, 8), np.float32)
    data[..., 4:] = 1.0  # a step between voxels 3 and 4 along x
    step_tf = TransferFunction.from_points([(0.0, 1, 1, 1, 0.0), (0.49, 1, 1, 1, 0.0), (0.51, 1, 1, 1, 1.0),
                                            (1.0, 1, 1, 1, 1.0)], name="step")
    scene = Scene([VolumeInstance(Volume(data), step_tf)], width=64, height=8,
                  camera=Camera(azimuth=0, elevation=0, view_height=1.0, distance=20.0))
    # Head-on through the one-voxel-thick row (Δ = Δ0 overall), pixel centres at x = (i + ½)/8 voxel units.
    post = render(scene, step_factor=0.25).image[4, :, 3]
    pre = render(scene, step_factor=0.25, classification="pre").image[4, :, 3]
    x = (np.arange(64) + 0.5) / 8 - 0.5  # voxel coordinate of each pixel
    inside = (x > 3.05) & (x < 3.95)
    # Post: the interpolated scalar crosses 0.5 at x = 3.5; pre: α itself is interpolated, α = x − 3.
    assert set(np.unique(post[inside & (x < 3.45)])) == {0.0} and (post[inside & (x > 3.55)] == 1.0).all()
    np.testing.assert_allclose(pre[inside], x[inside] - 3, atol=1e-6)


def test_pre_classification_is_for_dvr_only():
    volume = Volume(smooth_field((8, 8, 8)))
    scene = Scene([VolumeInstance(volume, RAMP)], mode="mip", width=8, height=8)
    with pytest.raises(InputError, match="classification='pre' applies to dvr only"):
        render(scene, classification="pre")


# ---------------------------------------------------------------------------------------------
# Several volumes and transforms


def test_two_coincident_volumes_with_split_opacity_equal_one():
    """With Δ = Δ0 the corrected opacities are the table's, so halves sum to the whole.

    Face-on, every cell lies whole in the box; a cell the box cuts corrects for a shorter
    length, where 2·(1 − (1 − α/2)^r) and 1 − (1 − α)^r differ (r < 1).
    """
    volume = Volume(smooth_field((16, 16, 16), seed=3))
    half = TransferFunction(RAMP.table * np.float32([1, 1, 1, 0.5]))
    camera = Camera(azimuth=0, elevation=0, view_height=28.0, distance=60.0)
    single = Scene([VolumeInstance(volume, RAMP)], camera=camera, width=32, height=32)
    double = Scene([VolumeInstance(volume, half, name="a"), VolumeInstance(volume, half, name="b")],
                   camera=camera, width=32, height=32)
    one = render(single, step_factor=1.0)
    two = render(double, step_factor=1.0)
    np.testing.assert_allclose(two.image, one.image, atol=1e-6)
    assert two.counters["samples"] == 2 * one.counters["samples"]
    assert one.image[..., 3].max() > 0.3


def test_overlapping_opacity_sum_is_clamped_and_colours_averaged():
    """Kainz et al. 2009: Σα' > 1 is clamped to 1 and the colour sum scaled by 1/Σα'."""
    volume = Volume(np.zeros((8, 8, 8), np.uint8))
    red = TransferFunction.constant(color=(1.0, 0.0, 0.0), alpha=0.8)
    green = TransferFunction.constant(color=(0.0, 1.0, 0.0), alpha=0.8)
    scene = Scene([VolumeInstance(volume, red, name="red"), VolumeInstance(volume, green, name="green")],
                  camera=Camera(view_height=16.0, distance=40.0), width=16, height=16)
    image = render(scene, step_factor=1.0).image
    np.testing.assert_allclose(image[4:12, 4:12], np.broadcast_to([0.5, 0.5, 0.0, 1.0], (8, 8, 4)), atol=1e-7)


def trilinear_clamped(data, u):
    """Clamp-to-edge trilinear value of ``data[z, y, x]`` at voxel coordinates ``u = (x, y, z)``."""
    index, weight = [], []
    for axis, n in zip(range(3), data.shape[::-1]):
        c = min(max(u[axis], 0.0), n - 1.0)
        i0 = min(int(math.floor(c)), max(n - 2, 0))
        index.append((i0, min(i0 + 1, n - 1)))
        weight.append(c - i0)
    value = 0.0
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                w = ((weight[0] if dx else 1 - weight[0]) * (weight[1] if dy else 1 - weight[1])
                     * (weight[2] if dz else 1 - weight[2]))
                value += w * data[index[2][dz], index[1][dy], index[0][dx]]
    return value


def exact_maximum(data, po, pd, spacing, near, far):
    """``(value, t)``: the maximum of the clamp-to-edge trilinear field on ``[near, far]``, found
    independently of the kernel: between consecutive lattice planes the field is a cubic in
    ``t``, fitted through four points, whose stationary points ``np.roots`` finds."""
    base, slope = po / spacing - 0.5, pd / spacing
    cuts = [near, far]
    for axis, n in enumerate(data.shape[::-1]):
        if slope[axis] != 0.0:
            cuts += [t for t in (np.arange(n) - base[axis]) / slope[axis] if near < t < far]
    cuts = sorted(cuts)
    best, best_t = -np.inf, None
    for a, b in zip(cuts, cuts[1:]):
        field = [trilinear_clamped(data, base + (a + s * (b - a)) * slope) for s in (0, 1 / 3, 2 / 3, 1)]
        cubic = np.polyfit([0, 1 / 3, 2 / 3, 1], field, 3)
        stationary = [r.real for r in np.roots(np.polyder(cubic)) if abs(r.imag) < 1e-9 and 0 < r.real < 1]
        for s in sorted([0.0, 1.0] + stationary):
            value = trilinear_clamped(data, base + (a + s * (b - a)) * slope)
            if value > best:
                best, best_t = value, a + s * (b - a)
    return best, best_t


def integrate_pixel(scene, step, origin, direction):
    """The documented rules, written out plainly: ``(dvr rgba, mip rgba)`` of one ray.

    DVR: cells ``[t_first + kΔ, t_first + (k + 1)Δ]`` from the union's entry; each volume samples
    the midpoint of its overlap with a cell, corrects opacity for the overlap's object-space
    length, and the volumes of a cell are summed with the sum of opacities clamped to 1 (Kainz
    2009). MIP: the exact maximum of each volume's trilinear field over its span
    (:func:`exact_maximum`); the largest wins with its own transfer function.
    """
    spans = []
    for instance in scene.volumes:
        inverse = np.linalg.inv(instance.transform)
        po = inverse[:3, :3] @ origin + inverse[:3, 3]
        pd = inverse[:3, :3] @ direction
        spacing = np.asarray(instance.volume.spacing, float)
        extent = np.asarray(instance.volume.shape_xyz) * spacing
        near, far = 0.0, np.inf
        for axis in range(3):
            if pd[axis] == 0.0:
                near = near if 0.0 <= po[axis] <= extent[axis] else np.inf
            else:
                ta, tb = -po[axis] / pd[axis], (extent[axis] - po[axis]) / pd[axis]
                near, far = max(near, min(ta, tb)), min(far, max(ta, tb))
        spans.append((near, far, po, pd, spacing))
    entered = [(near, far) for near, far, *_ in spans if near < far]
    dvr, mip = np.zeros(4), np.zeros(4)
    if not entered:
        return dvr, mip
    t_first, t_last = min(n for n, _ in entered), max(f for _, f in entered)
    best, best_rgba = -1.0, None
    k = 0
    while t_first + k * step < t_last:
        a, b = t_first + k * step, t_first + (k + 1) * step
        colour, alpha = np.zeros(3), 0.0
        for instance, (near, far, po, pd, spacing) in zip(scene.volumes, spans):
            lo, hi = max(a, near), min(b, far)
            if hi - lo <= 1e-9 * step:
                continue
            u = (po + 0.5 * (lo + hi) * pd) / spacing - 0.5
            s = trilinear_clamped(instance.volume.normalized(np.float32).astype(np.float64), u)
            rgba = instance.transfer_function.lookup(s)
            corrected = 1 - (1 - rgba[3]) ** ((hi - lo) * np.linalg.norm(pd) / instance.reference_step)
            colour += corrected * rgba[:3]
            alpha += corrected
        if alpha > 1:
            colour, alpha = colour / alpha, 1.0
        dvr += (1 - dvr[3]) * np.append(colour, alpha)
        k += 1
    for instance, (near, far, po, pd, spacing) in zip(scene.volumes, spans):
        if far - near > 1e-9 * step:
            s, _ = exact_maximum(instance.volume.normalized(np.float32).astype(np.float64), po, pd, spacing, near, far)
            if s > best:
                best, best_rgba = s, instance.transfer_function.lookup(s)
    if best_rgba is not None:
        mip = np.append(best_rgba[:3] * best_rgba[3], best_rgba[3])
    return dvr, mip


def overlapping_pair(projection="orthographic"):
    """Volume ``b`` (anisotropic, rotated) pokes out of volume ``a``; no face lies on the lattice."""
    z, y, x = np.meshgrid(np.arange(14), np.arange(16), np.arange(18), indexing="ij")
    field_a = (0.45 + 0.2 * np.sin(0.4 * x + 0.3 * y) + 0.015 * z).astype(np.float32)
    z, y, x = np.meshgrid(np.arange(8), np.arange(12), np.arange(10), indexing="ij")
    field_b = (0.5 + 0.3 * np.cos(0.5 * x - 0.2 * z) * np.sin(0.3 * y + 0.4)).astype(np.float32)
    volume_b = Volume(field_b, spacing=(1.0, 1.3, 0.7))
    angle = math.radians(30)
    rotation = np.eye(4)
    rotation[:3, :3] = [[math.cos(angle), 0, math.sin(angle)], [0, 1, 0], [-math.sin(angle), 0, math.cos(angle)]]
    tf_a = TransferFunction.from_points([(0, 0.9, 0.3, 0.1, 0.05), (0.5, 0.9, 0.8, 0.2, 0.15), (1, 1.0, 1.0, 0.6, 0.3)])
    tf_b = TransferFunction.from_points([(0, 0.1, 0.3, 1.0, 0.1), (1, 0.3, 1.0, 0.8, 0.5)])
    camera = Camera(azimuth=25, elevation=15, view_height=40.0, distance=80.0, projection=projection, fov_y=30.0)
    return [VolumeInstance(Volume(field_a), tf_a, name="a"),
            VolumeInstance(volume_b, tf_b, name="b",
                           transform=translation((5.3, 2.2, 3.1)) @ rotation @ centering_transform(volume_b))], camera


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_overlapping_volumes_follow_the_documented_sampling_rule(projection):
    """Both modes against a plain re-implementation, on rays that cross the faces of both boxes
    (MIP against the exact maximum of the trilinear fields, which no sampling reaches)."""
    instances, camera = overlapping_pair(projection)
    size, rows = 24, (5, 9, 12, 16)
    images = {mode: ReferenceRenderer(step_factor=1.0).render(
        Scene(instances, camera=camera, width=size, height=size, mode=mode)) for mode in ("dvr", "mip")}
    step = images["dvr"].info["step"]
    assert step == 0.7
    origins, directions = camera.rays(size, size)
    both = 0
    for row in rows:
        for col in range(size):
            dvr, mip = integrate_pixel(Scene(instances, camera=camera), step, origins[row, col], directions[row, col])
            np.testing.assert_allclose(images["dvr"].image[row, col], dvr, rtol=2e-7, atol=1e-9, err_msg=f"{row, col}")
            np.testing.assert_allclose(images["mip"].image[row, col], mip, rtol=2e-7, atol=1e-9, err_msg=f"{row, col}")
            both += bool(images["dvr"].image[row, col, 2] > 0.05 and images["dvr"].image[row, col, 0] > 0.05)
    assert both >= 10  # rays through both volumes


def test_iso_over_overlapping_volumes_finds_the_nearest_surface():
    """Each volume's surface alone, then both: the union's hit is the nearer one, within the tolerance."""
    n = 24
    idx = np.arange(n) - 11.5
    z, y, x = np.meshgrid(idx, idx, idx, indexing="ij")
    ball = Volume((np.abs(x) + np.abs(y) + np.abs(z)).astype(np.float32), value_range=(0.0, 40.0))
    sphere = Volume(np.sqrt(x * x + y * y + z * z).astype(np.float32), value_range=(0.0, 40.0),
                    spacing=(0.9, 1.1, 0.8))
    red = TransferFunction.constant(color=(1.0, 0.0, 0.0), alpha=1.0)
    blue = TransferFunction.constant(color=(0.0, 0.0, 1.0), alpha=1.0)
    instances = [VolumeInstance(ball, red, isovalue=10.0 / 40, name="ball"),
                 VolumeInstance(sphere, blue, isovalue=7.0 / 40, name="sphere",
                                transform=translation((5.7, 1.9, -2.3)) @ centering_transform(sphere))]
    camera = Camera(azimuth=20, elevation=25, view_height=26.0, distance=70.0)
    common = dict(camera=camera, width=32, height=32, mode="iso")
    backend = ReferenceRenderer(step_factor=1.0, depth=True)
    alone = [backend.render(Scene([instance], **common)) for instance in instances]
    union = backend.render(Scene(instances, **common))
    depths = np.stack([result.info["depth"] for result in alone])
    nearest = np.nanmin(np.where(np.isnan(depths), np.inf, depths), axis=0)
    winner = np.argmin(np.where(np.isnan(depths), np.inf, depths), axis=0)
    hit = np.isfinite(nearest)
    # A ray grazing a silhouette can cross in and out within one step, found on one lattice and
    # not on another: leave out the pixels next to either silhouette.
    silhouette = np.zeros_like(hit)
    for mask in np.isfinite(depths):
        padded = np.pad(mask, 1, mode="edge")
        neighbours = [padded[1 + dy:1 + dy + mask.shape[0], 1 + dx:1 + dx + mask.shape[1]]
                      for dy in (-1, 0, 1) for dx in (-1, 0, 1)]
        silhouette |= np.any(neighbours, axis=0) & ~np.all(neighbours, axis=0)
    clear = ~silhouette
    assert clear.sum() > 600
    np.testing.assert_array_equal(np.isfinite(union.info["depth"])[clear], hit[clear])
    hit &= clear
    np.testing.assert_allclose(union.info["depth"][hit], nearest[hit], atol=1e-5)
    expected = np.where((winner == 0)[..., None], [1.0, 0, 0, 1], [0, 0, 1.0, 1])
    np.testing.assert_array_equal(union.image[hit], expected[hit])
    assert (hit & (winner == 0)).sum() > 50 and (hit & (winner == 1)).sum() > 50
    assert (np.isfinite(depths).all(axis=0) & clear).sum() > 30  # pixels where both surfaces are on the ray


def test_mip_over_several_volumes_uses_the_transfer_function_of_the_maximum():
    """The largest scalar of any volume wins and keeps its own classification; ties go to the first."""
    low = Volume(np.full((8, 8, 8), 0.4, np.float32))
    high = Volume(np.full((8, 8, 8), 0.7, np.float32))
    red = TransferFunction.constant(color=(1.0, 0.0, 0.0), alpha=0.5)
    blue = TransferFunction.constant(color=(0.0, 0.0, 1.0), alpha=0.8)
    camera = Camera(view_height=16.0, distance=40.0)
    mixed = render(Scene([VolumeInstance(high, red, name="high"), VolumeInstance(low, blue, name="low")],
                         camera=camera, width=16, height=16, mode="mip")).image
    np.testing.assert_allclose(mixed[8, 8], [0.5, 0, 0, 0.5], atol=1e-7)
    tied = render(Scene([VolumeInstance(low, blue, name="first"), VolumeInstance(low, red, name="second")],
                        camera=camera, width=16, height=16, mode="mip")).image
    np.testing.assert_allclose(tied[8, 8], [0, 0, 0.8, 0.8], atol=1e-7)


def test_translated_volume_shifts_the_picture_by_whole_pixels():
    volume = Volume(smooth_field((16, 16, 16), seed=5))
    camera = Camera(azimuth=0, elevation=0, view_height=48.0, distance=80.0)
    base = render(Scene([VolumeInstance(volume, RAMP)], camera=camera, width=48, height=48)).image
    moved = VolumeInstance(volume, RAMP, transform=translation((5, -3, 7)) @ centering_transform(volume))
    shifted = render(Scene([moved], camera=camera, width=48, height=48)).image
    expected = np.zeros_like(base)
    expected[3:, 5:] = base[:-3, :-5]
    assert base[-3:].max() == 0 and base[:, -5:].max() == 0
    np.testing.assert_allclose(shifted, expected, atol=1e-6)
    assert base[..., 3].max() > 0.3


@pytest.mark.parametrize("model", ["none", "phong"])
def test_rotated_volume_equals_the_camera_rotated_the_other_way(model):
    """R_y(90°)·volume seen from azimuth 0 is the volume seen from azimuth −90 (normals included)."""
    volume = Volume(smooth_field((20, 24, 28), seed=7), spacing=(1.0, 1.2, 0.8))
    rotation = np.eye(4)
    rotation[:3, :3] = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]
    shading = Shading(model=model, light_direction=(0.3, 0.5, 1.0))
    common = dict(width=40, height=40, shading=shading)
    rotated = Scene([VolumeInstance(volume, RAMP, transform=rotation @ centering_transform(volume))],
                    camera=Camera(azimuth=0, view_height=40.0, distance=80.0), **common)
    turned = Scene([VolumeInstance(volume, RAMP)], camera=Camera(azimuth=-90, view_height=40.0, distance=80.0), **common)
    a, b = render(rotated).image, render(turned).image
    np.testing.assert_allclose(a, b, atol=1e-5)
    assert a[..., 3].max() > 0.3


# ---------------------------------------------------------------------------------------------
# Perspective cameras


def test_perspective_centre_ray_is_exact_and_picture_is_left_right_symmetric():
    field = smooth_field((16, 20, 12), seed=11)
    field = np.maximum(field, field[:, :, ::-1])  # mirror-symmetric in x
    volume = Volume(field)
    scene = Scene([VolumeInstance(volume, RAMP)], camera=Camera(elevation=25, projection="perspective", fov_y=40),
                  width=33, height=33, shading=Shading(model="phong"))
    image = render(scene).image
    np.testing.assert_allclose(image, image[:, ::-1], atol=1e-5)
    assert np.abs(image - image[::-1]).max() > 0.01 and image[..., 3].max() > 0.3
    box = Scene([VolumeInstance(Volume(np.zeros((10, 6, 6), np.uint8)), TransferFunction.constant(alpha=0.1))],
                camera=Camera(projection="perspective", distance=30.0), width=33, height=33)
    np.testing.assert_allclose(render(box).image[16, 16, 3], 1 - 0.9 ** 10, atol=2e-7)


def two_layer_volume():
    """s = 1 where world z > 4 (behind an eye at z = 2), 0.5 elsewhere; 32³ voxels centred on 0."""
    data = np.full((32, 32, 32), 0.5, np.float32)
    data[20:] = 1.0  # voxel centres z_obj >= 20.5, world >= 4.5
    tf = TransferFunction.from_points([(0, 0, 1, 0, 0.05), (0.6, 0, 1, 0, 0.05), (0.75, 0, 0, 1, 0.9), (1, 0, 0, 1, 0.9)])
    return VolumeInstance(Volume(data), tf, name="layers")


def test_camera_inside_a_volume_clips_at_the_eye():
    instance = two_layer_volume()
    inside = Scene([instance], camera=Camera(projection="perspective", distance=2.0, fov_y=60), width=24, height=24)
    assert inside.camera_inside_volume() == ["layers"]
    assert ReferenceRenderer.capabilities.missing(inside) == []
    result = render(inside)
    assert result.counters["rays_hit"] == 24 * 24
    assert (result.image[..., 1] > 0).all() and not result.image[..., 2].any()  # the blue layer is behind the eye
    outside = render(Scene([instance], camera=Camera(projection="perspective", distance=80.0), width=24, height=24)).image
    assert outside[..., 2].max() > 0.5


def test_volume_behind_the_camera_is_not_rendered():
    instance = two_layer_volume()
    away = Camera(azimuth=180, projection="perspective", distance=40.0, target=(0, 0, 60))
    result = render(Scene([instance], camera=away, width=16, height=16))
    assert result.counters["rays_hit"] == 0 and not result.image.any()


# ---------------------------------------------------------------------------------------------
# Shading and gradient opacity


def slab_scene(shading, *, azimuth=0.0, reverse=False):
    """A scalar ramp along the view axis: every gradient is parallel to the view direction."""
    ramp = np.linspace(0.3, 0.9, 16, dtype=np.float32)
    if reverse:
        ramp = ramp[::-1].copy()  # gradient pointing away from the viewer: tests two-sidedness
    data = np.broadcast_to(ramp[:, None, None], (16, 16, 16)).copy()  # varies with z
    if azimuth:
        data = np.ascontiguousarray(np.transpose(data, (2, 1, 0)))  # varies with x instead
    tf = TransferFunction.constant(color=(0.5, 0.3, 0.2), alpha=0.05)
    return Scene([VolumeInstance(Volume(data), tf)], camera=Camera(azimuth=azimuth, view_height=32.0, distance=60.0),
                 width=32, height=32, shading=shading)


@pytest.mark.parametrize("reverse", [False, True])
@pytest.mark.parametrize("azimuth", [0.0, 90.0])
def test_phong_head_on_gives_c_times_ka_plus_kd_plus_ks(azimuth, reverse):
    shading = Shading(model="phong", ambient=0.2, diffuse=0.5, specular=0.25, shininess=8.0)
    image = render(slab_scene(shading, azimuth=azimuth, reverse=reverse)).image
    covered = image[..., 3] > 0
    assert covered.sum() == 256
    colour = image[covered, :3] / image[covered, 3:]
    np.testing.assert_allclose(colour, np.broadcast_to(np.array([0.5, 0.3, 0.2]) * 0.7 + 0.25, colour.shape), atol=1e-6)


def test_phong_light_direction_is_in_view_space():
    """Light along view-space +x: N·L = 0 and H = (1, 0, 1)/√2, whichever way the camera faces."""
    shading = Shading(model="phong", ambient=0.2, diffuse=0.5, specular=0.25, shininess=8.0, light_direction=(1, 0, 0))
    expected = np.array([0.5, 0.3, 0.2]) * 0.2 + 0.25 * (1 / math.sqrt(2)) ** 8
    for azimuth in (0.0, 90.0):
        image = render(slab_scene(shading, azimuth=azimuth)).image
        covered = image[..., 3] > 0
        np.testing.assert_allclose(image[covered, :3] / image[covered, 3:],
                                   np.broadcast_to(expected, (covered.sum(), 3)), atol=1e-6)


def test_phong_with_zero_gradient_is_ambient_only():
    tf = TransferFunction.constant(color=(0.8, 0.6, 0.4), alpha=0.1)
    scene = Scene([VolumeInstance(Volume(np.full((8, 8, 8), 77, np.uint8)), tf)],
                  camera=Camera(azimuth=30, elevation=20), width=16, height=16, shading=Shading(model="phong", ambient=0.3))
    image = render(scene).image
    covered = image[..., 3] > 0
    np.testing.assert_allclose(image[covered, :3] / image[covered, 3:],
                               np.broadcast_to([0.24, 0.18, 0.12], (covered.sum(), 3)), atol=1e-6)


def gradient_scene(gradient_opacity, field):
    return Scene([VolumeInstance(Volume(field), RAMP, gradient_opacity=gradient_opacity)],
                 camera=Camera(azimuth=40, elevation=30), width=32, height=32, shading=Shading(model="phong"))


def test_gradient_opacity_zero_table_empties_and_ones_table_changes_nothing():
    field = smooth_field((20, 20, 20), seed=2)
    plain = render(gradient_scene(None, field)).image
    assert plain[..., 3].max() > 0.3
    assert not render(gradient_scene(GradientOpacity(np.zeros(16)), field)).image.any()
    ones = render(gradient_scene(GradientOpacity(np.ones(16)), field)).image
    assert ones.tobytes() == plain.tobytes()


def test_gradient_opacity_argument_is_gradient_per_reference_step_over_sqrt3_half():
    """A ramp of 0.02 per voxel along x has u = 0.02/(√3/2); with g(u) = u the opacity is α·u."""
    slope = 0.02
    data = np.broadcast_to((0.2 + slope * np.arange(24, dtype=np.float32)), (24, 24, 24)).copy()
    alpha = 0.5
    tf = TransferFunction.constant(alpha=alpha)
    linear = GradientOpacity(np.linspace(0, 1, 1001))
    scene = Scene([VolumeInstance(Volume(data), tf, gradient_opacity=linear)],
                  camera=Camera(view_height=24.0, distance=60.0), width=24, height=24)
    image = render(scene).image
    u = slope / (math.sqrt(3) / 2)
    # Columns 1..22 stay one voxel away from the x faces, where clamp-to-edge halves the gradient.
    np.testing.assert_allclose(image[:, 1:23, 3], 1 - (1 - alpha * u) ** 24, atol=1e-6)
    np.testing.assert_allclose(image[:, 0, 3], 1 - (1 - alpha * u * 0.5) ** 24, atol=1e-6)  # (f(1) − f(0))/2


# -- what a frame costs, checked before any work -----------------------------------------------

def _cube_scene(n, image, **scene):
    volume = Volume(np.zeros((n, n, n), np.uint8), name="cube")
    return Scene(volumes=VolumeInstance(volume, RAMP), width=image, height=image, **scene)


def test_absurd_work_is_refused_before_any_work_naming_the_step_and_the_cap():
    scene = _cube_scene(8, 32)
    with pytest.raises(InputError, match=r"^reference: scene 'scene' takes about 1.42e\+11 samples a frame \(1024 pixels "
                                         r"× 1.39e\+08 steps of 1e-07 across the volumes' 13.9 diagonal\), more than "
                                         r"max_samples=1e\+11; use a larger step \(step_factor ≥ 1.42e-07\) or fewer "
                                         r"pixels, or raise the cap with the option max_samples"):
        ReferenceRenderer(step_factor=1e-7).check(scene)
    ReferenceRenderer(step_factor=1e-7, max_samples=1e12).check(scene)
    with pytest.raises(InputError, match=r"use a larger step \(step ≥ 1.42e-07\)"):
        ReferenceRenderer(step=1e-7).check(scene)
    # mip and iso walk the voxel lattice: the step does not change their work.
    ReferenceRenderer(step_factor=1e-7).check(_cube_scene(8, 32, mode="mip"))
    with pytest.raises(InputError, match=r"1000000 pixels × up to 27 voxel-lattice cells a ray\), more than max_samples=1e\+07; render fewer pixels"):
        ReferenceRenderer(max_samples=1e7).check(_cube_scene(8, 1000, mode="mip"))


def test_the_full_profiles_largest_frame_passes():
    # volbench-speed-accuracy's truth at full scale: a 256³ volume at 1/16 voxel, 512².
    samples, _ = ReferenceRenderer(step_factor=1 / 16).work(_cube_scene(256, 512))
    assert 1.8e9 < samples < 1.9e9
    ReferenceRenderer(step_factor=1 / 16).check(_cube_scene(256, 512))


def test_a_frame_this_machine_cannot_hold_is_refused(monkeypatch):
    import core.resources

    monkeypatch.setattr(core.resources, "memory_limit", lambda: 5 * 2 ** 20)
    with pytest.raises(InputError, match=r"reference: scene 'scene' at 256×256 needs 5.16 MiB \(the volumes' 32 KiB, 80 "
                                         r"bytes a pixel and 4 a voxel\), this machine has 5 MiB"):
        ReferenceRenderer().check(_cube_scene(32, 256))
    ReferenceRenderer().check(_cube_scene(32, 240))
    with pytest.raises(InputError, match="20 a voxel"):
        ReferenceRenderer(classification="pre").check(_cube_scene(128, 8))
