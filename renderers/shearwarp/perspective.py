"""Numba kernels of perspective shear-warp compositing (Lacroute 1995, §4.2, Fig. 4.10).

After the perspective factorization (:mod:`renderers.shearwarp.factor`) every viewing ray is
parallel to ``k`` in sheared space, and slice ``k`` is translated by ``(u0_k, v0_k)`` and uniformly
scaled by ``f_k <= 1`` (1 at the front slice): voxel ``(i, j)`` of slice ``k`` lands at
``(u, v) = (u0_k + f_k·i, v0_k + f_k·j)``, and intermediate pixel ``(row, column)`` is centred at
``(u, v) = (column, row)``.

Resampling filter (thesis §4.2.2)
---------------------------------
Box reconstruction of the slice (each voxel a ``1 × 1`` square about its centre) averaged over the
pixel's footprint (a ``1/f_k × 1/f_k`` square of voxel space): the weight of voxel ``i`` for the
pixel whose centre is at voxel coordinate ``c = (column − u0_k)/f_k`` is
``f_k · |[i − ½, i + ½] ∩ [c − ½/f_k, c + ½/f_k]|``, separably in ``j``. At ``f_k = 1`` this is
exactly the bilinear (tent) filter of the parallel renderer; below 1 it is the thesis's area
averaging with a footprint of at most ``1 + ceil(1/f_k)`` voxels (scanlines) per pixel (row),
so farther, decimated slices are low-pass filtered instead of aliased. Outside the slice the
volume is transparent (weights are not renormalised), as in the parallel renderer. The filter is
evaluated per pixel in the gather direction (the thesis's ``DecimateArea``): a pixel reads the
voxels its footprint covers, so the intermediate image's rows stay independent tasks (Ch. 6)
and every schedule gives the same bits.

Voxel values are opacity-corrected, shaded and premultiplied before being averaged, as in the
parallel renderer (classify → shade → resample, thesis Fig. 4.10's ``LoadVoxel``).

Opacity correction (thesis §4.2.3)
----------------------------------
The ray of intermediate pixel ``(u, v)`` passes through the eye, so the length ``Δ`` of its
segment between two slices is constant along the ray but differs between pixels. As in the
thesis, the renderer builds ``n`` tables ``1 − (1 − α)^(r_b)`` at ratios ``r_b`` spaced evenly over
``[min, max]`` of ``Δ/Δ0`` over the intermediate image, and stores per pixel the bracketing table
``b`` and the interpolation weight; a voxel's corrected opacity is
``T[b, α]·(1 − w) + T[b + 1, α]·w``. With 32 tables and the ray-length spread of a usual view
(< 10 %) the interpolation error is below 1e-6 (the second derivative of ``(1 − α)^r`` in ``r``
is ``ln²(1 − α)·(1 − α)^r``, at most about 0.6 over 8-bit opacities below 1).

Skipping (thesis §4.2.2)
------------------------
Transparent voxel runs: one run cursor per footprint scanline, kept at the first voxel of the
current pixel's footprint; when every footprint scanline is transparent over the footprint, the
loop jumps to the first pixel whose footprint reaches the next non-transparent run (every skipped
pixel would add exactly zero, so the image is the same bits as the brute-force path that visits
every pixel). Opaque pixels: the same run-length-encoded intermediate image (skip links, FIND
with path compression or union by rank) as the parallel kernel.
"""

import math

import numpy as np
from numba import njit, prange

from renderers.base.numba_kernels import JIT as _JIT
from renderers.shearwarp.composite import (BIG, C_CREATES, C_FINDS, C_RUNS, C_SAMPLES, C_SKIPPED, SHADE_LUT,
                                           SHADE_NONE, SHADE_PROCEDURAL, _fetch_add, _premultiply, _procedural,
                                           _root_rank, _union_rank, clear_rows, colour_index, normal_code,
                                           opacity_table)

OPACITY_TABLES = 32
"""Opacity-correction tables interpolated per pixel (thesis §4.2.3; error bound in the module notes)."""


def opacity_tables(ratios, correct=True, tables=OPACITY_TABLES):
    """Per-pixel opacity-correction tables.

    Parameters
    ----------
    ratios : numpy.ndarray, shape (h, w)
        ``Δ/Δ0`` of each intermediate pixel's ray.
    correct : bool
        ``False``: every table is the uncorrected ``α``.

    Returns
    -------
    tables : numpy.ndarray, (n, 256) float64
    index : numpy.ndarray, (h, w) int32
        The lower bracketing table of each pixel (``n − 2`` at most).
    weight : numpy.ndarray, (h, w) float64
        Interpolation weight of table ``index + 1``.
    """
    ratios = np.asarray(ratios, dtype=np.float64)
    low = float(ratios.min()) if ratios.size else 1.0
    high = float(ratios.max()) if ratios.size else 1.0
    n = tables if high > low else 2
    levels = np.linspace(low, high, n) if high > low else np.array([low, low])
    table = np.stack([opacity_table(r, correct) for r in levels])
    if high > low:
        position = (ratios - low) / (high - low) * (n - 1)
        index = np.minimum(np.floor(position), n - 2).astype(np.int32)
        weight = position - index
    else:
        index = np.zeros(ratios.shape, dtype=np.int32)
        weight = np.zeros(ratios.shape)
    return table, np.ascontiguousarray(index), np.ascontiguousarray(weight)


@njit(inline="always", **_JIT)
def _overlap(i, c, half_width):
    """Length of ``[i − ½, i + ½] ∩ [c − half_width, c + half_width]``."""
    lo = max(i - 0.5, c - half_width)
    hi = min(i + 0.5, c + half_width)
    return max(hi - lo, 0.0)


@njit(**_JIT)
def _composite_task(task, r0, r1, slices, scales, uoff, voff, fmax, ni, nj, lengths, run_offsets, data_offsets, voxels,
                    gradients, optabs, pix_table, pix_weight, coltab, shadetab, shade_mode, nmat, light, half, has_half,
                    params, early, threshold, rank_mode, skip_empty, image, link, rank, runend, counters):
    """Clear intermediate rows ``r0 .. r1 − 1`` and composite every slice into them, front to back (module notes)."""
    height, width = image.shape[0], image.shape[1]
    clear_rows(image, link, r0, r1)
    m00, m01, m02 = nmat[0, 0], nmat[0, 1], nmat[0, 2]
    m10, m11, m12 = nmat[1, 0], nmat[1, 1], nmat[1, 2]
    m20, m21, m22 = nmat[2, 0], nmat[2, 1], nmat[2, 2]
    lx, ly, lz = light[0], light[1], light[2]
    hx, hy, hz = half[0], half[1], half[2]
    ambient, diffuse, specular, shininess = params[0], params[1], params[2], params[3]
    shaded = shade_mode != SHADE_NONE
    # Run cursors and row weights, one per footprint scanline.
    c_run = np.zeros(fmax, dtype=np.int64)
    c_start = np.zeros(fmax, dtype=np.int64)
    c_end = np.zeros(fmax, dtype=np.int64)
    c_nt = np.zeros(fmax, dtype=np.bool_)
    c_dat = np.zeros(fmax, dtype=np.int64)
    c_weight = np.zeros(fmax, dtype=np.float64)
    samples = runs = finds = creates = skipped = 0  # this task's counters
    for s in range(slices.shape[0]):
        k = slices[s]
        f = scales[k]
        inv = 1.0 / f
        u0 = uoff[k]
        v0 = voff[k]
        hv = 0.5 + 0.5 * inv  # half support of the filter in voxels
        hp = 0.5 * inv  # half width of a pixel in voxels
        row_lo = max(max(r0, 0), int(math.floor(v0 - hv * f)) + 1)
        row_hi = min(min(r1, height) - 1, int(math.ceil(v0 + (nj - 1 + hv) * f)) - 1)
        col_lo = max(0, int(math.floor(u0 - hv * f)) + 1)
        col_hi = min(width - 1, int(math.ceil(u0 + (ni - 1 + hv) * f)) - 1)
        for row in range(row_lo, row_hi + 1):
            cv = (row - v0) * inv
            j_lo = max(0, int(math.floor(cv - hv)) + 1)
            j_hi = min(nj - 1, int(math.ceil(cv + hv)) - 1)
            nf = min(j_hi - j_lo + 1, fmax)
            if nf <= 0:
                continue
            for q in range(nf):
                sl = k * nj + j_lo + q
                c_run[q] = run_offsets[sl]
                c_start[q] = 0
                c_end[q] = np.int64(lengths[c_run[q]])
                c_nt[q] = False
                c_dat[q] = data_offsets[sl]
                c_weight[q] = f * _overlap(j_lo + q, cv, hp)
            x = col_lo
            while x <= col_hi:
                p = x
                if early and link[row, p] != 0:
                    if rank_mode:
                        qq = runend[row, _root_rank(link, row, p)]
                    else:
                        qq = p
                        while link[row, qq] != 0:
                            qq += link[row, qq]
                        y = p
                        while y != qq:
                            nxt = y + link[row, y]
                            link[row, y] = qq - y
                            y = nxt
                    finds += 1
                    skipped += min(qq, col_hi + 1) - x
                    x = qq
                    continue
                cu = (x - u0) * inv
                i_lo = max(0, int(math.floor(cu - hv)) + 1)
                i_hi = min(ni - 1, int(math.ceil(cu + hv)) - 1)
                if i_lo > i_hi:
                    x += 1
                    continue
                # Bring every cursor to the run holding i_lo; find whether any footprint voxel can be non-transparent.
                empty = True
                next_nt = BIG
                for q in range(nf):
                    while i_lo >= c_end[q]:
                        if c_nt[q]:
                            c_dat[q] += c_end[q] - c_start[q]
                        c_start[q] = c_end[q]
                        c_run[q] += 1
                        c_end[q] = c_start[q] + lengths[c_run[q]]
                        c_nt[q] = not c_nt[q]
                        runs += 1
                    if c_nt[q] or c_end[q] <= i_hi:
                        empty = False
                    elif c_end[q] < next_nt:
                        next_nt = c_end[q]
                if skip_empty and empty:
                    if next_nt >= ni:
                        break
                    # The first pixel whose footprint reaches voxel next_nt (one early, for rounding).
                    landing = int(math.floor(u0 + f * (next_nt - hv))) + 1 - 1
                    x = max(x + 1, landing)
                    continue
                sr = sg = sb = sa = 0.0
                tb = pix_table[row, p]
                tw = pix_weight[row, p]
                for q in range(nf):
                    wj = c_weight[q]
                    run = c_run[q]
                    start = c_start[q]
                    end = c_end[q]
                    nt = c_nt[q]
                    dat = c_dat[q]
                    for i in range(i_lo, i_hi + 1):
                        while i >= end:
                            if nt:
                                dat += end - start
                            start = end
                            run += 1
                            end = start + lengths[run]
                            nt = not nt
                        if not nt:
                            continue
                        index = dat + i - start
                        record = voxels[index]
                        opacity = record & 255
                        if opacity == 0:
                            continue
                        a0 = optabs[tb, opacity]
                        alpha = a0 + tw * (optabs[tb + 1, opacity] - a0)
                        ci = colour_index(record)
                        fs = 1.0
                        hs = 0.0
                        if shade_mode == SHADE_LUT:
                            fs = shadetab[normal_code(record), 0]
                            hs = shadetab[normal_code(record), 1]
                        elif shade_mode == SHADE_PROCEDURAL:
                            fs, hs = _procedural(gradients[index, 0], gradients[index, 1], gradients[index, 2],
                                                 m00, m01, m02, m10, m11, m12, m20, m21, m22, lx, ly, lz, hx, hy, hz,
                                                 has_half, ambient, diffuse, specular, shininess)
                        vr, vg, vb, va = _premultiply(alpha, coltab[ci, 0], coltab[ci, 1], coltab[ci, 2], fs, hs,
                                                      shaded)
                        weight = wj * f * _overlap(i, cu, hp)
                        sr += weight * vr
                        sg += weight * vg
                        sb += weight * vb
                        sa += weight * va
                samples += 1
                if sa > 0.0:
                    transparency = 1.0 - np.float64(image[row, p, 3])
                    image[row, p, 0] += transparency * sr
                    image[row, p, 1] += transparency * sg
                    image[row, p, 2] += transparency * sb
                    image[row, p, 3] = image[row, p, 3] + transparency * sa
                    if early and image[row, p, 3] >= threshold:
                        creates += 1
                        if rank_mode:
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
                x += 1

    counters[task, C_SAMPLES] = samples
    counters[task, C_RUNS] = runs
    counters[task, C_FINDS] = finds
    counters[task, C_CREATES] = creates
    counters[task, C_SKIPPED] = skipped

@njit(parallel=True, **_JIT)
def composite(workers, steal, task_size, queue_tasks, queue_start, queue_next, worker_stats, slices, scales, uoff,
              voff, fmax, ni, nj, lengths, run_offsets, data_offsets, voxels, gradients, optabs, pix_table, pix_weight,
              coltab, shadetab, shade_mode, nmat, light, half, has_half, params, early, threshold, rank_mode,
              skip_empty, image, link, rank, runend, counters):
    """Clear the intermediate image and composite every slice into it; tasks dealt as in
    :func:`renderers.shearwarp.composite.composite`."""
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
                _composite_task(task, r0, r1, slices, scales, uoff, voff, fmax, ni, nj, lengths, run_offsets, data_offsets,
                                voxels, gradients, optabs, pix_table, pix_weight, coltab, shadetab, shade_mode, nmat,
                                light, half, has_half, params, early, threshold, rank_mode, skip_empty, image, link,
                                rank, runend, counters)
                samples += counters[task, C_SAMPLES]
                done += 1
        worker_stats[w, 0] = done
        worker_stats[w, 1] = samples
