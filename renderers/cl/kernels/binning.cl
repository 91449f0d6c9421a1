// Triangle kernel (Kainz et al. 2009, §3.1): transform every boundary triangle, compute the 64-bit
// coverage mask of each 8x8 tile its screen bounding box touches by bit shifts (no lookup tables),
// and append (mask, triangle) records to the tile's chunked list with atomics.
//
// Exactly-once coverage: vertices are snapped to 1/SUBPIXEL pixel and every edge function is
// evaluated in 64-bit integers, so it is exact. An edge's function is built from its two vertices
// in a canonical (lexicographic) order, so the two triangles sharing the edge evaluate the very
// same integer at a pixel centre, with opposite inside signs. Inside means s*E > 0, and on the
// edge (E == 0) the pixel goes to the triangle with s > 0; that is the same as moving every pixel
// centre by an infinitesimal (-eps^2, +eps) before testing, so each pixel centre covered by a closed
// mesh's projection lies in exactly one front-facing and one back-facing triangle per crossing.
//
// Build options:
//   EDGE_COVERAGE  evaluate the edge function at each of the tile's 64 pixel centres instead of the
//                  bit-shift row/column masks (the per-pixel method the paper compares with, E11);
//                  the same integer test, so the same masks
//   ORDERED        work-item i bins triangle order[i] (the submission order of E7); triangle ids,
//                  and so fragment codes and images, do not change
//   HOMOGENEOUS    2-D homogeneous rasterisation (Olano & Greer 1997) for perspective frames whose
//                  geometry reaches behind the eye (an eye inside a volume or mesh): no projection,
//                  so no near-plane clipping; see homogeneous_edges

long floor_div(long n, long d) {          // d > 0
    return n >= 0 ? n / d : -((-n + d - 1) / d);
}

ulong shift_left(ulong v, long s) {       // OpenCL takes shift counts modulo 64: guard 64 and up
    return s >= 64 ? 0UL : v << s;
}

ulong shift_right(ulong v, long s) {
    return s >= 64 ? 0UL : v >> s;
}

// Pixels of the tile (origin x0, y0 in fixed point at the first pixel centre) where
// F = f00 + a*i + b*j >= threshold, i the column and j the row inside the tile (bit 8j + i).
// Row mode (|a| >= |b|) cuts each row at one column, column mode each column at one row: the
// paper's row/column masks r0 = 0xFF and c0 = 0x0101010101010101.
#ifndef EDGE_COVERAGE
ulong edge_mask(long f00, long a, long b) {
    ulong mask = 0UL;
    if (a != 0 && (a >= 0 ? a : -a) >= (b >= 0 ? b : -b)) {
        for (int j = 0; j < TILE; j++) {
            long g = f00 + b * j;               // F at column 0 of row j
            ulong bits;
            if (a > 0) {                        // columns i >= ceil(-g / a)
                long first = -floor_div(g, a);
                first = clamp(first, 0L, (long)TILE);
                bits = shift_left(0xFFUL, first) & 0xFFUL;
            } else {                            // columns i <= floor(g / -a)
                long count = clamp(floor_div(g, -a) + 1, 0L, (long)TILE);
                bits = shift_right(0xFFUL, TILE - count);
            }
            mask |= bits << (TILE * j);
        }
    } else {
        const ulong column = 0x0101010101010101UL;
        for (int i = 0; i < TILE; i++) {
            long g = f00 + a * i;
            ulong bits;
            if (b > 0) {
                long first = clamp(-floor_div(g, b), 0L, (long)TILE);
                bits = shift_left(column, TILE * first);
            } else {
                long count = clamp(floor_div(g, -b) + 1, 0L, (long)TILE);
                bits = shift_right(column, TILE * (TILE - count));
            }
            mask |= bits << i;
        }
    }
    return mask;
}
#else
ulong edge_mask(long f00, long a, long b) {
    ulong mask = 0UL;
    for (int j = 0; j < TILE; j++) {
        for (int i = 0; i < TILE; i++) {
            mask |= (ulong)(f00 + a * i + b * j >= 0) << (TILE * j + i);
        }
    }
    return mask;
}
#endif

#ifdef HOMOGENEOUS
// A world point in the perspective eye's homogeneous screen space: (x, y) over the half sizes and w
// the view depth, so the pixel ray (px, py, 1) of pixel_ray reaches (λpx, λpy, λ) at depth λ.
float3 view_point(float3 p, float4 eye, float4 right, float4 up, float4 back, float2 half_size) {
    float3 v = p - eye.xyz;
    return (float3)(dot(v, right.xyz) / half_size.x, dot(v, up.xyz) / half_size.y, -dot(v, back.xyz));
}

bool before(float3 a, float3 b) {
    return a.x < b.x || (a.x == b.x && (a.y < b.y || (a.y == b.y && a.z < b.z)));
}

// Oriented edge functions (A, B, C) of a triangle with homogeneous vertices h: the pixel ray
// (px, py, 1) meets the triangle in front of the eye (ray parameter > 0) exactly where every
// A px + B py + C is positive, since its barycentrics are those values over their sum, whatever
// side of the eye the vertices lie on. An edge's (A, B, C) is the cross product of its endpoints in
// canonical order, negated (exactly) so that the opposite vertex is on the positive side: the two
// triangles sharing the edge evaluate the same float with opposite signs. Returns 0 when the
// triangle's plane passes through the eye (edge-on to every ray: it covers no pixel).
int homogeneous_edges(float3 h[3], float3 edge[3]) {
    for (int k = 0; k < 3; k++) {
        float3 u = h[k], w = h[(k + 1) % 3], r = h[(k + 2) % 3];
        float3 c = before(w, u) ? cross(w, u) : cross(u, w);
        float side = dot(c, r);
        if (side == 0.0f) {
            return 0;
        }
        edge[k] = side > 0.0f ? c : -c;
    }
    return 1;
}

// The pixel centres of tile (tx, ty) that the triangle covers. On an edge (E == 0) the pixel goes
// to the triangle with A > 0 (or A == 0, B > 0): every pixel moved by the same infinitesimal
// (+eps, +eps^2), so shared edges and vertices are covered once, as in the integer path.
ulong homogeneous_mask(float3 edge[3], long tx, long ty, int width, int height) {
    ulong mask = 0UL;
    for (int j = 0; j < TILE; j++) {
        int row = ty * TILE + j;
        float py = 1.0f - ((float)row + 0.5f) / (float)height * 2.0f;
        for (int i = 0; i < TILE; i++) {
            int col = tx * TILE + i;
            float px = ((float)col + 0.5f) / (float)width * 2.0f - 1.0f;
            bool inside = col < width && row < height;
            for (int k = 0; k < 3 && inside; k++) {
                float e = edge[k].x * px + edge[k].y * py + edge[k].z;
                inside = e > 0.0f || (e == 0.0f && (edge[k].x > 0.0f || (edge[k].x == 0.0f && edge[k].y > 0.0f)));
            }
            mask |= (ulong)inside << (TILE * j + i);
        }
    }
    return mask;
}
#endif

long2 to_screen(float3 p, float4 eye, float4 right, float4 up, float4 back, float2 half_size, int perspective,
                int width, int height) {
    float3 v = p - eye.xyz;
    float x = dot(v, right.xyz);
    float y = dot(v, up.xyz);
    if (perspective) {
        float depth = -dot(v, back.xyz);
        x /= depth;
        y /= depth;
    }
    float sx = (x / half_size.x + 1.0f) * 0.5f * (float)width;
    float sy = (1.0f - y / half_size.y) * 0.5f * (float)height;
    return (long2)(convert_long_rte(sx * SUBPIXEL), convert_long_rte(sy * SUBPIXEL));
}

__kernel void bin_triangles(
    __global const float4* vertices,        // 3 per triangle, object space
    __global const uint* triangle_object,
    __constant Object* objects,
    uint triangles,
    float4 eye, float4 right, float4 up, float4 back, float2 half_size, int perspective,
    int width, int height, int tiles_x,
    __global float4* planes,                // out: world plane (outward unit normal, offset)
    __global uint* codes,                   // out: object << 24 | front << 23 | triangle
    __global uint* tile_count,
    __global uint* tile_chunks,             // MAX_CHUNKS per tile, EMPTY_CHUNK where unallocated
    __global ulong* pool_mask,
    __global uint* pool_triangle,
    uint pool_chunks,
    __global uint* counters                 // [0] chunks taken, [1] records dropped (tile full)
#ifdef ORDERED
    , __global const uint* order
#endif
    )
{
    if (get_global_id(0) >= triangles) {
        return;
    }
#ifdef ORDERED
    uint tri = order[get_global_id(0)];
#else
    uint tri = get_global_id(0);
#endif
    uint obj = triangle_object[tri];
    __constant Object* o = &objects[obj];
    float3 p[3];
    for (int k = 0; k < 3; k++) {
        float4 v = (float4)(vertices[3 * tri + k].xyz, 1.0f);
        p[k] = (float3)(dot(o->to_world[0], v), dot(o->to_world[1], v), dot(o->to_world[2], v));
    }
    float orientation = o->params.x;
    float3 normal = cross(p[1] - p[0], p[2] - p[0]) * orientation;
    float length_n = length(normal);
    planes[tri] = length_n > 0.0f ? (float4)(normal / length_n, -dot(normal, p[0]) / length_n) : (float4)(0.0f);

#ifdef HOMOGENEOUS
    float3 h[3], edge[3];
    for (int k = 0; k < 3; k++) {
        h[k] = view_point(p[k], eye, right, up, back, half_size);
    }
    if (!homogeneous_edges(h, edge)) {
        codes[tri] = 0;
        return;
    }
    // Front-facing: the eye is on the outer side of the plane (the ray enters there).
    uint front = dot(planes[tri].xyz, eye.xyz) + planes[tri].w > 0.0f;
    codes[tri] = (obj << 24) | (front << 23) | tri;
    // Pixels: the projected vertices' box with a pixel's margin, or every pixel when a vertex lies
    // at or behind the eye plane (the projection is unbounded there).
    long col0 = 0, col1 = width - 1, row0 = 0, row1 = height - 1;
    if (h[0].z > 0.0f && h[1].z > 0.0f && h[2].z > 0.0f) {
        float min_x = INFINITY, max_x = -INFINITY, min_y = INFINITY, max_y = -INFINITY;
        for (int k = 0; k < 3; k++) {
            float sx = (h[k].x / h[k].z + 1.0f) * 0.5f * (float)width;
            float sy = (1.0f - h[k].y / h[k].z) * 0.5f * (float)height;
            min_x = fmin(min_x, sx); max_x = fmax(max_x, sx);
            min_y = fmin(min_y, sy); max_y = fmax(max_y, sy);
        }
        col0 = (long)clamp(floor(min_x - 1.0f), 0.0f, (float)width);
        col1 = (long)clamp(ceil(max_x + 1.0f), -1.0f, (float)(width - 1));
        row0 = (long)clamp(floor(min_y - 1.0f), 0.0f, (float)height);
        row1 = (long)clamp(ceil(max_y + 1.0f), -1.0f, (float)(height - 1));
    }
#else
    long2 s[3];
    for (int k = 0; k < 3; k++) {
        s[k] = to_screen(p[k], eye, right, up, back, half_size, perspective, width, height);
    }
    long area = (s[1].x - s[0].x) * (s[2].y - s[0].y) - (s[2].x - s[0].x) * (s[1].y - s[0].y);
    if (area == 0) {                        // edge-on after snapping: covers no pixel centre
        codes[tri] = 0;
        return;
    }
    // Counter-clockwise seen from outside in a y-up view is clockwise in rows-down pixels.
    uint front = (area < 0) == (orientation > 0.0f);
    codes[tri] = (obj << 24) | (front << 23) | tri;

    // Edge functions E(x, y) = ea*(x - px) + eb*(y - py) from canonically ordered endpoints.
    long ea[3], eb[3], epx[3], epy[3], sign[3];
    for (int k = 0; k < 3; k++) {
        long2 u = s[k], w = s[(k + 1) % 3], r = s[(k + 2) % 3];
        bool swap = w.x < u.x || (w.x == u.x && w.y < u.y);
        long2 first = swap ? w : u, second = swap ? u : w;
        ea[k] = first.y - second.y;
        eb[k] = second.x - first.x;
        epx[k] = first.x;
        epy[k] = first.y;
        sign[k] = ea[k] * (r.x - first.x) + eb[k] * (r.y - first.y) > 0 ? 1 : -1;
    }

    long min_x = min(s[0].x, min(s[1].x, s[2].x)), max_x = max(s[0].x, max(s[1].x, s[2].x));
    long min_y = min(s[0].y, min(s[1].y, s[2].y)), max_y = max(s[0].y, max(s[1].y, s[2].y));
    const long centre = SUBPIXEL / 2;          // pixel centres sit at half pixels
    long col0 = max(-floor_div(centre - min_x, SUBPIXEL), 0L);   // first pixel centre >= min_x
    long col1 = min(floor_div(max_x - centre, SUBPIXEL), (long)width - 1);
    long row0 = max(-floor_div(centre - min_y, SUBPIXEL), 0L);
    long row1 = min(floor_div(max_y - centre, SUBPIXEL), (long)height - 1);
#endif
    if (col0 > col1 || row0 > row1) {
        return;
    }
    for (long ty = row0 / TILE; ty <= row1 / TILE; ty++) {
        for (long tx = col0 / TILE; tx <= col1 / TILE; tx++) {
#ifdef HOMOGENEOUS
            ulong mask = homogeneous_mask(edge, tx, ty, width, height);
#else
            long x0 = (tx * TILE) * SUBPIXEL + centre, y0 = (ty * TILE) * SUBPIXEL + centre;
            long cols = min((long)TILE, width - tx * TILE), rows = min((long)TILE, height - ty * TILE);
            ulong mask = shift_right(~0UL, 64 - TILE * rows) & ((0xFFUL >> (TILE - cols)) * 0x0101010101010101UL);
            for (int k = 0; k < 3 && mask; k++) {
                long f00 = sign[k] * (ea[k] * (x0 - epx[k]) + eb[k] * (y0 - epy[k]));
                long threshold = sign[k] > 0 ? 0 : 1;          // ties go to the canonical side
                mask &= edge_mask(f00 - threshold, sign[k] * ea[k] * SUBPIXEL, sign[k] * eb[k] * SUBPIXEL);
            }
#endif
            if (!mask) {
                continue;
            }
            uint tile = ty * tiles_x + tx;
            uint k = atomic_inc(&tile_count[tile]);
            if (k >= CHUNK * MAX_CHUNKS) {
                atomic_inc(&counters[1]);
                continue;
            }
            __global uint* slot = &tile_chunks[tile * MAX_CHUNKS + k / CHUNK];
            uint chunk = *slot;
            if (chunk == EMPTY_CHUNK) {
                // Allocate without waiting on another work-item (OpenCL promises no forward
                // progress to a spin loop): the loser of the exchange uses the winner's chunk,
                // its own stays unused (counted in the pool use).
                uint fresh = atomic_inc(&counters[0]);
                uint previous = atomic_cmpxchg(slot, EMPTY_CHUNK, fresh < pool_chunks ? fresh : EMPTY_CHUNK);
                chunk = previous == EMPTY_CHUNK ? fresh : previous;
            }
            if (chunk >= pool_chunks) {     // pool exhausted: the host grows it and bins again
                continue;
            }
            pool_mask[chunk * CHUNK + k % CHUNK] = mask;
            pool_triangle[chunk * CHUNK + k % CHUNK] = tri;
        }
    }
}

// View depth of each triangle's centroid (distance along the viewing direction from the eye):
// the key of the front-to-back and back-to-front submission orders.
__kernel void view_depths(__global const float4* vertices, __global const uint* triangle_object,
                          __constant Object* objects, uint triangles, float4 eye, float4 back,
                          __global float* depths) {
    uint tri = get_global_id(0);
    if (tri >= triangles) {
        return;
    }
    __constant Object* o = &objects[triangle_object[tri]];
    float4 c = (float4)((vertices[3 * tri].xyz + vertices[3 * tri + 1].xyz + vertices[3 * tri + 2].xyz) / 3.0f, 1.0f);
    float3 p = (float3)(dot(o->to_world[0], c), dot(o->to_world[1], c), dot(o->to_world[2], c));
    depths[tri] = -dot(p - eye.xyz, back.xyz);
}
