// Pixel kernel (Kainz et al. 2009, §3.2-3.3): one 8x8 work-group per tile, one work-item per pixel.
// Each work-item gathers the fragments of its pixel from the tile's records, keeps them sorted by
// depth, then walks them front to back with the set of objects the ray is inside (one bit each),
// evaluates which leaves contribute (volume boundaries, the CSG forest), samples the contributing
// volumes at one common world step, composites homogeneous media analytically and draws surfaces
// where their tree's root changes inside/outside.
//
// Build options:
//   ATLAS_T, ATLAS_SCALE  atlas element type and its factor to the normalised scalar
//   MAXF                  fragments kept per pixel in local memory (the depth cap; paper: 63)
//   GLOBAL_FRAGMENTS      unbounded per-pixel lists in global memory instead (the ground truth)
//   PHONG, GRADIENT_OPACITY
//   CSG                   the scene has CSG trees (evaluate_forest); without, every leaf stands alone
//   SAMPLED_MEDIA         segments of media alone are composited cell by cell at the common step
//                         instead of analytically over the segment (the shortcut's ablation, E9)
//   SORT_ONLY             stop after gathering and sorting the fragments (the ablation that times
//                         them, E7): the image stays transparent, the counters are written
//   MIP                   keep the largest scalar along the ray instead of compositing (mip_segment)
//   ISO                   the first crossing of any volume's iso-surface, exact (iso_segment, iso.cl)
//
// The objects around the ray origin: an orthographic ray starts on the image plane, and the
// crossings behind it (depth < 0) toggle their objects; a perspective ray starts at the eye, whose
// objects the host finds (eye_inside), and every crossing it bins lies in front of the eye, so a
// depth below 0 is rounding and counts as 0.
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
// Adds the entries it shifts to *moves (the insertion sort's work: 0 for input in depth order).
int insert_fragment(FRAG_SPACE float* depths, FRAG_SPACE uint* codes_out, int stride, int* n, int cap,
                    float depth, uint code, uint* moves) {
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
        (*moves)++;
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
        if (depth >= 0.0f || perspective) {
            if (CODE_FRONT(code)) found.x++; else found.y++;
        }
    )
    if (in_image) {
        counts[row * width + col] = found;
    }
}
#endif

// ---------------------------------------------------------------------------------------------
// Leaves and CSG (core.scene semantics; objects and leaves as renderers/cl/scene.py numbers them).

// Leaves the ray is inside, from the objects' inside mask: leaf i is object i, and a volume with
// a polygonal boundary (object leaf_count + j bounds volume boundary_volume[j]) is inside only
// where its box (or hull) and its boundary both are.
ulong leaves_inside(ulong inside, ulong leaf_bits, __global const int* boundary_volume, int leaf_count,
                    int boundary_count) {
    ulong leaves = inside & leaf_bits;
    for (int j = 0; j < boundary_count; j++) {
        if (!((inside >> (leaf_count + j)) & 1UL)) {
            leaves &= ~(1UL << boundary_volume[j]);
        }
    }
    return leaves;
}

#ifdef CSG
#define MAX_CSG_NODES 128            // trees over at most 64 leaves have at most 127 nodes
#define OP_LEAF 0
#define OP_UNION 1
#define OP_INTERSECTION 2
#define OP_OPERATION 3               // the operation bits of a node's code
#define OP_FIRST 4                   // flag: the node is its parent's first child

// The CSG forest, a postfix program (int4 per node: code, leaf or first child entry, child count,
// parent), over the leaves' inside mask. Returns the tree leaves that contribute (inside, and let
// through by every ancestor) and sets *roots to the tree leaves whose tree's root is inside.
ulong evaluate_forest(ulong leaves, __global const int4* nodes, __global const int* children, int count,
                      ulong* roots) {
    uchar value[MAX_CSG_NODES], pass[MAX_CSG_NODES], root[MAX_CSG_NODES];
    for (int j = 0; j < count; j++) {
        int4 node = nodes[j];
        int op = node.x & OP_OPERATION;
        bool v;
        if (op == OP_LEAF) {
            v = (leaves >> node.y) & 1UL;
        } else {
            v = op != OP_UNION;          // union: any child; intersection: all; difference: the first, no other
            for (int c = 0; c < node.z; c++) {
                bool child = value[children[node.y + c]];
                v = op == OP_UNION ? (v || child) : op == OP_INTERSECTION ? (v && child) : (v && (c == 0) == child);
            }
        }
        value[j] = v;
    }
    ulong contributing = 0UL, inside_roots = 0UL;
    for (int j = count - 1; j >= 0; j--) {   // parents come after their children
        int4 node = nodes[j];
        if (node.w < 0) {
            pass[j] = 1;
            root[j] = value[j];
        } else {
            int op = nodes[node.w].x & OP_OPERATION;
            pass[j] = pass[node.w] && (op == OP_UNION
                                       || (value[node.w] && (op == OP_INTERSECTION || (node.x & OP_FIRST))));
            root[j] = root[node.w];
        }
        if ((node.x & OP_OPERATION) == OP_LEAF) {
            contributing |= (ulong)(value[j] && pass[j]) << node.y;
            inside_roots |= (ulong)root[j] << node.y;
        }
    }
    *roots = inside_roots;
    return contributing;
}
#endif

// The leaves contributing in a segment and (*roots) the leaves whose tree's root is inside; a
// standalone leaf is its own root.
ulong leaf_state(ulong inside, ulong leaf_bits, ulong tree_leaves, __global const int* boundary_volume,
                 int leaf_count, int boundary_count, __global const int4* csg_nodes, __global const int* csg_children,
                 int csg_count, ulong* roots) {
    ulong leaves = leaves_inside(inside, leaf_bits, boundary_volume, leaf_count, boundary_count);
#ifdef CSG
    ulong tree_roots;
    ulong contributing = evaluate_forest(leaves, csg_nodes, csg_children, csg_count, &tree_roots);
    *roots = (leaves & ~tree_leaves) | tree_roots;
    return (leaves & ~tree_leaves) | contributing;
#else
    *roots = leaves;
    return leaves;
#endif
}

// Overlapping homogeneous media: (sum of sigma * colour, sum of sigma) over the contributing leaves.
float4 media_of(ulong contributing, __global const float4* materials) {
    float4 sum = (float4)(0.0f);
    while (contributing) {
        ulong lowest = contributing & (~contributing + 1UL);
        int leaf = 63 - (int)clz(lowest);
        contributing ^= lowest;
        float4 medium = materials[3 * leaf + 2];
        sum += (float4)(medium.w * medium.xyz, medium.w);
    }
    return sum;
}

// Premultiplied colour and opacity of media (sigma-weighted colour) over a world length.
float4 media_sample(float4 media, float length) {
    float alpha = -expm1(-media.w * length);
    return (float4)(alpha * media.xyz / media.w, alpha);
}

// ---------------------------------------------------------------------------------------------

// Composite the segment [t0, t1] in which the volumes of `volumes` and the media `media` (see
// media_of) contribute into *color. Volumes are sampled on the cells [anchor + k*step, ...]; media
// alone are composited analytically over the whole segment (one step), or on the cells with
// SAMPLED_MEDIA. Adds volume samples to *samples and media steps to *medium_steps. Returns 1 on
// early termination.
int composite_segment(float t0, float t1, ulong volumes, float4 media, float anchor, float step, float threshold,
                      float3 origin, float3 direction, __constant Object* objects, __global const ATLAS_T* atlas,
                      int4 atlas_dims, __global const float4* transfer, __global const float* gradient_tables,
                      float3 light_dir, float3 half_vector, bool has_half, float4 phong, float4* color,
                      uint* samples, uint* medium_steps) {
#ifndef SAMPLED_MEDIA
    if (!volumes) {
        (*medium_steps)++;
        *color += (1.0f - color->w) * media_sample(media, t1 - t0);
        return color->w > threshold;
    }
#endif
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
        if (media.w > 0.0f) {
            sum = media_sample(media, span);
            *medium_steps += !volumes;
        }
        ulong pending = volumes;
        while (pending) {
            ulong lowest = pending & (~pending + 1UL);
            int obj = 63 - (int)clz(lowest);
            pending ^= lowest;
            __constant Object* o = &objects[obj];
            float4 hp = (float4)(p, 1.0f);
            float3 u = (float3)(dot(o->to_voxel[0], hp), dot(o->to_voxel[1], hp), dot(o->to_voxel[2], hp));
            (*samples)++;
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
            // Overlapping volumes and media: premultiplied samples summed, opacity clamped to 1.
            if (sum.w > 1.0f) {
                sum /= sum.w;
            }
            *color += (1.0f - color->w) * sum;
            if (color->w > threshold) {
                return 1;
            }
        }
    }
    return 0;
}

#ifdef MIP
// The normalised scalar of object `obj` at ray parameter t, kept in *best (and its object) when it
// is larger than the maximum so far, so ties keep the nearer sample and then the lower object.
void mip_sample(float t, int obj, float3 origin, float3 direction, __constant Object* objects,
                __global const ATLAS_T* atlas, int4 atlas_dims, float* best, int* best_object, uint* samples) {
    __constant Object* o = &objects[obj];
    float4 hp = (float4)(origin + t * direction, 1.0f);
    float3 u = (float3)(dot(o->to_voxel[0], hp), dot(o->to_voxel[1], hp), dot(o->to_voxel[2], hp));
    float s = trilinear(atlas, atlas_dims, o->slot, o->dims, u);
    (*samples)++;
    if (s > *best) {
        *best = s;
        *best_object = obj;
    }
}

// Maximum intensity along the segment [t0, t1] of the volumes of `volumes`: each samples both ends
// and the cells of composite_segment (a whole cell at its centre, a cut one at its part's middle),
// as gl-raycast does. The raw scalar is compared, not its classification (the reference's mip), so
// a transparent voxel can hold the maximum: empty space is never skipped in this mode. Returns 1
// once the maximum reaches 1, the top of the normalised range: no later sample can replace it.
int mip_segment(float t0, float t1, ulong volumes, float anchor, float step, float3 origin, float3 direction,
                __constant Object* objects, __global const ATLAS_T* atlas, int4 atlas_dims, float* best,
                int* best_object, uint* samples) {
    int cell = max((int)floor((t0 - anchor) / step), 0);
    while (cell > 0 && anchor + (float)cell * step > t0) cell--;
    while (anchor + (float)(cell + 1) * step <= t0) cell++;
    for (float t = t0;;) {
        for (ulong pending = volumes; pending;) {
            ulong lowest = pending & (~pending + 1UL);
            pending ^= lowest;
            mip_sample(t, 63 - (int)clz(lowest), origin, direction, objects, atlas, atlas_dims, best, best_object,
                       samples);
        }
        if (*best >= 1.0f) {
            return 1;
        }
        if (t == t1) {
            return 0;
        }
        for (;; cell++) {                // the next cell's sample, or the segment's end
            float a = anchor + (float)cell * step, b = anchor + (float)(cell + 1) * step;
            float lo = fmax(a, t0), hi = fmin(b, t1);
            if (a >= t1) {
                t = t1;
                break;
            }
            if (hi - lo > SLIVER * step) {
                t = (lo == a && hi == b) ? anchor + ((float)cell + 0.5f) * step : 0.5f * (lo + hi);
                cell++;
                break;
            }
        }
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
                __global const float4* materials, __global const int* boundary_volume, int leaf_count,
                int boundary_count, __global const int4* csg_nodes, __global const int* csg_children, int csg_count,
                ulong leaf_bits, ulong volume_leaves, ulong surface_leaves, ulong medium_leaves, ulong tree_leaves,
                ulong eye_inside,
#ifdef GLOBAL_FRAGMENTS
                __global const uint* offsets, __global float* list_depth, __global uint* list_code,
#endif
                __global float4* image, __global uint8* stats) {
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
    uint dropped = 0, moves = 0;
    ulong inside = eye_inside;           // objects around the ray origin (see the notes at the top)
    FOR_EACH_FRAGMENT(
        if (depth < 0.0f && !perspective) {
            inside ^= 1UL << CODE_OBJECT(code);
        } else {
            dropped += insert_fragment(depths, frag_codes, stride, &n, cap, fmax(depth, 0.0f), code, &moves);
        }
    )
    if (!in_image) {
        return;
    }
#ifdef SORT_ONLY
    image[row * width + col] = (float4)(0.0f);
    stats[row * width + col] = (uint8)((uint)n, dropped, 0u, 0u, moves, 0u, 0u, 0u);
    return;
#endif

    float3 light_dir = light.xyz;
    float3 half_vector = light_dir - direction;
    bool has_half = length(half_vector) > 0.0f;
    half_vector = has_half ? normalize(half_vector) : half_vector;

    float4 color = (float4)(0.0f);
    uint samples = 0, medium_steps = 0;
#ifdef MIP
    float best = -INFINITY;              // the largest scalar so far, and its object (-1: none)
    int best_object = -1;
#endif
#ifdef ISO
    ulong iso_below = iso_entry_states(inside & volume_leaves, 0.0f, origin, direction, objects, atlas, atlas_dims,
                                       0UL);   // each volume's state where the ray entered its box (iso_segment)
    int hit_object = -1;
    float hit_t = 0.0f;
    uint solved = 0;
#endif
    int terminated = 0;
    ulong roots;
    ulong contributing = leaf_state(inside, leaf_bits, tree_leaves, boundary_volume, leaf_count, boundary_count,
                                    csg_nodes, csg_children, csg_count, &roots);
    float t0 = 0.0f;                     // start of the open segment: `contributing` holds since t0
    bool anchored = (inside & volume_leaves) != 0UL;
    float anchor = 0.0f;                 // cells [anchor + k*step, anchor + (k+1)*step]
    // Fragments at one depth form a group; the open segment closes where a group changes the
    // contributing leaves or shows a surface (where its tree's root changes inside/outside).
    for (int k = 0; k < n && !terminated;) {
        float t1 = depths[k * stride];
        int end = k;
        ulong after = inside;
        while (end < n && depths[end * stride] == t1) {
            after ^= 1UL << CODE_OBJECT(frag_codes[end * stride]);
            end++;
        }
        ulong roots_after;
        ulong contributing_after = leaf_state(after, leaf_bits, tree_leaves, boundary_volume, leaf_count,
                                              boundary_count, csg_nodes, csg_children, csg_count, &roots_after);
        ulong shown = (roots ^ roots_after) & surface_leaves;
        if (contributing_after != contributing || shown) {
            ulong volumes = contributing & volume_leaves;
            if (contributing && t1 > t0 && (volumes || (contributing & medium_leaves))) {
                if (volumes && !anchored) {
                    anchor = t0;
                    anchored = true;
                }
#if defined(MIP)
                terminated = mip_segment(t0, t1, volumes, anchor, step, origin, direction, objects, atlas, atlas_dims,
                                         &best, &best_object, &samples);
#elif defined(ISO)
                // The surface's first crossing in this segment, then the media in front of it.
                float end = t1;
                if (volumes) {
                    hit_t = iso_segment(t0, t1, volumes, origin, direction, objects, atlas, atlas_dims, iso_below,
                                        &hit_object, &samples, &solved);
                    end = hit_object >= 0 ? hit_t : t1;
                }
                float4 media = media_of(contributing & medium_leaves, materials);
                if (media.w > 0.0f && end > t0) {
                    medium_steps++;
                    color += (1.0f - color.w) * media_sample(media, end - t0);
                }
                terminated = hit_object >= 0 || color.w > threshold;
#else
                terminated = composite_segment(t0, t1, volumes, media_of(contributing & medium_leaves, materials),
                                               anchor, step, threshold, origin, direction, objects, atlas,
                                               atlas_dims, transfer, gradient_tables, light_dir, half_vector,
                                               has_half, phong, &color, &samples, &medium_steps);
#endif
            }
            for (int j = k; j < end && shown && !terminated; j++) {
                uint code = frag_codes[j * stride];
                uint leaf = CODE_OBJECT(code);
                if (!((shown >> leaf) & 1UL)) {
                    continue;
                }
                float4 surface = materials[3 * leaf];
                float3 rgb = surface.xyz;
#ifdef PHONG
                rgb = blinn_phong(rgb, planes[code & 0x7FFFFFu].xyz, light_dir, half_vector, has_half,
                                  materials[3 * leaf + 1]);
#endif
                color += (1.0f - color.w) * (float4)(surface.w * rgb, surface.w);
                terminated = color.w > threshold;
            }
            t0 = t1;
        }
        if (!anchored && (after & volume_leaves)) {
            anchor = t1;                 // the first entry into a volume's box or hull
            anchored = true;
        }
#ifdef ISO
        iso_below = iso_entry_states(after & ~inside & volume_leaves, t1, origin, direction, objects, atlas, atlas_dims,
                                     iso_below);
#endif
        inside = after;
        contributing = contributing_after;
        roots = roots_after;
        k = end;
    }
#ifdef MIP
    if (best_object >= 0) {
        // Classified by its volume's transfer function, no opacity correction or shading (the reference).
        __constant Object* o = &objects[best_object];
        int i0;
        float w;
        table_position(best, o->tables.y, &i0, &w);
        float4 c = mix(transfer[o->tables.x + i0], transfer[o->tables.x + i0 + 1], w);
        color = (float4)(c.w * c.xyz, c.w);
    }
#endif
#ifdef ISO
    if (hit_object >= 0) {
        // Its transfer function's colour at the isovalue, shaded at the hit, opaque (the reference).
        __constant Object* o = &objects[hit_object];
        int i0;
        float w;
        table_position(o->params.z, o->tables.y, &i0, &w);
        float3 rgb = mix(transfer[o->tables.x + i0], transfer[o->tables.x + i0 + 1], w).xyz;
#ifdef PHONG
        float4 hp = (float4)(origin + hit_t * direction, 1.0f);
        float3 u = (float3)(dot(o->to_voxel[0], hp), dot(o->to_voxel[1], hp), dot(o->to_voxel[2], hp));
        float3 diff = voxel_differences(atlas, atlas_dims, o->slot, o->dims, u);
        float3 normal = (float3)(dot(o->gradient[0].xyz, diff), dot(o->gradient[1].xyz, diff),
                                 dot(o->gradient[2].xyz, diff));
        rgb = blinn_phong(rgb, normal, light_dir, half_vector, has_half, phong);
#endif
        color += (1.0f - color.w) * (float4)(rgb, 1.0f);
    }
    // Early terminations are the rays surfaces and media in front stopped; a hit is a crossing found.
    uint stopped = terminated && hit_object < 0, iso_solved = solved, crossing = hit_object >= 0;
#else
    uint stopped = terminated, iso_solved = 0u, crossing = 0u;
#endif
    image[row * width + col] = color;
    stats[row * width + col] = (uint8)((uint)n, dropped, samples, stopped, moves, medium_steps, iso_solved, crossing);
}
