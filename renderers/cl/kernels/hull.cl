// Tight empty-space hulls (Kainz et al. 2009, §3.4): a brick mask of each volume and the closed
// polygon boundary around its non-empty bricks, built on the device.
//
// Brick (bx, by, bz) of B voxels per edge covers object space [b*B*s, min((b+1)*B, n)*s) per axis,
// i.e. the cells of voxel coordinates [bB - 1/2, (b+1)B - 1/2): a trilinear sample there blends
// voxels bB - 1 ... (b+1)B (clamped), so each brick's range includes a one-voxel apron and holds
// every scalar a sample inside the brick can take.

float atlas_value(__global const ATLAS_T* atlas, int4 atlas_dims, int x, int y, int z) {
    return (float)atlas[((long)z * atlas_dims.y + y) * atlas_dims.x + x] * ATLAS_SCALE;
}

// Smallest and largest scalar of every brick of one volume, apron included.
__kernel void brick_minmax(__global const ATLAS_T* atlas, int4 atlas_dims, int4 slot, int4 dims, int brick,
                           int4 bricks, __global float2* ranges) {
    int bx = get_global_id(0), by = get_global_id(1), bz = get_global_id(2);
    if (bx >= bricks.x || by >= bricks.y || bz >= bricks.z) {
        return;
    }
    int4 lo = max((int4)(bx, by, bz, 0) * brick - 1, (int4)(0));
    int4 hi = min((int4)(bx + 1, by + 1, bz + 1, 1) * brick, dims - 1);
    float smallest = INFINITY, largest = -INFINITY;
    for (int z = lo.z; z <= hi.z; z++) {
        for (int y = lo.y; y <= hi.y; y++) {
            for (int x = lo.x; x <= hi.x; x++) {
                float v = atlas_value(atlas, atlas_dims, slot.x + x, slot.y + y, slot.z + z);
                smallest = fmin(smallest, v);
                largest = fmax(largest, v);
            }
        }
    }
    ranges[(bz * bricks.y + by) * bricks.x + bx] = (float2)(smallest, largest);
}

// Whether some transfer-function entry a scalar in `range` blends with a non-zero weight is
// visible: `visible_prefix[i]` counts the visible entries below i (a prefix sum over the table).
bool brick_visible(__global const float2* ranges, int4 bricks, int x, int y, int z,
                   __global const int* visible_prefix, int tf_size) {
    if (x < 0 || y < 0 || z < 0 || x >= bricks.x || y >= bricks.y || z >= bricks.z) {
        return false;
    }
    float2 range = ranges[(z * bricks.y + y) * bricks.x + x];
    float top = (float)(tf_size - 1);
    // 1e-4 entries of slack: float32 interpolation can land an ulp past the range's ends.
    int first = clamp((int)floor(range.x * top - 1e-4f), 0, tf_size - 1);
    int last = clamp((int)ceil(range.y * top + 1e-4f), 0, tf_size - 1);
    return visible_prefix[last + 1] - visible_prefix[first] > 0;
}

// One work-item per brick: a visible brick emits the faces it shares with invisible bricks or
// with the outside, two triangles each, counter-clockwise seen from outside. Shared corners are
// computed by one expression, so neighbouring faces meet bit for bit (a watertight mesh). With
// `everything` set every brick counts as visible (the hull is the volume's box).
__kernel void build_hull(__global const float2* ranges, int4 bricks, float4 brick_extent, float4 extent,
                         __global const int* visible_prefix, int tf_size, int everything,
                         uint capacity, __global float4* vertices, __global uint* count) {
    int x = get_global_id(0), y = get_global_id(1), z = get_global_id(2);
    if (x >= bricks.x || y >= bricks.y || z >= bricks.z) {
        return;
    }
    if (!everything && !brick_visible(ranges, bricks, x, y, z, visible_prefix, tf_size)) {
        return;
    }
    int3 b = (int3)(x, y, z);
    for (int axis = 0; axis < 3; axis++) {
        for (int side = 0; side < 2; side++) {
            int3 n = b;
            if (axis == 0) n.x += side ? 1 : -1;
            if (axis == 1) n.y += side ? 1 : -1;
            if (axis == 2) n.z += side ? 1 : -1;
            bool outside = n.x < 0 || n.y < 0 || n.z < 0 || n.x >= bricks.x || n.y >= bricks.y || n.z >= bricks.z;
            if (!outside && (everything || brick_visible(ranges, bricks, n.x, n.y, n.z, visible_prefix, tf_size))) {
                continue;
            }
            uint index = atomic_add(count, 2u);
            if (index + 2 > capacity) {     // the host grows the buffer and builds again
                continue;
            }
            // Quad corners (0,0) (1,0) (1,1) (0,1) in the axes u = axis+1, v = axis+2: e_u x e_v = e_axis,
            // counter-clockwise seen from +axis; reversed on the -axis side.
            float4 corner[4];
            for (int c = 0; c < 4; c++) {
                int du = (c == 1 || c == 2), dv = (c >= 2);
                int4 g = (int4)(b, 0);
                if (axis == 0) { g.x += side; g.y += du; g.z += dv; }
                if (axis == 1) { g.y += side; g.z += du; g.x += dv; }
                if (axis == 2) { g.z += side; g.x += du; g.y += dv; }
                corner[c] = fmin(convert_float4(g) * brick_extent, extent);
                corner[c].w = 0.0f;
            }
            __global float4* out = &vertices[3 * index];
            if (side) {
                out[0] = corner[0]; out[1] = corner[1]; out[2] = corner[2];
                out[3] = corner[0]; out[4] = corner[2]; out[5] = corner[3];
            } else {
                out[0] = corner[3]; out[1] = corner[2]; out[2] = corner[1];
                out[3] = corner[3]; out[4] = corner[1]; out[5] = corner[0];
            }
        }
    }
}
