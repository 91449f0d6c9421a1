// What every cl-tiled kernel shares: tile and chunk constants, the scene object record, rays.

#define TILE 8                       // tile edge in pixels: one 64-bit coverage mask per tile
#define TILE_PIXELS 64
#define CHUNK 64                     // records per chunk of the pool
#define MAX_CHUNKS 64                // chunks per tile, so at most 4096 records per tile
#define EMPTY_CHUNK 0xffffffffu
#define SUBPIXEL 256                 // fixed-point vertex positions: 1/256 pixel

// One scene object (a volume instance). The Python side (renderers/cl/scene.py) writes the
// same layout; every member is 16-byte aligned so that no compiler pads it differently.
typedef struct {
    float4 to_voxel[3];   // world point -> continuous voxel coordinates u = p_obj / s - 1/2 (rows)
    float4 to_world[3];   // object point -> world point (rows of the object->world transform)
    float4 gradient[3];   // rows of A^-T diag(1/2s): voxel differences -> world-space gradient
    float4 spacing;       // sx, sy, sz, reference step (object units)
    float4 params;        // x: sign of det(A) (mirroring), y: gradient-opacity scale, z: isovalue (NaN: none), w: 0
    int4 dims;            // nx, ny, nz, 0
    int4 slot;            // atlas slot origin ox, oy, oz, 0
    int4 tables;          // transfer-function offset, size; gradient-opacity table offset, size (0: none)
} Object;

// The pixel's ray exactly as core.camera.Camera.rays builds it (row 0 at the top).
void pixel_ray(int col, int row, int width, int height, float4 eye, float4 right, float4 up, float4 back,
               float2 half_size, int perspective, float3* origin, float3* direction) {
    float px = ((float)col + 0.5f) / (float)width * 2.0f - 1.0f;
    float py = 1.0f - ((float)row + 0.5f) / (float)height * 2.0f;
    if (perspective) {
        float3 d = px * half_size.x * right.xyz + py * half_size.y * up.xyz - back.xyz;
        *origin = eye.xyz;
        *direction = normalize(d);
    } else {
        *origin = eye.xyz + px * half_size.x * right.xyz + py * half_size.y * up.xyz;
        *direction = -back.xyz;
    }
}
