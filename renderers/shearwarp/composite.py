"""Numba kernels of the shear-warp compositing loop (Lacroute 1995, §4.1, Fig. 4.8; Ch. 6).

Per-frame tables
----------------
* :func:`opacity_table`: ``α' = 1 − (1 − α)^(Δ/Δ0)`` for each 8-bit stored opacity (§4.1.6), rebuilt
  per view (``Δ`` = the world length of a ray segment between two slices).
* :func:`shade_table`: for each of the 8193 normal codes, the Blinn–Phong factors ``(f, h)`` with
  ``f = ambient + diffuse·|N·L|`` and ``h = specular·|N·H|^shininess`` (two-sided, CONVENTIONS),
  ``N`` the code's object-space direction carried to world space by the normal matrix; a voxel of
  colour ``c`` shades to ``clamp(c·f + h)`` per channel, exactly the reference's formula with a
  quantised normal. ``shading="procedural"`` evaluates the same formula per voxel from its stored
  unquantised gradient instead (thesis Table 7.1's "no lookup tables").

Compositing
-----------
The intermediate image is float32 premultiplied RGBA, pixel ``(row, column)`` at ``(u, v) =
(column, row)``. Slice ``k`` lands at offset ``(u0, v0)`` with integer parts ``(iu, iv)`` and
fractions ``(fu, fv)``; intermediate pixel ``(row, iu + x)`` of that slice is the bilinear
combination of voxels ``x`` and ``x − 1`` of voxel scanlines ``j = row − iv`` and ``j − 1``, with the
weights ``(1−fu)(1−fv)``, ``(1−fu)fv``, ``fu(1−fv)``, ``fu·fv``, the same for the whole slice
(property 3). Each voxel is opacity-corrected (table), coloured (colour table, the lens's rows
for a voxel classified by a lens: :func:`colour_index`; shaded by the LUT or procedurally) and
premultiplied before resampling, as the thesis does (classify → shade → interpolate), and each
sample is composited front to back, ``C += (1 − A)·c``, ``A += (1 − A)·α``.

Along a row the two voxel scanlines are walked with run cursors, positions ``x = 0..n_i`` (the
``n_i + 1`` pixels a scanline's bilinear footprint covers). Three cases per position, as in Fig.
4.8: (1) the pixel is opaque (skip link ≠ 0): FIND the end of its opaque run and jump there,
re-reading the voxel left of the landing position; (2) the current and the previous voxel of both
scanlines are transparent: jump to the next non-transparent run start of either scanline (every
skipped sample is exactly zero, so skipping changes no bit); (3) resample and composite. The
brute-force path (``rle=False``) feeds the same loop an encoding where every voxel is one
non-transparent run and no scanline extents, which turns case (2) off, so it resamples every position and
both produce the same image bit for bit when early termination is off.

Early ray termination (§4.1.3): a pixel with ``A >= opaque_threshold`` gets skip link 1
(CREATE; UNION is free because links point forward). FIND follows links to the first
non-opaque pixel and, with path compression, rewrites every visited link to point there. The
``union="rank"`` variant keeps a parent pointer (stored as parent + 1), a rank and the run end per
root, and unions a new opaque pixel with its opaque neighbours by rank, FIND also compressing
paths. Links are int32 (the thesis's are 8-bit, capping one skip at 255 pixels).

Skipping opaque pixels jumps in the voxel scanlines too: FIND's landing position is reached from the
scanline's run index (:func:`renderers.shearwarp.classify.run_index`, a cursor checkpoint every 32
voxels) instead of by walking every run under the opaque pixels; on a 256³ head this walk was nine
runs in ten that the cursors passed. A row composites only the positions its two scanlines' voxels
reach (:func:`renderers.shearwarp.classify.scanline_extents`; every other sample is zero), so a row
without voxels is skipped whole and one wholly behind opaque pixels ends at its first FIND.

Fast classification (thesis §4.3.4, Fig. 4.17), ``lazy``: the scanlines are the octree's candidate
runs (:func:`renderers.shearwarp.octree.voxel_runs`) and a voxel is classified where the loop first
needs it, from the unclassified voxel array (scalar, gradient magnitude, normal code, 16 bytes;
:func:`renderers.shearwarp.classify.classify_parameters`, the same record bits as the classified
RLE's), after a one-lookup test of its parameter bins that decides most transparent voxels
(:func:`_lazy_record`). Voxels behind opaque pixels are never classified; a voxel is classified once for each of
the two rows that read its scanline, as VolPack's raw-volume loop does. Keeping scanline ``j``'s
records for row ``j + 1`` (a two-scanline cache) halved the classifications and made the frame
slower: 30 ms against 22 ms on a 256³ head.

Speed notes: the row loop is written out inside :func:`_composite_task` (one call per task, not
per slice and row), and inside the loops only scalars are passed to helper functions. Numba
reference-counts array arguments at calls it does not inline (an atomic increment and decrement
per array), which made a sample several times dearer than its arithmetic; the shading lookups
and FIND are therefore written in place, with :func:`_procedural` and :func:`_premultiply`
taking scalars only, and helpers that take arrays are inlined (``inline="always"``). Each voxel is
shaded where it is first needed and carried in registers as the "previous" voxel of the next
position (twice per slice: once per scanline of the pair); shading whole scanlines ahead of time
would shade many voxels that early termination never reaches (on the bone phantom five times more
voxels than samples); a lazily filled two-scanline cache of shaded voxels was measured and gained
nothing. Counters are kept in registers for the whole task and written once: five read-modify-writes
of a shared array per row and slice cost 8 % of the frame. Walking each stretch where neither
scanline's run changes as an inner loop without the per-position run tests (VolPack's
``min(run_a, run_b)`` pixels per step) gave the same bits and made the compositing 10 % slower on
brainsmall and the folded-brain phantom (256², one worker): not kept.

Specialised kernels: each option that turns a feature off (brute force, shading mode, early
termination, union by rank, fast classification) is passed as an array or ``None``, and the loop
tests ``x is None``. Numba compiles the kernel once per combination of argument types and drops the
branches a ``None`` decides before typing, so each option set runs a loop with only its own code in
it (a flag argument would be tested at run time at every position). Measured on a 256³ CT head at
512² and on brainsmall at 256², one worker, each alone: the compositing took 10 to 15 % less time,
the same bits (1 to 6 % in lacroute1995-volpack's interleaved job).

Threads (Ch. 6): the intermediate image's rows are cut into tasks of ``task_size`` rows; a task
composites all slices front to back over its rows. Tasks are dealt to ``workers`` queues
contiguously or round-robin; a worker takes its own queue's tasks in order and, in the
``-steal`` schedules, then takes tasks from the other queues, with an atomic fetch-and-add per
queue (:func:`_fetch_add`) so that each task is taken once. Compositing a row never reads another
row, so the image and every counter are the same bits for any schedule and worker count.
"""

import math

import numpy as np
from numba import njit, prange, types
from numba.core import cgutils
from numba.extending import intrinsic

from renderers.base.numba_kernels import JIT as _JIT
from renderers.shearwarp.classify import INDEX_SHIFT, NORMAL_CODES, NORMAL_DIRECTIONS, classify_parameters
from renderers.shearwarp.warp import row_extent

SHADE_NONE, SHADE_LUT, SHADE_PROCEDURAL = 0, 1, 2
N_COUNTERS = 6
C_SAMPLES, C_RUNS, C_FINDS, C_CREATES, C_SKIPPED, C_CLASSIFIED = range(N_COUNTERS)
BIG = 1 << 60


@intrinsic
def _fetch_add(typingctx, array, index, value):
    """Atomic ``old = array[index]; array[index] += value; return old`` on an int64 array."""
    if not (isinstance(array, types.Array) and array.dtype == types.int64 and array.ndim == 1):
        return None
    signature = types.int64(array, types.intp, types.int64)

    def codegen(context, builder, sig, args):
        arr, idx, val = args
        aryty = sig.args[0]
        ary = context.make_array(aryty)(context, builder, arr)
        pointer = cgutils.get_item_pointer(context, builder, aryty, ary, [idx])
        return builder.atomic_rmw("add", pointer, val, "seq_cst")

    return signature, codegen


# ---------------------------------------------------------------------------------------------
# Voxel records (layout: renderers.shearwarp.classify). Defined here, beside the kernels that inline
# them: Numba's cache of a kernel is invalidated by edits to its own file only.


@njit(inline="always", **_JIT)
def colour_index(record):
    """Row of the colour table for ``record``: its 8-bit index, plus 256 for a lens voxel (``LENS_BIT``)."""
    return ((record >> 8) & 255) | ((record >> 22) & 256)


@njit(inline="always", **_JIT)
def normal_code(record):
    """The 13-bit normal code of ``record`` (or ``NO_NORMAL``), without the lens bit."""
    return (record >> 16) & 16383


@njit(inline="always", **_JIT)
def _lazy_record(index, raw, alpha_table, gtab, ref_step, min_opacity, visible):
    """The record of voxel ``index`` of the unclassified voxel array, classified now (fast classification).

    A voxel whose parameter bins ``visible`` marks 0 is transparent without interpolating either table:
    no value in those bins has ``α > min_opacity`` (the octree's conservative bound), so
    :func:`classify_parameters` would return 0 too.
    """
    voxel = raw[index]
    if visible[voxel.scalar_bin, voxel.gradient_bin] == 0:
        return np.uint32(0)
    return classify_parameters(voxel.scalar, voxel.magnitude, np.int64(voxel.normal), alpha_table, gtab, ref_step,
                               min_opacity)


# ---------------------------------------------------------------------------------------------
# Tables


def opacity_table(ratio, correct=True):
    """Corrected opacity for each stored 8-bit opacity, float64 (256,)."""
    alpha = np.arange(256, dtype=np.float64) / 255.0
    if not correct:
        return alpha
    with np.errstate(divide="ignore"):
        return -np.expm1(ratio * np.log1p(-alpha))


@njit(inline="always", **_JIT)
def _power(x, exponent):
    """``x ** exponent``; a whole exponent up to 64 by repeated squaring (a few ulp from ``pow``, which
    took four fifths of the shading table's time)."""
    if exponent == math.floor(exponent) and 0.0 <= exponent <= 64.0:
        n = int(exponent)
        result = 1.0
        while n > 0:
            if n & 1:
                result *= x
            x *= x
            n >>= 1
        return result
    return x ** exponent


@njit(**_JIT)
def _phong_factors(nx, ny, nz, lx, ly, lz, hx, hy, hz, has_half, ambient, diffuse, specular, shininess):
    norm = math.sqrt(nx * nx + ny * ny + nz * nz)
    if norm == 0.0:
        return ambient, 0.0
    factor = ambient + diffuse * abs(nx * lx + ny * ly + nz * lz) / norm
    highlight = 0.0
    if has_half:
        highlight = specular * _power(abs(nx * hx + ny * hy + nz * hz) / norm, shininess)
    return factor, highlight


@njit(**_JIT)
def _shade_codes(first, last, dirs, nmat, light, half, has_half, params, table):
    for code in range(first, last):
        gx, gy, gz = dirs[code, 0], dirs[code, 1], dirs[code, 2]
        nx = nmat[0, 0] * gx + nmat[0, 1] * gy + nmat[0, 2] * gz
        ny = nmat[1, 0] * gx + nmat[1, 1] * gy + nmat[1, 2] * gz
        nz = nmat[2, 0] * gx + nmat[2, 1] * gy + nmat[2, 2] * gz
        f, h = _phong_factors(nx, ny, nz, light[0], light[1], light[2], half[0], half[1], half[2], has_half,
                              params[0], params[1], params[2], params[3])
        table[code, 0] = f
        table[code, 1] = h


@njit(parallel=True, **_JIT)
def _shade_table_parallel(dirs, nmat, light, half, has_half, params, workers, table):
    n = dirs.shape[0]
    for w in prange(workers):  # contiguous chunks, one per worker: the same bits for any count
        _shade_codes(w * n // workers, (w + 1) * n // workers, dirs, nmat, light, half, has_half, params, table)


def shade_table(normal_matrix, light, half, has_half, params, out=None, workers=1):
    """``(8193, 2)`` float64 Blinn–Phong factors per normal code (see the module notes).

    ``workers > 1`` splits the codes over that many threads (same bits); one worker runs in the
    calling thread without a parallel launch (cheaper for a table this small).
    """
    if out is None:
        out = np.empty((NORMAL_CODES, 2))
    if workers > 1:
        _shade_table_parallel(NORMAL_DIRECTIONS, normal_matrix, light, half, has_half, params, int(workers), out)
    else:
        _shade_codes(0, NORMAL_CODES, NORMAL_DIRECTIONS, normal_matrix, light, half, has_half, params, out)
    return out


# ---------------------------------------------------------------------------------------------
# Compositing


@njit(**_JIT)
def _procedural(gx, gy, gz, m00, m01, m02, m10, m11, m12, m20, m21, m22, lx, ly, lz, hx, hy, hz, has_half, ambient,
                diffuse, specular, shininess):
    """Phong factors ``(f, h)`` of an object-space gradient (float32 components), carried by the normal matrix."""
    gx = np.float64(gx)
    gy = np.float64(gy)
    gz = np.float64(gz)
    nx = m00 * gx + m01 * gy + m02 * gz
    ny = m10 * gx + m11 * gy + m12 * gz
    nz = m20 * gx + m21 * gy + m22 * gz
    return _phong_factors(nx, ny, nz, lx, ly, lz, hx, hy, hz, has_half, ambient, diffuse, specular, shininess)


@njit(**_JIT)
def _premultiply(a, r, g, b, f, h, shaded):
    """Premultiplied ``(a·r', a·g', a·b', a)`` with ``c' = clamp(c·f + h)`` when ``shaded``, else ``c' = c``."""
    if shaded:
        r = min(max(r * f + h, 0.0), 1.0)
        g = min(max(g * f + h, 0.0), 1.0)
        b = min(max(b * f + h, 0.0), 1.0)
    return a * r, a * g, a * b, a


@njit(**_JIT)
def _root_rank(link, row, p):
    """Root of ``p``'s set in the union-by-rank forest (links hold parent + 1), compressing the path."""
    root = p
    while link[row, root] - 1 != root:
        root = link[row, root] - 1
    x = p
    while x != root:
        nxt = link[row, x] - 1
        link[row, x] = root + 1
        x = nxt
    return root


@njit(**_JIT)
def _union_rank(link, rank, runend, row, a, b):
    if a == b:
        return
    end = max(runend[row, a], runend[row, b])
    if rank[row, a] < rank[row, b]:
        link[row, a] = b + 1
        runend[row, b] = end
    elif rank[row, a] > rank[row, b]:
        link[row, b] = a + 1
        runend[row, a] = end
    else:
        link[row, b] = a + 1
        rank[row, a] += 1
        runend[row, a] = end


@njit(inline="always", **_JIT)
def clear_rows(image, link, r0, r1):
    """Zero rows ``r0 .. r1 − 1`` of the intermediate image and of its skip links (``link`` may be None)."""
    for row in range(r0, r1):
        for col in range(image.shape[1]):
            image[row, col, 0] = 0.0
            image[row, col, 1] = 0.0
            image[row, col, 2] = 0.0
            image[row, col, 3] = 0.0
        if link is not None:
            for col in range(link.shape[1]):
                link[row, col] = 0


@njit(**_JIT)
def _composite_task(task, r0, r1, slices, iu, iv, weights, ni, nj, scan_k, scan_j, lengths, run_offsets, data_offsets,
                    run_index, extents, voxels, gradients, optab, coltab, shadetab, nmat, light, half, has_half, params,
                    threshold, raw, alpha_table, gtab, ref_step, min_opacity, visible, stride_i, stride_j, stride_k,
                    image, link, rank, runend, extent, counters):
    """Clear intermediate rows ``r0 .. r1 − 1`` and composite every slice into them, front to back.

    The row loop is written out here (one call per task, not per row and slice: a call with
    this many array arguments costs more than a short row). For each slice and row, voxel
    scanlines ``j = row − iv[k]`` (cursor A, weights ``wca``/``wpa``) and ``j − 1`` (cursor B)
    are walked as the module notes describe. The task's counters go to ``counters[task]`` and each
    finished row's first and last non-zero pixel to ``extent[row]`` (for the warp: the rows are still
    in cache here, where a pass over the image would read them again).

    An optional array passed as ``None`` turns its feature off (module notes, "Specialised kernels"):
    ``extents`` None: brute force, every position resampled and no transparent stretch skipped;
    ``shadetab`` (LUT) or ``gradients`` (procedural) given: Phong shading, neither: unshaded; ``link``
    None: no early termination; ``rank`` and ``runend`` given: the union-by-rank variant; ``raw``
    given: fast classification, the records classified from ``raw`` (the unclassified voxel array,
    flat; voxel ``(i, j, k)`` at ``i·stride_i + j·stride_j + k·stride_k``) with the tables
    ``alpha_table``, ``gtab`` and the bin test ``visible`` instead of read from ``voxels``.
    """
    # Scalars only inside the loops: array references created there would cost reference counting.
    m00, m01, m02 = nmat[0, 0], nmat[0, 1], nmat[0, 2]
    m10, m11, m12 = nmat[1, 0], nmat[1, 1], nmat[1, 2]
    m20, m21, m22 = nmat[2, 0], nmat[2, 1], nmat[2, 2]
    lx, ly, lz = light[0], light[1], light[2]
    hx, hy, hz = half[0], half[1], half[2]
    ambient, diffuse, specular, shininess = params[0], params[1], params[2], params[3]
    samples = runs = finds = creates = skipped = classified = 0  # this task's counters
    shaded = shadetab is not None or gradients is not None
    # The task's own rows, cleared here rather than by a pass over the image: no extra parallel launch,
    # and the rows are in cache when compositing starts.
    clear_rows(image, link, r0, r1)
    indexed = run_index.shape[1] > 0
    for s in range(slices.shape[0]):
        k = slices[s]
        iuk = iu[k]
        ivk = iv[k]
        wca = weights[k, 0]
        wcb = weights[k, 1]
        wpa = weights[k, 2]
        wpb = weights[k, 3]
        row_lo = max(r0, ivk)
        row_hi = min(r1, ivk + nj + 1)
        for row in range(row_lo, row_hi):
            j = row - ivk
            # The scanlines' entries in the per-scanline tables (per block of scanlines with the octree's runs).
            sl_a = scan_k[k] + scan_j[j]
            sl_b = scan_k[k] + scan_j[j - 1] if j >= 1 else 0
            a_ok = j < nj
            b_ok = j >= 1
            if extents is None:  # brute force: every position
                x_lo = 0
                x_hi = ni
            else:
                # Positions x_lo .. x_hi reach a voxel of either scanline; every sample outside them is zero.
                x_lo = ni
                x_hi = 0
                if a_ok:
                    x_lo = min(x_lo, np.int64(extents[sl_a, 0]))
                    x_hi = max(x_hi, np.int64(extents[sl_a, 1]))
                if b_ok:
                    x_lo = min(x_lo, np.int64(extents[sl_b, 0]))
                    x_hi = max(x_hi, np.int64(extents[sl_b, 1]))
                if x_lo > x_hi:
                    continue  # both scanlines hold no voxel
            # Cursor A: scanline j (weight 1 − fv); cursor B: scanline j − 1 (weight fv). A scanline
            # outside the slice is one endless transparent run (end = BIG), so the loop needs no
            # test for it.
            a_obj = j * stride_j + k * stride_k  # lazy: voxel i of scanline j is a_obj + i·stride_i
            b_obj = a_obj - stride_j
            a_run = 0
            a_start = 0
            a_end = BIG
            a_nt = False
            a_dat = 0
            a_first = 0
            a_base = 0
            if a_ok:
                a_first = a_run = run_offsets[sl_a]
                a_end = np.int64(lengths[a_run])
                a_base = a_dat = data_offsets[sl_a]
            b_run = 0
            b_start = 0
            b_end = BIG
            b_nt = False
            b_dat = 0
            b_first = 0
            b_base = 0
            if b_ok:
                b_first = b_run = run_offsets[sl_b]
                b_end = np.int64(lengths[b_run])
                b_base = b_dat = data_offsets[sl_b]
            par = pag = pab = paa = 0.0  # previous voxel (x − 1) of scanline A, premultiplied
            pbr = pbg = pbb = pba = 0.0
            x = x_lo
            while x <= x_hi:
                p = x + iuk
                if link is not None and link[row, p] != 0:
                    if rank is not None:
                        q = runend[row, _root_rank(link, row, p)]
                    else:
                        # FIND with path compression (relative links): the first non-opaque pixel
                        # at or after p; every link on the way is rewritten to point there.
                        q = p
                        while link[row, q] != 0:
                            q += link[row, q]
                        y = p
                        while y != q:
                            nxt = y + link[row, y]
                            link[row, y] = q - y
                            y = nxt
                    finds += 1
                    landing = q - iuk
                    skipped += min(landing, x_hi + 1) - x
                    if landing > x_hi:
                        break
                    # Re-read the voxels left of the landing position (they may be non-transparent).
                    left = landing - 1
                    par = pag = pab = paa = 0.0
                    pbr = pbg = pbb = pba = 0.0
                    if indexed and left >= a_end and (left >> INDEX_SHIFT) << INDEX_SHIFT >= a_end:
                        # A checkpoint of the run index lies past the current run: jump there.
                        point = left >> INDEX_SHIFT
                        rel = np.int64(run_index[sl_a, point, 0])
                        a_run = a_first + rel
                        a_start = np.int64(run_index[sl_a, point, 1])
                        a_end = a_start + lengths[a_run]
                        a_dat = a_base + run_index[sl_a, point, 2]
                        a_nt = (rel & 1) == 1
                    while left >= a_end:
                        if a_nt:
                            a_dat += a_end - a_start
                        a_start = a_end
                        a_run += 1
                        a_end = a_start + lengths[a_run]
                        a_nt = not a_nt
                        runs += 1
                    if a_nt:
                        index = a_dat + left - a_start
                        if raw is not None:
                            record = _lazy_record(a_obj + left * stride_i, raw, alpha_table, gtab, ref_step,
                                                  min_opacity, visible)
                            classified += 1
                        else:
                            record = voxels[index]
                        opacity = record & 255
                        if opacity != 0:
                            ci = colour_index(record)
                            f = 1.0
                            h = 0.0
                            if shadetab is not None:
                                f = shadetab[normal_code(record), 0]
                                h = shadetab[normal_code(record), 1]
                            elif gradients is not None:
                                f, h = _procedural(gradients[index, 0], gradients[index, 1], gradients[index, 2],
                                                   m00, m01, m02, m10, m11, m12, m20, m21, m22, lx, ly, lz, hx, hy, hz,
                                                   has_half, ambient, diffuse, specular, shininess)
                            par, pag, pab, paa = _premultiply(optab[opacity], coltab[ci, 0], coltab[ci, 1],
                                                              coltab[ci, 2], f, h, shaded)
                    if indexed and left >= b_end and (left >> INDEX_SHIFT) << INDEX_SHIFT >= b_end:
                        # A checkpoint of the run index lies past the current run: jump there.
                        point = left >> INDEX_SHIFT
                        rel = np.int64(run_index[sl_b, point, 0])
                        b_run = b_first + rel
                        b_start = np.int64(run_index[sl_b, point, 1])
                        b_end = b_start + lengths[b_run]
                        b_dat = b_base + run_index[sl_b, point, 2]
                        b_nt = (rel & 1) == 1
                    while left >= b_end:
                        if b_nt:
                            b_dat += b_end - b_start
                        b_start = b_end
                        b_run += 1
                        b_end = b_start + lengths[b_run]
                        b_nt = not b_nt
                        runs += 1
                    if b_nt:
                        index = b_dat + left - b_start
                        if raw is not None:
                            record = _lazy_record(b_obj + left * stride_i, raw, alpha_table, gtab, ref_step,
                                                  min_opacity, visible)
                            classified += 1
                        else:
                            record = voxels[index]
                        opacity = record & 255
                        if opacity != 0:
                            ci = colour_index(record)
                            f = 1.0
                            h = 0.0
                            if shadetab is not None:
                                f = shadetab[normal_code(record), 0]
                                h = shadetab[normal_code(record), 1]
                            elif gradients is not None:
                                f, h = _procedural(gradients[index, 0], gradients[index, 1], gradients[index, 2],
                                                   m00, m01, m02, m10, m11, m12, m20, m21, m22, lx, ly, lz, hx, hy, hz,
                                                   has_half, ambient, diffuse, specular, shininess)
                            pbr, pbg, pbb, pba = _premultiply(optab[opacity], coltab[ci, 0], coltab[ci, 1],
                                                              coltab[ci, 2], f, h, shaded)
                    x = landing
                    continue
                cur_a = False
                cur_b = False
                if x < ni:
                    while x >= a_end:
                        if a_nt:
                            a_dat += a_end - a_start
                        a_start = a_end
                        a_run += 1
                        a_end = a_start + lengths[a_run]
                        a_nt = not a_nt
                        runs += 1
                    cur_a = a_nt
                    while x >= b_end:
                        if b_nt:
                            b_dat += b_end - b_start
                        b_start = b_end
                        b_run += 1
                        b_end = b_start + lengths[b_run]
                        b_nt = not b_nt
                        runs += 1
                    cur_b = b_nt
                if extents is not None and not cur_a and not cur_b and paa == 0.0 and pba == 0.0:
                    # Both scanlines transparent here and just before: jump to the next non-transparent run.
                    landing = ni + 1
                    if x < ni:
                        landing = min(landing, a_end)
                        landing = min(landing, b_end)
                    x = landing
                    continue
                car = cag = cab = caa = 0.0
                cbr = cbg = cbb = cba = 0.0
                if cur_a:
                    index = a_dat + x - a_start
                    if raw is not None:
                        record = _lazy_record(a_obj + x * stride_i, raw, alpha_table, gtab, ref_step, min_opacity,
                                              visible)
                        classified += 1
                    else:
                        record = voxels[index]
                    opacity = record & 255
                    if opacity != 0:
                        ci = colour_index(record)
                        f = 1.0
                        h = 0.0
                        if shadetab is not None:
                            f = shadetab[normal_code(record), 0]
                            h = shadetab[normal_code(record), 1]
                        elif gradients is not None:
                            f, h = _procedural(gradients[index, 0], gradients[index, 1], gradients[index, 2],
                                               m00, m01, m02, m10, m11, m12, m20, m21, m22, lx, ly, lz, hx, hy, hz,
                                               has_half, ambient, diffuse, specular, shininess)
                        car, cag, cab, caa = _premultiply(optab[opacity], coltab[ci, 0], coltab[ci, 1], coltab[ci, 2],
                                                          f, h, shaded)
                if cur_b:
                    index = b_dat + x - b_start
                    if raw is not None:
                        record = _lazy_record(b_obj + x * stride_i, raw, alpha_table, gtab, ref_step, min_opacity,
                                              visible)
                        classified += 1
                    else:
                        record = voxels[index]
                    opacity = record & 255
                    if opacity != 0:
                        ci = colour_index(record)
                        f = 1.0
                        h = 0.0
                        if shadetab is not None:
                            f = shadetab[normal_code(record), 0]
                            h = shadetab[normal_code(record), 1]
                        elif gradients is not None:
                            f, h = _procedural(gradients[index, 0], gradients[index, 1], gradients[index, 2],
                                               m00, m01, m02, m10, m11, m12, m20, m21, m22, lx, ly, lz, hx, hy, hz,
                                               has_half, ambient, diffuse, specular, shininess)
                        cbr, cbg, cbb, cba = _premultiply(optab[opacity], coltab[ci, 0], coltab[ci, 1], coltab[ci, 2],
                                                          f, h, shaded)
                sa = wca * caa + wcb * cba + wpa * paa + wpb * pba
                samples += 1
                if sa > 0.0:
                    sr = wca * car + wcb * cbr + wpa * par + wpb * pbr
                    sg = wca * cag + wcb * cbg + wpa * pag + wpb * pbg
                    sb = wca * cab + wcb * cbb + wpa * pab + wpb * pbb
                    transparency = 1.0 - np.float64(image[row, p, 3])
                    image[row, p, 0] += transparency * sr
                    image[row, p, 1] += transparency * sg
                    image[row, p, 2] += transparency * sb
                    alpha = image[row, p, 3] + transparency * sa
                    image[row, p, 3] = alpha
                    if link is not None and image[row, p, 3] >= threshold:
                        creates += 1
                        if rank is not None:
                            link[row, p] = p + 1
                            rank[row, p] = 0
                            runend[row, p] = p + 1
                            if p > 0 and link[row, p - 1] != 0:
                                _union_rank(link, rank, runend, row, _root_rank(link, row, p - 1), p)
                            if link[row, p + 1] != 0:
                                _union_rank(link, rank, runend, row, _root_rank(link, row, p),
                                            _root_rank(link, row, p + 1))
                        else:
                            link[row, p] = 1
                par, pag, pab, paa = car, cag, cab, caa
                pbr, pbg, pbb, pba = cbr, cbg, cbb, cba
                x += 1

    for row in range(r0, r1):
        row_extent(image, row, extent)
    counters[task, C_SAMPLES] = samples
    counters[task, C_RUNS] = runs
    counters[task, C_FINDS] = finds
    counters[task, C_CREATES] = creates
    counters[task, C_SKIPPED] = skipped
    counters[task, C_CLASSIFIED] = classified

@njit(parallel=True, **_JIT)
def composite(workers, steal, task_size, queue_tasks, queue_start, queue_next, worker_stats, slices, iu, iv, weights,
              ni, nj, scan_k, scan_j, lengths, run_offsets, data_offsets, run_index, extents, voxels, gradients, optab, coltab,
              shadetab, nmat, light, half, has_half, params, threshold, raw, alpha_table, gtab, ref_step, min_opacity,
              visible, stride_i, stride_j, stride_k, image, link, rank, runend, extent, counters):
    """Clear the intermediate image, composite every slice into it and find each row's non-zero extent, tasks
    dealt to ``workers`` queues.

    ``queue_tasks[queue_start[w]:queue_start[w + 1]]`` is worker ``w``'s queue and ``queue_next[w]``
    (set to ``queue_start[w]`` by the caller) its next position; ``worker_stats[w]`` receives the
    tasks and samples worker ``w`` did. The arguments that may be ``None`` are
    :func:`_composite_task`'s.
    """
    height = image.shape[0]
    for w in prange(workers):
        done = 0
        samples = 0
        for t in range(workers if steal else 1):
            queue = (w + t) % workers
            while True:
                position = _fetch_add(queue_next, queue, 1)
                if position >= queue_start[queue + 1]:
                    break
                task = queue_tasks[position]
                r0 = task * task_size
                r1 = min(height, r0 + task_size)
                _composite_task(task, r0, r1, slices, iu, iv, weights, ni, nj, scan_k, scan_j, lengths, run_offsets, data_offsets,
                                run_index, extents, voxels, gradients, optab, coltab, shadetab, nmat, light, half,
                                has_half, params, threshold, raw, alpha_table, gtab, ref_step, min_opacity, visible,
                                stride_i, stride_j, stride_k, image, link, rank, runend, extent, counters)
                samples += counters[task, C_SAMPLES]
                done += 1
        worker_stats[w, 0] = done
        worker_stats[w, 1] = samples
