"""Numba kernels of the reference ray caster (CONVENTIONS, Volumes to Shading and compositing).

The kernels take the scene packed into flat arrays by :mod:`renderers.reference.renderer` and
write one pixel per ray. Everything is evaluated in double precision (the volume itself is a
normalised float32 copy), with ``fastmath`` off so that results are bit-reproducible; each
pixel is computed independently and counters are summed per image row, so the image does not
depend on how rows are scheduled on threads.

Conventions implemented here
----------------------------
* Reconstruction: trilinear, clamp-to-edge, cell-centred samples. A point ``p`` in a volume's
  object space has continuous voxel coordinates ``u = p/s − 0.5`` per axis (voxel ``i`` sits at
  ``u = i``); coordinates are clamped to ``[0, n − 1]`` (what a ``GL_CLAMP_TO_EDGE`` texture does).
* Gradient: central differences of the trilinear field one voxel apart in object space,
  ``(f(p + s_x e_x) − f(p − s_x e_x)) / (2 s_x)`` per axis (the on-the-fly GPU estimator).
* Classification: post-classification, linear interpolation between table entries, entry ``i``
  at ``s = i/(N − 1)``, clamped at the ends (:meth:`core.transfer.TransferFunction.lookup`).
* Sampling: one world step ``Δ`` for all volumes. Each volume's span on the ray,
  ``[t_entry, t_exit]``, comes from a slab test in its object space, clipped to ``t >= 0``;
  ``t_first`` is the smallest ``t_entry`` (the entry into the union of the boxes). The ray is
  cut into cells ``[a_k, b_k] = [t_first + k·Δ, t_first + (k + 1)·Δ]``, both ends evaluated
  with exactly these expressions wherever they are used, so neighbouring cells share their
  boundary bit for bit and nothing is counted twice or left out. A volume samples every cell
  whose overlap ``[lo, hi] = [a_k, b_k] ∩ [t_entry, t_exit]`` is longer than ``min_overlap``
  (``MIN_OVERLAP·Δ``, set by the renderer: the rounding slivers where a depth is a whole
  number of steps are left out); the cells run up to the last such one.
  A cell inside the box samples at ``t_k = t_first + (k + ½)·Δ`` with the full-step
  correction ``α' = 1 − (1 − α)^(|A⁻¹d|·Δ/Δ0)``; a cell the box cuts (only a volume's first
  and last cell can be cut) samples at the overlap's midpoint ``(lo + hi)/2`` with
  ``α' = 1 − (1 − α)^(|A⁻¹d|·(hi − lo)/Δ0)``. Every ray's optical depth through a
  homogeneous box is therefore exact, and a medium whose classified field is smooth along the
  ray converges with the second order of the midpoint rule, box faces included (a sharp
  transfer-function edge inside the box still leaves an ``O(Δ)`` error where the ray crosses
  it). Samples of several volumes in one cell are blended (see :func:`_dvr_ray`).
"""

import math

import numpy as np
from numba import njit, prange, types

MODE_DVR, MODE_MIP, MODE_ISO = 0, 1, 2
MODE_CODES = {"dvr": MODE_DVR, "mip": MODE_MIP, "iso": MODE_ISO}

MAX_GRADIENT = math.sqrt(3.0) / 2.0
"""Normaliser of the gradient-opacity argument (see :mod:`core.transfer`)."""

MAX_BISECTIONS = 64
"""Upper bound on the iso bisection steps, reached only if the tolerance is below rounding."""

_JIT = dict(cache=True, fastmath=False, nogil=True, error_model="numpy")


@njit(**_JIT)
def _axis_cell(u, n):
    """Clamp-to-edge linear filter along one axis: ``(i0, i1, weight of i1)``."""
    top = n - 1
    if u <= 0.0:
        return 0, 0, 0.0
    if u >= top:
        return top, top, 0.0
    i0 = int(math.floor(u))
    return i0, i0 + 1, u - i0


@njit(**_JIT)
def _trilinear(data, off, nx, ny, nz, u, v, w):
    """Trilinear value at voxel coordinates ``(u, v, w)`` of the volume stored at ``data[off:]``."""
    x0, x1, fx = _axis_cell(u, nx)
    y0, y1, fy = _axis_cell(v, ny)
    z0, z1, fz = _axis_cell(w, nz)
    r00 = off + (z0 * ny + y0) * nx
    r01 = off + (z0 * ny + y1) * nx
    r10 = off + (z1 * ny + y0) * nx
    r11 = off + (z1 * ny + y1) * nx
    gx = 1.0 - fx
    c00 = data[r00 + x0] * gx + data[r00 + x1] * fx
    c01 = data[r01 + x0] * gx + data[r01 + x1] * fx
    c10 = data[r10 + x0] * gx + data[r10 + x1] * fx
    c11 = data[r11 + x0] * gx + data[r11 + x1] * fx
    gy = 1.0 - fy
    return (c00 * gy + c01 * fy) * (1.0 - fz) + (c10 * gy + c11 * fy) * fz


@njit(**_JIT)
def _gradient(data, off, nx, ny, nz, u, v, w, sx, sy, sz):
    """Object-space gradient by central differences one voxel apart (clamp-to-edge)."""
    gx = (_trilinear(data, off, nx, ny, nz, u + 1.0, v, w) - _trilinear(data, off, nx, ny, nz, u - 1.0, v, w)) / (2.0 * sx)
    gy = (_trilinear(data, off, nx, ny, nz, u, v + 1.0, w) - _trilinear(data, off, nx, ny, nz, u, v - 1.0, w)) / (2.0 * sy)
    gz = (_trilinear(data, off, nx, ny, nz, u, v, w + 1.0) - _trilinear(data, off, nx, ny, nz, u, v, w - 1.0)) / (2.0 * sz)
    return gx, gy, gz


@njit(**_JIT)
def _table_position(x, size):
    """Lower entry and weight of ``x`` in [0, 1] on a table of ``size`` entries (clamped)."""
    if x <= 0.0:
        return 0, 0.0
    if x >= 1.0:
        return size - 2, 1.0
    f = x * (size - 1)
    i0 = min(int(math.floor(f)), size - 2)
    return i0, f - i0


@njit(**_JIT)
def _tf_channel(tf, vol, size, s, channel):
    i0, w = _table_position(s, size)
    return tf[vol, i0, channel] * (1.0 - w) + tf[vol, i0 + 1, channel] * w


@njit(**_JIT)
def _gradient_factor(gtab, vol, size, u):
    i0, w = _table_position(u, size)
    return gtab[vol, i0] * (1.0 - w) + gtab[vol, i0 + 1] * w


@njit(**_JIT)
def _blinn_phong(r, g, b, gx, gy, gz, nmat, vol, light, half, has_half, shading):
    """Two-sided Blinn–Phong of colour ``(r, g, b)`` (the :class:`core.scene.Shading` formula).

    The object-space gradient becomes a world-space normal through the normal matrix
    ``A^{-T}`` of the volume's object→world transform, so non-rigid transforms shade correctly.
    """
    nx = nmat[vol, 0, 0] * gx + nmat[vol, 0, 1] * gy + nmat[vol, 0, 2] * gz
    ny = nmat[vol, 1, 0] * gx + nmat[vol, 1, 1] * gy + nmat[vol, 1, 2] * gz
    nz = nmat[vol, 2, 0] * gx + nmat[vol, 2, 1] * gy + nmat[vol, 2, 2] * gz
    norm = math.sqrt(nx * nx + ny * ny + nz * nz)
    ambient, diffuse, specular, shininess = shading[0], shading[1], shading[2], shading[3]
    if norm == 0.0:
        factor = ambient
        highlight = 0.0
    else:
        # |N·L| and |N·H| make the sign of N = −∇s/|∇s| irrelevant (two-sided lighting).
        factor = ambient + diffuse * abs(nx * light[0] + ny * light[1] + nz * light[2]) / norm
        highlight = 0.0
        if has_half:
            highlight = specular * (abs(nx * half[0] + ny * half[1] + nz * half[2]) / norm) ** shininess
    return (min(max(r * factor + highlight, 0.0), 1.0),
            min(max(g * factor + highlight, 0.0), 1.0),
            min(max(b * factor + highlight, 0.0), 1.0))


@njit(**_JIT)
def _boundary_cell(k, t_first, step, t_in, t_out, min_overlap):
    """A volume's sample in a cell that may be cut by its box: ``(t, L, full)``, ``L = 0`` if none.

    ``[t_in, t_out]`` is the volume's span on the ray. A cell the box covers whole samples at
    ``t_k`` with ``L = Δ``; a cut one at the midpoint of its overlap, of length ``L``.
    """
    a = t_first + k * step
    b = t_first + (k + 1) * step
    if t_in <= a and b <= t_out:
        return t_first + (k + 0.5) * step, step, True
    lo = max(a, t_in)
    hi = min(b, t_out)
    length = hi - lo
    if length <= min_overlap:
        return 0.0, 0.0, False
    return 0.5 * (lo + hi), length, False


@njit(**_JIT)
def _dvr_ray(data, offsets, dims, spacing, tf, tf_size, gtab, gtab_size, ref_step, nmat, phong, shading,
             light, half, has_half, t_first, step, count, k_lo, k_hi, t_in, t_out, min_overlap, base, slope,
             ratio, length):
    """Front-to-back emission–absorption along one ray: ``(r, g, b, a, depth, samples)``.

    Overlapping volumes are blended per cell as in Kainz et al. 2009: premultiplied colours
    and corrected opacities are summed, and a sum of opacities above 1 is clamped to 1 with the
    colour scaled by the same factor (so colour never exceeds alpha). ``depth`` is the nearest
    contributing sample of the first cell that contributes.
    """
    cr = cg = cb = ca = 0.0
    depth = np.nan
    samples = 0
    for k in range(count):
        t_k = t_first + (k + 0.5) * step
        sr = sg = sb = sa = 0.0
        nearest = np.inf
        for vol in range(offsets.shape[0]):
            if k < k_lo[vol] or k > k_hi[vol]:
                continue
            t = t_k
            vol_ratio = ratio[vol]
            if k == k_lo[vol] or k == k_hi[vol]:
                # The volume's first and last cells: the only ones its box can cut.
                t, overlap, full = _boundary_cell(k, t_first, step, t_in[vol], t_out[vol], min_overlap)
                if overlap == 0.0:
                    continue
                if not full:
                    vol_ratio = length[vol] * overlap / ref_step[vol]
            off = offsets[vol]
            nx, ny, nz = dims[vol, 0], dims[vol, 1], dims[vol, 2]
            u = base[vol, 0] + t * slope[vol, 0]
            v = base[vol, 1] + t * slope[vol, 1]
            w = base[vol, 2] + t * slope[vol, 2]
            s = _trilinear(data, off, nx, ny, nz, u, v, w)
            samples += 1
            size = tf_size[vol]
            alpha = _tf_channel(tf, vol, size, s, 3)
            # A transparent sample adds exactly nothing, so skipping its shading changes no bit.
            if alpha <= 0.0:
                continue
            gx = gy = gz = 0.0
            have_gradient = False
            if gtab_size[vol] > 0:
                gx, gy, gz = _gradient(data, off, nx, ny, nz, u, v, w,
                                       spacing[vol, 0], spacing[vol, 1], spacing[vol, 2])
                have_gradient = True
                magnitude = math.sqrt(gx * gx + gy * gy + gz * gz)
                alpha *= _gradient_factor(gtab, vol, gtab_size[vol], magnitude * ref_step[vol] / MAX_GRADIENT)
                if alpha <= 0.0:
                    continue
            # α' = 1 − (1 − α)^(L_obj/Δ0), in the log1p/expm1 form that keeps small α accurate.
            alpha = -math.expm1(vol_ratio * math.log1p(-alpha))
            r = _tf_channel(tf, vol, size, s, 0)
            g = _tf_channel(tf, vol, size, s, 1)
            b = _tf_channel(tf, vol, size, s, 2)
            if phong:
                if not have_gradient:
                    gx, gy, gz = _gradient(data, off, nx, ny, nz, u, v, w,
                                           spacing[vol, 0], spacing[vol, 1], spacing[vol, 2])
                r, g, b = _blinn_phong(r, g, b, gx, gy, gz, nmat, vol, light, half, has_half, shading)
            sr += alpha * r
            sg += alpha * g
            sb += alpha * b
            sa += alpha
            if t < nearest:
                nearest = t
        if sa > 0.0:
            if sa > 1.0:
                sr /= sa
                sg /= sa
                sb /= sa
                sa = 1.0
            if np.isnan(depth):
                depth = nearest
            transparency = 1.0 - ca
            cr += transparency * sr
            cg += transparency * sg
            cb += transparency * sb
            ca += transparency * sa
    return cr, cg, cb, ca, depth, samples


@njit(**_JIT)
def _mip_ray(data, offsets, dims, tf, tf_size, t_first, step, count, k_lo, k_hi, t_in, t_out, min_overlap,
             base, slope):
    """Maximum intensity along one ray, classified without opacity correction.

    The maximum is taken over the samples the volumes take (cell midpoints, and overlap
    midpoints in the cells a box cuts). With several volumes the largest normalised scalar of
    any of them wins and is classified by the transfer function of the volume it came from
    (the earlier cell, then the earlier volume, on ties). Returns ``(r, g, b, a, depth,
    samples)``, colour premultiplied.
    """
    best = -1.0
    best_vol = -1
    depth = np.nan
    samples = 0
    for k in range(count):
        t_k = t_first + (k + 0.5) * step
        for vol in range(offsets.shape[0]):
            if k < k_lo[vol] or k > k_hi[vol]:
                continue
            t = t_k
            if k == k_lo[vol] or k == k_hi[vol]:
                t, overlap, full = _boundary_cell(k, t_first, step, t_in[vol], t_out[vol], min_overlap)
                if overlap == 0.0:
                    continue
            s = _trilinear(data, offsets[vol], dims[vol, 0], dims[vol, 1], dims[vol, 2],
                           base[vol, 0] + t * slope[vol, 0], base[vol, 1] + t * slope[vol, 1],
                           base[vol, 2] + t * slope[vol, 2])
            samples += 1
            if s > best:
                best = s
                best_vol = vol
                depth = t
    if best_vol < 0:
        return 0.0, 0.0, 0.0, 0.0, depth, samples
    size = tf_size[best_vol]
    a = _tf_channel(tf, best_vol, size, best, 3)
    return (_tf_channel(tf, best_vol, size, best, 0) * a, _tf_channel(tf, best_vol, size, best, 1) * a,
            _tf_channel(tf, best_vol, size, best, 2) * a, a, depth, samples)


@njit(**_JIT)
def _iso_ray(data, offsets, dims, spacing, tf, tf_size, isovalue, nmat, phong, shading, light, half,
             has_half, t_first, step, count, k_lo, k_hi, t_in, t_out, min_overlap, base, slope, tolerance,
             below, previous, started):
    """First isovalue crossing along one ray: ``(r, g, b, a, depth, samples)``.

    A crossing is a change of ``s < isovalue`` between two consecutive samples of the same
    volume (either direction, so surfaces are seen from inside too; a box face is not a
    surface). It is refined by bisection between the two sample positions until the bracket is
    shorter than ``tolerance``; among volumes crossing in the same cell the nearest refined hit
    wins, and the search stops after that cell. That is the nearest crossing of all, cut cells
    included: a crossing found in cell ``k`` lies before the volume's sample in that cell, which
    is at ``t_k``, or before it where the box ends in that cell. A crossing found in a later
    cell lies after its volume's sample in cell ``k`` or later, which is at ``t_k`` or after
    unless that box ends in cell ``k`` (and then it has no later sample). The colour is the
    volume's transfer-function colour at its isovalue, shaded at the hit; alpha is 1.
    """
    samples = 0
    hit_t = np.inf
    hit_vol = -1
    nvol = offsets.shape[0]
    for vol in range(nvol):
        started[vol] = False
    for k in range(count):
        t_k = t_first + (k + 0.5) * step
        for vol in range(nvol):
            if k < k_lo[vol] or k > k_hi[vol]:
                continue
            t = t_k
            if k == k_lo[vol] or k == k_hi[vol]:
                t, overlap, full = _boundary_cell(k, t_first, step, t_in[vol], t_out[vol], min_overlap)
                if overlap == 0.0:
                    continue
            off = offsets[vol]
            nx, ny, nz = dims[vol, 0], dims[vol, 1], dims[vol, 2]
            s = _trilinear(data, off, nx, ny, nz, base[vol, 0] + t * slope[vol, 0],
                           base[vol, 1] + t * slope[vol, 1], base[vol, 2] + t * slope[vol, 2])
            samples += 1
            now_below = s < isovalue[vol]
            if started[vol] and now_below != below[vol]:
                lo = previous[vol]
                hi = t
                for _ in range(MAX_BISECTIONS):
                    if hi - lo <= tolerance:
                        break
                    mid = 0.5 * (lo + hi)
                    s_mid = _trilinear(data, off, nx, ny, nz, base[vol, 0] + mid * slope[vol, 0],
                                       base[vol, 1] + mid * slope[vol, 1], base[vol, 2] + mid * slope[vol, 2])
                    if (s_mid < isovalue[vol]) == below[vol]:
                        lo = mid
                    else:
                        hi = mid
                refined = 0.5 * (lo + hi)
                if refined < hit_t:
                    hit_t = refined
                    hit_vol = vol
            below[vol] = now_below
            previous[vol] = t
            started[vol] = True
        if hit_vol >= 0:
            break
    if hit_vol < 0:
        return 0.0, 0.0, 0.0, 0.0, np.nan, samples
    vol = hit_vol
    size = tf_size[vol]
    iso = isovalue[vol]
    r = _tf_channel(tf, vol, size, iso, 0)
    g = _tf_channel(tf, vol, size, iso, 1)
    b = _tf_channel(tf, vol, size, iso, 2)
    if phong:
        gx, gy, gz = _gradient(data, offsets[vol], dims[vol, 0], dims[vol, 1], dims[vol, 2],
                               base[vol, 0] + hit_t * slope[vol, 0], base[vol, 1] + hit_t * slope[vol, 1],
                               base[vol, 2] + hit_t * slope[vol, 2], spacing[vol, 0], spacing[vol, 1], spacing[vol, 2])
        r, g, b = _blinn_phong(r, g, b, gx, gy, gz, nmat, vol, light, half, has_half, shading)
    return r, g, b, 1.0, hit_t, samples


@njit(**_JIT)
def _cell_range(t_first, step, t_in, t_out, min_overlap):
    """The cells ``k_lo … k_hi`` in which a volume spanning ``[t_in, t_out]`` takes samples.

    ``k_lo`` is the first cell whose end passes ``t_in + min_overlap`` and ``k_hi`` the last whose
    start is before ``t_out − min_overlap``, found with the same expressions for ``a_k`` and
    ``b_k`` that the sampling loops use (an estimate, then corrected), so every cell strictly
    between them lies inside ``[t_in, t_out]``. ``k_lo > k_hi`` when there is none.
    """
    start = t_in + min_overlap
    k = max(int(math.floor((start - t_first) / step)), 0)
    while k > 0 and t_first + k * step > start:
        k -= 1
    while t_first + (k + 1) * step <= start:
        k += 1
    stop = t_out - min_overlap
    j = int(math.ceil((stop - t_first) / step)) - 1
    while t_first + (j + 1) * step < stop:
        j += 1
    while j >= 0 and t_first + j * step >= stop:
        j -= 1
    return k, j


_f8, _f4, _i8 = types.float64, types.float32, types.int64
_RENDER_SIGNATURE = types.void(
    _i8, _i8[::1],                              # mode, row order
    _f8[:, :, ::1], _f8[:, :, ::1],             # ray origins, unit directions (H, W, 3), world
    _f4[::1], _i8[::1], _i8[:, ::1], _f8[:, ::1],  # packed data, offsets, dims (nx, ny, nz), spacing
    _f8[:, :, ::1], _f8[:, :, ::1],             # world→object (n, 3, 4), normal matrices (n, 3, 3)
    _f8[:, :, ::1], _i8[::1],                   # transfer tables (n, N, 4), their sizes
    _f8[:, ::1], _i8[::1],                      # gradient tables (n, M), sizes (0: none)
    _f8[::1], _f8[::1],                         # reference steps Δ0 (object units), isovalues
    _f8, _f8,                                   # world step, shortest overlap sampled
    _i8, _f8[::1], _f8[::1], _f8,               # phong flag, (ka, kd, ks, n), light, iso tolerance
    _f4[:, :, ::1], _f8[:, ::1], _i8[::1], _i8[::1],  # out: image, depth, hits and samples per row
)


@njit(_RENDER_SIGNATURE, parallel=True, **_JIT)
def render(mode, row_order, origins, directions, data, offsets, dims, spacing, world_to_object, nmat, tf, tf_size,
           gtab, gtab_size, ref_step, isovalue, step, min_overlap, phong, shading, light, tolerance,
           image, depth, row_hits, row_samples):
    """Cast one ray per pixel into ``image`` (premultiplied RGBA) and ``depth``.

    ``depth`` is the ray parameter (world distance from the ray origin) of the first sample
    that contributed (``dvr``; the nearest one in the first contributing cell), of the maximum
    (``mip``) or of the surface (``iso``); NaN where nothing did. ``row_hits[i]`` counts the
    rays of row ``i`` that enter any volume box and ``row_samples[i]`` the volume samples they
    took (bisection steps not included). ``row_order`` is a permutation of the rows: prange
    hands each thread a contiguous block of it, so interleaving the rows balances pictures
    whose content sits in one band.
    """
    height, width = origins.shape[0], origins.shape[1]
    nvol = offsets.shape[0]
    for i in prange(height):
        row = row_order[i]
        t_in = np.empty(nvol)
        t_out = np.empty(nvol)
        k_lo = np.empty(nvol, np.int64)
        k_hi = np.empty(nvol, np.int64)
        base = np.empty((nvol, 3))
        slope = np.empty((nvol, 3))
        ratio = np.empty(nvol)
        length = np.empty(nvol)
        below = np.zeros(nvol, np.bool_)
        previous = np.zeros(nvol)
        started = np.zeros(nvol, np.bool_)
        half = np.empty(3)
        hits = 0
        samples = 0
        for col in range(width):
            o = origins[row, col]
            d = directions[row, col]
            t_first = np.inf
            for vol in range(nvol):
                m = world_to_object[vol]
                # Slab test in object space; starting at t = 0 clips everything behind the origin.
                lo = 0.0
                hi = np.inf
                length2 = 0.0
                for axis in range(3):
                    po = m[axis, 0] * o[0] + m[axis, 1] * o[1] + m[axis, 2] * o[2] + m[axis, 3]
                    pd = m[axis, 0] * d[0] + m[axis, 1] * d[1] + m[axis, 2] * d[2]
                    length2 += pd * pd
                    size = spacing[vol, axis]
                    extent = dims[vol, axis] * size
                    base[vol, axis] = po / size - 0.5
                    slope[vol, axis] = pd / size
                    if pd == 0.0:
                        if po < 0.0 or po > extent:
                            lo = np.inf
                    else:
                        ta = -po / pd
                        tb = (extent - po) / pd
                        lo = max(lo, min(ta, tb))
                        hi = min(hi, max(ta, tb))
                t_in[vol] = lo
                t_out[vol] = hi
                # |A⁻¹·d| turns a world length on this ray into object units; a full cell is Δ.
                length[vol] = math.sqrt(length2)
                ratio[vol] = length[vol] * step / ref_step[vol]
                if lo < hi:
                    t_first = min(t_first, lo)
            pixel = image[row, col]
            if t_first == np.inf:
                pixel[:] = 0.0
                depth[row, col] = np.nan
                continue
            hits += 1
            count = 0
            for vol in range(nvol):
                if t_in[vol] < t_out[vol]:
                    k_lo[vol], k_hi[vol] = _cell_range(t_first, step, t_in[vol], t_out[vol], min_overlap)
                    count = max(count, k_hi[vol] + 1)
                else:
                    k_lo[vol] = 1
                    k_hi[vol] = 0
            if mode == MODE_MIP:
                r, g, b, a, t_hit, n = _mip_ray(data, offsets, dims, tf, tf_size, t_first, step, count,
                                                k_lo, k_hi, t_in, t_out, min_overlap, base, slope)
            else:
                # Blinn–Phong half vector between the light and V = −d (towards the viewer).
                half[0] = light[0] - d[0]
                half[1] = light[1] - d[1]
                half[2] = light[2] - d[2]
                half_norm = math.sqrt(half[0] ** 2 + half[1] ** 2 + half[2] ** 2)
                has_half = half_norm > 0.0
                if has_half:
                    half[0] /= half_norm
                    half[1] /= half_norm
                    half[2] /= half_norm
                if mode == MODE_DVR:
                    r, g, b, a, t_hit, n = _dvr_ray(data, offsets, dims, spacing, tf, tf_size, gtab, gtab_size,
                                                    ref_step, nmat, phong, shading, light, half, has_half,
                                                    t_first, step, count, k_lo, k_hi, t_in, t_out, min_overlap,
                                                    base, slope, ratio, length)
                else:
                    r, g, b, a, t_hit, n = _iso_ray(data, offsets, dims, spacing, tf, tf_size, isovalue, nmat,
                                                    phong, shading, light, half, has_half, t_first, step, count,
                                                    k_lo, k_hi, t_in, t_out, min_overlap, base, slope, tolerance,
                                                    below, previous, started)
            pixel[0] = r
            pixel[1] = g
            pixel[2] = b
            pixel[3] = a
            depth[row, col] = t_hit
            samples += n
        row_hits[row] = hits
        row_samples[row] = samples
