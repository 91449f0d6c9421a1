// The exact first crossing of a volume's iso-surface on a segment of a ray (build option ISO):
// the reference renderer's cell walk (renderers/reference/raycast.py, _walk_volume) in float32.
//
// The segment is walked with a 3-D DDA through the cells of the volume's voxel lattice (interior
// cells and the clamp-to-edge half voxels at the faces). In a cell whose eight corners reach across
// the isovalue from the ray's state, the trilinear field along the segment is a cubic in the ray
// parameter: cut at the roots of its derivative into monotone pieces, the first piece whose end
// changes state holds the crossing, which is bisected to float32's resolution of the segment
// (Marmitt et al. 2004). No crossing between two samples can be missed: there are no samples.
// A crossing is a change of `s < isovalue` from the state where the ray entered the volume, so a
// surface is seen from inside as well and a box face is not a surface.

#ifdef ISO
#define ISO_FAR INFINITY
#define ISO_BISECTIONS 24            // halvings of a monotone piece: float32's resolution of a segment

// Sampling (pixel.cl, which follows this file).
float load(__global const ATLAS_T* atlas, int4 atlas_dims, int x, int y, int z);
float trilinear(__global const ATLAS_T* atlas, int4 atlas_dims, int4 slot, int4 dims, float3 u);

// Lattice region of voxel coordinate u on an axis of n voxels, for a ray moving by `slope` (_region).
int iso_region(float u, float slope, int n) {
    float c = floor(u);
    if (slope < 0.0f && u == c) {
        c -= 1.0f;
    }
    return (int)clamp(c, -1.0f, (float)(n - 1));
}

// Ray parameter where the ray leaves region c of an axis through its far side (_crossing).
float iso_crossing(int c, float slope, float base, int n) {
    if (slope > 0.0f) {
        return c + 1 > n - 1 ? ISO_FAR : ((float)(c + 1) - base) / slope;
    }
    if (slope < 0.0f) {
        return c < 0 ? ISO_FAR : ((float)c - base) / slope;
    }
    return ISO_FAR;
}

// Corner indices and local coordinates at both ends of a segment in region c of one axis (_axis_span).
void iso_axis(int c, int n, float base, float slope, float t0, float t1, bool entered, bool leaving,
              int* i0, int* i1, float* f0, float* f1) {
    if (c < 0 || c >= n - 1) {
        *i0 = *i1 = clamp(c, 0, n - 1);
        *f0 = *f1 = 0.0f;
        return;
    }
    *i0 = c;
    *i1 = c + 1;
    *f0 = entered ? (slope > 0.0f ? 0.0f : 1.0f) : clamp(base + t0 * slope - (float)c, 0.0f, 1.0f);
    *f1 = leaving ? (slope > 0.0f ? 1.0f : 0.0f) : clamp(base + t1 * slope - (float)c, 0.0f, 1.0f);
}

float iso_blend(const float* k, float3 f) {
    float c00 = mix(k[0], k[1], f.x), c01 = mix(k[2], k[3], f.x);
    float c10 = mix(k[4], k[5], f.x), c11 = mix(k[6], k[7], f.x);
    return mix(mix(c00, c01, f.y), mix(c10, c11, f.y), f.z);
}

// Roots in (0, 1), ascending, of the derivative of the segment's cubic (_stationary_points).
int iso_stationary(const float* k, float3 x0, float3 d, float* r0, float* r1) {
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
    float qa = 3.0f * k3, qb = 2.0f * k2, qc = k1;
    float s0 = 2.0f, s1 = 2.0f;
    if (qa == 0.0f) {
        if (qb != 0.0f) {
            s0 = -qc / qb;
        }
    } else {
        float disc = qb * qb - 4.0f * qa * qc;
        if (disc >= 0.0f) {
            float q = -0.5f * (qb + (qb < 0.0f ? -sqrt(disc) : sqrt(disc)));
            s0 = q / qa;
            s1 = q != 0.0f ? qc / q : s0;
            if (s1 < s0) {
                float swap = s0;
                s0 = s1;
                s1 = swap;
            }
        }
    }
    int count = 0;
    *r0 = *r1 = 0.0f;
    if (s0 > 0.0f && s0 < 1.0f) {
        *r0 = s0;
        count = 1;
    }
    if (s1 > 0.0f && s1 < 1.0f && s1 != s0) {
        if (count == 0) {
            *r0 = s1;
        } else {
            *r1 = s1;
        }
        count += 1;
    }
    return count;
}

// The first crossing on [t0, t1] of `s < iso` of object o's field (ISO_FAR: none). *state is the
// ray's state in this volume: -1 before its first segment (then set from the field at t0, where
// the ray enters the volume), else 1 below the isovalue, 0 not. Adds the cell segments walked to
// *cells and those whose corners reach across the isovalue (solved) to *solved.
float iso_walk(float t_lo, float t_hi, __constant Object* o, float3 origin, float3 direction,
               __global const ATLAS_T* atlas, int4 atlas_dims, int* state, uint* cells, uint* solved) {
    float iso = o->params.z;
    int n[3] = {o->dims.x, o->dims.y, o->dims.z};
    float4 hp = (float4)(origin, 1.0f);
    float base[3] = {dot(o->to_voxel[0], hp), dot(o->to_voxel[1], hp), dot(o->to_voxel[2], hp)};
    float slope[3] = {dot(o->to_voxel[0].xyz, direction), dot(o->to_voxel[1].xyz, direction),
                      dot(o->to_voxel[2].xyz, direction)};
    float t0 = t_lo;
    int c[3];
    float tc[3];
    bool entered[3] = {false, false, false};
    for (int a = 0; a < 3; a++) {
        c[a] = iso_region(base[a] + t0 * slope[a], slope[a], n[a]);
        tc[a] = iso_crossing(c[a], slope[a], base[a], n[a]);
    }
    for (int it = 0; it < n[0] + n[1] + n[2] + 4; it++) {
        float t_next = fmin(tc[0], fmin(tc[1], tc[2]));
        bool last = !(t_next < t_hi);
        float t1 = last ? t_hi : fmax(t_next, t0);
        bool leaving[3];
        int i0[3], i1[3];
        float f0[3], f1[3];
        for (int a = 0; a < 3; a++) {
            leaving[a] = !last && tc[a] == t_next;
            iso_axis(c[a], n[a], base[a], slope[a], t0, t1, entered[a], leaving[a], &i0[a], &i1[a], &f0[a], &f1[a]);
        }
        float k[8] = {load(atlas, atlas_dims, o->slot.x + i0[0], o->slot.y + i0[1], o->slot.z + i0[2]),
                      load(atlas, atlas_dims, o->slot.x + i1[0], o->slot.y + i0[1], o->slot.z + i0[2]),
                      load(atlas, atlas_dims, o->slot.x + i0[0], o->slot.y + i1[1], o->slot.z + i0[2]),
                      load(atlas, atlas_dims, o->slot.x + i1[0], o->slot.y + i1[1], o->slot.z + i0[2]),
                      load(atlas, atlas_dims, o->slot.x + i0[0], o->slot.y + i0[1], o->slot.z + i1[2]),
                      load(atlas, atlas_dims, o->slot.x + i1[0], o->slot.y + i0[1], o->slot.z + i1[2]),
                      load(atlas, atlas_dims, o->slot.x + i0[0], o->slot.y + i1[1], o->slot.z + i1[2]),
                      load(atlas, atlas_dims, o->slot.x + i1[0], o->slot.y + i1[1], o->slot.z + i1[2])};
        float3 start = (float3)(f0[0], f0[1], f0[2]);
        (*cells)++;
        if (*state < 0) {
            *state = iso_blend(k, start) < iso;
        }
        bool below = *state;
        float top = fmax(fmax(fmax(k[0], k[1]), fmax(k[2], k[3])), fmax(fmax(k[4], k[5]), fmax(k[6], k[7])));
        float bottom = fmin(fmin(fmin(k[0], k[1]), fmin(k[2], k[3])), fmin(fmin(k[4], k[5]), fmin(k[6], k[7])));
        if (below ? !(top < iso) : bottom < iso) {   // the cell's range reaches across the isovalue
            (*solved)++;
            if ((iso_blend(k, start) < iso) != below) {
                return t0;
            }
            float3 d = (float3)(f1[0], f1[1], f1[2]) - start;
            float r0, r1;
            int count = iso_stationary(k, start, d, &r0, &r1);
            float lo = 0.0f;
            for (int j = 0; j <= count; j++) {
                float hi = j == count ? 1.0f : (j == 0 ? r0 : r1);
                if ((iso_blend(k, start + d * hi) < iso) != below) {
                    for (int b = 0; b < ISO_BISECTIONS; b++) {
                        float mid = 0.5f * (lo + hi);
                        if ((iso_blend(k, start + d * mid) < iso) == below) {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                    return t0 + 0.5f * (lo + hi) * (t1 - t0);
                }
                lo = hi;
            }
        }
        if (last) {
            break;
        }
        for (int a = 0; a < 3; a++) {
            entered[a] = leaving[a];
            if (leaving[a]) {
                c[a] += slope[a] > 0.0f ? 1 : -1;
                tc[a] = iso_crossing(c[a], slope[a], base[a], n[a]);
            }
        }
        t0 = t1;
    }
    return ISO_FAR;
}

// The states of the volumes `entered` (object bits) where the ray enters their boxes at t: their
// bits of `below` set to `s < isovalue` there (the reference takes a crossing relative to it).
ulong iso_entry_states(ulong entered, float t, float3 origin, float3 direction, __constant Object* objects,
                       __global const ATLAS_T* atlas, int4 atlas_dims, ulong below) {
    float4 hp = (float4)(origin + t * direction, 1.0f);
    for (ulong pending = entered; pending;) {
        ulong lowest = pending & (~pending + 1UL);
        pending ^= lowest;
        __constant Object* o = &objects[63 - (int)clz(lowest)];
        float3 u = (float3)(dot(o->to_voxel[0], hp), dot(o->to_voxel[1], hp), dot(o->to_voxel[2], hp));
        below = trilinear(atlas, atlas_dims, o->slot, o->dims, u) < o->params.z ? (below | lowest) : (below & ~lowest);
    }
    return below;
}

// The first crossing on [t0, t1] of any volume of `volumes` (object bits): the nearest, the lower
// object on a tie (the reference's order); *hit_object is set and the crossing returned, or ISO_FAR.
// Each volume's state is its bit of `below` (iso_entry_states). A crossing at t0 itself is where a
// boundary or CSG opens the volume inside its surface: the cut face (a cap), as the reference draws it.
float iso_segment(float t0, float t1, ulong volumes, float3 origin, float3 direction, __constant Object* objects,
                  __global const ATLAS_T* atlas, int4 atlas_dims, ulong below, int* hit_object, uint* cells,
                  uint* solved) {
    float nearest = ISO_FAR;
    for (ulong pending = volumes; pending;) {
        ulong lowest = pending & (~pending + 1UL);
        pending ^= lowest;
        int obj = 63 - (int)clz(lowest);
        int state = (below & lowest) != 0UL;
        float t = iso_walk(t0, fmin(t1, nearest), &objects[obj], origin, direction, atlas, atlas_dims, &state, cells,
                           solved);
        if (t < nearest) {
            nearest = t;
            *hit_object = obj;
        }
    }
    return nearest;
}
#endif
