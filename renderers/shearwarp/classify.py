"""Pre-classification, 13-bit normals and the run-length-encoded classified volume (Lacroute 1995, §4.1.2, §7.1).

Classification (``classify``)
-----------------------------
Shear-warp classifies *before* resampling: every voxel gets its opacity and colour index at its
centre, and the compositing loop interpolates these pre-classified (opacity-weighted) values
bilinearly inside each slice. This is the method's documented difference from the reference
renderer, which interpolates scalars and classifies afterwards (post-classification,
CONVENTIONS); with smooth transfer functions the two agree closely, with sharp ones they differ
(thesis Fig. 5.10). Per voxel, following CONVENTIONS and the project README:

* ``s``: the scalar normalised by the volume's value range;
* gradient: central differences one voxel apart in object space with clamp-to-edge,
  ``(s[i+1] − s[i−1]) / (2·spacing)`` per axis, i.e. the reference's estimator evaluated at the
  voxel centre (where the trilinear field equals the voxel values);
* opacity ``α = α_tf(s)·g(u)``, ``u = |∇s|·Δ0/(√3/2)`` (``g`` = 1 without a gradient-opacity
  table), the tables interpolated exactly as the reference does;
* a voxel is *transparent* when ``α <= min_opacity`` (the thesis's 0.05 by default); its record
  is zero. Otherwise it keeps its unthresholded opacity.

Voxel records (4 bytes, the thesis's layout): ``uint32 = opacity | colour index << 8 |
normal code << 16``: opacity quantised to 8 bits (``round(255·α)``; the per-view opacity
correction table is indexed by it, as in VolPack), the colour index ``round(255·s)`` into a
256-entry table of the transfer function's RGB (exact for 8-bit data with a 256-entry table,
else an 8-bit quantisation of the scalar), and the 13-bit normal code below (with
:data:`NO_NORMAL`, bits 16–29). Bit 30 (:data:`LENS_BIT`) marks a voxel classified with a lens's
table, whose colour is row ``256 + index`` of a 512-row colour table (the compositing kernels
decode a record with :func:`renderers.shearwarp.composite.colour_index` and ``normal_code``). For
``shading="procedural"`` an aligned float32 array keeps each voxel's unquantised object-space
gradient.

Lenses (Ropinski et al. 2005, by pre-classification)
----------------------------------------------------
With a :class:`LensClassification` each voxel whose centre lies in the lens (closed: on its
surface counts as inside) is classified with the lens's appearance instead of the volume's: a
``clip`` lens makes it transparent, a ``dvr`` lens classifies it with the lens's opacity and
gradient-opacity tables by the rule above and sets :data:`LENS_BIT`. Every other voxel gets the
record it has without a lens, bit for bit. The lens is placed in voxel-index space once
(:func:`lens_classification`: index → object → world by the instance transform → the lens's own
frame), so the test per voxel is a sphere's ``|p|² <= r²`` or a convex solid's ``n·p <= c`` for
every face, in the lens frame.

13-bit normals (thesis §7.1, Fig. 7.2)
--------------------------------------
The gradient direction ``g/|g|₁`` is put on the octahedron ``|n_x| + |n_y| + |n_z| = 1``, its
``(n_x, n_y)`` rotated by 45° (``x_r = (n_x − n_y)/√2``, ``y_r = (n_x + n_y)/√2``, which fills the
square ``|x_r|, |y_r| <= 1/√2``), each quantised to 6 bits on a uniform 64-cell grid, plus the
sign of ``n_z``: ``code = x_i << 7 | y_i << 1 | (n_z < 0)``, 8192 codes. Decoding takes the cell
centre and applies the thesis's formulas ``n_x = (y_r + x_r)/√2``, ``n_y = (y_r − x_r)/√2``,
``n_z = ±(1 − |n_x| − |n_y|)`` and normalises. A zero gradient gets the extra code
:data:`NO_NORMAL` (8192), shaded with the ambient term only (CONVENTIONS), so tables have 8193
entries. The code is of the *object-space* gradient (spacing included); the per-frame shade
table carries each direction to world space with the normal matrix, so the quantisation does not
depend on the view.

Run-length encoding (``encode``)
--------------------------------
One encoding per principal axis, in standard object order ``[k, j, i]`` (slices, scanlines,
voxels; :func:`renderers.shearwarp.factor.axes_ijk`):

* ``lengths`` (uint8): per voxel scanline, alternating transparent / non-transparent run lengths
  starting with a transparent run; a run longer than 255 is split by a zero-length run of the
  other kind, and every scanline ends with a non-transparent run (possibly of length 0), so each
  scanline has an even number of entries and a fully transparent one is ``[n, 0]``;
* ``voxels`` (uint32): the records of the non-transparent voxels, packed in scanline order;
* ``run_offsets``, ``data_offsets`` (int64, ``n_k·n_j + 1``): where each scanline's runs and
  voxels start (the per-scanline pointer array of the parallel renderer, Ch. 6; slice ``k``
  starts at scanline ``k·n_j``).

The brute-force variant (``rle=False``) uses the same format with every voxel stored (one
non-transparent run per scanline, split at 255), so one compositing kernel serves both.
"""

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from core.transfer import MAX_GRADIENT
from renderers.base.numba_kernels import JIT as _JIT, table_position


NORMAL_GRID = 64
"""Cells per rotated octahedral axis (6 bits)."""
NO_NORMAL = 8192
"""Normal code of a zero gradient (ambient light only); codes 0..8191 are directions."""
NORMAL_CODES = NO_NORMAL + 1
SQRT2 = math.sqrt(2.0)
LENS_BIT = np.uint32(1 << 30)
"""Record bit of a voxel classified with a ``dvr`` lens's table (its colour: row ``256 + index``)."""
NO_LENS, LENS_SPHERE, LENS_PLANES = 0, 1, 2
"""Lens shapes in the kernels: none, a sphere about the lens frame's origin, half-spaces of the lens frame."""


@njit(**_JIT)
def encode_normal(gx, gy, gz):
    """13-bit code of the direction of ``(gx, gy, gz)`` (:data:`NO_NORMAL` for the zero vector)."""
    norm1 = abs(gx) + abs(gy) + abs(gz)
    if not norm1 > 0.0:
        return NO_NORMAL
    qx = gx / norm1
    qy = gy / norm1
    # x_r·√2 = q_x − q_y and y_r·√2 = q_x + q_y lie in [−1, 1].
    xi = int(math.floor((qx - qy + 1.0) * 0.5 * NORMAL_GRID))
    yi = int(math.floor((qx + qy + 1.0) * 0.5 * NORMAL_GRID))
    xi = min(max(xi, 0), NORMAL_GRID - 1)
    yi = min(max(yi, 0), NORMAL_GRID - 1)
    return (xi << 7) | (yi << 1) | (1 if gz < 0.0 else 0)


def normal_directions():
    """``(8193, 3)`` float64 unit directions of every code (row :data:`NO_NORMAL` is zero)."""
    codes = np.arange(NO_NORMAL)
    xi, yi, sign = codes >> 7, (codes >> 1) & 63, codes & 1
    xr = ((xi + 0.5) / NORMAL_GRID * 2.0 - 1.0) / SQRT2
    yr = ((yi + 0.5) / NORMAL_GRID * 2.0 - 1.0) / SQRT2
    nx = (yr + xr) / SQRT2
    ny = (yr - xr) / SQRT2
    nz = np.maximum(1.0 - np.abs(nx) - np.abs(ny), 0.0) * np.where(sign == 1, -1.0, 1.0)
    dirs = np.zeros((NORMAL_CODES, 3))
    dirs[:NO_NORMAL] = np.stack([nx, ny, nz], axis=1)
    dirs[:NO_NORMAL] /= np.linalg.norm(dirs[:NO_NORMAL], axis=1, keepdims=True)
    return dirs


NORMAL_DIRECTIONS = normal_directions()


@njit(inline="always", **_JIT)  # inlined in Numba IR: no per-voxel call or array reference counting
def central_gradient(s, z, y, x, sx, sy, sz):
    """Object-space gradient at voxel ``(z, y, x)`` by central differences (one-sided at the faces)."""
    nz, ny, nx = s.shape
    x0 = max(x - 1, 0)
    x1 = min(x + 1, nx - 1)
    y0 = max(y - 1, 0)
    y1 = min(y + 1, ny - 1)
    z0 = max(z - 1, 0)
    z1 = min(z + 1, nz - 1)
    gx = (np.float64(s[z, y, x1]) - np.float64(s[z, y, x0])) / (2.0 * sx)
    gy = (np.float64(s[z, y1, x]) - np.float64(s[z, y0, x])) / (2.0 * sy)
    gz = (np.float64(s[z1, y, x]) - np.float64(s[z0, y, x])) / (2.0 * sz)
    return gx, gy, gz


@njit(inline="always", **_JIT)
def scalar_opacity(value, alpha_table):
    """The transfer function's opacity at normalised scalar ``value`` (float64), interpolated."""
    i0, w = table_position(value, alpha_table.shape[0])
    return alpha_table[i0] * (1.0 - w) + alpha_table[i0 + 1] * w


@njit(inline="always", **_JIT)
def gradient_factor(magnitude, gtab, ref_step):
    """The gradient-opacity factor ``g(u)``, ``u = |∇s|·Δ0/(√3/2)``, interpolated (``gtab`` non-empty)."""
    j0, wg = table_position(magnitude * ref_step / MAX_GRADIENT, gtab.shape[0])
    return gtab[j0] * (1.0 - wg) + gtab[j0 + 1] * wg


@njit(inline="always", **_JIT)
def pack_record(alpha, value, code):
    """The 4-byte record of a visible voxel: 8-bit opacity, 8-bit colour index, normal code."""
    opacity = min(int(alpha * 255.0 + 0.5), 255)
    colour = min(int(value * 255.0 + 0.5), 255)
    return np.uint32(opacity | (colour << 8) | (code << 16))


@njit(inline="always", **_JIT)  # inlined in Numba IR: no per-voxel call or array reference counting
def classify_voxel(s, z, y, x, sx, sy, sz, alpha_table, gtab, ref_step, min_opacity):
    """One voxel's ``(record, gx, gy, gz, visible)``: record and gradient 0 where it is transparent.

    ``visible`` says the opacity passed ``min_opacity`` (a faint voxel's record can still be 0 once
    its opacity is rounded to 8 bits). The one classification rule of the RLE build
    (:func:`_classify_kernel`) and the octree's on-the-fly classification; :func:`classify_parameters`
    is the same rule on precomputed parameters.
    """
    value = np.float64(s[z, y, x])
    alpha = scalar_opacity(value, alpha_table)
    if not alpha > min_opacity:
        return np.uint32(0), 0.0, 0.0, 0.0, False
    gx, gy, gz = central_gradient(s, z, y, x, sx, sy, sz)
    if gtab.shape[0] > 0:
        alpha *= gradient_factor(math.sqrt(gx * gx + gy * gy + gz * gz), gtab, ref_step)
        if not alpha > min_opacity:
            return np.uint32(0), 0.0, 0.0, 0.0, False
    return pack_record(alpha, value, encode_normal(gx, gy, gz)), gx, gy, gz, True


@njit(inline="always", **_JIT)
def classify_parameters(value, magnitude, code, alpha_table, gtab, ref_step, min_opacity):
    """:func:`classify_voxel`'s record from a voxel's precomputed parameters (the fast classification's
    voxel array): its scalar (float32), gradient magnitude and normal code, computed as that function
    computes them, so the record is the same bits."""
    value = np.float64(value)
    alpha = scalar_opacity(value, alpha_table)
    if not alpha > min_opacity:
        return np.uint32(0)
    if gtab.shape[0] > 0:
        alpha *= gradient_factor(magnitude, gtab, ref_step)
        if not alpha > min_opacity:
            return np.uint32(0)
    return pack_record(alpha, value, code)


@njit(inline="always", **_JIT)
def inside_lens(z, y, x, kind, m, radius, normals, offsets):
    """Whether voxel ``(z, y, x)``'s centre lies in the lens; ``m`` (3, 4) maps voxel indices to the lens frame."""
    fx = np.float64(x)
    fy = np.float64(y)
    fz = np.float64(z)
    px = m[0, 0] * fx + m[0, 1] * fy + m[0, 2] * fz + m[0, 3]
    py = m[1, 0] * fx + m[1, 1] * fy + m[1, 2] * fz + m[1, 3]
    pz = m[2, 0] * fx + m[2, 1] * fy + m[2, 2] * fz + m[2, 3]
    if kind == LENS_SPHERE:
        return px * px + py * py + pz * pz <= radius * radius
    for i in range(normals.shape[0]):
        if normals[i, 0] * px + normals[i, 1] * py + normals[i, 2] * pz > offsets[i]:
            return False
    return True


@njit(inline="always", **_JIT)
def classify_lens_voxel(s, z, y, x, sx, sy, sz, alpha_table, gtab, ref_step, min_opacity, lens_kind, lens_m,
                        lens_radius, lens_normals, lens_offsets, lens_clip, lens_alpha, lens_gtab):
    """:func:`classify_voxel` with the lens's tables inside the lens (``lens_kind`` :data:`NO_LENS`: none).

    A ``clip`` lens's voxels are transparent, a ``dvr`` lens's non-zero records carry :data:`LENS_BIT`.
    """
    if lens_kind != NO_LENS and inside_lens(z, y, x, lens_kind, lens_m, lens_radius, lens_normals, lens_offsets):
        if lens_clip:
            return np.uint32(0), 0.0, 0.0, 0.0, False
        record, gx, gy, gz, visible = classify_voxel(s, z, y, x, sx, sy, sz, lens_alpha, lens_gtab, ref_step,
                                                     min_opacity)
        if record != 0:
            record |= LENS_BIT
        return record, gx, gy, gz, visible
    return classify_voxel(s, z, y, x, sx, sy, sz, alpha_table, gtab, ref_step, min_opacity)


@njit(parallel=True, **_JIT)
def _classify_kernel(s, spacing, alpha_table, gtab, ref_step, min_opacity, want_gradients, lens_kind, lens_m,
                     lens_radius, lens_normals, lens_offsets, lens_clip, lens_alpha, lens_gtab, records, gradients,
                     nontransparent):
    nz, ny, nx = s.shape
    sx, sy, sz = spacing[0], spacing[1], spacing[2]
    for z in prange(nz):
        count = 0
        for y in range(ny):
            for x in range(nx):
                record, gx, gy, gz, visible = classify_lens_voxel(
                    s, z, y, x, sx, sy, sz, alpha_table, gtab, ref_step, min_opacity, lens_kind, lens_m, lens_radius,
                    lens_normals, lens_offsets, lens_clip, lens_alpha, lens_gtab)
                records[z, y, x] = record
                if want_gradients:
                    gradients[z, y, x, 0] = gx
                    gradients[z, y, x, 1] = gy
                    gradients[z, y, x, 2] = gz
                if visible:
                    count += 1
        nontransparent[z] = count


@dataclass(frozen=True, eq=False)
class LensClassification:
    """A lens as the classification kernels see it (built by :func:`lens_classification`).

    ``index_to_lens`` (3, 4) maps voxel indices ``(x, y, z)`` to the lens frame; ``kind`` is
    :data:`LENS_SPHERE` (``radius`` about the frame's origin) or :data:`LENS_PLANES` (inside:
    ``normals @ p <= offsets``). ``clip``: the lens's voxels are transparent; otherwise they are
    classified with ``alpha_table``, ``gradient_table`` (``(0,)``: no gradient opacity) and coloured
    by ``colour_table`` (256 rows, the lens table's RGB).
    """

    kind: int
    index_to_lens: np.ndarray
    radius: float
    normals: np.ndarray
    offsets: np.ndarray
    clip: bool
    alpha_table: np.ndarray
    gradient_table: np.ndarray
    colour_table: np.ndarray | None

    def kernel_arguments(self):
        """The kernels' lens arguments, in their order (``lens_kind`` … ``lens_gtab``)."""
        return (self.kind, self.index_to_lens, self.radius, self.normals, self.offsets, self.clip, self.alpha_table,
                self.gradient_table)

    def colour_table_beside(self, outside):
        """The colour table beside ``outside``'s: its 256 rows, then the lens's (a ``clip`` lens: ``outside``)."""
        if self.colour_table is None:
            return outside
        return np.ascontiguousarray(np.concatenate([outside, self.colour_table]))


NO_LENS_ARGUMENTS = (NO_LENS, np.zeros((3, 4)), 0.0, np.zeros((0, 3)), np.zeros(0), False, np.zeros(2), np.zeros(0))
"""The kernels' lens arguments when there is no lens (the same types, never read)."""


def lens_classification(lens, transform, spacing, outside):
    """The :class:`LensClassification` of ``lens`` over a volume placed by ``transform`` with ``spacing``.

    Parameters
    ----------
    lens : core.lens.Lens
        A ``clip`` or ``dvr`` lens (the renderer refuses ``mip`` and ``iso`` first).
    transform : numpy.ndarray
        The instance's 4×4 object→world transform.
    spacing : tuple of float
        ``(sx, sy, sz)``: voxel ``(i, j, k)``'s centre is ``((i + ½)·sx, (j + ½)·sy, (k + ½)·sz)`` in
        object space.
    outside : core.transfer.TransferFunction
        The volume's own table (a ``dvr`` appearance's table may derive from it, see
        :meth:`core.lens.LensAppearance.classification`).
    """
    sx, sy, sz = spacing
    index_to_object = np.array([[sx, 0, 0, 0.5 * sx], [0, sy, 0, 0.5 * sy], [0, 0, sz, 0.5 * sz], [0, 0, 0, 1.0]])
    index_to_lens = np.linalg.inv(lens.object_to_world()) @ np.asarray(transform, dtype=np.float64) @ index_to_object
    normals, offsets = lens.half_spaces()
    appearance = lens.appearance
    tf = appearance.classification(outside)
    clip = tf is None
    return LensClassification(
        kind=LENS_SPHERE if lens.shape == "sphere" else LENS_PLANES,
        index_to_lens=np.ascontiguousarray(index_to_lens[:3]),
        radius=float(lens.radius or 0.0),
        normals=np.ascontiguousarray(normals, dtype=np.float64),
        offsets=np.ascontiguousarray(offsets, dtype=np.float64),
        clip=clip,
        alpha_table=np.zeros(2) if clip else np.ascontiguousarray(tf.table[:, 3], dtype=np.float64),
        gradient_table=(np.zeros(0) if clip or appearance.gradient_opacity is None
                        else np.ascontiguousarray(appearance.gradient_opacity.table, dtype=np.float64)),
        colour_table=None if clip else np.ascontiguousarray(tf.lookup(np.arange(256) / 255.0)[:, :3]),
    )


@dataclass(frozen=True, eq=False)
class Classified:
    """A classified volume, ``[z, y, x]``: records (0 = transparent) and optional gradients."""

    records: np.ndarray
    gradients: np.ndarray | None
    colour_table: np.ndarray
    nontransparent: int


def classify(scalars, spacing, transfer_function, gradient_opacity, reference_step, min_opacity, *, gradients=False,
             lens=None):
    """Classify normalised float32 ``scalars`` (``[z, y, x]``) into 4-byte voxel records.

    Parameters
    ----------
    scalars : numpy.ndarray
        Normalised scalars in [0, 1], float32, ``(nz, ny, nx)``.
    spacing : tuple of float
        ``(sx, sy, sz)``.
    transfer_function : core.transfer.TransferFunction
    gradient_opacity : core.transfer.GradientOpacity or None
    reference_step : float
        ``Δ0`` (object units) for the gradient-opacity argument.
    min_opacity : float
        Voxels with ``α <= min_opacity`` are transparent (record 0).
    gradients : bool
        Also keep each voxel's object-space gradient (float32, zero where transparent).
    lens : LensClassification, optional
        Classify the voxels inside it with its appearance (module notes); the colour table then
        has 512 rows for a ``dvr`` lens.

    Returns
    -------
    Classified
    """
    scalars = np.ascontiguousarray(scalars, dtype=np.float32)
    records = np.empty(scalars.shape, dtype=np.uint32)
    grads = np.empty(scalars.shape + (3,) if gradients else (1, 1, 1, 3), dtype=np.float32)
    alpha_table = np.ascontiguousarray(transfer_function.table[:, 3], dtype=np.float64)
    gtab = (np.zeros(0) if gradient_opacity is None
            else np.ascontiguousarray(gradient_opacity.table, dtype=np.float64))
    counts = np.zeros(scalars.shape[0], dtype=np.int64)
    lens_arguments = NO_LENS_ARGUMENTS if lens is None else lens.kernel_arguments()
    _classify_kernel(scalars, np.asarray(spacing, dtype=np.float64), alpha_table, gtab, float(reference_step),
                     float(min_opacity), bool(gradients), *lens_arguments, records, grads, counts)
    colour_table = np.ascontiguousarray(transfer_function.lookup(np.arange(256) / 255.0)[:, :3])
    if lens is not None:
        colour_table = lens.colour_table_beside(colour_table)
    return Classified(records, grads if gradients else None, colour_table, int(counts.sum()))


# ---------------------------------------------------------------------------------------------
# Run-length encoding


@dataclass(frozen=True, eq=False)
class Encoding:
    """One principal axis's classified volume in standard object order (see the module notes)."""

    axis: int
    shape_ijk: tuple
    lengths: np.ndarray
    run_offsets: np.ndarray
    data_offsets: np.ndarray
    voxels: np.ndarray
    gradients: np.ndarray  # (n, 3) float32 aligned with voxels, or (0, 3)
    encoded: bool
    run_index: np.ndarray = None  # (scanlines, checkpoints, 3): see run_index(); built when None
    extents: np.ndarray = None  # (scanlines, 2): see scanline_extents(); built when None

    def __post_init__(self):
        if self.run_index is None:
            object.__setattr__(self, "run_index", run_index(self.lengths, self.run_offsets, self.data_offsets,
                                                            self.shape_ijk[0]))
        if self.extents is None:
            object.__setattr__(self, "extents", scanline_extents(self.lengths, self.run_offsets, self.shape_ijk[0]))

    @property
    def nbytes(self):
        """Bytes of the encoding: run lengths, voxel records, per-scanline offsets, run index and extents
        (gradients apart)."""
        return int(self.lengths.nbytes + self.voxels.nbytes + self.run_offsets.nbytes + self.data_offsets.nbytes
                   + self.run_index.nbytes + self.extents.nbytes)

    @property
    def runs(self):
        return int(self.lengths.size)


INDEX_SHIFT = 5
INDEX_STEP = 1 << INDEX_SHIFT
"""Voxels between two checkpoints of the run index (a power of two: the kernels shift by :data:`INDEX_SHIFT`)."""


@njit(parallel=True, **_JIT)
def _run_index_kernel(lengths, run_offsets, data_offsets, out):
    scanlines, checkpoints = out.shape[0], out.shape[1]
    for sl in prange(scanlines):
        first = run_offsets[sl]
        run = first
        start = 0
        end = np.int64(lengths[run])
        data = 0
        for c in range(checkpoints):
            position = c * INDEX_STEP
            while position >= end:  # the cursors' walk: zero-length runs are passed, as in the kernels
                if (run - first) & 1:
                    data += end - start
                start = end
                run += 1
                end = start + lengths[run]
            out[sl, c, 0] = run - first
            out[sl, c, 1] = start
            out[sl, c, 2] = data


def run_index(lengths, run_offsets, data_offsets, ni):
    """Where a scanline cursor stands at every :data:`INDEX_STEP`-th voxel: ``(scanlines, checkpoints, 3)``.

    uint16 entries (int32 for scanlines of 32767 voxels or more).

    Checkpoint ``c`` of a scanline holds the run that contains voxel ``c·INDEX_STEP`` (its index among
    the scanline's runs, odd for a non-transparent run), the voxel where that run starts and the
    scanline's records before it: the state a cursor reaches by walking the runs from the start.
    Compositing jumps there when early termination skips a stretch of opaque pixels, instead of
    walking every run under them (VolPack's optional per-voxel index, ``INDEX_VOLUME``, at one entry
    per :data:`INDEX_STEP` voxels).
    """
    checkpoints = max(-(-int(ni) // INDEX_STEP), 1)
    # A scanline has at most 2·ni + 2 runs: 16 bits hold every entry below 32767 voxels a scanline.
    dtype = np.uint16 if 2 * int(ni) + 2 <= np.iinfo(np.uint16).max else np.int32
    out = np.empty((run_offsets.size - 1, checkpoints, 3), dtype=dtype)
    if out.size:
        _run_index_kernel(lengths, run_offsets, data_offsets, out)
    return out


@njit(parallel=True, **_JIT)
def _extents_kernel(lengths, run_offsets, ni, out):
    for sl in prange(out.shape[0]):
        first = ni
        end = 0
        position = 0
        for run in range(run_offsets[sl], run_offsets[sl + 1]):
            length = np.int64(lengths[run])
            if (run - run_offsets[sl]) & 1 and length > 0:
                first = min(first, position)
                end = position + length
            position += length
        out[sl, 0] = first
        out[sl, 1] = end


def scanline_extents(lengths, run_offsets, ni):
    """``(scanlines, 2)`` int32: each scanline's first non-transparent voxel and the voxel after its last.

    ``(ni, 0)`` for a scanline without one. Compositing a row starts at the first of its two scanlines'
    first voxels and stops one past their last (the bilinear footprint's reach): every position
    outside resamples to zero.
    """
    out = np.empty((run_offsets.size - 1, 2), dtype=np.int32)
    if out.size:
        _extents_kernel(lengths, run_offsets, int(ni), out)
    return out


@njit(**_JIT)
def _scanline_runs(line, out, pos, write):
    """Emit one scanline's alternating run lengths (transparent first); return the entries used."""
    n = line.shape[0]
    i = 0
    used = 0
    kind = False  # False: transparent run; True: non-transparent
    while True:
        length = 0
        while i + length < n and (line[i + length] != 0) == kind:
            length += 1
        i += length
        while length > 255:
            if write:
                out[pos + used] = 255
                out[pos + used + 1] = 0
            used += 2
            length -= 255
        if write:
            out[pos + used] = length
        used += 1
        kind = not kind
        if i >= n:
            if kind:  # ended on a transparent run: close the pair with an empty non-transparent run
                if write:
                    out[pos + used] = 0
                used += 1
            return used


@njit(parallel=True, **_JIT)
def _count_runs(dense, run_counts, voxel_counts):
    nk, nj, ni = dense.shape
    dummy = np.zeros(1, dtype=np.uint8)
    for k in prange(nk):
        for j in range(nj):
            line = dense[k, j]
            run_counts[k * nj + j] = _scanline_runs(line, dummy, 0, False)
            c = 0
            for i in range(ni):
                if line[i] != 0:
                    c += 1
            voxel_counts[k * nj + j] = c


@njit(parallel=True, **_JIT)
def _fill_runs(dense, dense_gradients, want_gradients, run_offsets, data_offsets, lengths, voxels, gradients):
    nk, nj, ni = dense.shape
    for k in prange(nk):
        for j in range(nj):
            line = dense[k, j]
            sl = k * nj + j
            _scanline_runs(line, lengths, run_offsets[sl], True)
            d = data_offsets[sl]
            for i in range(ni):
                if line[i] != 0:
                    voxels[d] = line[i]
                    if want_gradients:
                        gradients[d, 0] = dense_gradients[k, j, i, 0]
                        gradients[d, 1] = dense_gradients[k, j, i, 1]
                        gradients[d, 2] = dense_gradients[k, j, i, 2]
                    d += 1


def standard_order(array, axis):
    """View of a ``[z, y, x]``-indexed array in standard object order ``[k, j, i]`` for ``axis``."""
    from renderers.shearwarp.factor import axes_ijk

    i_ax, j_ax, k_ax = axes_ijk(axis)
    order = (2 - k_ax, 2 - j_ax, 2 - i_ax)
    return array.transpose(order + tuple(range(3, array.ndim)))


def encode(classified, axis):
    """Run-length encode ``classified`` for principal ``axis`` (transparent voxels dropped)."""
    dense = np.ascontiguousarray(standard_order(classified.records, axis))
    want = classified.gradients is not None
    dense_gradients = (np.ascontiguousarray(standard_order(classified.gradients, axis)) if want
                       else np.zeros((1, 1, 1, 3), np.float32))
    nk, nj, ni = dense.shape
    run_counts = np.empty(nk * nj, dtype=np.int64)
    voxel_counts = np.empty(nk * nj, dtype=np.int64)
    _count_runs(dense, run_counts, voxel_counts)
    run_offsets = np.zeros(nk * nj + 1, dtype=np.int64)
    np.cumsum(run_counts, out=run_offsets[1:])
    data_offsets = np.zeros(nk * nj + 1, dtype=np.int64)
    np.cumsum(voxel_counts, out=data_offsets[1:])
    lengths = np.empty(run_offsets[-1], dtype=np.uint8)
    voxels = np.empty(data_offsets[-1], dtype=np.uint32)
    gradients = np.empty((data_offsets[-1] if want else 0, 3), dtype=np.float32)
    _fill_runs(dense, dense_gradients, want, run_offsets, data_offsets, lengths, voxels, gradients)
    return Encoding(axis, (ni, nj, nk), lengths, run_offsets, data_offsets, voxels, gradients, True)


def dense_encoding(classified, axis):
    """The unencoded classified volume for ``axis`` in the same format (brute force: every voxel stored)."""
    dense = np.ascontiguousarray(standard_order(classified.records, axis))
    nk, nj, ni = dense.shape
    pattern = []
    left = ni
    while True:
        chunk = min(left, 255)
        pattern += [0, chunk]
        left -= chunk
        if left == 0:
            break
    per_line = np.array(pattern, dtype=np.uint8)
    lengths = np.tile(per_line, nk * nj)
    run_offsets = np.arange(nk * nj + 1, dtype=np.int64) * per_line.size
    data_offsets = np.arange(nk * nj + 1, dtype=np.int64) * ni
    if classified.gradients is not None:
        gradients = np.ascontiguousarray(standard_order(classified.gradients, axis)).reshape(-1, 3)
    else:
        gradients = np.zeros((0, 3), dtype=np.float32)
    return Encoding(axis, (ni, nj, nk), lengths, run_offsets, data_offsets, dense.ravel(), gradients, False)


def decode(encoding):
    """The dense ``[k, j, i]`` records of an encoding (transparent voxels 0): the inverse of :func:`encode`."""
    ni, nj, nk = encoding.shape_ijk
    out = np.zeros((nk, nj, ni), dtype=np.uint32)
    lengths = encoding.lengths
    for sl in range(nk * nj):
        k, j = divmod(sl, nj)
        pos = int(encoding.data_offsets[sl])
        i = 0
        nontransparent = False
        for entry in range(int(encoding.run_offsets[sl]), int(encoding.run_offsets[sl + 1])):
            n = int(lengths[entry])
            if nontransparent:
                out[k, j, i:i + n] = encoding.voxels[pos:pos + n]
                pos += n
            i += n
            nontransparent = not nontransparent
        if i != ni or nontransparent or pos != encoding.data_offsets[sl + 1]:
            raise ValueError(f"corrupt encoding at slice {k}, scanline {j}: runs cover {i} of {ni} voxels")
    return out
