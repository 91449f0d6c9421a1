"""iSBVR's CPU side (renderers/gl/isosurfaces.py): transfer-function analysis, the min–max octree's
conservativeness at every node size, the cube sets of Figs. 5 and 8, their meshes' closure and winding,
and the marching-cubes "original" surfaces (Xue, Zhang & Crawfis 2005, note 001 §2.3, §2.7)."""

from collections import Counter

import numpy as np
import pytest
from scipy import ndimage

from renderers.gl.emptyspace import LEVELS
from renderers.gl.isosurfaces import (NODE_SIZES, analyse, boundary_faces, check_node_size, marching_cubes_surface,
                                      node_classes, on_boundary, opacity_bounds, phi_p_cubes, phi_t_cubes)

# ---------------------------------------------------------------------------------------- helpers
RAMP = np.array([0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1, 1.0])
"""Monotone (the paper's Fig. 9e): 0 below 0.3, a ramp, 1 from 0.6."""
BAND = np.array([0, 0, 0.5, 1, 1, 0.5, 0, 0, 0, 0, 0.0])
"""A band with zero opacity on both sides, opaque in its middle."""
TWO_OPAQUE = np.array([0, 1, 1, 0.2, 0, 0, 0.4, 1, 1, 1, 0.3])
"""Two opaque intervals, two visible intervals, never transparent at the top end."""


def sample_opacity(table_alpha, scalars):
    """The shaders' classification: the table interpolated linearly, entry ``i`` at ``i/(N − 1)``."""
    n = len(table_alpha)
    return np.interp(np.asarray(scalars, np.float64) * (n - 1), np.arange(n), table_alpha)


def smooth_volume(shape=(24, 28, 30), seed=7):
    """Seeded random field smoothed into blobs, in [0, 1]; no side a multiple of 8 but 24 (partial blocks)."""
    field = ndimage.gaussian_filter(np.random.default_rng(seed).random(shape), 4.0)
    return ((field - field.min()) / (field.max() - field.min())).astype(np.float32)


def table(points, size=256):
    """Opacities of a piecewise-linear transfer function ``[(scalar, alpha)]`` on ``size`` entries."""
    s, a = zip(*points)
    return np.interp(np.linspace(0, 1, size), s, a)


TFS = {"ramp": table([(0, 0), (0.45, 0), (0.5, 0.005), (0.52, 0.005), (0.56, 0.97), (0.6, 0.97), (0.62, 1), (1, 1)]),
       "band": table([(0, 0), (0.44, 0), (0.5, 1), (0.62, 1), (0.7, 0), (1, 0)])}
"""Transfer functions for the conservativeness tests: monotone with a faint foot and a shoulder just below 1
(opacities just above 0 must count as visible, those just below 1 not as opaque), and a band transparent on both
sides."""


def block_of(texture, shape, node_size):
    """``(z, y, x)`` block indices of texture-space points ``(P, 3)`` (x, y, z): the block whose voxels' cells
    hold the point (voxel coordinate ``u = t·n − ½`` lies in ``[bB − ½, (b + 1)B − ½)``)."""
    n_xyz = np.asarray(shape[::-1])
    counts = -(-n_xyz // node_size)
    index = np.clip(np.floor(texture * n_xyz / node_size).astype(int), 0, counts - 1)
    return tuple(index[:, ::-1].T)


def trilinear(volume, texture):
    """Clamp-to-edge trilinear samples of ``volume`` (z, y, x) at texture points ``(P, 3)`` (x, y, z)."""
    voxel = texture[:, ::-1] * np.asarray(volume.shape) - 0.5
    return ndimage.map_coordinates(volume.astype(np.float64), voxel.T, order=1, mode="nearest")


def directed_edges(triangles):
    """Counter of directed edges ``(a, b)`` of ``(T, 3, 3)`` triangles (shared vertices are bit-identical)."""
    edges = Counter()
    for triangle in triangles.tolist():
        for k in range(3):
            edges[tuple(triangle[k]), tuple(triangle[(k + 1) % 3])] += 1
    return edges


def unbalanced(edges):
    """Directed edges that do not appear as often as their reverse (none: a closed, consistently wound mesh)."""
    return [edge for edge, count in edges.items() if edges[edge[::-1]] != count]


def normals(triangles):
    return np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])


# --------------------------------------------------------------------------- transfer-function analysis
def test_analysis_of_a_monotone_ramp():
    found = analyse(RAMP)
    assert found.visible == ((0.3, 1.0),) and found.opaque == ((0.6, 1.0),)
    assert found.iso_t == 0.3 and found.iso_p == 0.6
    assert found.has_empty and found.has_opaque


def test_analysis_of_non_monotone_functions():
    band = analyse(BAND)
    assert band.visible == ((0.2, 0.5),) and band.opaque == ((0.3, 0.4),)
    assert (band.iso_t, band.iso_p) == (0.2, 0.3) and band.has_empty and band.has_opaque
    two = analyse(TWO_OPAQUE)
    assert two.visible == ((0.1, 0.3), (0.6, 1.0))
    assert two.opaque == ((0.1, 0.2), (0.7, 0.9))
    assert (two.iso_t, two.iso_p) == (0.1, 0.1) and two.has_empty and two.has_opaque


def test_analysis_without_empty_or_opaque_scalars():
    fuzzy = analyse(np.full(11, 0.3))
    assert fuzzy.visible == ((0.0, 1.0),) and not fuzzy.has_empty
    assert fuzzy.opaque == () and fuzzy.iso_p is None and not fuzzy.has_opaque
    nothing = analyse(np.zeros(11))
    assert nothing.iso_t is None and nothing.iso_p is None and nothing.has_empty and not nothing.has_opaque
    with pytest.raises(ValueError, match="1-D table of at least 2 entries"):
        analyse(np.zeros((4, 4)))


@pytest.mark.parametrize("alpha", [RAMP, BAND, TWO_OPAQUE, np.random.default_rng(3).random(37).round(1),
                                   TFS["band"]], ids=["ramp", "band", "two-opaque", "random-37", "band-256"])
def test_opacity_bounds_are_the_extremes_of_the_entries_a_range_blends(alpha):
    least, greatest = opacity_bounds(alpha)
    assert least.shape == greatest.shape == (LEVELS, LEVELS)
    n = len(alpha)
    top = LEVELS - 1
    for lo in range(LEVELS):
        # A scalar in [lo, hi]/top sits at table position s·(N − 1) and blends the entries around it,
        # floor(lo·(N − 1)/top) … ceil(hi·(N − 1)/top), computed in integers.
        first = lo * (n - 1) // top
        for hi in range(lo, LEVELS):
            last = -(-hi * (n - 1) // top)
            entries = alpha[first:last + 1]
            assert least[lo, hi] == entries.min() and greatest[lo, hi] == entries.max(), (lo, hi)
        assert np.all(least[lo, :lo] == 1) and np.all(greatest[lo, :lo] == 0)  # min > max: never looked up
    # And the classification of any scalar in a range lies between the range's bounds.
    rng = np.random.default_rng(0)
    lo, hi = np.sort(rng.integers(0, LEVELS, (2, 4000)), axis=0)
    s = (lo + rng.random(lo.size) * (hi - lo)) / top
    opacity = sample_opacity(alpha, s)
    assert np.all(opacity >= least[lo, hi] - 1e-12) and np.all(opacity <= greatest[lo, hi] + 1e-12)


# ------------------------------------------------------------------------------------------- octree
@pytest.fixture(scope="module")
def volume():
    return smooth_volume()


@pytest.mark.parametrize("tf", sorted(TFS))
@pytest.mark.parametrize("node_size", NODE_SIZES)
def test_octree_is_conservative(volume, tf, node_size):
    alpha = TFS[tf]
    classes = node_classes(volume, alpha, node_size)
    counts = tuple(-(-n // node_size) for n in volume.shape)
    assert classes.visible.shape == counts and classes.node_size == node_size and classes.shape == volume.shape
    # The case has empty blocks at every node size, and opaque ones at all but 8 (too coarse for its blobs).
    assert not classes.visible.all() and (classes.opaque.any() or node_size == 8)
    # (a) every voxel and every trilinear sample with opacity above 0 lies in a visible block.
    voxels = np.argwhere(sample_opacity(alpha, volume) > 0)
    assert classes.visible[tuple((voxels // node_size).T)].all()
    points = np.random.default_rng(node_size).random((40000, 3))
    opacity = sample_opacity(alpha, trilinear(volume, points))
    blocks = block_of(points, volume.shape, node_size)
    assert (opacity > 0).any() and (opacity == 0).any()
    assert classes.visible[blocks][opacity > 0].all()
    # (b) no sample in an opaque block (Φ_p's cube set among them) is less than opaque.
    assert classes.opaque[blocks].any() == classes.opaque.any()
    assert np.all(opacity[classes.opaque[blocks]] >= 1.0)
    assert np.all(opacity[phi_p_cubes(classes)[blocks]] >= 1.0)
    # The other classes: wholly visible blocks hold no transparent sample; some_opaque holds every opaque one.
    assert np.all(opacity[classes.wholly_visible[blocks]] > 0)
    assert classes.some_opaque[blocks][opacity >= 1].all()


def test_bad_node_sizes_are_refused_by_name(volume):
    for bad in (3, 0, 16, "2"):
        with pytest.raises(ValueError, match=r"node_size: expected one of 1, 2, 4, 8 voxels, got"):
            node_classes(volume, TFS["ramp"], bad)
    with pytest.raises(ValueError, match="phi_p_node: expected one of 1, 2, 4, 8"):
        check_node_size(3, name="phi_p_node")
    assert check_node_size(8) == 8


# --------------------------------------------------------------------------------- Fig. 5: Φ_t's set
def touching_faces(shape=(30, 28, 26)):
    """A smooth slab filling the lower half of z plus a blob: material touching five of the box's faces."""
    z, y, x = np.meshgrid(*(np.arange(n) + 0.5 for n in shape), indexing="ij")
    slab = np.clip((shape[0] * 0.45 - z) / 3, 0, 1)
    blob = np.clip(1 - np.sqrt((x - 13) ** 2 + (y - 14) ** 2 + (z - 22) ** 2) / 5, 0, 1)
    return np.maximum(slab, blob).astype(np.float32)


@pytest.mark.parametrize("node_size", NODE_SIZES)
def test_phi_t_mesh_is_closed_only_with_the_boundary_cubes(node_size):
    field = touching_faces()
    classes = node_classes(field, TFS["ramp"], node_size)
    cubes = phi_t_cubes(classes)
    contains = classes.visible & ~classes.wholly_visible
    closure = classes.wholly_visible & on_boundary(cubes.shape)
    assert np.array_equal(cubes, contains | closure) and closure.any()
    closed = boundary_faces(cubes, node_size, field.shape, region=classes.visible)
    assert len(closed) and not unbalanced(directed_edges(closed))
    open_mesh = boundary_faces(contains, node_size, field.shape, region=classes.visible)
    assert unbalanced(directed_edges(open_mesh))


@pytest.mark.parametrize("node_size", NODE_SIZES)
def test_faces_point_from_a_member_to_a_non_member(node_size):
    field = touching_faces()
    classes = node_classes(field, TFS["ramp"], node_size)
    for members, region in ((phi_t_cubes(classes), classes.visible), (phi_p_cubes(classes), classes.opaque),
                            (phi_p_cubes(classes), None)):
        triangles = boundary_faces(members, node_size, field.shape, region=region).astype(np.float64)
        region = members if region is None else region | members
        assert len(triangles)
        normal = normals(triangles)
        assert np.all(np.count_nonzero(normal, axis=1) == 1)  # axis-aligned faces
        direction = np.sign(normal)
        centre = triangles.mean(axis=1)
        quarter = node_size / np.asarray(field.shape[::-1]) / 4  # a quarter block, texture units
        inside, outside = centre - direction * quarter, centre + direction * quarter
        assert members[block_of(inside, field.shape, node_size)].all()
        beyond = np.all((outside >= 0) & (outside <= 1), axis=1)
        assert not region[block_of(outside[beyond], field.shape, node_size)].any()
        assert (~beyond).any() and beyond.any()  # faces on the volume's faces and inside it


def test_faces_lie_on_the_block_planes_clamped_to_the_box():
    members = np.zeros((2, 2, 3), bool)
    members[1, 1, 2] = True  # the corner block, partial in x (20 voxels = 8 + 8 + 4)
    triangles = boundary_faces(members, 8, (14, 16, 20))
    assert triangles.shape == (12, 3, 3) and triangles.dtype == np.float32
    assert np.allclose(triangles.min(axis=(0, 1)), [16 / 20, 8 / 16, 8 / 14])
    assert np.allclose(triangles.max(axis=(0, 1)), [1, 1, 1])
    assert boundary_faces(np.zeros((2, 2, 2), bool), 8, (16, 16, 16)).shape == (0, 3, 3)


# --------------------------------------------------------------------------------- Fig. 8: Φ_p's set
@pytest.mark.parametrize("node_size", NODE_SIZES)
def test_phi_p_set_is_the_opaque_blocks_beside_a_non_opaque_one(volume, node_size):
    for alpha in TFS.values():
        classes = node_classes(volume, alpha, node_size)
        opaque = classes.opaque
        expected = np.zeros_like(opaque)
        for z, y, x in np.argwhere(opaque):
            for axis in range(3):
                for step in (-1, 1):
                    k = [z, y, x]
                    k[axis] += step
                    if not 0 <= k[axis] < opaque.shape[axis] or not opaque[tuple(k)]:
                        expected[z, y, x] = True
        assert np.array_equal(phi_p_cubes(classes), expected)
    # A solid opaque core: the set is its outer layer, the core's inside is not in it.
    field = np.zeros((16, 16, 16), np.float32)
    field[2:14, 2:14, 2:14] = 1
    classes = node_classes(field, TFS["ramp"], 1)
    assert classes.opaque[3:13, 3:13, 3:13].all() and not classes.opaque[2, 2, 2]
    cubes = phi_p_cubes(classes)
    assert cubes.sum() == 10 ** 3 - 8 ** 3 and not cubes[4:12, 4:12, 4:12].any()
    # Opaque up to the volume's faces: the blocks on the faces are in the set.
    cubes = phi_p_cubes(node_classes(np.ones((8, 8, 8), np.float32), TFS["ramp"], 2))
    assert np.array_equal(cubes, on_boundary((4, 4, 4)))


def test_a_thin_shell_vanishes_at_coarse_nodes():
    n = 32
    z, y, x = np.meshgrid(*(np.arange(n) + 0.5,) * 3, indexing="ij")
    radius = np.sqrt((x - 16) ** 2 + (y - 16) ** 2 + (z - 16) ** 2)
    shell = np.clip(2 - np.abs(radius - 10), 0, 1).astype(np.float32)  # 1 over 2 voxels, 0 a voxel beyond
    alpha = (np.linspace(0, 1, 256) >= 0.5).astype(float)
    cubes = {size: int(phi_p_cubes(node_classes(shell, alpha, size)).sum()) for size in NODE_SIZES}
    assert cubes[1] > 100 and cubes[8] == 0, cubes  # the paper's Fig. 7: the skull vanishes at 8³


# -------------------------------------------------------------------------------- marching cubes
def sphere_field(shape=(20, 24, 28), centre=(9.0, 13.0, 12.0), radius=6.3):
    """Cone profile 1 − r/(2·radius): level ½ is the sphere of ``radius`` voxels (no grid value exactly ½)."""
    z, y, x = np.meshgrid(*(np.arange(n) for n in shape), indexing="ij")
    r = np.sqrt((z - centre[0]) ** 2 + (y - centre[1]) ** 2 + (x - centre[2]) ** 2)
    return np.clip(1 - r / (2 * radius), 0, 1).astype(np.float32)


@pytest.mark.parametrize("cell", [1, 2])
def test_marching_cubes_faces_point_outwards(cell):
    shape, centre = (20, 24, 28), (9.0, 13.0, 12.0)  # voxel (z, y, x)
    field = sphere_field(shape, centre)
    if cell > 1:
        field = field.reshape(10, 2, 12, 2, 14, 2).max(axis=(1, 3, 5))
    triangles = marching_cubes_surface(field, 0.5, cell=cell, shape=shape).astype(np.float64)
    assert triangles.ndim == 3 and len(triangles) > 100
    assert np.all((triangles >= 0) & (triangles <= 1))
    # The inside (the values at or above the level) is a convex blob: every normal points away from its centre.
    centre_texture = (np.asarray(centre[::-1]) + 0.5) / np.asarray(shape[::-1])
    away = np.einsum("ij,ij->i", normals(triangles), triangles.mean(axis=1) - centre_texture)
    assert np.all(away > 0)
    # Closed (the blob is inside the volume) and of the sphere's volume (r = 6.3 voxels) in texture units.
    assert not unbalanced(directed_edges(triangles))
    signed = np.einsum("ij,ij->i", triangles[:, 0], np.cross(triangles[:, 1], triangles[:, 2])).sum() / 6
    expected = 4 / 3 * np.pi * 6.3 ** 3 / np.prod(shape)
    assert signed == pytest.approx(expected, rel=0.05 if cell == 1 else 0.5)  # the max grid inflates it


def test_marching_cubes_is_empty_where_the_level_is_not_crossed():
    field = sphere_field()
    for level in (1.5, 0.0, -1.0):
        assert marching_cubes_surface(field, level).shape == (0, 3, 3)
    assert marching_cubes_surface(np.ones((1, 8, 8)), 0.5).shape == (0, 3, 3)
    assert len(marching_cubes_surface(field, 0.5))
