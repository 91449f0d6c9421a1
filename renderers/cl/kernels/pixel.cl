// Pixel kernel (Kainz et al. 2009, §3.2-3.3): one 8x8 work-group per tile, one work-item per pixel.
// Each work-item gathers the fragments of its pixel from the tile's records, keeps them sorted by
// depth, then walks the homogeneous segments between consecutive fragments front to back with the
// set of objects the ray is inside, sampling every active volume at one common world step.
//
// Build options:
//   ATLAS_T, ATLAS_SCALE  atlas element type and its factor to the normalised scalar
//   MAXF                  fragments kept per pixel in local memory (the depth cap; paper: 63)
//   GLOBAL_FRAGMENTS      unbounded per-pixel lists in global memory instead (the ground truth)
//   PHONG, GRADIENT_OPACITY
//
// Fragment records are (depth, code), code = object << 24 | front << 23 | triangle.

#define CODE_OBJECT(c) ((c) >> 24)
#define CODE_FRONT(c) (((c) >> 23) & 1u)
#define SLIVER 1e-3f                 // partial cells shorter than this fraction of the step are skipped
#define MAX_GRADIENT 0.8660254037844386f

#ifdef GLOBAL_FRAGMENTS
#define FRAG_SPACE __global
#else
#define FRAG_SPACE __local
#endif

// Every work-item of the tile runs this loop (it holds barriers): the work-group loads one chunk
// of records into local memory (chunk_mask, chunk_triangle of PIXEL_SETUP) at a time and each work-item tests its own bit in each mask.
// BODY sees `code` and `depth` (ray parameter of the triangle's plane) of each covering triangle.
#define FOR_EACH_FRAGMENT(BODY)                                                                     \
    {                                                                                               \
        uint records = min(tile_count[tile], (uint)(CHUNK * MAX_CHUNKS));                           \
        for (uint first = 0; first < records; first += CHUNK) {                                     \
            barrier(CLK_LOCAL_MEM_FENCE);                                                           \
            if (first + lid < records) {                                                            \
                uint chunk = tile_chunks[tile * MAX_CHUNKS + first / CHUNK];                        \
                chunk_mask[lid] = pool_mask[chunk * CHUNK + lid];                                   \
                chunk_triangle[lid] = pool_triangle[chunk * CHUNK + lid];                           \
            }                                                                                       \
            barrier(CLK_LOCAL_MEM_FENCE);                                                           \
            uint in_chunk = min((uint)CHUNK, records - first);                                      \
            for (uint r = 0; r < in_chunk; r++) {                                                   \
                if (!in_image || !((chunk_mask[r] >> lid) & 1UL)) {                                 \
                    continue;                                                                       \
                }                                                                                   \
                uint tri = chunk_triangle[r];                                                       \
                float4 plane = planes[tri];                                                         \
                float depth = -(dot(plane.xyz, origin) + plane.w) / dot(plane.xyz, direction);     \
                uint code = codes[tri];                                                             \
                if (!isfinite(depth)) {                                                             \
                    continue;                                                                       \
                }                                                                                   \
                BODY                                                                                \
            }                                                                                       \
        }                                                                                           \
    }

#define PIXEL_SETUP                                                                                 \
    __local ulong chunk_mask[CHUNK];                                                                \
    __local uint chunk_triangle[CHUNK];                                                             \
    int lid = get_local_id(1) * TILE + get_local_id(0);                                             \
    uint tile = get_group_id(1) * tiles_x + get_group_id(0);                                        \
    int col = get_global_id(0), row = get_global_id(1);                                             \
    bool in_image = col < width && row < height;                                                    \
    float3 origin, direction;                                                                       \
    pixel_ray(min(col, width - 1), min(row, height - 1), width, height, eye, right, up, back,      \
              half_size, perspective, &origin, &direction);

// Insert (depth, code) into the list base[0], base[stride], ... of n entries sorted by depth then
// code, keeping at most `cap`: a full list drops its farthest entry. Returns 1 if one was dropped.
int insert_fragment(FRAG_SPACE float* depths, FRAG_SPACE uint* codes_out, int stride, int* n, int cap,
                    float depth, uint code) {
    int j = *n;
    int dropped = 0;
    if (j == cap) {
        float last_depth = depths[(cap - 1) * stride];
        uint last_code = codes_out[(cap - 1) * stride];
        if (depth > last_depth || (depth == last_depth && code >= last_code)) {
            return 1;
        }
        j = cap - 1;
        dropped = 1;
    } else {
        *n = j + 1;
    }
    while (j > 0) {
        float d = depths[(j - 1) * stride];
        uint c = codes_out[(j - 1) * stride];
        if (d < depth || (d == depth && c < code)) {
            break;
        }
        depths[j * stride] = d;
        codes_out[j * stride] = c;
        j--;
    }
    depths[j * stride] = depth;
    codes_out[j * stride] = code;
    return dropped;
}

// ---------------------------------------------------------------------------------------------
// Sampling: the reference renderer's (renderers/reference/raycast.py) in float32.

float load(__global const ATLAS_T* atlas, int4 atlas_dims, int x, int y, int z) {
    return (float)atlas[((long)z * atlas_dims.y + y) * atlas_dims.x + x] * ATLAS_SCALE;
}

// Clamp-to-edge linear filter along one axis of n voxels: lower voxel, upper voxel, upper weight.
void axis_cell(float u, int n, int* i0, int* i1, float* w) {
    if (u <= 0.0f) {
        *i0 = 0; *i1 = 0; *w = 0.0f;
    } else if (u >= (float)(n - 1)) {
        *i0 = n - 1; *i1 = n - 1; *w = 0.0f;
    } else {
        float f = floor(u);
        *i0 = (int)f; *i1 = *i0 + 1; *w = u - f;
    }
}

// Trilinear scalar at continuous voxel coordinates u of the volume in atlas slot `slot`.
float trilinear(__global const ATLAS_T* atlas, int4 atlas_dims, int4 slot, int4 dims, float3 u) {
    int x0, x1, y0, y1, z0, z1;
    float fx, fy, fz;
    axis_cell(u.x, dims.x, &x0, &x1, &fx);
    axis_cell(u.y, dims.y, &y0, &y1, &fy);
    axis_cell(u.z, dims.z, &z0, &z1, &fz);
    x0 += slot.x; x1 += slot.x; y0 += slot.y; y1 += slot.y; z0 += slot.z; z1 += slot.z;
    float c00 = mix(load(atlas, atlas_dims, x0, y0, z0), load(atlas, atlas_dims, x1, y0, z0), fx);
    float c01 = mix(load(atlas, atlas_dims, x0, y1, z0), load(atlas, atlas_dims, x1, y1, z0), fx);
    float c10 = mix(load(atlas, atlas_dims, x0, y0, z1), load(atlas, atlas_dims, x1, y0, z1), fx);
    float c11 = mix(load(atlas, atlas_dims, x0, y1, z1), load(atlas, atlas_dims, x1, y1, z1), fx);
    return mix(mix(c00, c01, fy), mix(c10, c11, fy), fz);
}

// Linear lookup in a table of `size` entries, entry i at x = i / (size - 1), clamped.
void table_position(float x, int size, int* i0, float* w) {
    if (x <= 0.0f) {
        *i0 = 0; *w = 0.0f;
    } else if (x >= 1.0f) {
        *i0 = size - 2; *w = 1.0f;
    } else {
        float f = x * (float)(size - 1);
        *i0 = min((int)floor(f), size - 2);
        *w = f - (float)*i0;
    }
}

#if defined(PHONG) || defined(GRADIENT_OPACITY)
// Central differences of the trilinear field one voxel apart (times 2s: scaled by the caller).
float3 voxel_differences(__global const ATLAS_T* atlas, int4 atlas_dims, int4 slot, int4 dims, float3 u) {
    const float3 ex = (float3)(1.0f, 0.0f, 0.0f), ey = (float3)(0.0f, 1.0f, 0.0f), ez = (float3)(0.0f, 0.0f, 1.0f);
    return (float3)(trilinear(atlas, atlas_dims, slot, dims, u + ex) - trilinear(atlas, atlas_dims, slot, dims, u - ex),
                    trilinear(atlas, atlas_dims, slot, dims, u + ey) - trilinear(atlas, atlas_dims, slot, dims, u - ey),
                    trilinear(atlas, atlas_dims, slot, dims, u + ez) - trilinear(atlas, atlas_dims, slot, dims, u - ez));
}
#endif

#ifdef PHONG
// Two-sided Blinn-Phong (core.scene.Shading) with the world-space normal n (unnormalised).
float3 blinn_phong(float3 rgb, float3 n, float3 light, float3 half_vector, bool has_half, float4 phong) {
    float norm = length(n);
    float factor = phong.x;
    float highlight = 0.0f;
    if (norm > 0.0f) {
        factor += phong.y * fabs(dot(n, light)) / norm;
        if (has_half) {
            highlight = phong.z * pow(fabs(dot(n, half_vector)) / norm, phong.w);
        }
    }
    return clamp(rgb * factor + highlight, 0.0f, 1.0f);
}
#endif

// ---------------------------------------------------------------------------------------------

#ifdef GLOBAL_FRAGMENTS
// Fragments per pixel (front- and back-facing, depth >= 0): sizes the unbounded lists and shows
// coverage (a closed mesh gives every pixel as many front as back fragments).
__kernel __attribute__((reqd_work_group_size(TILE, TILE, 1)))
void count_fragments(__global const uint* tile_count, __global const uint* tile_chunks,
                     __global const ulong* pool_mask, __global const uint* pool_triangle,
                     __global const float4* planes, __global const uint* codes,
                     float4 eye, float4 right, float4 up, float4 back, float2 half_size, int perspective,
                     int width, int height, int tiles_x, __global uint2* counts) {
    PIXEL_SETUP
    uint2 found = (uint2)(0u);
    FOR_EACH_FRAGMENT(
        if (depth >= 0.0f) {
            if (CODE_FRONT(code)) found.x++; else found.y++;
        }
    )
    if (in_image) {
        counts[row * width + col] = found;
    }
}
#endif

__kernel __attribute__((reqd_work_group_size(TILE, TILE, 1)))
void cast_tiles(__global const uint* tile_count, __global const uint* tile_chunks,
                __global const ulong* pool_mask, __global const uint* pool_triangle,
                __global const float4* planes, __global const uint* codes,
                float4 eye, float4 right, float4 up, float4 back, float2 half_size, int perspective,
                int width, int height, int tiles_x,
                __constant Object* objects, __global const ATLAS_T* atlas, int4 atlas_dims,
                __global const float4* transfer, __global const float* gradient_tables,
                float step, float threshold, float4 light, float4 phong,
#ifdef GLOBAL_FRAGMENTS
                __global const uint* offsets, __global float* list_depth, __global uint* list_code,
#endif
                __global float4* image, __global uint4* stats) {
    PIXEL_SETUP
#ifdef GLOBAL_FRAGMENTS
    uint pixel = in_image ? row * width + col : 0;
    FRAG_SPACE float* depths = list_depth + offsets[pixel];
    FRAG_SPACE uint* frag_codes = list_code + offsets[pixel];
    int stride = 1;
    int cap = in_image ? (int)(offsets[pixel + 1] - offsets[pixel]) : 0;
#else
    __local float local_depth[MAXF * TILE_PIXELS];
    __local uint local_code[MAXF * TILE_PIXELS];
    FRAG_SPACE float* depths = local_depth + lid;      // interleaved: entry j of this pixel at j*64 + lid
    FRAG_SPACE uint* frag_codes = local_code + lid;
    int stride = TILE_PIXELS;
    int cap = MAXF;
#endif
    int n = 0;
    uint dropped = 0;
    ulong inside = 0UL;                  // objects around the ray origin: parity of crossings behind it
    FOR_EACH_FRAGMENT(
        if (depth < 0.0f) {
            inside ^= 1UL << CODE_OBJECT(code);
        } else {
            dropped += insert_fragment(depths, frag_codes, stride, &n, cap, depth, code);
        }
    )
    if (!in_image) {
        return;
    }

    float3 light_dir = light.xyz;
    float3 half_vector = light_dir - direction;
    bool has_half = length(half_vector) > 0.0f;
    half_vector = has_half ? normalize(half_vector) : half_vector;

    float4 color = (float4)(0.0f);
    uint samples = 0;
    uint terminated = 0;
    ulong active = inside;
    float t0 = 0.0f;
    float anchor = 0.0f;                 // cells [anchor + k*step, anchor + (k+1)*step]
    bool anchored = false;
    for (int k = 0; k <= n && !terminated; k++) {
        float t1 = k < n ? depths[k * stride] : t0;
        if (active && t1 > t0) {
            // A homogeneous segment [t0, t1] with the objects of `active` (empty ones are skipped).
            if (!anchored) {
                anchor = t0;             // the first entry: the reference's t_first
                anchored = true;
            }
            int cell = max((int)floor((t0 - anchor) / step), 0);
            while (cell > 0 && anchor + (float)cell * step > t0) cell--;
            while (anchor + (float)(cell + 1) * step <= t0) cell++;
            for (;; cell++) {
                float a = anchor + (float)cell * step;
                if (a >= t1) {
                    break;
                }
                float b = anchor + (float)(cell + 1) * step;
                float lo = fmax(a, t0), hi = fmin(b, t1);
                float span = hi - lo;
                if (span <= SLIVER * step) {
                    continue;
                }
                // A whole cell samples at its centre, one a boundary cuts at its part's midpoint.
                float t = (lo == a && hi == b) ? anchor + ((float)cell + 0.5f) * step : 0.5f * (lo + hi);
                float3 p = origin + t * direction;
                float4 sum = (float4)(0.0f);
                ulong pending = active;
                while (pending) {
                    ulong lowest = pending & (~pending + 1UL);
                    int obj = 63 - (int)clz(lowest);
                    pending ^= lowest;
                    __constant Object* o = &objects[obj];
                    float4 hp = (float4)(p, 1.0f);
                    float3 u = (float3)(dot(o->to_voxel[0], hp), dot(o->to_voxel[1], hp), dot(o->to_voxel[2], hp));
                    samples++;
                    float s = trilinear(atlas, atlas_dims, o->slot, o->dims, u);
                    int i0;
                    float w;
                    table_position(s, o->tables.y, &i0, &w);
                    float4 c = mix(transfer[o->tables.x + i0], transfer[o->tables.x + i0 + 1], w);
                    float alpha = c.w;
                    if (alpha <= 0.0f) {
                        continue;
                    }
#if defined(PHONG) || defined(GRADIENT_OPACITY)
                    float3 diff = voxel_differences(atlas, atlas_dims, o->slot, o->dims, u);
#endif
#ifdef GRADIENT_OPACITY
                    if (o->tables.w > 0) {
                        float magnitude = length(diff * 0.5f / o->spacing.xyz);
                        table_position(magnitude * o->params.y, o->tables.w, &i0, &w);
                        alpha *= mix(gradient_tables[o->tables.z + i0], gradient_tables[o->tables.z + i0 + 1], w);
                        if (alpha <= 0.0f) {
                            continue;
                        }
                    }
#endif
                    // Opacity correction for the object-space length of this sample's cell part.
                    float3 d_voxel = (float3)(dot(o->to_voxel[0].xyz, direction), dot(o->to_voxel[1].xyz, direction),
                                              dot(o->to_voxel[2].xyz, direction));
                    float ratio = length(d_voxel * o->spacing.xyz) * span / o->spacing.w;
                    alpha = -expm1(ratio * log1p(-alpha));
                    float3 rgb = c.xyz;
#ifdef PHONG
                    float3 normal = (float3)(dot(o->gradient[0].xyz, diff), dot(o->gradient[1].xyz, diff),
                                             dot(o->gradient[2].xyz, diff));
                    rgb = blinn_phong(rgb, normal, light_dir, half_vector, has_half, phong);
#endif
                    sum += (float4)(alpha * rgb, alpha);
                }
                if (sum.w > 0.0f) {
                    // Overlapping volumes: premultiplied samples summed, opacity clamped to 1.
                    if (sum.w > 1.0f) {
                        sum /= sum.w;
                    }
                    color += (1.0f - color.w) * sum;
                    if (color.w > threshold) {
                        terminated = 1;
                        break;
                    }
                }
            }
        }
        if (k == n) {
            break;
        }
        uint code = frag_codes[k * stride];
        ulong bit = 1UL << CODE_OBJECT(code);
        active = CODE_FRONT(code) ? (active | bit) : (active & ~bit);
        t0 = t1;
    }
    image[row * width + col] = color;
    stats[row * width + col] = (uint4)((uint)n, dropped, samples, terminated);
}
