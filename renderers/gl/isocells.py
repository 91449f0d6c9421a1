"""The exact first crossing of an iso-surface in GLSL: every lattice cell a ray crosses is resolved.

A ray caster that tests ``s < isovalue`` at its samples misses a surface whose crossing lies between two samples
(a vessel thinner than a step, a one-voxel sheet) or takes the wrong one of two. Here the ray's span is walked
with a 3-D DDA through the cells of the voxel lattice, as the reference renderer does
(:func:`renderers.reference.raycast._walk_volume`, the same regions, boundaries and arithmetic): in each cell
whose eight corners reach across the isovalue from the ray's entry state, the trilinear field along the
segment is a cubic in the ray parameter; cut at the roots of its derivative into monotone pieces, the first
piece whose end changes state holds the crossing, which is bisected to float32's resolution of the segment
(Marmitt et al. 2004 solve the cubic the same way after a min–max test of the cell). The corners are fetched
(``texelFetch``) and blended in float32: the texture unit's trilinear filter weights have 8 fractional bits on
most GPUs, too coarse for a crossing within 1e-4 voxel. A cell whose range does not reach across the isovalue
costs its eight fetches and no more. The hit's normal is the reference's gradient (central differences one voxel
apart of the same trilinear field), blended the same way, not the half-float gradient texture.

:data:`CELL_WALK` defines ``iso_first_crossing(start, dir, t_lo, t_hi, below)`` (``ISO_FAR`` where there is
no crossing), ``scalar_exact(p)`` (the ray's entry state, blended as the walk blends), ``gradient_exact(p)`` (the hit's normal)
and the counters ``iso_cells`` (cell segments walked) and ``iso_solved`` (those whose range reaches across the
isovalue, solved). It needs :data:`renderers.gl.glsl.COMMON`
(``u_volume``, ``u_value_map``, ``u_extent``) and the isovalue ``ISO_VALUE`` (the uniform ``u_iso`` unless a
program defines another, as the lens's ``u_lens_iso``).
"""

CELL_WALK = """
#ifndef ISO_VALUE
#define ISO_VALUE u_iso         // the isovalue the walk crosses (a lens defines its own)
#endif
const float ISO_FAR = 3.0e38;
const int ISO_BISECTIONS = 24;   // halvings of a monotone piece: float32's resolution of a segment
int iso_cells;                   // cell segments walked by this invocation (the counter)
int iso_solved;                  // of those, the cells whose range reaches across the isovalue: solved

float corner_value(ivec3 c) {
    return texelFetch(u_volume, c, 0).r * u_value_map.x + u_value_map.y;
}

// The eight corners of the cell from voxel i0 to voxel i1 (equal on a clamped axis), x fastest.
float[8] cell_corners(ivec3 i0, ivec3 i1) {
    return float[8](corner_value(ivec3(i0.x, i0.y, i0.z)), corner_value(ivec3(i1.x, i0.y, i0.z)),
                    corner_value(ivec3(i0.x, i1.y, i0.z)), corner_value(ivec3(i1.x, i1.y, i0.z)),
                    corner_value(ivec3(i0.x, i0.y, i1.z)), corner_value(ivec3(i1.x, i0.y, i1.z)),
                    corner_value(ivec3(i0.x, i1.y, i1.z)), corner_value(ivec3(i1.x, i1.y, i1.z)));
}

int iso_region(float u, float slope, int n) {
    float c = floor(u);
    if (slope < 0.0 && u == c) {
        c -= 1.0;
    }
    return int(clamp(c, -1.0, float(n - 1)));
}

float iso_crossing(int c, float slope, float base, int n) {
    if (slope > 0.0) {
        return c + 1 > n - 1 ? ISO_FAR : (float(c + 1) - base) / slope;
    }
    if (slope < 0.0) {
        return c < 0 ? ISO_FAR : (float(c) - base) / slope;
    }
    return ISO_FAR;
}

// Corner indices and local coordinates at both ends of a segment in region c of one axis.
void iso_axis(int c, int n, float base, float slope, float t0, float t1, bool entered, bool leaving,
              out int i0, out int i1, out float f0, out float f1) {
    if (c < 0 || c >= n - 1) {
        i0 = i1 = clamp(c, 0, n - 1);
        f0 = f1 = 0.0;
        return;
    }
    i0 = c;
    i1 = c + 1;
    f0 = entered ? (slope > 0.0 ? 0.0 : 1.0) : clamp(base + t0 * slope - float(c), 0.0, 1.0);
    f1 = leaving ? (slope > 0.0 ? 1.0 : 0.0) : clamp(base + t1 * slope - float(c), 0.0, 1.0);
}

float iso_blend(float k[8], vec3 f) {
    float c00 = mix(k[0], k[1], f.x), c01 = mix(k[2], k[3], f.x);
    float c10 = mix(k[4], k[5], f.x), c11 = mix(k[6], k[7], f.x);
    return mix(mix(c00, c01, f.y), mix(c10, c11, f.y), f.z);
}

// Roots in (0, 1), ascending, of the derivative of the segment's cubic (reference: _stationary_points).
int iso_stationary(float k[8], vec3 x0, vec3 d, out float r0, out float r1) {
    float b = k[1] - k[0], c = k[2] - k[0], dd = k[4] - k[0];
    float e = k[3] - k[1] - k[2] + k[0];
    float f = k[5] - k[1] - k[4] + k[0];
    float g = k[6] - k[2] - k[4] + k[0];
    float h = k[7] - k[3] - k[5] - k[6] + k[1] + k[2] + k[4] - k[0];
    float k1 = b * d.x + c * d.y + dd * d.z + e * (x0.x * d.y + d.x * x0.y) + f * (x0.x * d.z + d.x * x0.z)
               + g * (x0.y * d.z + d.y * x0.z) + h * (d.x * x0.y * x0.z + x0.x * d.y * x0.z + x0.x * x0.y * d.z);
    float k2 = e * d.x * d.y + f * d.x * d.z + g * d.y * d.z
               + h * (d.x * d.y * x0.z + d.x * x0.y * d.z + x0.x * d.y * d.z);
    float k3 = h * d.x * d.y * d.z;
    float qa = 3.0 * k3, qb = 2.0 * k2, qc = k1;
    float s0 = 2.0, s1 = 2.0;
    if (qa == 0.0) {
        if (qb != 0.0) {
            s0 = -qc / qb;
        }
    } else {
        float disc = qb * qb - 4.0 * qa * qc;
        if (disc >= 0.0) {
            float q = -0.5 * (qb + (qb < 0.0 ? -sqrt(disc) : sqrt(disc)));
            s0 = q / qa;
            s1 = q != 0.0 ? qc / q : s0;
            if (s1 < s0) {
                float swap = s0; s0 = s1; s1 = swap;
            }
        }
    }
    int count = 0;
    r0 = r1 = 0.0;
    if (s0 > 0.0 && s0 < 1.0) {
        r0 = s0;
        count = 1;
    }
    if (s1 > 0.0 && s1 < 1.0 && s1 != s0) {
        if (count == 0) {
            r0 = s1;
        } else {
            r1 = s1;
        }
        count += 1;
    }
    return count;
}

// The first crossing on [t_lo, t_hi] of `s < ISO_VALUE` relative to `below` (ISO_FAR: none); ray p = start + t dir in
// texture coordinates.
float iso_first_crossing(vec3 start, vec3 dir, float t_lo, float t_hi, bool below) {
    ivec3 n = textureSize(u_volume, 0);
    vec3 base = start * vec3(n) - 0.5;
    vec3 slope = dir * vec3(n);
    float t0 = t_lo;
    ivec3 c;
    vec3 tc;
    for (int a = 0; a < 3; a++) {
        c[a] = iso_region(base[a] + t0 * slope[a], slope[a], n[a]);
        tc[a] = iso_crossing(c[a], slope[a], base[a], n[a]);
    }
    bvec3 entered = bvec3(false);
    for (int it = 0; it < n.x + n.y + n.z + 4; it++) {
        float t_next = min(tc.x, min(tc.y, tc.z));
        bool last = !(t_next < t_hi);
        float t1 = last ? t_hi : max(t_next, t0);
        bvec3 leaving = bvec3(!last && tc.x == t_next, !last && tc.y == t_next, !last && tc.z == t_next);
        ivec3 i0, i1;
        vec3 f0, f1;
        for (int a = 0; a < 3; a++) {
            iso_axis(c[a], n[a], base[a], slope[a], t0, t1, entered[a], leaving[a], i0[a], i1[a], f0[a], f1[a]);
        }
        float k[8] = cell_corners(i0, i1);
        iso_cells += 1;
        float top = max(max(max(k[0], k[1]), max(k[2], k[3])), max(max(k[4], k[5]), max(k[6], k[7])));
        float bottom = min(min(min(k[0], k[1]), min(k[2], k[3])), min(min(k[4], k[5]), min(k[6], k[7])));
        if (below ? !(top < ISO_VALUE) : bottom < ISO_VALUE) {   // the cell's range reaches across the isovalue
            iso_solved += 1;
            if ((iso_blend(k, f0) < ISO_VALUE) != below) {
                return t0;
            }
            vec3 d = f1 - f0;
            float r0, r1;
            int count = iso_stationary(k, f0, d, r0, r1);
            float lo = 0.0;
            for (int j = 0; j <= count; j++) {
                float hi = j == count ? 1.0 : (j == 0 ? r0 : r1);
                if ((iso_blend(k, f0 + d * hi) < ISO_VALUE) != below) {
                    for (int b = 0; b < ISO_BISECTIONS; b++) {
                        float mid = 0.5 * (lo + hi);
                        if ((iso_blend(k, f0 + d * mid) < ISO_VALUE) == below) {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                    return t0 + 0.5 * (lo + hi) * (t1 - t0);
                }
                lo = hi;
            }
        }
        if (last) {
            break;
        }
        entered = leaving;
        for (int a = 0; a < 3; a++) {
            if (leaving[a]) {
                c[a] += slope[a] > 0.0 ? 1 : -1;
                tc[a] = iso_crossing(c[a], slope[a], base[a], n[a]);
            }
        }
        t0 = t1;
    }
    return ISO_FAR;
}

// The exact scalar at p (the entry state of a ray), blended from fetched corners as the walk does.
float scalar_exact(vec3 p) {
    ivec3 n = textureSize(u_volume, 0);
    vec3 u = clamp(p * vec3(n) - 0.5, vec3(0.0), vec3(n - 1));
    ivec3 i0 = min(ivec3(floor(u)), n - 2);
    i0 = max(i0, ivec3(0));
    ivec3 i1 = min(i0 + 1, n - 1);
    vec3 f = u - vec3(i0);
    return iso_blend(cell_corners(i0, i1), f);
}

// The field's gradient at p as the reference defines it (central differences one voxel apart of the trilinear
// field, clamp-to-edge, over the spacing), from fetched corners: the hit's normal.
vec3 gradient_exact(vec3 p) {
    vec3 n = vec3(textureSize(u_volume, 0));
    vec3 e = 1.0 / n;
    vec3 spacing = u_extent / n;
    return vec3(scalar_exact(p + vec3(e.x, 0.0, 0.0)) - scalar_exact(p - vec3(e.x, 0.0, 0.0)),
                scalar_exact(p + vec3(0.0, e.y, 0.0)) - scalar_exact(p - vec3(0.0, e.y, 0.0)),
                scalar_exact(p + vec3(0.0, 0.0, e.z)) - scalar_exact(p - vec3(0.0, 0.0, e.z))) / (2.0 * spacing);
}
"""
