"""Fast classification: min-max octree + summed-area table (Lacroute 1995, §4.3, §4.4, Fig. 4.17).

Rendering a volume whose transfer function is being edited without re-encoding it: the
classification-independent *min-max octree* bounds, per block of voxels, the two classification
parameters (scalar ``s`` and gradient magnitude ``|∇s|``); a *summed-area table* (SAT) over the
parameter domain, rebuilt on each transfer-function edit, says in O(1) whether any parameter pair
in a node's box can be non-transparent. Scanlines are then cut into runs of possibly
non-transparent voxels (``ComputeVoxelRuns``) and only those voxels are classified.

Parameters and bins
-------------------
Both parameters are quantised to ``bins`` bins (256 by default, the thesis's 8-bit domain):

* scalar bin ``b = ⌊s·bins⌋`` (clamped to ``bins − 1``) covers ``[b/bins, (b+1)/bins]``; for 8-bit
  data and 256 bins each bin holds exactly one value (``v/255`` falls in bin ``v``);
* gradient bin ``⌊m·bins/m_max⌋`` of the magnitude ``m = |∇s|`` (the central differences of
  :mod:`.classify`, spacing included, evaluated exactly as the classification kernel does), with
  ``m_max`` the volume's largest magnitude.

Min-max octree (:func:`build_octree`, once per volume)
------------------------------------------------------
A full pyramid is built bottom-up: base nodes of ``base_size³`` voxels (4 in the thesis) hold the
min and max bin of both parameters over their voxels (clipped at the volume's faces); each parent
combines its (up to) 8 children, until one root covers the volume (``root_size = base_size·2^L ≥``
every dimension). The pyramid is then laid out as a pointer tree, breadth first, with the 8
children of a node contiguous (``child[n]`` = the first, −1 for a leaf; child ``c`` has offset
``c = dx | dy << 1 | dz << 2``); the children of a node whose parameter ranges are both within
``threshold`` (``max − min ≤ threshold``, 4 in the thesis) are pruned. Children that lie wholly
outside a non-cubic volume are *empty* nodes (``min > max``), always transparent.
:attr:`MinMaxOctree.nbytes` counts the node arrays (4 bytes of min/max bins per node with
``bins ≤ 256`` and a 4-byte child pointer); the float32 scalars it also keeps are the volume.
Beside it the build keeps the thesis's *unclassified voxel array* (:data:`VOXEL`, one 16-byte entry
per voxel: scalar, normal code, gradient magnitude and the two parameters' 8-bit bins,
:attr:`MinMaxOctree.voxel_bytes`), from which the compositing loop classifies the voxels it reaches.
The thesis stores one byte of scalar and one of gradient magnitude (4 bytes a voxel) and classifies
by looking both up; here the parameters keep the classification's float precision, so that a lazily
classified voxel gets the classified RLE's record bit for bit, and the bins (on a 256-bin grid,
:data:`VOXEL_BINS`) serve a one-lookup test first: each classification keeps the SAT's indicator on
that grid (:attr:`OctreeClassification.voxel_visible`), and a voxel whose bin pair it marks 0 is
transparent without interpolating a table (on a 256³ CT head this cut the octree mode's compositing
from 24–26 to 20–22 ms). Its rows and planes are
padded to an odd number of cache lines (:func:`padded_shape`): scanlines along ``y`` or ``z`` read
it a row or a plane apart.

Summed-area table (:func:`classify_octree`, once per classification)
--------------------------------------------------------------------
For each scalar bin the maximum of the transfer function's opacity over the bin's interval, and
for each gradient bin the maximum of the gradient-opacity factor ``g(u)``,
``u = m·Δ0/(√3/2)``, over its interval (``g = 1`` without a table): both tables are interpolated
linearly between entries (the classification rule), so each maximum is attained at an interval
end or at an entry inside it, and those are evaluated with the classification kernel's own
arithmetic. The indicator is ``f_T(p, q) = 1`` when ``max_α(p)·max_g(q)`` exceeds
``min_opacity`` (with a relative margin of 1e-9 against rounding, and never where the bound is
exactly 0), and the SAT is its 2-D prefix sum. A node is ``TRANSPARENT`` when the SAT integral
over its box is 0 (or the node is empty), else ``NONTRANSPARENT`` if it is a leaf, else
``SUBDIVIDE``. The verdict is conservative: a transparent node holds no voxel with
``α > min_opacity`` (tested against brute-force classification).

With a lens (:class:`renderers.shearwarp.classify.LensClassification`) a voxel may be classified
by either table, so a node is transparent only where the volume's table and a ``dvr`` lens's
table both say so (a ``clip`` lens only removes voxels: the volume's verdict stays conservative);
the SAT kept is the volume's. The on-the-fly classification then tests each candidate voxel
against the lens as :func:`renderers.shearwarp.classify.classify` does, so the exact encodings
stay byte-identical to the brute-force build with the lens.

Voxel runs and encodings (:func:`encode`)
-----------------------------------------
For principal axis ``axis`` the scanlines run along ``i`` in standard object order ``[k, j, i]``.
All scanlines of a ``base_size × base_size`` block of ``(j, k)`` cross the same nodes, so the
candidate runs are computed once per block (the thesis's reuse over ``n_min`` scanlines) by a
depth-first walk that visits, at each SUBDIVIDE node, the two children the scanline crosses.
The voxels of candidate runs are classified on the fly with the arithmetic of
:func:`renderers.shearwarp.classify.classify` (same records, same float32 gradients), every
other voxel is transparent. Then:

* ``exact=True`` (the mode switch, §4.4): the classified candidates are run-length encoded per
  scanline with :mod:`.classify`'s own run writer, so the result is byte-identical to
  ``classify.encode(classify.classify(...), axis)``, built without classifying or scanning the
  voxels of transparent nodes;
* :func:`voxel_runs` (rendering unclassified volumes, Fig. 4.17, what ``classification="octree"``
  does every frame): the candidate runs alone, their voxels classified later by the compositing loop
  as it reaches them;
* ``exact=False`` (the same with every candidate classified first: a perspective view, a lens or
  procedural shading): the candidate runs *are* the non-transparent runs, transparent voxels inside
  them stored as zero records.

Either way the compositing kernels resample a transparent candidate to exact zeros, so the image is
bit-identical to the classified RLE's; only the sample count grows (the thesis's "conservative runs
produce more samples").

The octree is stored once in ``[z, y, x]`` order (no transposes, as in the thesis): for
``axis ≠ z`` the on-the-fly classification reads the scalars against the storage stride.
"""

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from core.errors import InputError
from core.transfer import MAX_GRADIENT
from core.validation import check_positive_int
from renderers.base.numba_kernels import JIT as _JIT, table_position
from renderers.shearwarp.classify import (NO_LENS_ARGUMENTS, Encoding, _scanline_runs, central_gradient,
                                          classify_lens_voxel, encode_normal)


TRANSPARENT, NONTRANSPARENT, SUBDIVIDE = 0, 1, 2
MARGIN = 1e-9
"""Relative margin of the SAT's opacity bound against floating-point rounding (conservative)."""


# ---------------------------------------------------------------------------------------------
# Octree build


VOXEL = np.dtype([("scalar", np.float32), ("normal", np.uint16), ("scalar_bin", np.uint8), ("gradient_bin", np.uint8),
                  ("magnitude", np.float64)], align=True)
"""One voxel of the unclassified voxel array (16 bytes): its scalar, 13-bit normal code, the bins of its
two parameters on a :data:`VOXEL_BINS` grid and its gradient magnitude, the normal and the magnitude
computed exactly as :func:`renderers.shearwarp.classify.classify_voxel` computes them (so classifying
these parameters gives that function's record, bit for bit)."""

VOXEL_BINS = 256
"""Bins per parameter of the voxel array's ``scalar_bin`` and ``gradient_bin`` (8 bits each, the thesis's
domain), whatever the octree's own ``bins``."""


def padded_shape(shape_zyx):
    """``(nz, ny', nx')`` of the voxel array: rows and planes an odd number of 64-byte lines apart.

    A scanline along ``y`` or ``z`` reads one voxel a row or a plane apart; at a power-of-two distance
    every such voxel falls in the same cache set and evicts the last, so each read would go to memory.
    """
    nz, ny, nx = shape_zyx
    per_line = 64 // VOXEL.itemsize
    nx_padded = nx + (per_line - nx % (2 * per_line)) % (2 * per_line)  # nx' / per_line odd
    ny_padded = ny + (1 - ny % 2)  # odd: the plane holds an odd number of lines too
    return nz, ny_padded, nx_padded


@njit(parallel=True, **_JIT)
def _voxel_parameters(s, spacing, voxels):
    """Scalar, gradient magnitude and normal code of every voxel (the classification's central differences)."""
    nz, ny, nx = s.shape
    sx, sy, sz = spacing[0], spacing[1], spacing[2]
    for z in prange(nz):
        for y in range(ny):
            for x in range(nx):
                gx, gy, gz = central_gradient(s, z, y, x, sx, sy, sz)
                voxel = voxels[z, y, x]
                voxel.scalar = s[z, y, x]
                voxel.magnitude = math.sqrt(gx * gx + gy * gy + gz * gz)
                voxel.normal = encode_normal(gx, gy, gz)


@njit(parallel=True, **_JIT)
def _voxel_bins(voxels, nz, ny, nx, gscale):
    """Each voxel's scalar and gradient bin on the :data:`VOXEL_BINS` grid (the octree's binning rule)."""
    for z in prange(nz):
        for y in range(ny):
            for x in range(nx):
                voxel = voxels[z, y, x]
                p = int(math.floor(np.float64(voxel.scalar) * VOXEL_BINS))
                voxel.scalar_bin = min(max(p, 0), VOXEL_BINS - 1)
                q = int(math.floor(voxel.magnitude * gscale))
                voxel.gradient_bin = min(max(q, 0), VOXEL_BINS - 1)


@njit(parallel=True, **_JIT)
def _base_level(s, mag, bins, gscale, base, dims, smin, smax, gmin, gmax):
    """Min/max parameter bins of every base node (``dims`` = nodes per axis, x, y, z)."""
    nz, ny, nx = s.shape
    bx, by, bz = dims[0], dims[1], dims[2]
    for c in prange(bz):
        for b in range(by):
            for a in range(bx):
                lo_s = bins
                hi_s = -1
                lo_g = bins
                hi_g = -1
                for z in range(c * base, min((c + 1) * base, nz)):
                    for y in range(b * base, min((b + 1) * base, ny)):
                        for x in range(a * base, min((a + 1) * base, nx)):
                            p = int(math.floor(np.float64(s[z, y, x]) * bins))
                            p = min(max(p, 0), bins - 1)
                            q = int(math.floor(mag[z, y, x] * gscale))
                            q = min(max(q, 0), bins - 1)
                            lo_s = min(lo_s, p)
                            hi_s = max(hi_s, p)
                            lo_g = min(lo_g, q)
                            hi_g = max(hi_g, q)
                n = (c * by + b) * bx + a
                smin[n] = lo_s
                smax[n] = hi_s
                gmin[n] = lo_g
                gmax[n] = hi_g


@njit(**_JIT)
def _parent_level(dims_child, off_child, dims, off, smin, smax, gmin, gmax):
    for c in range(dims[2]):
        for b in range(dims[1]):
            for a in range(dims[0]):
                lo_s = smin[off_child]  # overwritten below; keeps the types
                hi_s = smax[off_child]
                lo_g = gmin[off_child]
                hi_g = gmax[off_child]
                first = True
                for dz in range(2):
                    cz = 2 * c + dz
                    if cz >= dims_child[2]:
                        continue
                    for dy in range(2):
                        cy = 2 * b + dy
                        if cy >= dims_child[1]:
                            continue
                        for dx in range(2):
                            cx = 2 * a + dx
                            if cx >= dims_child[0]:
                                continue
                            m = off_child + (cz * dims_child[1] + cy) * dims_child[0] + cx
                            if first:
                                lo_s, hi_s, lo_g, hi_g = smin[m], smax[m], gmin[m], gmax[m]
                                first = False
                            else:
                                lo_s = min(lo_s, smin[m])
                                hi_s = max(hi_s, smax[m])
                                lo_g = min(lo_g, gmin[m])
                                hi_g = max(hi_g, gmax[m])
                n = off + (c * dims[1] + b) * dims[0] + a
                smin[n] = lo_s
                smax[n] = hi_s
                gmin[n] = lo_g
                gmax[n] = hi_g


@njit(**_JIT)
def _prune(levels, offsets, dims, smin, smax, gmin, gmax, threshold, empty, out_smin, out_smax, out_gmin, out_gmax,
           out_child):
    """Lay the pyramid out as a breadth-first pointer tree, pruning uniform nodes' children."""
    capacity = out_child.shape[0]
    q_level = np.empty(capacity, np.int64)
    q_a = np.empty(capacity, np.int64)
    q_b = np.empty(capacity, np.int64)
    q_c = np.empty(capacity, np.int64)
    top = levels - 1
    r = offsets[top]
    out_smin[0], out_smax[0], out_gmin[0], out_gmax[0] = smin[r], smax[r], gmin[r], gmax[r]
    q_level[0], q_a[0], q_b[0], q_c[0] = top, 0, 0, 0
    count = 1
    head = 0
    while head < count:
        level = q_level[head]
        out_child[head] = -1
        is_empty = out_smin[head] > out_smax[head]
        uniform = (out_smax[head] - out_smin[head] <= threshold) and (out_gmax[head] - out_gmin[head] <= threshold)
        if level > 0 and not is_empty and not uniform:
            out_child[head] = count
            cl = level - 1
            for child in range(8):
                dx = child & 1
                dy = (child >> 1) & 1
                dz = (child >> 2) & 1
                a = 2 * q_a[head] + dx
                b = 2 * q_b[head] + dy
                c = 2 * q_c[head] + dz
                n = count + child
                q_level[n], q_a[n], q_b[n], q_c[n] = cl, a, b, c
                if a < dims[cl, 0] and b < dims[cl, 1] and c < dims[cl, 2]:
                    m = offsets[cl] + (c * dims[cl, 1] + b) * dims[cl, 0] + a
                    out_smin[n], out_smax[n], out_gmin[n], out_gmax[n] = smin[m], smax[m], gmin[m], gmax[m]
                else:  # outside the volume: an empty node
                    q_level[n] = 0
                    out_smin[n], out_smax[n], out_gmin[n], out_gmax[n] = empty, 0, empty, 0
            count += 8
        head += 1
    return count


@dataclass(frozen=True, eq=False)
class MinMaxOctree:
    """A min-max octree over (scalar, gradient magnitude) bins of one volume (see the module notes)."""

    shape_zyx: tuple
    spacing: tuple
    base_size: int
    threshold: int
    bins: int
    levels: int
    root_size: int
    gradient_max: float
    scalars: np.ndarray  # float32 [z, y, x], normalised
    voxels: np.ndarray  # VOXEL [z, y', x'] (padded_shape): the unclassified voxel array of the fast classification
    smin: np.ndarray
    smax: np.ndarray
    gmin: np.ndarray
    gmax: np.ndarray
    child: np.ndarray  # int32, first child or -1

    @property
    def nodes(self):
        return int(self.child.size)

    @property
    def nbytes(self):
        """Bytes of the node arrays (min/max bins and child pointers; not the scalars)."""
        return int(self.smin.nbytes + self.smax.nbytes + self.gmin.nbytes + self.gmax.nbytes + self.child.nbytes)

    @property
    def voxel_bytes(self):
        """Bytes of the unclassified voxel array (16 per voxel, padding included)."""
        return int(self.voxels.nbytes)

    def gradient_bin_edges(self):
        """``(lo, hi)`` float64 magnitude interval of each gradient bin."""
        return _gradient_bin_edges(self.gradient_max, self.bins)


def _gradient_bin_edges(gradient_max, bins):
    width = gradient_max / bins if gradient_max > 0 else 0.0
    b = np.arange(bins, dtype=np.float64)
    return b * width, (b + 1) * width


def build_octree(scalars, spacing, *, base_size=4, threshold=4, bins=256):
    """Build the min-max octree of normalised ``scalars`` (``[z, y, x]``, values in [0, 1]).

    Parameters
    ----------
    scalars : numpy.ndarray
        ``(nz, ny, nx)`` normalised scalars (converted to float32 as the classification does).
    spacing : tuple of float
        ``(sx, sy, sz)`` for the gradient magnitudes.
    base_size : int
        Voxels per side of a base (smallest) node (thesis: 4).
    threshold : int
        A node whose parameter ranges (in bins) are both at most this keeps no children (thesis: 4).
    bins : int
        Bins per parameter (2..65536; thesis: 256).

    Returns
    -------
    MinMaxOctree
    """
    base_size = check_positive_int(base_size, name="octree base_size")
    bins = check_positive_int(bins, name="octree bins", minimum=2)
    if bins > 65536:
        raise InputError(f"octree bins: at most 65536 bins per parameter, got {bins}")
    if isinstance(threshold, bool) or not isinstance(threshold, (int, np.integer)) or threshold < 0:
        raise InputError(f"octree threshold: expected an integer >= 0 (bins), got {threshold!r}")
    s = np.ascontiguousarray(scalars, dtype=np.float32)
    if s.ndim != 3 or min(s.shape) < 1:
        raise InputError(f"octree scalars: expected a non-empty 3-D array, got shape {s.shape}")
    spacing_arr = np.asarray(spacing, dtype=np.float64)
    voxels = np.zeros(padded_shape(s.shape), dtype=VOXEL)
    _voxel_parameters(s, spacing_arr, voxels)
    mag = voxels["magnitude"][:, :s.shape[1], :s.shape[2]]
    gradient_max = float(mag.max())
    gscale = bins / gradient_max if gradient_max > 0 else 0.0
    _voxel_bins(voxels, *s.shape, VOXEL_BINS / gradient_max if gradient_max > 0 else 0.0)

    nz, ny, nx = s.shape
    dims = [(-(-nx // base_size), -(-ny // base_size), -(-nz // base_size))]
    while max(dims[-1]) > 1:
        dims.append(tuple(-(-d // 2) for d in dims[-1]))
    levels = len(dims)
    dims_arr = np.array(dims, dtype=np.int64)
    offsets = np.zeros(levels + 1, dtype=np.int64)
    np.cumsum([a * b * c for a, b, c in dims], out=offsets[1:])
    total = int(offsets[-1])
    dtype = np.uint8 if bins <= 256 else np.uint16
    work = [np.empty(total, dtype=np.int32) for _ in range(4)]
    _base_level(s, mag, bins, gscale, base_size, dims_arr[0], *work)
    for level in range(1, levels):
        _parent_level(dims_arr[level - 1], offsets[level - 1], dims_arr[level], offsets[level], *work)
    capacity = 1 + 8 * int(offsets[-1] - offsets[1])
    out = [np.empty(capacity, dtype=np.int32) for _ in range(4)]
    child = np.empty(capacity, dtype=np.int32)
    count = _prune(levels, offsets, dims_arr, *work, int(threshold), bins - 1, *out, child)
    smin, smax, gmin, gmax = (np.ascontiguousarray(a[:count]).astype(dtype) for a in out)
    # Empty nodes were written as (bins − 1, 0): min > max survives the narrowing cast (bins >= 2).
    return MinMaxOctree((nz, ny, nx), tuple(float(v) for v in spacing_arr), base_size, int(threshold), bins, levels,
                        base_size << (levels - 1), gradient_max, s, voxels, smin, smax, gmin, gmax,
                        np.ascontiguousarray(child[:count]))


# ---------------------------------------------------------------------------------------------
# Summed-area table and node classification


@njit(**_JIT)
def _interval_maxima(table, lo, hi, out):
    """Maximum of the linearly interpolated ``table`` over each ``[lo[b], hi[b]]`` (classification rule)."""
    size = table.shape[0]
    for b in range(lo.shape[0]):
        i0, w = table_position(lo[b], size)
        best = table[i0] * (1.0 - w) + table[i0 + 1] * w
        i0, w = table_position(hi[b], size)
        best = max(best, table[i0] * (1.0 - w) + table[i0 + 1] * w)
        first = max(int(math.floor(lo[b] * (size - 1))), 0)
        last = min(int(math.ceil(hi[b] * (size - 1))), size - 1)
        for i in range(first, last + 1):
            x = i / (size - 1)
            if lo[b] <= x <= hi[b]:
                best = max(best, table[i])
        out[b] = best


@dataclass(frozen=True, eq=False)
class OctreeClassification:
    """One classification of an octree: the SAT, node statuses and the per-voxel tables."""

    sat: np.ndarray  # int32 (bins + 1, bins + 1), row/column 0 zero; the volume's table's with a lens
    status: np.ndarray  # uint8 per node
    alpha_table: np.ndarray
    gradient_table: np.ndarray  # (0,) without gradient opacity
    reference_step: float
    min_opacity: float
    colour_table: np.ndarray
    voxel_visible: np.ndarray  # uint8 (VOXEL_BINS, VOXEL_BINS): 0 where no voxel of the bin pair is visible
    lens: object = None  # classify.LensClassification or None

    def box_sum(self, s_lo, s_hi, g_lo, g_hi):
        """SAT integral of the indicator over bins ``[s_lo, s_hi] × [g_lo, g_hi]`` (arrays allowed)."""
        sat = self.sat
        return (sat[s_hi + 1, g_hi + 1] - sat[s_lo, g_hi + 1] - sat[s_hi + 1, g_lo] + sat[s_lo, g_lo])


def _indicator(bins, gradient_max, alpha_table, gtab, reference_step, min_opacity):
    """``(bins, bins)`` bool: whether a voxel of scalar bin ``p`` and gradient bin ``q`` may be visible (module notes)."""
    b = np.arange(bins, dtype=np.float64)
    pad = 1e-12
    s_max = np.empty(bins)
    _interval_maxima(alpha_table, b / bins - pad, (b + 1) / bins + pad, s_max)
    if gtab.size:
        m_lo, m_hi = _gradient_bin_edges(gradient_max, bins)
        m_lo = np.maximum(m_lo * (1 - MARGIN), 0.0)
        m_hi = m_hi * (1 + MARGIN)
        if gradient_max == 0:
            m_lo[:] = 0.0
            m_hi[:] = 0.0
        step = float(reference_step)
        g_max = np.empty(bins)
        _interval_maxima(gtab, m_lo * step / MAX_GRADIENT, m_hi * step / MAX_GRADIENT, g_max)
    else:
        g_max = np.ones(bins)
    bound = s_max[:, None] * g_max[None, :]
    return (bound > 0) & (bound * (1 + MARGIN) > min_opacity)


def _verdicts(octree, alpha_table, gtab, reference_step, min_opacity):
    """The SAT of one opacity / gradient-opacity table pair and every node's status (module notes)."""
    bins = octree.bins
    indicator = _indicator(bins, octree.gradient_max, alpha_table, gtab, reference_step, min_opacity)
    sat = np.zeros((bins + 1, bins + 1), dtype=np.int32)
    sat[1:, 1:] = indicator.astype(np.int32).cumsum(axis=0).cumsum(axis=1)
    smin = octree.smin.astype(np.int64)
    smax = octree.smax.astype(np.int64)
    gmin = octree.gmin.astype(np.int64)
    gmax = octree.gmax.astype(np.int64)
    empty = smin > smax
    lo_s, hi_s = np.where(empty, 0, smin), np.where(empty, 0, smax)
    lo_g, hi_g = np.where(empty, 0, gmin), np.where(empty, 0, gmax)
    total = sat[hi_s + 1, hi_g + 1] - sat[lo_s, hi_g + 1] - sat[hi_s + 1, lo_g] + sat[lo_s, lo_g]
    status = np.where(empty | (total == 0), TRANSPARENT,
                      np.where(octree.child < 0, NONTRANSPARENT, SUBDIVIDE)).astype(np.uint8)
    return sat, status


def classify_octree(octree, transfer_function, gradient_opacity, reference_step, min_opacity, *, lens=None):
    """Summed-area table of the classification and the status of every octree node (Fig. 4.17).

    ``lens`` (a :class:`renderers.shearwarp.classify.LensClassification`): a node is transparent
    only where a ``dvr`` lens's table also makes it so (module notes).
    """
    alpha_table = np.ascontiguousarray(transfer_function.table[:, 3], dtype=np.float64)
    gtab = (np.zeros(0) if gradient_opacity is None
            else np.ascontiguousarray(gradient_opacity.table, dtype=np.float64))
    sat, status = _verdicts(octree, alpha_table, gtab, reference_step, min_opacity)
    # The fast classification's per-voxel test, the SAT's indicator on the voxel array's bins (the volume's table).
    visible = _indicator(VOXEL_BINS, octree.gradient_max, alpha_table, gtab, reference_step, min_opacity)
    colour_table = np.ascontiguousarray(transfer_function.lookup(np.arange(256) / 255.0)[:, :3])
    if lens is not None:
        if not lens.clip:
            # A node's non-transparent verdicts agree (leaf or not), so the union is the larger status.
            _, inside = _verdicts(octree, lens.alpha_table, lens.gradient_table, reference_step, min_opacity)
            status = np.maximum(status, inside)
        colour_table = lens.colour_table_beside(colour_table)
    return OctreeClassification(sat, status, alpha_table, gtab, float(reference_step), float(min_opacity),
                                colour_table, np.ascontiguousarray(visible, dtype=np.uint8), lens)


# ---------------------------------------------------------------------------------------------
# ComputeVoxelRuns and on-the-fly classification


@njit(**_JIT)
def _block_runs(status, child, root_size, ni, jc, kc, bit_i, bit_j, bit_k, stack, out):
    """Candidate (possibly non-transparent) runs of the scanlines through ``(j, k) = (jc, kc)``.

    Writes ``[start, end)`` pairs to ``out`` in increasing order, merged and clipped to ``[0, ni)``;
    returns their number. ``stack``: ``(5, 2·levels + 2)`` int64 scratch for the walk (the caller's, so
    that a block costs no allocation).
    """
    st_node, st_oi, st_oj, st_ok, st_size = stack[0], stack[1], stack[2], stack[3], stack[4]
    st_node[0], st_oi[0], st_oj[0], st_ok[0], st_size[0] = 0, 0, 0, 0, root_size
    top = 1
    count = 0
    while top > 0:
        top -= 1
        node = st_node[top]
        oi, oj, ok, size = st_oi[top], st_oj[top], st_ok[top], st_size[top]
        if oi >= ni:
            continue
        state = status[node]
        if state == TRANSPARENT:
            continue
        if state == NONTRANSPARENT:
            end = min(oi + size, ni)
            if count > 0 and out[count - 1, 1] == oi:
                out[count - 1, 1] = end
            else:
                out[count, 0] = oi
                out[count, 1] = end
                count += 1
            continue
        half = size // 2
        cj = 1 if jc - oj >= half else 0
        ck = 1 if kc - ok >= half else 0
        first = child[node] + (cj << bit_j) + (ck << bit_k)
        # Push the far child first so that the near one (lower i) is walked first.
        for ci in (1, 0):
            st_node[top] = first + (ci << bit_i)
            st_oi[top] = oi + ci * half
            st_oj[top] = oj + cj * half
            st_ok[top] = ok + ck * half
            st_size[top] = half
            top += 1
    return count


@njit(parallel=True, **_JIT)
def _all_block_runs(status, child, root_size, base, ni, nbj, nbk, bit_i, bit_j, bit_k, levels, runs, run_count,
                    block_voxels):
    """Every block's candidate runs (``runs[t, :run_count[t]]``) and their voxels per scanline (``block_voxels``)."""
    blocks = nbj * nbk
    chunks = min(blocks, 64)  # one walk stack per chunk of blocks (an allocation per block was a quarter of the walk)
    for c in prange(chunks):
        stack = np.empty((5, 2 * levels + 2), np.int64)
        for t in range(c * blocks // chunks, (c + 1) * blocks // chunks):
            bk = t // nbj
            bj = t - bk * nbj
            count = _block_runs(status, child, root_size, ni, bj * base, bk * base, bit_i, bit_j, bit_k, stack, runs[t])
            run_count[t] = count
            voxels = 0
            for r in range(count):
                voxels += runs[t, r, 1] - runs[t, r, 0]
            block_voxels[t] = voxels


@njit(**_JIT)
def _object_index(i, j, k, ax_i, ax_j, ax_k):
    """``(z, y, x)`` of standard-order voxel ``(i, j, k)``."""
    x = i if ax_i == 0 else (j if ax_j == 0 else k)
    y = i if ax_i == 1 else (j if ax_j == 1 else k)
    z = i if ax_i == 2 else (j if ax_j == 2 else k)
    return z, y, x


@njit(parallel=True, **_JIT)
def _classify_candidates(s, spacing, alpha_table, gtab, ref_step, min_opacity, want_gradients, lens_kind, lens_m,
                         lens_radius, lens_normals, lens_offsets, lens_clip, lens_alpha, lens_gtab, ax_i, ax_j, ax_k,
                         ni, nj, nk, base, nbj, runs, run_count, cand_offsets, records, gradients):
    """Classify every candidate voxel, scanline by scanline, into the packed candidate arrays."""
    sx, sy, sz = spacing[0], spacing[1], spacing[2]
    for kk in prange(nk):
        k = np.int64(kk)  # prange may index with uint64; mixed with int64 that would give floats
        for j in range(nj):
            t = (k // base) * nbj + j // base
            d = cand_offsets[k * nj + j]
            for r in range(run_count[t]):
                for i in range(runs[t, r, 0], runs[t, r, 1]):
                    z, y, x = _object_index(np.int64(i), np.int64(j), k, ax_i, ax_j, ax_k)
                    rec, gx, gy, gz, _visible = classify_lens_voxel(
                        s, z, y, x, sx, sy, sz, alpha_table, gtab, ref_step, min_opacity, lens_kind, lens_m,
                        lens_radius, lens_normals, lens_offsets, lens_clip, lens_alpha, lens_gtab)
                    records[d] = rec
                    if want_gradients:
                        if rec != 0:
                            gradients[d, 0] = gx
                            gradients[d, 1] = gy
                            gradients[d, 2] = gz
                        else:
                            gradients[d, 0] = 0.0
                            gradients[d, 1] = 0.0
                            gradients[d, 2] = 0.0
                    d += 1


@njit(**_JIT)
def _emit(out, pos, length, write):
    """Write one run of ``length`` (split at 255 by zero-length runs of the other kind); entries used."""
    used = 0
    while length > 255:
        if write:
            out[pos + used] = 255
            out[pos + used + 1] = 0
        used += 2
        length -= 255
    if write:
        out[pos + used] = length
    return used + 1


@njit(**_JIT)
def _interval_runs(runs, count, ni, out, pos, write):
    """The run lengths of a scanline whose non-transparent runs are ``runs[:count]`` (classify's format)."""
    used = 0
    x = 0
    for r in range(count):
        used += _emit(out, pos + used, runs[r, 0] - x, write)
        used += _emit(out, pos + used, runs[r, 1] - runs[r, 0], write)
        x = runs[r, 1]
    if x < ni or count == 0:
        used += _emit(out, pos + used, ni - x, write)
        used += _emit(out, pos + used, 0, write)
    return used


@njit(parallel=True, **_JIT)
def _exact_counts(ni, nj, nk, base, nbj, runs, run_count, cand_offsets, records, run_counts, voxel_counts):
    dummy = np.zeros(1, dtype=np.uint8)
    for k in prange(nk):
        line = np.zeros(ni, dtype=np.uint32)
        for j in range(nj):
            t = (k // base) * nbj + j // base
            d = cand_offsets[k * nj + j]
            c = 0
            for r in range(run_count[t]):
                for i in range(runs[t, r, 0], runs[t, r, 1]):
                    line[i] = records[d]
                    if records[d] != 0:
                        c += 1
                    d += 1
            run_counts[k * nj + j] = _scanline_runs(line, dummy, 0, False)
            voxel_counts[k * nj + j] = c
            for r in range(run_count[t]):
                for i in range(runs[t, r, 0], runs[t, r, 1]):
                    line[i] = 0


@njit(parallel=True, **_JIT)
def _exact_fill(ni, nj, nk, base, nbj, runs, run_count, cand_offsets, records, cand_gradients, want_gradients,
                run_offsets, data_offsets, lengths, voxels, gradients):
    for k in prange(nk):
        line = np.zeros(ni, dtype=np.uint32)
        for j in range(nj):
            sl = k * nj + j
            t = (k // base) * nbj + j // base
            d = cand_offsets[sl]
            out = data_offsets[sl]
            for r in range(run_count[t]):
                for i in range(runs[t, r, 0], runs[t, r, 1]):
                    rec = records[d]
                    line[i] = rec
                    if rec != 0:
                        voxels[out] = rec
                        if want_gradients:
                            gradients[out, 0] = cand_gradients[d, 0]
                            gradients[out, 1] = cand_gradients[d, 1]
                            gradients[out, 2] = cand_gradients[d, 2]
                        out += 1
                    d += 1
            _scanline_runs(line, lengths, run_offsets[sl], True)
            for r in range(run_count[t]):
                for i in range(runs[t, r, 0], runs[t, r, 1]):
                    line[i] = 0


@njit(parallel=True, **_JIT)
def _conservative_runs(ni, nj, nk, base, nbj, runs, run_count, run_offsets, lengths, write, run_counts):
    dummy = np.zeros(1, dtype=np.uint8)
    for k in prange(nk):
        for j in range(nj):
            sl = k * nj + j
            t = (k // base) * nbj + j // base
            if write:
                _interval_runs(runs[t], run_count[t], ni, lengths, run_offsets[sl], True)
            else:
                run_counts[sl] = _interval_runs(runs[t], run_count[t], ni, dummy, 0, False)


@dataclass(frozen=True, eq=False)
class OctreeEncodingStats:
    """What one octree encode did: voxels classified on the fly, candidate runs per block."""

    classified: int
    nontransparent: int
    candidate_runs: int


def _candidate_runs(octree, classification, axis):
    """ComputeVoxelRuns for every block of scanlines of ``axis``: the runs, their counts and the candidate
    voxels of one of the block's scanlines, with the shape ``(ni, nj, nk)``, the axes and the blocks along
    ``j``."""
    from renderers.shearwarp.factor import axes_ijk

    ax_i, ax_j, ax_k = axes_ijk(axis)
    nz, ny, nx = octree.shape_zyx
    n_xyz = (nx, ny, nz)
    ni, nj, nk = n_xyz[ax_i], n_xyz[ax_j], n_xyz[ax_k]
    base = octree.base_size
    nbj, nbk = -(-nj // base), -(-nk // base)
    max_runs = -(-ni // base) // 2 + 2
    runs = np.empty((nbj * nbk, max_runs, 2), dtype=np.int64)
    run_count = np.empty(nbj * nbk, dtype=np.int64)
    block_voxels = np.empty(nbj * nbk, dtype=np.int64)  # candidate voxels of each of a block's base² scanlines
    _all_block_runs(classification.status, octree.child, octree.root_size, base, ni, nbj, nbk, ax_i, ax_j, ax_k,
                    octree.levels, runs, run_count, block_voxels)
    return runs, run_count, block_voxels, (ni, nj, nk), (ax_i, ax_j, ax_k), nbj


def _candidate_offsets(block_voxels, nj, nk, base, nbj):
    """Where each scanline's candidate voxels start in the packed candidate arrays (``nk·nj + 1``)."""
    kk, jj = np.divmod(np.arange(nk * nj), nj)
    cand_offsets = np.zeros(nk * nj + 1, dtype=np.int64)
    np.cumsum(block_voxels[(kk // base) * nbj + jj // base], out=cand_offsets[1:])
    return cand_offsets


def _conservative_lengths(ni, nj, nk, base, nbj, runs, run_count):
    """The candidate runs as run lengths per scanline (classify's format) and the scanlines' run offsets."""
    run_counts = np.empty(nk * nj, dtype=np.int64)
    run_offsets = np.zeros(nk * nj + 1, dtype=np.int64)
    dummy = np.zeros(1, dtype=np.uint8)
    _conservative_runs(ni, nj, nk, base, nbj, runs, run_count, run_offsets, dummy, False, run_counts)
    np.cumsum(run_counts, out=run_offsets[1:])
    lengths = np.empty(run_offsets[-1], dtype=np.uint8)
    _conservative_runs(ni, nj, nk, base, nbj, runs, run_count, run_offsets, lengths, True, run_counts)
    return lengths, run_offsets


@njit(parallel=True, **_JIT)
def _block_lengths(ni, runs, run_count, run_offsets, lengths, write, counts):
    dummy = np.zeros(1, dtype=np.uint8)
    for t in prange(run_count.shape[0]):
        if write:
            _interval_runs(runs[t], run_count[t], ni, lengths, run_offsets[t], True)
        else:
            counts[t] = _interval_runs(runs[t], run_count[t], ni, dummy, 0, False)


@dataclass(frozen=True, eq=False)
class VoxelRuns:
    """The candidate runs of one principal axis, one run-length list per block of ``block²`` scanlines.

    All scanlines of a block cross the same octree nodes, so they share their runs (the thesis's reuse
    over ``n_min`` scanlines): ``lengths`` (classify's format) from ``run_offsets[t]`` and ``extents[t]``
    (first candidate voxel, one past the last) belong to block ``t = (k // block)·blocks_j + j // block``.
    """

    axis: int
    shape_ijk: tuple
    block: int
    blocks_j: int
    lengths: np.ndarray
    run_offsets: np.ndarray
    extents: np.ndarray
    candidates: int

    @property
    def nbytes(self):
        return int(self.lengths.nbytes + self.run_offsets.nbytes + self.extents.nbytes)

    def scanline_tables(self):
        """``(scan_k, scan_j)``: scanline ``(j, k)``'s block is ``scan_k[k] + scan_j[j]`` (``j`` up to ``nj``)."""
        _, nj, nk = self.shape_ijk
        return ((np.arange(nk, dtype=np.int64) // self.block) * self.blocks_j,
                np.arange(nj + 1, dtype=np.int64) // self.block)


def voxel_runs(octree, classification, axis):
    """The candidate runs of ``axis``'s scanlines, unclassified: the fast classification's per-frame step.

    The compositing kernel classifies the voxels it reaches inside these runs from the octree's voxel
    array (:func:`renderers.shearwarp.classify.classify_parameters`). Returns a :class:`VoxelRuns`.
    """
    runs, run_count, block_voxels, (ni, nj, nk), _, nbj = _candidate_runs(octree, classification, axis)
    base = octree.base_size
    scanlines = np.outer(np.minimum(base, nk - base * np.arange(-(-nk // base))),
                         np.minimum(base, nj - base * np.arange(nbj))).ravel()  # per block
    counts = np.empty(run_count.size, dtype=np.int64)
    _block_lengths(ni, runs, run_count, np.zeros(1, np.int64), np.zeros(1, np.uint8), False, counts)
    run_offsets = np.zeros(run_count.size + 1, dtype=np.int64)
    np.cumsum(counts, out=run_offsets[1:])
    lengths = np.empty(run_offsets[-1], dtype=np.uint8)
    _block_lengths(ni, runs, run_count, run_offsets, lengths, True, counts)
    extents = np.empty((run_count.size, 2), dtype=np.int32)
    blocks = np.arange(run_count.size)
    last = np.maximum(run_count - 1, 0)
    extents[:, 0] = np.where(run_count > 0, runs[blocks, 0, 0], ni)
    extents[:, 1] = np.where(run_count > 0, runs[blocks, last, 1], 0)
    return VoxelRuns(axis, (ni, nj, nk), base, nbj, lengths, run_offsets, extents, int(block_voxels @ scanlines))


def encode(octree, classification, axis, *, exact=True, gradients=False):
    """Run-length encoding of ``axis`` built from the octree (see the module notes).

    Parameters
    ----------
    octree : MinMaxOctree
    classification : OctreeClassification
        From :func:`classify_octree` for this octree.
    axis : int
        Principal axis 0/1/2 (x/y/z).
    exact : bool
        ``True``: byte-identical to ``classify.encode`` (the mode switch); ``False``: the octree's
        conservative runs, transparent voxels inside them stored as zero records.
    gradients : bool
        Keep each stored voxel's float32 gradient (procedural shading).

    Returns
    -------
    (Encoding, OctreeEncodingStats)
    """
    runs, run_count, block_voxels, (ni, nj, nk), (ax_i, ax_j, ax_k), nbj = _candidate_runs(octree, classification,
                                                                                          axis)
    base = octree.base_size
    cand_offsets = _candidate_offsets(block_voxels, nj, nk, base, nbj)
    n_cand = int(cand_offsets[-1])
    records = np.empty(n_cand, dtype=np.uint32)
    cand_gradients = np.empty((n_cand if gradients else 0, 3), dtype=np.float32)
    scalars = octree.scalars
    lens = NO_LENS_ARGUMENTS if classification.lens is None else classification.lens.kernel_arguments()
    _classify_candidates(scalars, np.asarray(octree.spacing, dtype=np.float64), classification.alpha_table,
                         classification.gradient_table, classification.reference_step, classification.min_opacity,
                         bool(gradients), *lens, ax_i, ax_j, ax_k, ni, nj, nk, base, nbj, runs, run_count, cand_offsets,
                         records, cand_gradients if gradients else np.zeros((1, 3), np.float32))
    if exact:
        run_counts = np.empty(nk * nj, dtype=np.int64)
        run_offsets = np.zeros(nk * nj + 1, dtype=np.int64)
        voxel_counts = np.empty(nk * nj, dtype=np.int64)
        _exact_counts(ni, nj, nk, base, nbj, runs, run_count, cand_offsets, records, run_counts, voxel_counts)
        np.cumsum(run_counts, out=run_offsets[1:])
        data_offsets = np.zeros(nk * nj + 1, dtype=np.int64)
        np.cumsum(voxel_counts, out=data_offsets[1:])
        lengths = np.empty(run_offsets[-1], dtype=np.uint8)
        voxels = np.empty(data_offsets[-1], dtype=np.uint32)
        out_gradients = np.empty((data_offsets[-1] if gradients else 0, 3), dtype=np.float32)
        _exact_fill(ni, nj, nk, base, nbj, runs, run_count, cand_offsets, records,
                    cand_gradients if gradients else np.zeros((1, 3), np.float32), bool(gradients), run_offsets,
                    data_offsets, lengths, voxels, out_gradients if gradients else np.zeros((1, 3), np.float32))
        nontransparent = int(data_offsets[-1])
    else:
        lengths, run_offsets = _conservative_lengths(ni, nj, nk, base, nbj, runs, run_count)
        data_offsets = cand_offsets
        voxels = records
        out_gradients = cand_gradients
        nontransparent = int(np.count_nonzero(records))
    encoding = Encoding(axis, (ni, nj, nk), lengths, run_offsets, data_offsets, voxels, out_gradients, True)
    stats = OctreeEncodingStats(n_cand, nontransparent, int(run_count.sum()))
    return encoding, stats


def transparent_voxel_mask(octree, classification):
    """``[z, y, x]`` bool mask of the voxels inside TRANSPARENT nodes (for tests and diagnostics)."""
    nz, ny, nx = octree.shape_zyx
    mask = np.zeros((nz, ny, nx), dtype=bool)
    stack = [(0, 0, 0, 0, octree.root_size)]
    status, child = classification.status, octree.child
    while stack:
        node, ox, oy, oz, size = stack.pop()
        if ox >= nx or oy >= ny or oz >= nz:
            continue
        if status[node] == TRANSPARENT:
            mask[oz:oz + size, oy:oy + size, ox:ox + size] = True
        elif status[node] == SUBDIVIDE:
            half = size // 2
            for c in range(8):
                stack.append((int(child[node]) + c, ox + (c & 1) * half, oy + ((c >> 1) & 1) * half,
                              oz + ((c >> 2) & 1) * half, half))
    return mask
