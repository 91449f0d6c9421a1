"""The reference's exact MIP and iso (cubic along the ray in each lattice cell), non-finite rays,
and tests that pin down details a one-line change could get wrong unnoticed.

Along a ray inside one cell of the voxel lattice the trilinear field is a cubic in the ray
parameter; the reference finds its maximum (MIP) and its first isovalue crossing (iso) in
closed form, so both are exact for the trilinear field and independent of the step.
"""

import json
import math
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from core.camera import Camera
from core.scene import Scene, VolumeInstance
from core.transfer import GradientOpacity, TransferFunction
from core.volume import Volume
from renderers.reference import ReferenceRenderer
from renderers.reference import raycast

STEPS = (1.0, 0.5, 0.25, 0.125)
IDENTITY = TransferFunction.from_points([(0, 1, 1, 1, 0), (1, 1, 1, 1, 1)], name="alpha=s")
"""Alpha (and premultiplied colour) equal to the scalar: entry i/255 holds i/255."""


def render(scene, **options):
    return ReferenceRenderer(depth=True, **options).render(scene)


# ---------------------------------------------------------------------------------------------
# MIP: a single bright voxel (the reproduction)


def single_voxel_scene(mode="mip", isovalue=None):
    data = np.zeros((33, 33, 33), np.uint8)
    data[16, 16, 16] = 200
    instance = VolumeInstance(Volume(data), IDENTITY, isovalue=isovalue)
    return Scene([instance], camera=Camera(view_height=33.0, distance=80.0), width=33, height=33, mode=mode)


def test_single_voxel_mip_is_exact_at_every_step():
    """Head-on rays through voxel centres: the bright pixel is the voxel's value, not 87.5 % of it.

    Sampled at cell midpoints the old kernel gave 0.6863 at Δ = ¼, 0.5882 at ½ and 0.7843 only at 1.
    """
    scene = single_voxel_scene()
    value = float(Volume(scene.volumes[0].volume.data).normalized(np.float32)[16, 16, 16])
    expected = IDENTITY.lookup(value)[3]
    images = []
    for factor in STEPS:
        result = render(scene, step_factor=factor)
        image = result.image
        assert image[16, 16, 3] == pytest.approx(200 / 255, abs=1e-7)
        np.testing.assert_allclose(image[16, 16], [expected] * 4, rtol=0, atol=1e-7)
        dark = np.ones((33, 33), bool)
        dark[16, 16] = False
        assert not image[dark].any()  # neighbouring columns pass through zeros only
        # Depth: the voxel centre, world z = 0, seen from z = 80.
        assert result.info["depth"][16, 16] == pytest.approx(80.0, abs=1e-9)
        images.append(image)
    assert all(image.tobytes() == images[0].tobytes() for image in images)


def test_mip_counts_lattice_cell_segments():
    """``samples`` counts lattice-cell segments walked: head-on, 34 per ray through 33 voxels
    (32 cells between voxel centres and the two clamped half-voxels at the faces), whatever the step."""
    scene = single_voxel_scene()
    for factor in (1.0, 0.25):
        assert render(scene, step_factor=factor).counters["samples"] == 33 * 33 * 34


# ---------------------------------------------------------------------------------------------
# A field whose trilinear interpolant is known in closed form


SHAPE = (14, 16, 18)  # (nz, ny, nx)
SPACING = (1.0, 0.8, 1.25)


def multilinear(x, y, z):
    """A multilinear polynomial of voxel coordinates: trilinear interpolation reproduces it exactly.

    Its values at voxel centres are multiples of 2⁻¹⁴ below 1, exact in float32, so the
    interpolant of the stored volume is this polynomial to double rounding.
    """
    X, Y, Z = x / 16, y / 16, z / 16
    return 0.125 + 0.625 * X * (1 - Y) + 0.25 * X * Y * Z + 0.125 * (1 - X) * Z


def analytic_scene(mode, camera, isovalue=None, size=24):
    z, y, x = np.meshgrid(*(np.arange(n, dtype=np.float64) for n in SHAPE), indexing="ij")
    volume = Volume(multilinear(x, y, z).astype(np.float32), spacing=SPACING)
    table = TransferFunction.from_points([(0, 1, 1, 1, 0), (1, 1, 1, 1, 1)], size=4096).table
    return Scene([VolumeInstance(volume, TransferFunction(table), isovalue=isovalue)], camera=camera,
                 width=size, height=size, mode=mode)


def analytic_pieces(scene, origin, direction):
    """The field along one ray as cubics ``(a, b, coefficients in σ ∈ [0, 1])``, from the closed form.

    With clamp-to-edge the field at voxel coordinates ``u`` is ``multilinear(clip(u, 0, n − 1))``;
    along the ray it is a cubic between the places where an axis reaches a clamp plane.
    """
    instance = scene.volumes[0]
    inverse = np.linalg.inv(instance.transform)
    po, pd = inverse[:3, :3] @ origin + inverse[:3, 3], inverse[:3, :3] @ direction
    spacing = np.asarray(SPACING)
    extent = np.asarray(SHAPE[::-1]) * spacing
    near, far = 0.0, np.inf
    for axis in range(3):
        if pd[axis] == 0.0:
            near = near if 0.0 <= po[axis] <= extent[axis] else np.inf
        else:
            ta, tb = -po[axis] / pd[axis], (extent[axis] - po[axis]) / pd[axis]
            near, far = max(near, min(ta, tb)), min(far, max(ta, tb))
    if not far - near > 1e-9:
        return []
    base, slope = po / spacing - 0.5, pd / spacing
    top = np.asarray(SHAPE[::-1]) - 1.0
    cuts = [near, far]
    for axis in range(3):
        if slope[axis] != 0.0:
            cuts += [t for t in ((0.0 - base[axis]) / slope[axis], (top[axis] - base[axis]) / slope[axis])
                     if near < t < far]
    cuts = sorted(cuts)

    def field(t):
        u = np.clip(base + t * slope, 0.0, top)
        return multilinear(*u)

    pieces = []
    for a, b in zip(cuts, cuts[1:]):
        nodes = np.array([0, 1 / 3, 2 / 3, 1])
        pieces.append((a, b, np.polyfit(nodes, [field(a + s * (b - a)) for s in nodes], 3), field))
    return pieces


def analytic_maximum(pieces):
    best, best_t = -np.inf, np.nan
    for a, b, cubic, field in pieces:
        stationary = [r.real for r in np.roots(np.polyder(cubic)) if abs(r.imag) < 1e-12 and 0 < r.real < 1]
        for s in sorted([0.0, 1.0] + stationary):
            value = field(a + s * (b - a))
            if value > best:
                best, best_t = value, a + s * (b - a)
    return best, best_t


def analytic_crossing(pieces, iso):
    """First ``t`` where ``field < iso`` differs from its state at the entry (inf if none)."""
    if not pieces:
        return np.inf
    below = pieces[0][3](pieces[0][0]) < iso
    for a, b, cubic, field in pieces:
        shifted = cubic.copy()
        shifted[-1] -= iso
        roots = sorted(r.real for r in np.roots(shifted) if abs(r.imag) < 1e-9 and -1e-12 <= r.real <= 1 + 1e-12)
        for r in roots:
            after = field(a + min(r + 1e-7, 1.0) * (b - a))
            if (after < iso) != below:
                return a + r * (b - a)
    return np.inf


CAMERAS = {
    "orthographic": Camera(azimuth=33, elevation=21, view_height=30.0, distance=70.0),
    "perspective": Camera(azimuth=-52, elevation=-17, distance=45.0, projection="perspective", fov_y=40.0),
}


@pytest.mark.parametrize("projection", sorted(CAMERAS))
def test_mip_of_a_multilinear_field_is_exact_at_every_step(projection):
    scene = analytic_scene("mip", CAMERAS[projection])
    origins, directions = scene.camera.rays(scene.width, scene.height)
    truth = np.zeros((scene.height, scene.width))
    where = np.full((scene.height, scene.width), np.nan)
    for row in range(scene.height):
        for col in range(scene.width):
            pieces = analytic_pieces(scene, origins[row, col], directions[row, col])
            if pieces:
                truth[row, col], where[row, col] = analytic_maximum(pieces)
    covered = np.isfinite(where)
    assert covered.sum() > 200
    interior = 0
    for factor in STEPS:
        result = render(scene, step_factor=factor)
        # float32 voxels, a 4096-entry float32 table and a float32 image: a few 1e-8 each.
        np.testing.assert_allclose(result.image[..., 3], truth, rtol=0, atol=2e-7)
        depth = result.info["depth"]
        assert np.isnan(depth[~covered]).all() and np.isfinite(depth[covered]).all()
        # Where the maximum is sharp (a box face or a clamp plane) its place is exact too.
        for row, col in zip(*np.nonzero(covered)):
            pieces = analytic_pieces(scene, origins[row, col], directions[row, col])
            ends = [p[0] for p in pieces] + [pieces[-1][1]]
            if min(abs(where[row, col] - t) for t in ends) < 1e-9:
                assert depth[row, col] == pytest.approx(where[row, col], abs=1e-9)
            else:
                interior += 1
    assert interior > 0  # some maxima lie inside a piece, between lattice planes


@pytest.mark.parametrize("projection", sorted(CAMERAS))
def test_iso_of_a_multilinear_field_is_exact_at_every_step(projection):
    iso = 0.34
    scene = analytic_scene("iso", CAMERAS[projection], isovalue=iso)
    origins, directions = scene.camera.rays(scene.width, scene.height)
    truth = np.full((scene.height, scene.width), np.inf)
    for row in range(scene.height):
        for col in range(scene.width):
            truth[row, col] = analytic_crossing(analytic_pieces(scene, origins[row, col], directions[row, col]), iso)
    hit = np.isfinite(truth)
    assert 30 < hit.sum() < hit.size - 30
    for factor in (1.0, 0.25):
        depth = render(scene, step_factor=factor).info["depth"]
        np.testing.assert_array_equal(np.isfinite(depth), hit)
        np.testing.assert_allclose(depth[hit], truth[hit], rtol=0, atol=1e-9)


# ---------------------------------------------------------------------------------------------
# Iso semantics: a crossing is where s < isovalue changes (field reaching the isovalue counts)


def test_iso_hits_a_voxel_exactly_at_the_isovalue():
    """The field touches the isovalue at one voxel centre only: ``s >= iso`` there, so it is a hit
    (with ``s <= iso`` as the state no crossing would ever be seen)."""
    value = float(Volume(single_voxel_scene().volumes[0].volume.data).normalized(np.float32)[16, 16, 16])
    scene = single_voxel_scene("iso", isovalue=value)
    for factor in (1.0, 0.25):
        result = render(scene, step_factor=factor)
        assert result.image[16, 16, 3] == 1.0
        assert result.info["depth"][16, 16] == pytest.approx(80.0, abs=1e-9)
        assert (result.image[..., 3] > 0).sum() == 1  # the neighbouring columns never reach it


def test_iso_hits_a_plateau_at_the_isovalue_where_it_is_reached():
    """A block whose value equals the isovalue, in zeros: the surface is where the field first
    reaches it, the centre plane of the block's first voxel layer; from inside the block (the
    field starts at the isovalue) the surface is where it first drops below."""
    data = np.zeros((32, 32, 32), np.float32)
    data[8:24, 8:24, 8:24] = 0.5
    instance = VolumeInstance(Volume(data), IDENTITY, isovalue=0.5)
    outside = Scene([instance], camera=Camera(view_height=32.0, distance=80.0), width=32, height=32, mode="iso")
    result = render(outside)
    hit = result.image[..., 3] == 1.0
    assert hit[9:23, 9:23].all() and not hit[:7].any()
    # Voxel layer 23 (object z = 23.5, world 7.5) is where s first reaches 0.5.
    np.testing.assert_allclose(result.info["depth"][9:23, 9:23], 80.0 - 7.5, rtol=0, atol=1e-9)
    inside = Scene([instance], camera=Camera(distance=2.0, projection="perspective", fov_y=10.0), width=9,
                   height=9, mode="iso")
    result = render(inside)
    assert (result.image[..., 3] == 1.0).all()
    # From the eye (world z = 2) s = 0.5 down to voxel layer 8 (world −7.5), below it past that plane.
    np.testing.assert_allclose(result.info["depth"][4, 4], 9.5, rtol=1e-12)  # the centre ray
    np.testing.assert_allclose(result.info["depth"][3:6, 3:6], 9.5, rtol=1e-3)


# ---------------------------------------------------------------------------------------------
# Non-finite rays


NAN_SCRIPT = textwrap.dedent("""
    import json, sys
    import numpy as np
    from core.camera import Camera
    from core.scene import Scene, VolumeInstance
    from core.transfer import TransferFunction
    from core.volume import Volume
    from renderers.reference import ReferenceRenderer

    rays = Camera.rays

    def broken_rays(self, width, height):
        origins, directions = (np.array(a) for a in rays(self, width, height))
        directions[2, 3] = np.nan
        directions[5, 1] = (np.inf, 0.0, -1.0)
        origins[6, 6, 0] = -np.inf
        directions[1, 6] = 0.0
        return origins, directions

    Camera.rays = broken_rays
    field = np.random.default_rng(1).random((8, 8, 8)).astype(np.float32)
    out = {}
    for mode in ("dvr", "mip", "iso"):
        instance = VolumeInstance(Volume(field), TransferFunction.constant(alpha=0.2), isovalue=0.5)
        scene = Scene([instance], camera=Camera(view_height=7.0, distance=30.0), width=8, height=8, mode=mode)
        result = ReferenceRenderer(depth=True).render(scene)
        depth = result.info["depth"]
        out[mode] = {"pixels": [result.image[p].tolist() for p in ((2, 3), (5, 1), (6, 6), (1, 6))],
                     "depths": [None if np.isnan(depth[p]) else depth[p] for p in ((2, 3), (5, 1), (6, 6), (1, 6))],
                     "covered": int((result.image[..., 3] > 0).sum()), "hits": result.counters["rays_hit"]}
    print(json.dumps(out))
""")


def test_non_finite_rays_give_transparent_pixels_quickly():
    """NaN or infinite origins or directions (and a zero direction) end at once, transparent with
    depth NaN, in every mode; the old kernel spun forever on such a ray. Run in a child process so
    a regression fails on the timeout instead of hanging the test run."""
    root = Path(__file__).resolve().parents[1]
    done = subprocess.run([sys.executable, "-c", NAN_SCRIPT], cwd=root, capture_output=True, text=True,
                          timeout=240)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    for mode, row in out.items():
        assert row["pixels"] == [[0.0] * 4] * 4, mode
        assert row["depths"] == [None] * 4, mode
        assert row["hits"] == 64 - 4, mode  # the box fills the picture; the four broken rays hit nothing
        assert row["covered"] >= 50, mode


# ---------------------------------------------------------------------------------------------
# Gradient opacity: u = |∇s|·Δ0/(√3/2) with Δ0 not 1


@pytest.mark.parametrize("spacing, reference_step", [(2.0, None), (1.0, 0.5), (0.5, 1.5)])
def test_gradient_opacity_argument_scales_with_the_reference_step(spacing, reference_step):
    """A ramp of 0.02 per voxel along x: |∇s| = 0.02/spacing, so u = 0.02·Δ0/(spacing·√3/2).

    Δ0 is the smallest spacing unless the transfer function says otherwise; the path of 24 voxels
    is 24·spacing/Δ0 reference steps. With g(u) = u the opacity per reference step is α·u.
    """
    slope, alpha, n = 0.02, 0.5, 24
    data = np.broadcast_to((0.2 + slope * np.arange(n, dtype=np.float32)), (n, n, n)).copy()
    tf = TransferFunction(TransferFunction.constant(alpha=alpha).table, reference_step=reference_step)
    delta0 = spacing if reference_step is None else reference_step
    linear = GradientOpacity(np.linspace(0, 1, 1001))
    scene = Scene([VolumeInstance(Volume(data, spacing=(spacing,) * 3), tf, gradient_opacity=linear)],
                  camera=Camera(view_height=n * spacing, distance=60.0 * spacing), width=n, height=n)
    image = ReferenceRenderer().render(scene).image
    u = (slope / spacing) * delta0 / (math.sqrt(3) / 2)
    steps = n * spacing / delta0
    assert u < 1
    np.testing.assert_allclose(image[:, 1:n - 1, 3], 1 - (1 - alpha * u) ** steps, rtol=1e-6, atol=1e-7)


# ---------------------------------------------------------------------------------------------
# Table lookups at and past the top end


def top_table(size=8):
    """A table whose last two entries differ in every channel."""
    table = np.zeros((size, 4), np.float32)
    table[:, 0] = np.linspace(0.0, 0.4, size)
    table[:, 1] = 0.3
    table[:, 2] = np.linspace(0.9, 0.2, size)
    table[:, 3] = np.linspace(0.1, 0.6, size)
    table[-1] = (1.0, 0.75, 0.05, 0.9)
    return table


def test_kernel_table_lookup_at_and_past_one_is_the_last_entry():
    table = top_table()
    packed = np.ascontiguousarray(table.astype(np.float64)[None])
    size = table.shape[0]
    for s in (1.0, 1.0 + 1e-12, 1.5, 7.0):
        values = [raycast._tf_channel(packed, 0, size, s, c) for c in range(4)]
        assert values == table[-1].astype(np.float64).tolist(), s
        assert raycast._gradient_factor(packed[:, :, 3], 0, size, s) == float(table[-1, 3])
    for s in (0.0, -0.5):
        assert [raycast._tf_channel(packed, 0, size, s, c) for c in range(4)] == table[0].astype(np.float64).tolist()


@pytest.mark.parametrize("mode", ["mip", "dvr"])
def test_rendered_scalar_one_is_classified_by_the_last_entry(mode):
    """uint8 255 normalises to exactly 1: MIP gives the last entry premultiplied; a DVR box with
    Δ = Δ0 composites it 8 times."""
    table = top_table()
    volume = Volume(np.full((8, 8, 8), 255, np.uint8))
    scene = Scene([VolumeInstance(volume, TransferFunction(table))], camera=Camera(view_height=8.0, distance=30.0),
                  width=8, height=8, mode=mode)
    image = ReferenceRenderer(step_factor=1.0).render(scene).image
    r, g, b, a = table[-1].astype(np.float64)
    if mode == "dvr":
        a = 1 - (1 - a) ** 8
    np.testing.assert_allclose(image[4, 4], [r * a, g * a, b * a, a], rtol=1e-6, atol=1e-7)


def test_gradient_table_past_one_is_the_last_entry():
    """A ramp steep enough for u > 1 everywhere inside: g(u) is the table's last entry."""
    n = 12
    data = np.broadcast_to(np.linspace(0, 1, n, dtype=np.float32), (n, n, n)).copy()  # 1/11 per voxel
    gtab = np.array([0.0, 0.2, 0.4, 0.6], np.float32)
    tf = TransferFunction(TransferFunction.constant(alpha=0.05).table, reference_step=12.0)  # u = (1/11)·12/(√3/2) ≈ 1.26
    scene = Scene([VolumeInstance(Volume(data), tf, gradient_opacity=GradientOpacity(gtab))],
                  camera=Camera(view_height=float(n), distance=40.0), width=n, height=n)
    image = ReferenceRenderer().render(scene).image
    u = (1 / 11) * 12.0 / (math.sqrt(3) / 2)
    assert u > 1
    expected = 1 - (1 - 0.05 * float(gtab[-1])) ** (n / 12.0)
    np.testing.assert_allclose(image[1:n - 1, 1:n - 1, 3], expected, rtol=1e-6)
