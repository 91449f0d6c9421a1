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
  Optionally (``dvr`` only) pre-classification: :func:`preclassify` classifies and shades the
  voxels at their centres and the ray interpolates their premultiplied RGBA (the order of the
  1990s casters that shear-warp was compared with); the ground truth stays post-classified.
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
  it). Samples of several volumes in one cell are blended (see :func:`_dvr_ray`). This is
  ``dvr`` only.
* Exact ``mip`` and ``iso`` (:func:`_walk_volume`): no sampling. Each volume's span is walked
  with a 3-D DDA through the cells of its voxel lattice: along each axis the regions
  ``u <= 0`` (clamped), ``[i, i + 1]`` for ``0 <= i <= n − 2`` and ``u >= n − 1`` (clamped),
  boundaries found as ``t = (j − base)/slope`` (no accumulated increments), at most
  ``nx + ny + nz + 1`` segments per volume. On a segment the local coordinates are linear in
  the parameter ``σ ∈ [0, 1]`` (set exactly to 0 or 1 on the boundary planes the segment
  starts or ends on), so the trilinear field is a cubic ``k0 + k1σ + k2σ² + k3σ³`` of the 8
  corner values. ``mip`` takes the maximum over the segment ends and the real roots of the
  derivative inside the segment (closed form), which is the exact maximum of the trilinear
  field; ``iso`` cuts the cubic at those roots into monotone pieces and bisects the crossing in
  the first piece whose end changes ``s < isovalue`` (:func:`_below`) relative to the box entry,
  to ``tolerance`` (a fraction of the segment). Values are evaluated with the same blend as
  :func:`_trilinear`, so a ray through a voxel centre returns that voxel's value bit for bit.
* Lenses (:func:`render_lens`, semantics in :mod:`core.lens`): the lens's interval on the whole
  line comes from the sphere's quadratic (:func:`sphere_interval`) or from clipping the ray
  against half-spaces in the lens's frame (:func:`planes_interval`: a box's slabs, a convex
  mesh's face planes), then is cut to the box span. The ``dvr`` samples are exactly
  :func:`_dvr_ray`'s; each is classified with the lens's tables when it lies in that interval.
  ``mip`` and ``iso`` lenses walk the lattice cells of their segment only (:func:`_walk_volume`
  on ``[lo, hi]``). A tangent ray has an empty interval; no lens test divides by zero or makes NaN.
* Robustness: a ray whose origin or direction is not finite, or whose direction is zero, is a
  transparent pixel with depth NaN before any loop starts; a volume whose span is unbounded (a
  singular transform) is not entered; every loop has a bound (cells of a finite span, DDA
  segments ``<= nx + ny + nz + 1``, :data:`MAX_CELL_CORRECTIONS`, :data:`MAX_BISECTIONS`).
"""

import math

import numpy as np
from numba import njit, prange, types
from numba.extending import intrinsic

from renderers.base.numba_kernels import JIT as _JIT, table_position

MODE_DVR, MODE_MIP, MODE_ISO = 0, 1, 2
MODE_CODES = {"dvr": MODE_DVR, "mip": MODE_MIP, "iso": MODE_ISO}

MAX_GRADIENT = math.sqrt(3.0) / 2.0
"""Normaliser of the gradient-opacity argument (see :mod:`core.transfer`)."""

MAX_BISECTIONS = 64
"""Upper bound on the iso bisection steps, reached only if the tolerance is below rounding."""

MAX_CELL_CORRECTIONS = 64
"""Upper bound on each correction loop of :func:`_cell_range` (finite spans need one step at most)."""


@intrinsic
def stop_requested(typingctx, flag):
    """``flag[0] != 0`` for an int64 array ``flag``, read from memory at every call.

    Another thread sets the flag while a kernel runs (Ctrl-C); the read is an atomic load so
    that the compiler cannot hoist it out of the kernel's loops as it does an ordinary one.
    """
    if not (isinstance(flag, types.Array) and flag.dtype == types.int64):
        return None

    def codegen(context, builder, signature, args):
        array = context.make_array(signature.args[0])(context, builder, args[0])
        value = builder.load_atomic(array.data, ordering="monotonic", align=8)
        return builder.icmp_signed("!=", value, value.type(0))

    return types.boolean(flag), codegen


@njit(**_JIT)
def is_ray(origin, direction):
    """Whether a camera ray is usable: a finite origin and a finite, non-zero direction."""
    for k in range(3):
        if not (math.isfinite(origin[k]) and math.isfinite(direction[k])):
            return False
    return direction[0] != 0.0 or direction[1] != 0.0 or direction[2] != 0.0


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
def _tf_channel(tf, vol, size, s, channel):
    i0, w = table_position(s, size)
    return tf[vol, i0, channel] * (1.0 - w) + tf[vol, i0 + 1, channel] * w


@njit(**_JIT)
def _gradient_factor(gtab, vol, size, u):
    i0, w = table_position(u, size)
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
def volume_sample(data, offsets, dims, spacing, tf, tf_size, gtab, gtab_size, ref_step, nmat, phong, shading,
                  light, half, has_half, vol, t, vol_ratio, base, slope, pre):
    """Volume ``vol``'s classified, shaded, opacity-corrected sample at ray parameter ``t``.

    Returns premultiplied ``(r, g, b, α', contributes)``; ``vol_ratio`` is the sample's length in
    units of the volume's ``Δ0``. A transparent sample (α ≤ 0) does not contribute and is not
    shaded. With a non-empty ``pre`` (see :func:`preclassify`) the voxels' classified RGBA is
    interpolated instead of the scalar.
    """
    off = offsets[vol]
    nx, ny, nz = dims[vol, 0], dims[vol, 1], dims[vol, 2]
    u = base[vol, 0] + t * slope[vol, 0]
    v = base[vol, 1] + t * slope[vol, 1]
    w = base[vol, 2] + t * slope[vol, 2]
    if pre.shape[1] > 0:
        alpha = _trilinear(pre[3], off, nx, ny, nz, u, v, w)
        if alpha <= 0.0:
            return 0.0, 0.0, 0.0, 0.0, False
        # The interpolated colour is premultiplied by the Δ0 opacity: rescale it to α'.
        corrected = -math.expm1(vol_ratio * math.log1p(-min(alpha, 1.0)))
        scale = corrected / alpha
        return (scale * _trilinear(pre[0], off, nx, ny, nz, u, v, w), scale * _trilinear(pre[1], off, nx, ny, nz, u, v, w),
                scale * _trilinear(pre[2], off, nx, ny, nz, u, v, w), corrected, True)
    s = _trilinear(data, off, nx, ny, nz, u, v, w)
    size = tf_size[vol]
    alpha = _tf_channel(tf, vol, size, s, 3)
    # A transparent sample adds exactly nothing, so skipping its shading changes no bit.
    if alpha <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, False
    gx = gy = gz = 0.0
    have_gradient = False
    if gtab_size[vol] > 0:
        gx, gy, gz = _gradient(data, off, nx, ny, nz, u, v, w, spacing[vol, 0], spacing[vol, 1], spacing[vol, 2])
        have_gradient = True
        magnitude = math.sqrt(gx * gx + gy * gy + gz * gz)
        alpha *= _gradient_factor(gtab, vol, gtab_size[vol], magnitude * ref_step[vol] / MAX_GRADIENT)
        if alpha <= 0.0:
            return 0.0, 0.0, 0.0, 0.0, False
    # α' = 1 − (1 − α)^(L_obj/Δ0), in the log1p/expm1 form that keeps small α accurate.
    alpha = -math.expm1(vol_ratio * math.log1p(-alpha))
    r = _tf_channel(tf, vol, size, s, 0)
    g = _tf_channel(tf, vol, size, s, 1)
    b = _tf_channel(tf, vol, size, s, 2)
    if phong:
        if not have_gradient:
            gx, gy, gz = _gradient(data, off, nx, ny, nz, u, v, w, spacing[vol, 0], spacing[vol, 1], spacing[vol, 2])
        r, g, b = _blinn_phong(r, g, b, gx, gy, gz, nmat, vol, light, half, has_half, shading)
    return alpha * r, alpha * g, alpha * b, alpha, True


@njit(**_JIT)
def _dvr_ray(data, offsets, dims, spacing, tf, tf_size, gtab, gtab_size, ref_step, nmat, phong, shading,
             light, half, has_half, t_first, step, count, k_lo, k_hi, t_in, t_out, min_overlap, base, slope,
             ratio, length, pre):
    """Front-to-back emission–absorption along one ray: ``(r, g, b, a, depth, samples)``.

    Overlapping volumes are blended per cell as in Kainz et al. 2009: premultiplied colours
    and corrected opacities are summed, and a sum of opacities above 1 is clamped to 1 with the
    colour scaled by the same factor (so colour never exceeds alpha). ``depth`` is the nearest
    contributing sample of the first cell that contributes. With a non-empty ``pre`` (see
    :func:`preclassify`) the sample interpolates the voxels' classified, shaded, premultiplied
    RGBA instead of classifying the interpolated scalar.
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
            samples += 1
            ar, ag, ab, aa, hit = volume_sample(data, offsets, dims, spacing, tf, tf_size, gtab, gtab_size, ref_step,
                                                nmat, phong, shading, light, half, has_half, vol, t, vol_ratio,
                                                base, slope, pre)
            if hit:
                sr += ar
                sg += ag
                sb += ab
                sa += aa
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
def _below(s, iso):
    """The iso state of a value: ``s < iso``. A crossing is a change of this state along the ray."""
    return s < iso


@njit(**_JIT)
def _region(u, slope, n):
    """Lattice region of voxel coordinate ``u`` on an axis of ``n`` voxels, for a ray moving by ``slope``.

    Region ``c`` is ``[c, c + 1]`` for ``0 <= c <= n − 2``; region ``−1`` is ``u <= 0`` and region
    ``n − 1`` is ``u >= n − 1`` (the clamp-to-edge borders, where the field is constant along the
    axis). A ``u`` exactly on a boundary belongs to the region the ray moves into.
    """
    c = math.floor(u)
    if slope < 0.0 and u == c:
        c -= 1.0
    if c < -1.0:
        return -1
    if c > n - 1.0:
        return n - 1
    return int(c)


@njit(**_JIT)
def _crossing(c, slope, base, n):
    """Ray parameter where the ray leaves region ``c`` of an axis through its far side (inf: never)."""
    if slope > 0.0:
        if c + 1 > n - 1:
            return np.inf
        return (c + 1 - base) / slope
    if slope < 0.0:
        if c < 0:
            return np.inf
        return (c - base) / slope
    return np.inf


@njit(**_JIT)
def _axis_span(c, n, base, slope, t0, t1, entered, leaving):
    """Corner indices and local coordinates at both ends of a segment in region ``c`` of an axis.

    Returns ``(i0, i1, f0, f1)``: the two voxel indices the axis blends (equal in a clamped
    region, where the local coordinate is 0) and the local coordinate in ``[0, 1]`` at ``t0`` and
    ``t1``. Where the segment starts (``entered``) or ends (``leaving``) on a boundary of this
    axis the coordinate is set to that boundary exactly, so a ray through a voxel centre
    evaluates that voxel's value bit for bit.
    """
    if c < 0:
        return 0, 0, 0.0, 0.0
    if c >= n - 1:
        return n - 1, n - 1, 0.0, 0.0
    if entered:
        f0 = 0.0 if slope > 0.0 else 1.0
    else:
        f0 = min(max(base + t0 * slope - c, 0.0), 1.0)
    if leaving:
        f1 = 1.0 if slope > 0.0 else 0.0
    else:
        f1 = min(max(base + t1 * slope - c, 0.0), 1.0)
    return c, c + 1, f0, f1


@njit(**_JIT)
def _blend(c000, c100, c010, c110, c001, c101, c011, c111, fx, fy, fz):
    """Trilinear blend of a cell's corners ``c_xyz`` at local coordinates (the arithmetic of :func:`_trilinear`)."""
    gx = 1.0 - fx
    c00 = c000 * gx + c100 * fx
    c01 = c010 * gx + c110 * fx
    c10 = c001 * gx + c101 * fx
    c11 = c011 * gx + c111 * fx
    gy = 1.0 - fy
    return (c00 * gy + c01 * fy) * (1.0 - fz) + (c10 * gy + c11 * fy) * fz


@njit(**_JIT)
def _stationary_points(c000, c100, c010, c110, c001, c101, c011, c111, x0, dx, y0, dy, z0, dz):
    """Roots in ``(0, 1)``, ascending, of the derivative of the cubic ``f(σ)`` on a segment.

    Along the segment the local coordinates are ``x = x0 + dx·σ`` (likewise ``y``, ``z``), and
    the trilinear field ``A + Bx + Cy + Dz + Exy + Fxz + Gyz + Hxyz`` becomes
    ``k0 + k1σ + k2σ² + k3σ³``; ``f′ = k1 + 2k2σ + 3k3σ²`` is solved in closed form (the
    cancellation-free quadratic formula). Returns ``(count, r0, r1)``.
    """
    b = c100 - c000
    c = c010 - c000
    d = c001 - c000
    e = c110 - c100 - c010 + c000
    f = c101 - c100 - c001 + c000
    g = c011 - c010 - c001 + c000
    h = c111 - c110 - c101 - c011 + c100 + c010 + c001 - c000
    k1 = (b * dx + c * dy + d * dz + e * (x0 * dy + dx * y0) + f * (x0 * dz + dx * z0) + g * (y0 * dz + dy * z0)
          + h * (dx * y0 * z0 + x0 * dy * z0 + x0 * y0 * dz))
    k2 = e * dx * dy + f * dx * dz + g * dy * dz + h * (dx * dy * z0 + dx * y0 * dz + x0 * dy * dz)
    k3 = h * dx * dy * dz
    qa = 3.0 * k3
    qb = 2.0 * k2
    qc = k1
    r0 = r1 = 2.0
    if qa == 0.0:
        if qb != 0.0:
            r0 = -qc / qb
    else:
        disc = qb * qb - 4.0 * qa * qc
        if disc >= 0.0:
            q = -0.5 * (qb + math.copysign(math.sqrt(disc), qb))
            r0 = q / qa
            r1 = qc / q if q != 0.0 else r0
            if r1 < r0:
                r0, r1 = r1, r0
    count = 0
    first = second = 0.0
    if 0.0 < r0 < 1.0:
        first = r0
        count = 1
    if 0.0 < r1 < 1.0 and r1 != r0:
        if count == 0:
            first = r1
        else:
            second = r1
        count += 1
    return count, first, second


@njit(**_JIT)
def _walk_volume(data, off, nx, ny, nz, bx, by, bz, sx, sy, sz, t_in, t_out, iso_mode, iso, tolerance, t_stop,
                 entry_below=-1):
    """Walk one ray through one volume's lattice cells on ``[t_in, t_out]``: ``(value, t, segments)``.

    A 3-D DDA over the regions of :func:`_region` (interior cells and the clamp-to-edge borders)
    cuts the span into segments inside one lattice cell each; on a segment the trilinear field
    is a cubic in the ray parameter (:func:`_stationary_points`). ``segments`` counts the
    segments evaluated; the walk takes at most ``nx + ny + nz + 1`` of them (each boundary of
    each axis is crossed at most once), and the loop is bounded by that.

    ``mip`` (``iso_mode`` false): ``value`` is the exact maximum of the field on the span
    (largest of the segment ends and the stationary points inside the segments) and ``t`` the
    first place it is reached. A segment whose largest corner does not exceed the running
    maximum is passed over (the field in a cell never exceeds its largest corner).

    ``iso``: ``t`` is the first crossing (``inf`` if none): the first place where
    :func:`_below` differs from its value at ``t_in`` (or from ``entry_below``, 0 or 1, where the
    state was taken elsewhere: a volume clipped by geometry keeps its box entry's). Each segment
    is cut at the stationary points into monotone pieces; in the first piece whose end has the
    other state, the crossing is bracketed and bisected until the bracket is at most ``tolerance``
    of the segment. The walk stops at ``t_stop`` (a nearer hit of another volume). ``value`` is
    unused (0).
    """
    t0 = t_in
    cx = _region(bx + t0 * sx, sx, nx)
    cy = _region(by + t0 * sy, sy, ny)
    cz = _region(bz + t0 * sz, sz, nz)
    tx = _crossing(cx, sx, bx, nx)
    ty = _crossing(cy, sy, by, ny)
    tz = _crossing(cz, sz, bz, nz)
    ex = ey = ez = False
    best = -np.inf
    best_t = np.nan
    hit_t = np.inf
    below = False
    segments = 0
    for _ in range(nx + ny + nz + 4):
        if iso_mode and t0 >= t_stop:
            break
        t_next = min(tx, min(ty, tz))
        last = not t_next < t_out
        t1 = t_out if last else max(t_next, t0)
        lx = (not last) and tx == t_next
        ly = (not last) and ty == t_next
        lz = (not last) and tz == t_next
        x0i, x1i, fx0, fx1 = _axis_span(cx, nx, bx, sx, t0, t1, ex, lx)
        y0i, y1i, fy0, fy1 = _axis_span(cy, ny, by, sy, t0, t1, ey, ly)
        z0i, z1i, fz0, fz1 = _axis_span(cz, nz, bz, sz, t0, t1, ez, lz)
        r00 = off + (z0i * ny + y0i) * nx
        r01 = off + (z0i * ny + y1i) * nx
        r10 = off + (z1i * ny + y0i) * nx
        r11 = off + (z1i * ny + y1i) * nx
        c000 = np.float64(data[r00 + x0i])
        c100 = np.float64(data[r00 + x1i])
        c010 = np.float64(data[r01 + x0i])
        c110 = np.float64(data[r01 + x1i])
        c001 = np.float64(data[r10 + x0i])
        c101 = np.float64(data[r10 + x1i])
        c011 = np.float64(data[r11 + x0i])
        c111 = np.float64(data[r11 + x1i])
        segments += 1
        length = t1 - t0
        if not iso_mode:
            top = max(max(max(c000, c100), max(c010, c110)), max(max(c001, c101), max(c011, c111)))
            if top > best:
                v = _blend(c000, c100, c010, c110, c001, c101, c011, c111, fx0, fy0, fz0)
                if v > best:
                    best = v
                    best_t = t0
                dx = fx1 - fx0
                dy = fy1 - fy0
                dz = fz1 - fz0
                count, r0, r1 = _stationary_points(c000, c100, c010, c110, c001, c101, c011, c111,
                                                   fx0, dx, fy0, dy, fz0, dz)
                for j in range(count):
                    r = r0 if j == 0 else r1
                    v = _blend(c000, c100, c010, c110, c001, c101, c011, c111, fx0 + dx * r, fy0 + dy * r, fz0 + dz * r)
                    if v > best:
                        best = v
                        best_t = t0 + r * length
                v = _blend(c000, c100, c010, c110, c001, c101, c011, c111, fx1, fy1, fz1)
                if v > best:
                    best = v
                    best_t = t1
        else:
            if segments == 1:
                below = (_below(_blend(c000, c100, c010, c110, c001, c101, c011, c111, fx0, fy0, fz0), iso)
                         if entry_below < 0 else entry_below == 1)
            if below:
                top = max(max(max(c000, c100), max(c010, c110)), max(max(c001, c101), max(c011, c111)))
                possible = not _below(top, iso)
            else:
                bottom = min(min(min(c000, c100), min(c010, c110)), min(min(c001, c101), min(c011, c111)))
                possible = _below(bottom, iso)
            if possible:
                v = _blend(c000, c100, c010, c110, c001, c101, c011, c111, fx0, fy0, fz0)
                if _below(v, iso) != below:
                    hit_t = t0
                    break
                dx = fx1 - fx0
                dy = fy1 - fy0
                dz = fz1 - fz0
                count, r0, r1 = _stationary_points(c000, c100, c010, c110, c001, c101, c011, c111,
                                                   fx0, dx, fy0, dy, fz0, dz)
                lo = 0.0
                for j in range(count + 1):
                    hi = 1.0 if j == count else (r0 if j == 0 else r1)
                    v = _blend(c000, c100, c010, c110, c001, c101, c011, c111, fx0 + dx * hi, fy0 + dy * hi, fz0 + dz * hi)
                    if _below(v, iso) != below:
                        # Monotone on [lo, hi]: one crossing, bracketed; bisect it.
                        for _ in range(MAX_BISECTIONS):
                            if hi - lo <= tolerance:
                                break
                            mid = 0.5 * (lo + hi)
                            v = _blend(c000, c100, c010, c110, c001, c101, c011, c111,
                                       fx0 + dx * mid, fy0 + dy * mid, fz0 + dz * mid)
                            if _below(v, iso) == below:
                                lo = mid
                            else:
                                hi = mid
                        hit_t = t0 + 0.5 * (lo + hi) * length
                        break
                    lo = hi
                if hit_t < np.inf:
                    break
        if last:
            break
        ex = lx
        ey = ly
        ez = lz
        if lx:
            cx += 1 if sx > 0.0 else -1
            tx = _crossing(cx, sx, bx, nx)
        if ly:
            cy += 1 if sy > 0.0 else -1
            ty = _crossing(cy, sy, by, ny)
        if lz:
            cz += 1 if sz > 0.0 else -1
            tz = _crossing(cz, sz, bz, nz)
        t0 = t1
    if iso_mode:
        return 0.0, hit_t, segments
    return best, best_t, segments


@njit(**_JIT)
def _mip_ray(data, offsets, dims, tf, tf_size, t_in, t_out, min_overlap, base, slope):
    """Exact maximum intensity along one ray, classified without opacity correction.

    Each volume whose span ``[t_in, t_out]`` is longer than ``min_overlap`` is walked by
    :func:`_walk_volume`, which finds the maximum of its trilinear field on the span exactly
    (independent of the step). With several volumes the largest normalised scalar of any of them
    wins and is classified by the transfer function of the volume it came from (on ties the
    nearer maximum, then the earlier volume). Returns ``(r, g, b, a, depth, samples)``, colour
    premultiplied; ``samples`` counts the lattice-cell segments walked.
    """
    best = -1.0
    best_vol = -1
    depth = np.nan
    samples = 0
    for vol in range(offsets.shape[0]):
        if not t_out[vol] - t_in[vol] > min_overlap:
            continue
        value, t, n = _walk_volume(data, offsets[vol], dims[vol, 0], dims[vol, 1], dims[vol, 2],
                                   base[vol, 0], base[vol, 1], base[vol, 2], slope[vol, 0], slope[vol, 1],
                                   slope[vol, 2], t_in[vol], t_out[vol], False, 0.0, 0.0, np.inf)
        samples += n
        if value > best or (value == best and t < depth):
            best = value
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
             has_half, t_in, t_out, min_overlap, base, slope, tolerance):
    """First isovalue crossing along one ray: ``(r, g, b, a, depth, samples)``.

    A crossing is a change of ``s < isovalue`` (:func:`_below`) of the exact trilinear field,
    relative to its state where the ray enters the volume's box: from below to ``>= isovalue``
    or back, so surfaces are seen from inside too, a box face is not a surface, and a field
    that only touches the isovalue (a voxel or a plateau exactly at it, approached from below)
    is hit where it first reaches it. Each volume is walked by :func:`_walk_volume` up to the
    nearest hit so far; the nearest hit of all wins (the earlier volume on ties). The colour is
    the volume's transfer-function colour at its isovalue, shaded at the hit; alpha is 1.
    ``samples`` counts the lattice-cell segments walked.
    """
    samples = 0
    hit_t = np.inf
    hit_vol = -1
    for vol in range(offsets.shape[0]):
        if not t_out[vol] - t_in[vol] > min_overlap:
            continue
        value, t, n = _walk_volume(data, offsets[vol], dims[vol, 0], dims[vol, 1], dims[vol, 2],
                                   base[vol, 0], base[vol, 1], base[vol, 2], slope[vol, 0], slope[vol, 1],
                                   slope[vol, 2], t_in[vol], t_out[vol], True, isovalue[vol], tolerance, hit_t)
        samples += n
        if t < hit_t:
            hit_t = t
            hit_vol = vol
    if hit_vol < 0:
        return 0.0, 0.0, 0.0, 0.0, np.nan, samples
    r, g, b = iso_colour(data, offsets, dims, spacing, tf, tf_size, isovalue, nmat, phong, shading, light, half,
                         has_half, base, slope, hit_vol, hit_t)
    return r, g, b, 1.0, hit_t, samples


@njit(**_JIT)
def iso_colour(data, offsets, dims, spacing, tf, tf_size, isovalue, nmat, phong, shading, light, half, has_half, base,
               slope, vol, t):
    """The surface of volume ``vol`` hit at ``t``: its transfer function's colour at its isovalue, shaded with the
    gradient there (opacity 1)."""
    size = tf_size[vol]
    iso = isovalue[vol]
    r = _tf_channel(tf, vol, size, iso, 0)
    g = _tf_channel(tf, vol, size, iso, 1)
    b = _tf_channel(tf, vol, size, iso, 2)
    if phong:
        gx, gy, gz = _gradient(data, offsets[vol], dims[vol, 0], dims[vol, 1], dims[vol, 2],
                               base[vol, 0] + t * slope[vol, 0], base[vol, 1] + t * slope[vol, 1],
                               base[vol, 2] + t * slope[vol, 2], spacing[vol, 0], spacing[vol, 1], spacing[vol, 2])
        r, g, b = _blinn_phong(r, g, b, gx, gy, gz, nmat, vol, light, half, has_half, shading)
    return r, g, b


@njit(**_JIT)
def iso_first_crossing(data, offsets, dims, isovalue, base, slope, vol, t_entry, lo, hi, tolerance, t_stop):
    """The first crossing of volume ``vol``'s surface on ``[lo, hi]``, from its state at ``t_entry`` (where the ray
    entered its box): ``(t or inf, lattice-cell segments walked)``. A crossing at ``lo`` itself is where geometry
    opens the volume inside its surface: the cut face is drawn (a cap)."""
    nx, ny, nz = dims[vol, 0], dims[vol, 1], dims[vol, 2]
    iso = isovalue[vol]
    entry = _trilinear(data, offsets[vol], nx, ny, nz, base[vol, 0] + t_entry * slope[vol, 0],
                       base[vol, 1] + t_entry * slope[vol, 1], base[vol, 2] + t_entry * slope[vol, 2])
    _, t, n = _walk_volume(data, offsets[vol], nx, ny, nz, base[vol, 0], base[vol, 1], base[vol, 2], slope[vol, 0],
                           slope[vol, 1], slope[vol, 2], lo, hi, True, iso, tolerance, t_stop,
                           1 if _below(entry, iso) else 0)
    return t, n


@njit(**_JIT)
def _cell_range(t_first, step, t_in, t_out, min_overlap):
    """The cells ``k_lo … k_hi`` in which a volume spanning ``[t_in, t_out]`` takes samples.

    ``k_lo`` is the first cell whose end passes ``t_in + min_overlap`` and ``k_hi`` the last whose
    start is before ``t_out − min_overlap``, found with the same expressions for ``a_k`` and
    ``b_k`` that the sampling loops use (an estimate, then corrected), so every cell strictly
    between them lies inside ``[t_in, t_out]``. ``k_lo > k_hi`` when there is none. The callers
    pass finite spans only; each correction loop is bounded by :data:`MAX_CELL_CORRECTIONS`.
    """
    start = t_in + min_overlap
    k = max(int(math.floor((start - t_first) / step)), 0)
    # The estimate is off by a cell or two at most; the corrections are bounded all the same.
    for _ in range(MAX_CELL_CORRECTIONS):
        if not (k > 0 and t_first + k * step > start):
            break
        k -= 1
    for _ in range(MAX_CELL_CORRECTIONS):
        if not t_first + (k + 1) * step <= start:
            break
        k += 1
    stop = t_out - min_overlap
    j = int(math.ceil((stop - t_first) / step)) - 1
    for _ in range(MAX_CELL_CORRECTIONS):
        if not t_first + (j + 1) * step < stop:
            break
        j += 1
    for _ in range(MAX_CELL_CORRECTIONS):
        if not (j >= 0 and t_first + j * step >= stop):
            break
        j -= 1
    return k, j


@njit(parallel=True, **_JIT)
def preclassify(data, offsets, dims, spacing, tf, tf_size, gtab, gtab_size, ref_step, nmat, phong, shading, light,
                half, has_half, stop, out):
    """Classify and shade every voxel at its centre into ``out`` (4, packed size): premultiplied RGBA.

    The classify → shade → interpolate order of Levoy 1988 and of the shear-warp thesis's
    comparison ray caster: the transfer function (and gradient opacity) at the voxel's own
    value, Blinn–Phong with the central-difference gradient at the voxel centre (clamp-to-edge,
    as :func:`_gradient`) and one half vector for the whole volume (the view direction of an
    orthographic camera). Opacities are those of one reference step ``Δ0``; the ray corrects
    them for its step after interpolation. A non-zero ``stop[0]`` ends it early (as :func:`render`).
    """
    for vol in range(offsets.shape[0]):
        off = offsets[vol]
        nx, ny, nz = dims[vol, 0], dims[vol, 1], dims[vol, 2]
        size = tf_size[vol]
        for z in prange(nz):
            if stop_requested(stop):
                continue
            for y in range(ny):
                for x in range(nx):
                    index = off + (z * ny + y) * nx + x
                    s = np.float64(data[index])
                    alpha = _tf_channel(tf, vol, size, s, 3)
                    gx = gy = gz = 0.0
                    if alpha > 0.0 and (gtab_size[vol] > 0 or phong):
                        gx, gy, gz = _gradient(data, off, nx, ny, nz, np.float64(x), np.float64(y), np.float64(z),
                                               spacing[vol, 0], spacing[vol, 1], spacing[vol, 2])
                    if alpha > 0.0 and gtab_size[vol] > 0:
                        magnitude = math.sqrt(gx * gx + gy * gy + gz * gz)
                        alpha *= _gradient_factor(gtab, vol, gtab_size[vol], magnitude * ref_step[vol] / MAX_GRADIENT)
                    if alpha <= 0.0:
                        for c in range(4):
                            out[c, index] = 0.0
                        continue
                    r = _tf_channel(tf, vol, size, s, 0)
                    g = _tf_channel(tf, vol, size, s, 1)
                    b = _tf_channel(tf, vol, size, s, 2)
                    if phong:
                        r, g, b = _blinn_phong(r, g, b, gx, gy, gz, nmat, vol, light, half, has_half, shading)
                    out[0, index] = alpha * r
                    out[1, index] = alpha * g
                    out[2, index] = alpha * b
                    out[3, index] = alpha


@njit(**_JIT)
def volume_spans(world_to_object, dims, spacing, ref_step, step, o, d, t_in, t_out, base, slope, length, ratio):
    """Each volume box's span ``[t_in, t_out]`` on the ray ``o + t·d`` (``t >= 0``) and its sampling set-up.

    Fills ``base``/``slope`` (voxel coordinates ``base + t·slope``), ``length`` (``|A⁻¹·d|``,
    world → object length) and ``ratio`` (a full cell in units of ``Δ0``); returns ``t_first``,
    the entry into the union of the boxes (inf when the ray misses them all). A missed box has
    ``t_in >= t_out``.
    """
    t_first = np.inf
    for vol in range(dims.shape[0]):
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
        if not math.isfinite(hi):
            lo = np.inf  # an unbounded span (singular transform): the volume is not entered
        t_in[vol] = lo
        t_out[vol] = hi
        # |A⁻¹·d| turns a world length on this ray into object units; a full cell is Δ.
        length[vol] = math.sqrt(length2)
        ratio[vol] = length[vol] * step / ref_step[vol]
        if lo < hi:
            t_first = min(t_first, lo)
    return t_first


@njit(**_JIT)
def half_vector(light, d, half):
    """Blinn–Phong half vector between the light and ``V = −d`` (towards the viewer) into ``half``.

    Returns whether it exists (``False`` when the light points straight away from the viewer).
    """
    half[0] = light[0] - d[0]
    half[1] = light[1] - d[1]
    half[2] = light[2] - d[2]
    half_norm = math.sqrt(half[0] ** 2 + half[1] ** 2 + half[2] ** 2)
    if half_norm > 0.0:
        half[0] /= half_norm
        half[1] /= half_norm
        half[2] /= half_norm
    return half_norm > 0.0


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
    _i8, _f8[::1], _f8[::1], _f8,               # phong flag, (ka, kd, ks, n), light, iso tolerance (fraction of a segment)
    _f4[:, ::1],                                # pre-classified RGBA (4, packed size), or (4, 0): post-classify
    _i8[::1],                                   # stop flag (1,), set by another thread to end early
    _f4[:, :, ::1], _f8[:, ::1], _i8[::1], _i8[::1],  # out: image, depth, hits and samples per row
)


@njit(_RENDER_SIGNATURE, parallel=True, **_JIT)
def render(mode, row_order, origins, directions, data, offsets, dims, spacing, world_to_object, nmat, tf, tf_size,
           gtab, gtab_size, ref_step, isovalue, step, min_overlap, phong, shading, light, tolerance, pre, stop,
           image, depth, row_hits, row_samples):
    """Cast one ray per pixel into ``image`` (premultiplied RGBA) and ``depth``.

    ``depth`` is the ray parameter (world distance from the ray origin) of the first sample
    that contributed (``dvr``; the nearest one in the first contributing cell), of the maximum
    (``mip``) or of the surface (``iso``); NaN where nothing did. ``row_hits[i]`` counts the
    rays of row ``i`` that enter any volume box and ``row_samples[i]`` the volume samples they
    took (``dvr``) or the lattice-cell segments they walked (``mip``, ``iso``; bisection steps
    not included). ``tolerance`` is the iso bracket length as a fraction of a lattice-cell
    segment. Non-finite rays give transparent pixels. ``row_order`` is a permutation of the rows: prange
    hands each thread a contiguous block of it, so interleaving the rows balances pictures
    whose content sits in one band. A non-zero ``stop[0]``, set by another thread while the
    kernel runs (Ctrl-C, see :func:`renderers.reference.renderer.run_stoppable`), ends it before
    the next pixel; the outputs are then incomplete.
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
        half = np.empty(3)
        hits = 0
        samples = 0
        for col in range(width):
            if stop_requested(stop):
                break
            o = origins[row, col]
            d = directions[row, col]
            pixel = image[row, col]
            if not is_ray(o, d):
                # A ray that is no ray: transparent, before any loop could run away with it.
                pixel[:] = 0.0
                depth[row, col] = np.nan
                continue
            t_first = volume_spans(world_to_object, dims, spacing, ref_step, step, o, d, t_in, t_out, base, slope,
                                   length, ratio)
            if t_first == np.inf:
                pixel[:] = 0.0
                depth[row, col] = np.nan
                continue
            hits += 1
            if mode == MODE_MIP:
                r, g, b, a, t_hit, n = _mip_ray(data, offsets, dims, tf, tf_size, t_in, t_out, min_overlap,
                                                base, slope)
            else:
                has_half = half_vector(light, d, half)
                if mode == MODE_DVR:
                    count = 0
                    for vol in range(nvol):
                        if t_in[vol] < t_out[vol]:
                            k_lo[vol], k_hi[vol] = _cell_range(t_first, step, t_in[vol], t_out[vol], min_overlap)
                            count = max(count, k_hi[vol] + 1)
                        else:
                            k_lo[vol] = 1
                            k_hi[vol] = 0
                    r, g, b, a, t_hit, n = _dvr_ray(data, offsets, dims, spacing, tf, tf_size, gtab, gtab_size,
                                                    ref_step, nmat, phong, shading, light, half, has_half,
                                                    t_first, step, count, k_lo, k_hi, t_in, t_out, min_overlap,
                                                    base, slope, ratio, length, pre)
                else:
                    r, g, b, a, t_hit, n = _iso_ray(data, offsets, dims, spacing, tf, tf_size, isovalue, nmat,
                                                    phong, shading, light, half, has_half, t_in, t_out,
                                                    min_overlap, base, slope, tolerance)
            pixel[0] = r
            pixel[1] = g
            pixel[2] = b
            pixel[3] = a
            depth[row, col] = t_hit
            samples += n
        row_hits[row] = hits
        row_samples[row] = samples


LENS_CLIP, LENS_DVR, LENS_ISO, LENS_MIP = 0, 1, 2, 3
LENS_MODE_CODES = {"clip": LENS_CLIP, "dvr": LENS_DVR, "iso": LENS_ISO, "mip": LENS_MIP}
LENS_SPHERE, LENS_PLANES = 0, 1
"""Lens shapes in the kernel: a sphere (quadratic) or half-spaces in the lens's frame (box, convex mesh)."""


@njit(**_JIT)
def sphere_interval(o, d, sphere):
    """The ray parameters ``(t0, t1)`` where the line ``o + t·d`` is inside ``sphere`` (cx, cy, cz, r).

    The roots of ``|o + t·d − c|² = r²`` in the form that avoids cancellation: the discriminant
    from the distance of the centre to the line (Haines et al., Ray Tracing Gems ch. 7) and the
    second root from Vieta. A miss or a tangent line gives the empty ``(inf, −inf)``.
    """
    fx = o[0] - sphere[0]
    fy = o[1] - sphere[1]
    fz = o[2] - sphere[2]
    a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    bh = fx * d[0] + fy * d[1] + fz * d[2]
    k = bh / a
    px = fx - k * d[0]
    py = fy - k * d[1]
    pz = fz - k * d[2]
    r = sphere[3]
    disc = a * (r * r - (px * px + py * py + pz * pz))
    if not disc > 0.0:
        return np.inf, -np.inf
    q = -(bh + math.copysign(math.sqrt(disc), bh))
    t0 = q / a
    t1 = (fx * fx + fy * fy + fz * fz - r * r) / q
    return min(t0, t1), max(t0, t1)


@njit(**_JIT)
def planes_interval(o, d, m, normals, offsets):
    """The ray parameters ``(t0, t1)`` where ``o + t·d`` satisfies every ``n·x <= c`` of the lens frame.

    ``m`` is world→lens (3, 4); the ray is carried there unnormalised, so ``t`` is the world
    ray's. Cyrus–Beck clipping: each plane bounds ``t`` from one side; a ray parallel to a plane
    and outside it misses. Empty: ``t0 >= t1``.
    """
    ox = m[0, 0] * o[0] + m[0, 1] * o[1] + m[0, 2] * o[2] + m[0, 3]
    oy = m[1, 0] * o[0] + m[1, 1] * o[1] + m[1, 2] * o[2] + m[1, 3]
    oz = m[2, 0] * o[0] + m[2, 1] * o[1] + m[2, 2] * o[2] + m[2, 3]
    dx = m[0, 0] * d[0] + m[0, 1] * d[1] + m[0, 2] * d[2]
    dy = m[1, 0] * d[0] + m[1, 1] * d[1] + m[1, 2] * d[2]
    dz = m[2, 0] * d[0] + m[2, 1] * d[1] + m[2, 2] * d[2]
    lo = -np.inf
    hi = np.inf
    for i in range(normals.shape[0]):
        den = normals[i, 0] * dx + normals[i, 1] * dy + normals[i, 2] * dz
        num = offsets[i] - (normals[i, 0] * ox + normals[i, 1] * oy + normals[i, 2] * oz)
        if den == 0.0:
            if num < 0.0:
                return np.inf, -np.inf
        elif den > 0.0:
            hi = min(hi, num / den)
        else:
            lo = max(lo, num / den)
    return lo, hi


@njit(**_JIT)
def lens_interval(kind, o, d, sphere, m, normals, offsets):
    """The lens's interval on the whole line ``o + t·d`` (:func:`sphere_interval` or :func:`planes_interval`)."""
    if kind == LENS_SPHERE:
        return sphere_interval(o, d, sphere)
    return planes_interval(o, d, m, normals, offsets)


@njit(**_JIT)
def _lens_segment(data, offsets, dims, spacing, tf, tf_size, nmat, phong, shading, light, half, has_half, base,
                  slope, lo, hi, lens_mode, isovalue, tolerance):
    """A ``mip`` or ``iso`` lens's one contribution on its segment ``[lo, hi]``: ``(r, g, b, a, t, segments)``.

    The volume is slot 0, the lens's classification slot 1 (see :func:`render_lens`). ``mip``:
    the exact maximum of the segment, classified without opacity correction; ``iso``: the first
    crossing of the segment, shaded, opaque, or nothing (``a = 0``).
    """
    if lens_mode == LENS_MIP:
        value, t, n = _walk_volume(data, offsets[0], dims[0, 0], dims[0, 1], dims[0, 2], base[0, 0], base[0, 1],
                                   base[0, 2], slope[0, 0], slope[0, 1], slope[0, 2], lo, hi, False, 0.0, 0.0, np.inf)
        size = tf_size[1]
        a = _tf_channel(tf, 1, size, value, 3)
        return (_tf_channel(tf, 1, size, value, 0) * a, _tf_channel(tf, 1, size, value, 1) * a,
                _tf_channel(tf, 1, size, value, 2) * a, a, t, n)
    _, t, n = _walk_volume(data, offsets[0], dims[0, 0], dims[0, 1], dims[0, 2], base[0, 0], base[0, 1], base[0, 2],
                           slope[0, 0], slope[0, 1], slope[0, 2], lo, hi, True, isovalue, tolerance, np.inf)
    if t == np.inf:
        return 0.0, 0.0, 0.0, 0.0, np.nan, n
    size = tf_size[1]
    r = _tf_channel(tf, 1, size, isovalue, 0)
    g = _tf_channel(tf, 1, size, isovalue, 1)
    b = _tf_channel(tf, 1, size, isovalue, 2)
    if phong:
        gx, gy, gz = _gradient(data, offsets[0], dims[0, 0], dims[0, 1], dims[0, 2], base[0, 0] + t * slope[0, 0],
                               base[0, 1] + t * slope[0, 1], base[0, 2] + t * slope[0, 2], spacing[0, 0],
                               spacing[0, 1], spacing[0, 2])
        r, g, b = _blinn_phong(r, g, b, gx, gy, gz, nmat, 0, light, half, has_half, shading)
    return r, g, b, 1.0, t, n


@njit(**_JIT)
def _lens_ray(data, offsets, dims, spacing, tf, tf_size, gtab, gtab_size, ref_step, nmat, phong, shading, light,
              half, has_half, t_first, step, k_lo, k_hi, t_in, t_out, min_overlap, base, slope, ratio, length, pre,
              lens_mode, l_lo, l_hi, isovalue, tolerance):
    """Front-to-back ``dvr`` along one ray with a lens on ``[l_lo, l_hi]``: ``(r, g, b, a, depth, samples)``.

    The samples are :func:`_dvr_ray`'s for the one volume (slot 0), same positions, same
    arithmetic; a sample at ``t`` in the lens segment ``[max(l_lo, t_in), min(l_hi, t_out)]`` is
    classified with slot 1 (the lens's tables) in ``dvr``, skipped in ``clip``, ``mip`` and
    ``iso``, where the segment's one contribution (:func:`_lens_segment`) is composited before
    the first sample at or past the segment's start. A segment no longer than ``min_overlap``
    is no lens.
    """
    lo = max(l_lo, t_in[0])
    hi = min(l_hi, t_out[0])
    has_lens = hi - lo > min_overlap
    pending = has_lens and (lens_mode == LENS_MIP or lens_mode == LENS_ISO)
    cr = cg = cb = ca = 0.0
    depth = np.nan
    samples = 0
    for k in range(k_lo[0], k_hi[0] + 2):
        last = k > k_hi[0]
        t = np.inf
        full = True
        overlap = step
        if not last:
            t = t_first + (k + 0.5) * step
            if k == k_lo[0] or k == k_hi[0]:
                t, overlap, full = _boundary_cell(k, t_first, step, t_in[0], t_out[0], min_overlap)
                if overlap == 0.0:
                    continue
        inside = has_lens and lo <= t and t <= hi
        if pending and (inside or t > hi):
            pending = False
            ar, ag, ab, aa, t_hit, n = _lens_segment(data, offsets, dims, spacing, tf, tf_size, nmat, phong, shading,
                                                     light, half, has_half, base, slope, lo, hi, lens_mode, isovalue,
                                                     tolerance)
            samples += n
            if aa > 0.0:
                if np.isnan(depth):
                    depth = t_hit
                transparency = 1.0 - ca
                cr += transparency * ar
                cg += transparency * ag
                cb += transparency * ab
                ca += transparency * aa
        if last or (inside and lens_mode != LENS_DVR):
            continue
        vol = 1 if inside else 0
        vol_ratio = ratio[vol] if full else length[vol] * overlap / ref_step[vol]
        samples += 1
        ar, ag, ab, aa, hit = volume_sample(data, offsets, dims, spacing, tf, tf_size, gtab, gtab_size, ref_step, nmat,
                                            phong, shading, light, half, has_half, vol, t, vol_ratio, base, slope, pre)
        # The order and tests of _dvr_ray's single-volume path, so that equal tables give equal bits.
        if hit and aa > 0.0:
            if np.isnan(depth):
                depth = t
            transparency = 1.0 - ca
            cr += transparency * ar
            cg += transparency * ag
            cb += transparency * ab
            ca += transparency * aa
    return cr, cg, cb, ca, depth, samples


@njit(parallel=True, **_JIT)
def render_lens(row_order, origins, directions, data, offsets, dims, spacing, world_to_object, nmat, tf, tf_size,
                gtab, gtab_size, ref_step, step, min_overlap, phong, shading, light, tolerance, pre,
                lens_kind, lens_mode, sphere, lens_w2o, normals, plane_offsets, lens_isovalue,
                stop, image, depth, row_hits, row_samples):
    """:func:`render` for a ``dvr`` scene of one volume and one lens (see :func:`_lens_ray`).

    The packed arrays hold two slots over the same voxels and transform: 0 with the volume's
    own classification, 1 with the lens's. ``lens_kind`` is :data:`LENS_SPHERE` (``sphere`` =
    centre and radius, world) or :data:`LENS_PLANES` (``normals``/``plane_offsets`` in the frame
    ``lens_w2o`` maps to); ``lens_mode`` a :data:`LENS_MODE_CODES` value. Counters, depth,
    non-finite rays and ``stop`` are as in :func:`render`; ``samples`` adds a ``mip``/``iso``
    lens's lattice-cell segments.
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
        half = np.empty(3)
        hits = 0
        samples = 0
        for col in range(width):
            if stop_requested(stop):
                break
            o = origins[row, col]
            d = directions[row, col]
            pixel = image[row, col]
            pixel[:] = 0.0
            depth[row, col] = np.nan
            if not is_ray(o, d):
                continue
            t_first = volume_spans(world_to_object, dims, spacing, ref_step, step, o, d, t_in, t_out, base, slope,
                                   length, ratio)
            if t_first == np.inf:
                continue
            hits += 1
            has_half = half_vector(light, d, half)
            k_lo[0], k_hi[0] = _cell_range(t_first, step, t_in[0], t_out[0], min_overlap)
            l_lo, l_hi = lens_interval(lens_kind, o, d, sphere, lens_w2o, normals, plane_offsets)
            r, g, b, a, t_hit, n = _lens_ray(data, offsets, dims, spacing, tf, tf_size, gtab, gtab_size, ref_step,
                                             nmat, phong, shading, light, half, has_half, t_first, step, k_lo, k_hi,
                                             t_in, t_out, min_overlap, base, slope, ratio, length, pre, lens_mode,
                                             l_lo, l_hi, lens_isovalue, tolerance)
            pixel[0] = r
            pixel[1] = g
            pixel[2] = b
            pixel[3] = a
            depth[row, col] = t_hit
            samples += n
        row_hits[row] = hits
        row_samples[row] = samples
