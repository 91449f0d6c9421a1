"""The iSBVR surfaces (Xue, Zhang & Crawfis 2005, note 001 §2.3, §2.7), built on the CPU in NumPy.

* **Transfer-function analysis** (:func:`analyse`): the intervals of the normalised scalar where the
  opacity is above 0 (their lower ends are the paper's Φ_t, "opacity leaves 0") and where it is 1
  (Φ_p, "opacity reaches 1"); several of each where the function has them.
* **Opacity of a value range** (:func:`opacity_bounds`): the least and the greatest opacity a scalar in
  ``[min, max]`` can take, over the table entries it can blend with (note 001 §2.3's generalisation, so
  non-monotone functions work). A block is *empty* when its greatest opacity is 0 and *opaque* when its
  least is 1.
* **Min–max octree** (:func:`node_classes`): one level of blocks of 1, 2, 4 or 8 voxels a side, each
  range holding its voxels and a one-voxel apron (:func:`renderers.gl.emptyspace.block_minmax`), so
  every trilinear sample inside a block lies within its range.
* **Cube sets**: Φ_t's (:func:`phi_t_cubes`, Fig. 5) keeps the blocks that contain the boundary surface
  (some but not all of their values visible) and, to close the surface where material touches the volume's
  faces, the wholly visible blocks on the volume's boundary; Φ_p's (:func:`phi_p_cubes`, Fig. 8) keeps
  the wholly opaque blocks beside a block that is not (the paper's shrinking walk from the containing
  cubes reaches exactly these) or beside the volume's outside.
* **Meshes** (:func:`boundary_faces`): only the faces between a member and a non-member (or the
  outside), two triangles each, wound counter-clockwise seen from outside, in texture coordinates.
* **"Original" surfaces** (:func:`marching_cubes_surface`): marching cubes (scikit-image) on the coarse
  maximum or minimum grid, or on the full-resolution field: the paper's Fig. 4a failure case and its
  full-resolution overhead (E7, E8). Open where the surface leaves the volume, as the paper's were.

Conservativeness (what makes iSBVR lossless): a sample behind the last exit from Φ_t's cubes lies in
blocks whose greatest opacity is 0, and a sample inside Φ_p's cubes is fully opaque, so culling behind
them changes nothing once the Φ_p depth is pushed back by one slice (the first sample inside, which
carries the final colour, then stays: note 001 §2.7).
"""

from dataclasses import dataclass

import numpy as np

from renderers.gl.emptyspace import LEVELS, block_minmax

NODE_SIZES = (1, 2, 4, 8)
"""Octree node sizes (voxels a side) the cube sets may be built at (the paper: 8 for Φ_t, 2 for Φ_p)."""

_FACE_CORNERS = ((0, 0), (1, 0), (1, 1), (0, 1))
"""A face's corners in its two in-plane axes (b, c), counter-clockwise seen along +a (e_b × e_c = e_a)."""


# ------------------------------------------------------------------------------ transfer function
@dataclass(frozen=True)
class OpacityAnalysis:
    """Where a transfer function is visible and where it is opaque (normalised scalars).

    Attributes
    ----------
    visible, opaque : tuple of (float, float)
        Closed intervals of the scalar with opacity above 0 and equal to 1, in order.
    """

    visible: tuple
    opaque: tuple

    @property
    def iso_t(self):
        """Φ_t: the lowest scalar whose opacity is above 0 (``None``: nowhere)."""
        return self.visible[0][0] if self.visible else None

    @property
    def iso_p(self):
        """Φ_p: the lowest scalar whose opacity is 1 (``None``: never opaque)."""
        return self.opaque[0][0] if self.opaque else None

    @property
    def has_empty(self):
        """Whether some scalar is fully transparent (space leaping can help)."""
        return not (len(self.visible) == 1 and self.visible[0] == (0.0, 1.0))

    @property
    def has_opaque(self):
        """Whether some scalar is fully opaque (pseudo early termination can help)."""
        return bool(self.opaque)


def _intervals(mask):
    """Closed intervals ``[(lo, hi)]`` of normalised scalars over runs of True entries of ``mask``."""
    n = mask.size
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return tuple((float(a) / (n - 1), float(b - 1) / (n - 1)) for a, b in zip(edges[::2], edges[1::2]))


def analyse(table_alpha):
    """The :class:`OpacityAnalysis` of a transfer function's opacities (entry ``i`` at ``i/(N − 1)``)."""
    alpha = np.asarray(table_alpha, dtype=np.float64)
    if alpha.ndim != 1 or alpha.size < 2:
        raise ValueError(f"transfer-function opacities: expected a 1-D table of at least 2 entries, got shape {alpha.shape}")
    return OpacityAnalysis(_intervals(alpha > 0.0), _intervals(alpha >= 1.0))


def opacity_bounds(table_alpha):
    """``(least, greatest)``: ``(LEVELS, LEVELS)`` arrays, ``[min_level, max_level]`` → opacity bounds.

    A scalar in ``[min, max]`` (quantised to :data:`~renderers.gl.emptyspace.LEVELS` levels, as the
    block ranges are) blends table entries ``floor(min·(N−1)) … ceil(max·(N−1))``; its opacity lies
    between the least and the greatest of theirs. Entries with ``min > max`` are never looked up
    (least 1, greatest 0).
    """
    alpha = np.asarray(table_alpha, dtype=np.float64)
    n = alpha.size
    levels = np.arange(LEVELS) / (LEVELS - 1) * (n - 1)
    first = np.clip(np.floor(levels + 1e-9).astype(np.int64), 0, n - 1)
    last = np.clip(np.ceil(levels - 1e-9).astype(np.int64), 0, n - 1)
    lo, hi = np.broadcast_arrays(first[:, None], last[None, :])
    lo, hi = lo, np.maximum(hi, lo)  # entries min > max are replaced below
    return (np.where(_unused(), 1.0, _range_query(alpha, lo, hi, np.minimum)),
            np.where(_unused(), 0.0, _range_query(alpha, lo, hi, np.maximum)))


def _unused():
    return np.arange(LEVELS)[:, None] > np.arange(LEVELS)[None, :]


def _range_query(values, lo, hi, reduce):
    """``reduce`` of ``values[lo … hi]`` (inclusive) for arrays of ``lo <= hi``: a sparse table, O(N log N)."""
    table = [values]
    while 2 ** len(table) <= values.size:
        half = 2 ** (len(table) - 1)
        previous = table[-1]
        table.append(reduce(previous[:-half], previous[half:]))
    length = hi - lo + 1
    k = np.floor(np.log2(length)).astype(np.int64)
    out = np.empty(lo.shape)
    for level in np.unique(k):
        at = k == level
        row = table[level]
        out[at] = reduce(row[lo[at]], row[hi[at] - 2 ** level + 1])
    return out


# ------------------------------------------------------------------------------------ cube sets
@dataclass(frozen=True)
class NodeClasses:
    """One octree level's blocks, classified: ``(bz, by, bx)`` boolean grids.

    Attributes
    ----------
    node_size : int
        Voxels per block edge.
    shape : tuple of int
        The volume's ``(nz, ny, nx)``.
    visible : numpy.ndarray
        Some value in the block's range has opacity above 0.
    wholly_visible : numpy.ndarray
        Every value in the range has opacity above 0 (the block is inside Φ_t).
    opaque : numpy.ndarray
        Every value in the range has opacity 1 (the block is inside Φ_p).
    some_opaque : numpy.ndarray
        Some value in the range has opacity 1.
    """

    node_size: int
    shape: tuple
    visible: np.ndarray
    wholly_visible: np.ndarray
    opaque: np.ndarray
    some_opaque: np.ndarray


def check_node_size(node_size, *, name="node_size"):
    """``node_size`` as an int of :data:`NODE_SIZES`; ValueError naming ``name`` otherwise."""
    if node_size not in NODE_SIZES:
        raise ValueError(f"{name}: expected one of {', '.join(map(str, NODE_SIZES))} voxels, got {node_size!r}")
    return int(node_size)


def node_classes(normalised, table_alpha, node_size):
    """Classify the ``node_size³`` blocks of ``normalised`` (``(nz, ny, nx)`` in [0, 1]) by opacity."""
    node_size = check_node_size(node_size)
    grid = block_minmax(normalised, node_size)
    least, greatest = opacity_bounds(table_alpha)
    low, high = grid[..., 0], grid[..., 1]
    lo_alpha, hi_alpha = least[low, high], greatest[low, high]
    return NodeClasses(node_size, tuple(normalised.shape), hi_alpha > 0.0, lo_alpha > 0.0, lo_alpha >= 1.0,
                       hi_alpha >= 1.0)


def on_boundary(shape):
    """``shape`` boolean grid, True on its outer layer of cells."""
    edge = np.zeros(shape, bool)
    for axis in range(len(shape)):
        index = [slice(None)] * len(shape)
        for end in (0, -1):
            index[axis] = end
            edge[tuple(index)] = True
    return edge


def _beside(mask, *, outside):
    """Cells with a 6-neighbour where ``mask`` is True (``outside``: the value beyond the grid)."""
    padded = np.pad(mask, 1, constant_values=outside)
    found = np.zeros(mask.shape, bool)
    core = tuple(slice(1, -1) for _ in range(3))
    for axis in range(3):
        for shift in (-1, 1):
            found |= np.roll(padded, shift, axis=axis)[core]
    return found


def phi_t_cubes(classes):
    """Fig. 5's cube set S: blocks containing the boundary surface, and the wholly visible blocks on the
    volume's boundary (which close the surface where material touches the volume's faces)."""
    contains = classes.visible & ~classes.wholly_visible
    return contains | (classes.wholly_visible & on_boundary(classes.visible.shape))


def phi_p_cubes(classes):
    """Fig. 8's cube set T: the wholly opaque blocks beside a block that is not wholly opaque, or beside the
    volume's outside (the outer layer of the opaque region, which the paper's shrinking walk finds)."""
    return classes.opaque & _beside(~classes.opaque, outside=True)


# ----------------------------------------------------------------------------------------- meshes
def _planes(count, node_size, n):
    """Texture coordinates of the block boundaries along one axis (the last clamped to the box)."""
    return np.minimum(np.arange(count + 1) * node_size / n, 1.0)


def boundary_faces(members, node_size, shape, *, region=None):
    """Triangles of the faces between member blocks and blocks outside ``region`` (or the volume's
    outside), outward wound.

    Parameters
    ----------
    members : numpy.ndarray
        ``(bz, by, bx)`` boolean block grid.
    region : numpy.ndarray, optional
        The region the members bound (default: the members): a member's face towards another block of
        it is inside and not drawn. A cube set's region is everything on its side of the surface (Φ_t's:
        the visible blocks), so only the faces that make the surface are drawn, and a cube set that
        leaves a gap in its surface (no closure at the volume's faces) gives an open mesh.
    node_size : int
        Voxels per block edge.
    shape : tuple of int
        The volume's ``(nz, ny, nx)``.

    Returns
    -------
    numpy.ndarray
        ``(T, 3, 3)`` float32 texture coordinates (x, y, z), counter-clockwise seen from outside.
    """
    members = np.asarray(members, bool)
    region = members if region is None else np.asarray(region, bool) | members
    counts_xyz = members.shape[::-1]
    planes = [_planes(c, node_size, n) for c, n in zip(counts_xyz, tuple(shape)[::-1])]
    quads = []
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        padding = [(1, 1) if k == a else (0, 0) for k in range(3)]
        # Index [x, y, z]; cells before and after each plane along a.
        mine, theirs = (np.pad(grid.transpose(2, 1, 0), padding) for grid in (members, region))
        before, after = (np.arange(0, mine.shape[a] - 1), np.arange(1, mine.shape[a]))
        lower, upper = np.take(mine, before, axis=a), np.take(mine, after, axis=a)
        lower_r, upper_r = np.take(theirs, before, axis=a), np.take(theirs, after, axis=a)
        for sign, faces in ((1, lower & ~upper_r), (-1, upper & ~lower_r)):
            idx = np.argwhere(faces)  # [plane index along a, cell along the others]
            if idx.size == 0:
                continue
            corners = np.empty((len(idx), 4, 3))
            corners[:, :, a] = planes[a][idx[:, a]][:, None]
            order = _FACE_CORNERS if sign > 0 else _FACE_CORNERS[::-1]
            for k, (db, dc) in enumerate(order):
                corners[:, k, b] = planes[b][idx[:, b] + db]
                corners[:, k, c] = planes[c][idx[:, c] + dc]
            quads.append(corners)
    if not quads:
        return np.zeros((0, 3, 3), np.float32)
    quads = np.concatenate(quads)
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return np.ascontiguousarray(triangles, dtype=np.float32)


def marching_cubes_surface(field, level, *, cell=1, shape=None):
    """Marching cubes of ``field`` at ``level`` as outward-wound triangles in texture coordinates.

    Parameters
    ----------
    field : numpy.ndarray
        ``(z, y, x)`` scalars: the full-resolution normalised volume (``cell`` 1), or a coarse block grid's
        maxima or minima, value ``[k]`` at the centre of block ``k`` (``cell`` its node size).
    level : float
        Iso-value; the inside is ``field >= level`` (normals point to lower values, outwards).
    cell : int
        Voxels between neighbouring samples of ``field``.
    shape : tuple of int, optional
        The volume's ``(nz, ny, nx)``; default ``field.shape`` (full resolution).

    Returns
    -------
    numpy.ndarray
        ``(T, 3, 3)`` float32; empty where ``level`` is not crossed.
    """
    from skimage.measure import marching_cubes

    field = np.asarray(field, dtype=np.float32)
    shape = tuple(shape or field.shape)
    if min(field.shape) < 2 or not (field.min() < level <= field.max()):
        return np.zeros((0, 3, 3), np.float32)
    verts, faces, normals, _ = marching_cubes(field, level=level, gradient_direction="descent")
    # Sample k sits at the centre of its cell: voxel k·cell + (cell − 1)/2, texture ((that) + ½)/n.
    n_zyx = np.asarray(shape, np.float64)
    tex_zyx = (verts * cell + (cell - 1) / 2.0 + 0.5) / n_zyx
    triangles = np.clip(tex_zyx[:, ::-1], 0.0, 1.0)[faces]
    # Orientation judged in the grid's own index space, where scikit-image's normals live.
    corners = verts[faces]
    geometric = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    # (z, y, x) is a reflection of (x, y, z): a face counter-clockwise in one is clockwise in the other.
    flip = np.einsum("ij,ij->i", geometric, normals[faces].sum(axis=1)) > 0
    triangles[flip] = triangles[flip][:, ::-1]
    return np.ascontiguousarray(triangles, dtype=np.float32)
