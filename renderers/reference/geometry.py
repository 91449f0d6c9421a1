"""Numba kernel of the reference ray caster for scenes with meshes, volume boundaries and CSG.

The ground truth for Kainz et al. 2009: every ray keeps *all* of its fragments (no depth limit),
found by exact ray–triangle intersection, sorted by depth and walked front to back with the
active-object set and the CSG forest (semantics in :mod:`core.scene`).

Conventions implemented here
----------------------------
* Intersection: the watertight ray–triangle test of Woop, Benthin and Wald (JCGT 2013) in each
  instance's object space (``o' = A⁻¹o``, ``d' = A⁻¹d`` unnormalised, so the hit's ``t`` is the
  world ``t``), double precision, no fused multiply-add (``fastmath`` off). Vertices are sheared
  once per ray and object, the edge function of an edge ``P→Q`` is ``Q.x·P.y − Q.y·P.x``, so the
  two triangles sharing an edge compute exactly opposite values. A ray exactly on an edge (value
  0) is given to one triangle by a tie rule on the edge's direction in the triangle's own
  orientation (the top-left rule of rasterisers): two triangles of the same facing never both
  take it and never both leave it, so each surface crossing yields exactly one fragment; at a
  silhouette edge (opposite facings) both or neither take it, which keeps the parity.
* Parity: the whole line ``o + t·d`` is intersected; hits at ``t < 0`` set the initial inside state
  of each mesh (an eye inside a mesh is handled), hits at ``t >= 0`` are the fragments. Volume
  boxes enter at their span ``[t_in, t_out]`` (clipped to ``t >= 0``, as the volume-only kernel).
* Walk: fragments at the same depth form one group; after each group the CSG forest is
  re-evaluated. Each leaf's contributing intervals are merged across fragments that do not
  change it, so a volume's intervals are its box span wherever no geometry cuts it. A surface
  fragment is kept when its tree root's inside/outside differs across the group and its
  instance has a surface material. Contributions left open after the last fragment (impossible
  for closed meshes, only by rounding) are dropped.
* Sampling: the cells of the volume-only kernel (``[t_first + k·Δ, t_first + (k + 1)·Δ]``,
  ``t_first`` the entry into the union of the volume boxes), further cut at every visible
  surface and every medium interval's end. A whole cell samples each volume interval exactly
  as the volume-only kernel (:func:`raycast._boundary_cell`), so a volume that no geometry cuts
  is sampled at the same positions with the same arithmetic; a cut piece samples each interval
  that overlaps it by more than ``min_overlap`` at the overlap's midpoint, corrected for its
  length. Homogeneous media in a piece of length ``L`` give ``α = 1 − exp(−Σσ·L)`` with the
  ``σ``-weighted colour; this joins the piece's volume samples in the sum (clamped to 1), so a
  piece of media alone is exact. Visible surfaces are composited at their depth, after the
  piece in front of them.
"""

import math

import numpy as np
from numba import njit, prange

from renderers.base.numba_kernels import JIT as _JIT
from renderers.reference.raycast import (_blinn_phong, _boundary_cell, _cell_range, half_vector, is_ray, iso_colour,
                                         iso_first_crossing, stop_requested, volume_sample, volume_spans)

OP_LEAF, OP_UNION, OP_INTERSECTION, OP_DIFFERENCE = 0, 1, 2, 3
OPERATION_CODES = {"union": OP_UNION, "intersection": OP_INTERSECTION, "difference": OP_DIFFERENCE}

INITIAL_FRAGMENTS = 64
"""Starting capacity of the per-row fragment lists; they double when full (no depth limit)."""


@njit(**_JIT)
def _grow(array):
    bigger = np.empty(2 * array.shape[0], array.dtype)
    bigger[:array.shape[0]] = array
    return bigger


@njit(**_JIT)
def _append(times, refs, extras, n, t, ref, extra):
    """Write entry ``n`` of three parallel lists, doubling them first when full; returns the lists."""
    if n == times.shape[0]:
        times = _grow(times)
        refs = _grow(refs)
        extras = _grow(extras)
    times[n] = t
    refs[n] = ref
    extras[n] = extra
    return times, refs, extras


@njit(**_JIT)
def _owns_edge(value, ex, ey):
    """Whether a point with edge-function ``value`` (orientation-corrected) is inside that edge.

    A zero value is inside only for edges pointing up, or right when horizontal: the same edge
    seen from the neighbouring triangle points the other way, so exactly one of the two owns it.
    """
    if value > 0.0:
        return True
    return value == 0.0 and (ey > 0.0 or (ey == 0.0 and ex > 0.0))


@njit(**_JIT)
def _component(x, y, z, k):
    if k == 0:
        return x
    if k == 1:
        return y
    return z


@njit(**_JIT)
def intersect_object(obj, o, d, obj_w2o, obj_lo, obj_hi, obj_faces, verts, faces, frag_t, frag_ref, frag_tri, n):
    """Append object ``obj``'s hits at ``t >= 0`` to the fragment lists; count those at ``t < 0``.

    Returns ``(n, behind, frag_t, frag_ref, frag_tri)``: the new fragment count, the parity of
    the hits behind the origin, and the (possibly grown) lists.
    """
    m = obj_w2o[obj]
    ox = m[0, 0] * o[0] + m[0, 1] * o[1] + m[0, 2] * o[2] + m[0, 3]
    oy = m[1, 0] * o[0] + m[1, 1] * o[1] + m[1, 2] * o[2] + m[1, 3]
    oz = m[2, 0] * o[0] + m[2, 1] * o[1] + m[2, 2] * o[2] + m[2, 3]
    dx = m[0, 0] * d[0] + m[0, 1] * d[1] + m[0, 2] * d[2]
    dy = m[1, 0] * d[0] + m[1, 1] * d[1] + m[1, 2] * d[2]
    dz = m[2, 0] * d[0] + m[2, 1] * d[1] + m[2, 2] * d[2]
    # The padded bounding box, over the whole line: most rays miss most objects here.
    t_lo = -np.inf
    t_hi = np.inf
    for axis in range(3):
        p = _component(ox, oy, oz, axis)
        q = _component(dx, dy, dz, axis)
        if q == 0.0:
            if p < obj_lo[obj, axis] or p > obj_hi[obj, axis]:
                return n, False, frag_t, frag_ref, frag_tri
        else:
            ta = (obj_lo[obj, axis] - p) / q
            tb = (obj_hi[obj, axis] - p) / q
            t_lo = max(t_lo, min(ta, tb))
            t_hi = min(t_hi, max(ta, tb))
    if not t_lo <= t_hi:
        return n, False, frag_t, frag_ref, frag_tri
    # Woop et al.: kz is the dominant axis of d'; swapping kx, ky keeps the winding when d'_kz < 0.
    ax, ay, az = abs(dx), abs(dy), abs(dz)
    kz = 0 if (ax >= ay and ax >= az) else (1 if ay >= az else 2)
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    dkz = _component(dx, dy, dz, kz)
    if dkz < 0.0:
        kx, ky = ky, kx
    sx = _component(dx, dy, dz, kx) / dkz
    sy = _component(dx, dy, dz, ky) / dkz
    sz = 1.0 / dkz
    okx = _component(ox, oy, oz, kx)
    oky = _component(ox, oy, oz, ky)
    okz = _component(ox, oy, oz, kz)
    behind = False
    for f in range(obj_faces[obj, 0], obj_faces[obj, 1]):
        ia = faces[f, 0]
        ib = faces[f, 1]
        ic = faces[f, 2]
        az_ = verts[ia, kz] - okz
        bz_ = verts[ib, kz] - okz
        cz_ = verts[ic, kz] - okz
        a_x = (verts[ia, kx] - okx) - sx * az_
        a_y = (verts[ia, ky] - oky) - sy * az_
        b_x = (verts[ib, kx] - okx) - sx * bz_
        b_y = (verts[ib, ky] - oky) - sy * bz_
        c_x = (verts[ic, kx] - okx) - sx * cz_
        c_y = (verts[ic, ky] - oky) - sy * cz_
        u = c_x * b_y - c_y * b_x   # edge B→C
        v = a_x * c_y - a_y * c_x   # edge C→A
        w = b_x * a_y - b_y * a_x   # edge A→B
        det = u + v + w
        if det == 0.0:
            continue
        sign = 1.0 if det > 0.0 else -1.0
        if not (_owns_edge(sign * u, sign * (c_x - b_x), sign * (c_y - b_y))
                and _owns_edge(sign * v, sign * (a_x - c_x), sign * (a_y - c_y))
                and _owns_edge(sign * w, sign * (b_x - a_x), sign * (b_y - a_y))):
            continue
        t = (u * (sz * az_) + v * (sz * bz_) + w * (sz * cz_)) / det
        if t < 0.0:
            behind = not behind
            continue
        frag_t, frag_ref, frag_tri = _append(frag_t, frag_ref, frag_tri, n, t, obj, f)
        n += 1
    return n, behind, frag_t, frag_ref, frag_tri


@njit(**_JIT)
def _leaf_active(leaf, leaf_box, leaf_obj, box_in, parity):
    """A leaf is inside where it is inside its box (volumes) and its mesh (by parity), if it has them."""
    vol = leaf_box[leaf]
    if vol >= 0 and not box_in[vol]:
        return False
    obj = leaf_obj[leaf]
    return obj < 0 or parity[obj]


@njit(**_JIT)
def evaluate_forest(node_op, node_leaf, node_parent, node_first, node_children, node_child_start, node_child_count,
                    leaf_box, leaf_obj, box_in, parity, value, enabled):
    """Inside/outside ``value`` of every CSG node and whether it is ``enabled`` (lets its leaves contribute).

    Nodes are in postfix order (children before parents), roots have parent −1. A leaf
    contributes where it is both enabled and inside (see :mod:`core.scene`).
    """
    count = node_op.shape[0]
    for j in range(count):
        op = node_op[j]
        if op == OP_LEAF:
            value[j] = _leaf_active(node_leaf[j], leaf_box, leaf_obj, box_in, parity)
            continue
        start = node_child_start[j]
        stop = start + node_child_count[j]
        if op == OP_UNION:
            result = False
            for c in range(start, stop):
                result = result or value[node_children[c]]
        elif op == OP_INTERSECTION:
            result = True
            for c in range(start, stop):
                result = result and value[node_children[c]]
        else:
            result = value[node_children[start]]
            for c in range(start + 1, stop):
                result = result and not value[node_children[c]]
        value[j] = result
    for j in range(count - 1, -1, -1):
        parent = node_parent[j]
        if parent < 0:
            enabled[j] = True
        elif node_op[parent] == OP_UNION:
            enabled[j] = enabled[parent]
        elif node_op[parent] == OP_INTERSECTION:
            enabled[j] = enabled[parent] and value[parent]
        else:
            enabled[j] = enabled[parent] and value[parent] and node_first[j]


@njit(**_JIT)
def _composite(cr, cg, cb, ca, sr, sg, sb, sa):
    """Front-to-back over-operator of a premultiplied sample sum, its opacity clamped to 1."""
    if sa > 1.0:
        sr /= sa
        sg /= sa
        sb /= sa
        sa = 1.0
    transparency = 1.0 - ca
    return cr + transparency * sr, cg + transparency * sg, cb + transparency * sb, ca + transparency * sa


@njit(parallel=True, **_JIT)
def render(origins, directions,
           data, offsets, dims, spacing, world_to_object, nmat, tf, tf_size, gtab, gtab_size, ref_step, pre,
           step, min_overlap, phong, shading, light, iso_mode, isovalue, tolerance,
           verts, faces, face_normals, obj_w2o, obj_nmat, obj_lo, obj_hi, obj_faces, obj_leaf,
           leaf_box, leaf_obj, leaf_surface, leaf_has_surface, leaf_medium, leaf_has_medium, leaf_node, leaf_root,
           node_op, node_leaf, node_parent, node_first, node_children, node_child_start, node_child_count,
           row_order, stop, image, depth, row_hits, row_samples, row_fragments, row_max_fragments):
    """Cast one ray per pixel through volumes, meshes and CSG (see the module notes).

    ``image`` gets premultiplied RGBA and ``depth`` the ray parameter of the first contribution
    (a surface or the nearest sample of the first contributing piece), NaN where none. Per row:
    rays that meet any box or mesh, volume samples (``iso_mode``: lattice-cell segments walked),
    fragments (crossings at ``t >= 0``, volume boxes excluded) and the largest fragment count of one
    ray (its depth complexity). With ``iso_mode`` a volume contributes no samples but the first
    crossing of its surface inside its contributing intervals (:func:`raycast.iso_first_crossing`,
    its state taken where the ray enters its box), the nearest of all volumes, opaque, composited
    in depth order with the surfaces and media in front of it. A non-zero
    ``stop[0]`` ends the kernel before the next pixel (Ctrl-C, as :func:`raycast.render`).
    """
    height, width = origins.shape[0], origins.shape[1]
    nvol = offsets.shape[0]
    nobj = obj_leaf.shape[0]
    nleaf = leaf_box.shape[0]
    nnode = node_op.shape[0]
    for i in prange(height):
        row = row_order[i]
        t_in = np.empty(nvol)
        t_out = np.empty(nvol)
        base = np.empty((nvol, 3))
        slope = np.empty((nvol, 3))
        ratio = np.empty(nvol)
        length = np.empty(nvol)
        half = np.empty(3)
        parity = np.zeros(nobj, np.bool_)
        box_in = np.zeros(nvol, np.bool_)
        value = np.zeros(nnode, np.bool_)
        before = np.zeros(nnode, np.bool_)
        enabled = np.zeros(nnode, np.bool_)
        open_at = np.empty(nleaf)
        frag_t = np.empty(INITIAL_FRAGMENTS)
        frag_ref = np.empty(INITIAL_FRAGMENTS, np.int64)
        frag_tri = np.empty(INITIAL_FRAGMENTS, np.int64)
        cut_t = np.empty(INITIAL_FRAGMENTS)
        cut_obj = np.empty(INITIAL_FRAGMENTS, np.int64)
        cut_tri = np.empty(INITIAL_FRAGMENTS, np.int64)
        iv_leaf = np.empty(INITIAL_FRAGMENTS, np.int64)
        iv_lo = np.empty(INITIAL_FRAGMENTS)
        iv_hi = np.empty(INITIAL_FRAGMENTS)
        hits = 0
        samples = 0
        fragments = 0
        most = 0
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
            # Fragments: mesh crossings first (object by object), then the volume boxes' entries and exits.
            n = 0
            for obj in range(nobj):
                n, behind, frag_t, frag_ref, frag_tri = intersect_object(
                    obj, o, d, obj_w2o, obj_lo, obj_hi, obj_faces, verts, faces, frag_t, frag_ref, frag_tri, n)
                parity[obj] = behind
            crossings = n
            for vol in range(nvol):
                box_in[vol] = False
                if t_in[vol] < t_out[vol]:
                    # frag_tri carries the event for a box: 1 enters, 0 leaves.
                    frag_t, frag_ref, frag_tri = _append(frag_t, frag_ref, frag_tri, n, t_in[vol], -1 - vol, 1)
                    frag_t, frag_ref, frag_tri = _append(frag_t, frag_ref, frag_tri, n + 1, t_out[vol], -1 - vol, 0)
                    n += 2
            if n == 0:
                continue
            hits += 1
            fragments += crossings
            most = max(most, crossings)
            order = np.argsort(frag_t[:n], kind="mergesort")

            # The walk: contributing intervals per leaf and the visible surfaces, in depth order.
            evaluate_forest(node_op, node_leaf, node_parent, node_first, node_children, node_child_start,
                            node_child_count, leaf_box, leaf_obj, box_in, parity, value, enabled)
            for leaf in range(nleaf):
                node = leaf_node[leaf]
                open_at[leaf] = 0.0 if (value[node] and enabled[node]) else -1.0
            n_iv = 0
            n_cut = 0
            g = 0
            while g < n:
                t_group = frag_t[order[g]]
                end = g
                while end < n and frag_t[order[end]] == t_group:
                    end += 1
                before[:] = value
                for j in range(g, end):
                    ref = frag_ref[order[j]]
                    if ref >= 0:
                        parity[ref] = not parity[ref]
                    else:
                        box_in[-1 - ref] = frag_tri[order[j]] == 1
                evaluate_forest(node_op, node_leaf, node_parent, node_first, node_children, node_child_start,
                                node_child_count, leaf_box, leaf_obj, box_in, parity, value, enabled)
                for j in range(g, end):
                    ref = frag_ref[order[j]]
                    if ref < 0:
                        continue
                    leaf = obj_leaf[ref]
                    root = leaf_root[leaf]
                    if leaf_has_surface[leaf] and value[root] != before[root]:
                        cut_t, cut_obj, cut_tri = _append(cut_t, cut_obj, cut_tri, n_cut, t_group, ref,
                                                          frag_tri[order[j]])
                        n_cut += 1
                for leaf in range(nleaf):
                    node = leaf_node[leaf]
                    now = value[node] and enabled[node]
                    if now and open_at[leaf] < 0.0:
                        open_at[leaf] = t_group
                    elif not now and open_at[leaf] >= 0.0:
                        if t_group > open_at[leaf]:
                            iv_lo, iv_leaf, iv_hi = _append(iv_lo, iv_leaf, iv_hi, n_iv, open_at[leaf], leaf, t_group)
                            n_iv += 1
                        open_at[leaf] = -1.0
                g = end

            # Iso: each volume's first crossing inside its intervals (in depth order), the nearest of all a cut.
            iso_t = np.inf
            iso_vol = -1
            if iso_mode:
                for vol in range(nvol):
                    for j in range(n_iv):
                        if iv_leaf[j] != vol or iv_lo[j] >= iso_t or iv_hi[j] - iv_lo[j] <= min_overlap:
                            continue
                        t, walked = iso_first_crossing(data, offsets, dims, isovalue, base, slope, vol, t_in[vol],
                                                       iv_lo[j], iv_hi[j], tolerance, iso_t)
                        samples += walked
                        if t < iso_t:
                            iso_t = t
                            iso_vol = vol
                            break
                if iso_vol >= 0:
                    cut_t, cut_obj, cut_tri = _append(cut_t, cut_obj, cut_tri, n_cut, iso_t, -2, iso_vol)
                    n_cut += 1
            # Medium intervals cut the ray like surfaces, so each piece is inside a medium or not.
            for j in range(n_iv):
                if leaf_has_medium[iv_leaf[j]]:
                    cut_t, cut_obj, cut_tri = _append(cut_t, cut_obj, cut_tri, n_cut, iv_lo[j], -1, -1)
                    cut_t, cut_obj, cut_tri = _append(cut_t, cut_obj, cut_tri, n_cut + 1, iv_hi[j], -1, -1)
                    n_cut += 2
            cut_order = np.argsort(cut_t[:n_cut], kind="mergesort")
            # Volume intervals by volume (the order the volume-only kernel sums them in), each in depth order.
            iv_order = np.argsort(iv_leaf[:n_iv], kind="mergesort")
            k_lo = np.empty(n_iv, np.int64)
            k_hi = np.empty(n_iv, np.int64)
            count = 0
            for j in range(n_iv):
                if iv_leaf[j] < nvol and not iso_mode:
                    k_lo[j], k_hi[j] = _cell_range(t_first, step, iv_lo[j], iv_hi[j], min_overlap)
                    count = max(count, k_hi[j] + 1)

            has_half = half_vector(light, d, half)
            cr = cg = cb = ca = 0.0
            t_hit = np.nan
            p0 = 0.0
            k = 0
            c = 0
            while True:
                cell = -1
                a_k = b_k = np.inf
                if k < count:
                    a_k = t_first + k * step
                    b_k = t_first + (k + 1) * step
                    cell = k if p0 >= a_k else -1
                next_cell = b_k if cell >= 0 else a_k
                next_cut = cut_t[cut_order[c]] if c < n_cut else np.inf
                p1 = min(next_cell, next_cut)
                if p1 == np.inf:
                    break
                if p1 > p0:
                    whole = cell >= 0 and p0 == a_k and p1 == b_k
                    sr = sg = sb = sa = 0.0
                    nearest = np.inf
                    if cell >= 0:
                        for jj in range(n_iv):
                            j = iv_order[jj]
                            vol = iv_leaf[j]
                            if vol >= nvol or cell < k_lo[j] or cell > k_hi[j]:
                                continue
                            if whole:
                                t, overlap, full = _boundary_cell(cell, t_first, step, iv_lo[j], iv_hi[j], min_overlap)
                                if overlap == 0.0:
                                    continue
                                vol_ratio = ratio[vol] if full else length[vol] * overlap / ref_step[vol]
                            else:
                                lo = max(p0, iv_lo[j])
                                hi = min(p1, iv_hi[j])
                                overlap = hi - lo
                                if overlap <= min_overlap:
                                    continue
                                t = 0.5 * (lo + hi)
                                vol_ratio = length[vol] * overlap / ref_step[vol]
                            samples += 1
                            ar, ag, ab, aa, contributes = volume_sample(
                                data, offsets, dims, spacing, tf, tf_size, gtab, gtab_size, ref_step, nmat, phong,
                                shading, light, half, has_half, vol, t, vol_ratio, base, slope, pre)
                            if contributes:
                                sr += ar
                                sg += ag
                                sb += ab
                                sa += aa
                                nearest = min(nearest, t)
                    sigma = mr = mg = mb = 0.0
                    for j in range(n_iv):
                        leaf = iv_leaf[j]
                        if leaf_has_medium[leaf] and iv_lo[j] <= p0 and p1 <= iv_hi[j]:
                            s = leaf_medium[leaf, 3]
                            sigma += s
                            mr += s * leaf_medium[leaf, 0]
                            mg += s * leaf_medium[leaf, 1]
                            mb += s * leaf_medium[leaf, 2]
                    if sigma > 0.0:
                        alpha = -math.expm1(-sigma * (p1 - p0))
                        sr += alpha * mr / sigma
                        sg += alpha * mg / sigma
                        sb += alpha * mb / sigma
                        sa += alpha
                        nearest = min(nearest, p0)
                    if sa > 0.0:
                        if np.isnan(t_hit):
                            t_hit = nearest
                        cr, cg, cb, ca = _composite(cr, cg, cb, ca, sr, sg, sb, sa)
                iso_surface = False
                while c < n_cut and cut_t[cut_order[c]] == p1:
                    obj = cut_obj[cut_order[c]]
                    c += 1
                    if obj == -2:  # the iso-surface: opaque, nothing behind it counts
                        r, g_, b = iso_colour(data, offsets, dims, spacing, tf, tf_size, isovalue, nmat, phong,
                                              shading, light, half, has_half, base, slope, cut_tri[cut_order[c - 1]],
                                              p1)
                        if np.isnan(t_hit):
                            t_hit = p1
                        cr, cg, cb, ca = _composite(cr, cg, cb, ca, r, g_, b, 1.0)
                        iso_surface = True
                        break
                    if obj < 0:
                        continue
                    leaf = obj_leaf[obj]
                    material = leaf_surface[leaf]
                    alpha = material[3]
                    r, g_, b = material[0], material[1], material[2]
                    if phong:
                        f = cut_tri[cut_order[c - 1]]
                        r, g_, b = _blinn_phong(r, g_, b, face_normals[f, 0], face_normals[f, 1], face_normals[f, 2],
                                                obj_nmat, obj, light, half, has_half, material[4:])
                    if alpha > 0.0 and np.isnan(t_hit):
                        t_hit = p1
                    cr, cg, cb, ca = _composite(cr, cg, cb, ca, alpha * r, alpha * g_, alpha * b, alpha)
                if iso_surface:
                    break
                if cell >= 0 and p1 == b_k:
                    k += 1
                p0 = p1
            pixel[0] = cr
            pixel[1] = cg
            pixel[2] = cb
            pixel[3] = ca
            depth[row, col] = t_hit
        row_hits[row] = hits
        row_samples[row] = samples
        row_fragments[row] = fragments
        row_max_fragments[row] = most
