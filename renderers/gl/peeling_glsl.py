"""GLSL of the depth-peeling caster ``gl-peel`` (:mod:`renderers.gl.peeling`): front-to-back peeling of
volume boxes and mesh surfaces, and dual depth peeling of mesh surfaces.

Every program is compiled with ``N_VOLUMES`` (the volume count, 0 for meshes only) and
``VOLUME_SLOTS`` (the uniform arrays' size, at least 1) defined, and uses
:data:`renderers.gl.glsl.COMMON` for the pixel ray (:func:`pixel_ray`), the unit-box slab test
and the opacity correction. Per-pixel state lives in images, read and written in place (one
fragment per pixel and pass, a memory barrier between passes):

* ``masks`` (a storage buffer, two ``uint`` per pixel, row-major from the bottom row): word 0 has
  bit ``v`` set while the ray is inside volume ``v``'s box (parity, toggled with ``atomicXor`` by
  every box fragment of a peeled layer; a buffer, as llvmpipe 15 fails to compile
  ``imageAtomicXor``); word 1 the volumes met so far by the open cell piece;
* ``u_acc`` (``rgba32f``): the composited premultiplied colour;
* ``u_aux`` (``rgba32f``): the open cell (index, or −1), ``t_first``, the last surface's ray
  parameter (where the open piece starts);
* ``u_prev`` (``r32f``): the previous layer's ray parameter (ping-pong with the peel target);
* ``u_surf`` (``rgba32f``) and ``u_cuts`` (``r32f``): the surfaces at the layer just peeled, their
  premultiplied colours and their count (summed by additive blending in the surface pass).

Geometry is one vertex buffer in world space: the volumes' boxes (object ``0 … N_VOLUMES − 1``)
then the meshes' triangles, each with its plane. A fragment's layer value is the exact ray
parameter of its crossing: a box face's from the slab test of its own box (its entry or exit,
whichever is nearer the rasterised point), a triangle's from its plane, so segment ends, peel
order and the volumes' spans agree bit for bit between passes that run the same program.
"""

from renderers.gl import glsl

GEOMETRY_VERTEX = """
uniform mat4 u_viewproj;
in vec3 in_world;
in vec4 in_plane;
in int in_object;
out vec3 v_world;
flat out vec4 v_plane;
flat out int v_object;
void main() {
    v_world = in_world;
    v_plane = in_plane;
    v_object = in_object;
    gl_Position = u_viewproj * vec4(in_world, 1.0);
}
"""

VOLUMES = """
uniform mat4 u_w2t[VOLUME_SLOTS];     // world -> texture coordinate, per volume
uniform float u_t_near;              // ray parameter of the near plane along the view axis
layout(std430, binding = 1) coherent buffer Masks { uint masks[]; };   // per pixel: box parity, piece's volumes

int pixel_index(ivec2 px) {
    return px.y * int(u_viewport.x) + px.x;
}

// Span of the ray in volume v's box, clipped to t >= 0 (empty when x >= y).
vec2 box_span(int v, vec3 origin, vec3 direction) {
    return slab((u_w2t[v] * vec4(origin, 1.0)).xyz, mat3(u_w2t[v]) * direction);
}

// Ray parameter of the near plane (faces nearer than it are clipped, so never peeled).
float near_t(vec3 direction) {
    return u_perspective == 1 ? u_t_near / max(dot(direction, -u_back), 1e-6) : u_t_near;
}
"""

SURFACES = """
in vec3 v_world;
flat in vec4 v_plane;                // triangles: unit world normal n, n . vertex
flat in int v_object;                // boxes 0 .. N_VOLUMES - 1, then the meshes
layout(std430, binding = 2) readonly buffer Materials { vec4 materials[]; };   // per mesh: rgb + alpha, terms
#ifdef SHADED
""" + glsl.LIGHTING + """
#endif

// The ray parameter of this fragment's crossing (see the module notes).
float fragment_layer(vec3 origin, vec3 direction) {
    if (v_object < N_VOLUMES) {
        vec2 span = box_span(v_object, origin, direction);
        float lo = min(span.x, span.y);
        float hi = max(span.x, span.y);
        return dot(v_world - origin, direction) < 0.5 * (lo + hi) ? lo : hi;
    }
    return (v_plane.w - dot(v_plane.xyz, origin)) / dot(v_plane.xyz, direction);
}

// A mesh fragment's premultiplied colour: its material, two-sided Blinn-Phong with the face normal.
vec4 surface_colour(vec3 direction) {
    int m = 2 * (v_object - N_VOLUMES);
    vec4 colour = materials[m];
    vec3 rgb = colour.rgb;
#ifdef SHADED
    rgb = blinn_phong_terms(rgb, v_plane.xyz, direction, materials[m + 1]);
#endif
    return vec4(colour.a * rgb, colour.a);
}
"""

SETUP_FRAGMENT = """
layout(rgba32f) uniform writeonly image2D u_acc;
layout(rgba32f) uniform writeonly image2D u_aux;
layout(r32f) uniform writeonly image2D u_prev;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 origin, direction;
    pixel_ray(gl_FragCoord.xy, origin, direction);
    float t_near = near_t(direction);
    float t_first = 3.0e38;
    uint mask = 0u;
    for (int v = 0; v < N_VOLUMES; v++) {
        vec2 span = box_span(v, origin, direction);
        if (span.x < span.y) {
            t_first = min(t_first, span.x);       // the reference's cell origin: entry into the union
            // A box around the near point has its entry face clipped: the ray starts inside it.
            if (span.x < t_near && t_near < span.y) {
                mask |= 1u << uint(v);
            }
        }
    }
    masks[2 * pixel_index(px)] = mask;
    masks[2 * pixel_index(px) + 1] = 0u;
    imageStore(u_acc, px, vec4(0.0));
    imageStore(u_aux, px, vec4(-1.0, t_first, -3.0e38, 0.0));
    imageStore(u_prev, px, vec4(-1.0));
}
"""

PEEL_FRAGMENT = """
layout(r32f) uniform readonly image2D u_prev;
layout(r32f) uniform readonly image2D u_layer;
layout(rgba32f) uniform readonly image2D u_acc;
uniform float u_threshold;
uniform int u_surface_pass;          // 0: peel the next layer; 1: shade the meshes' fragments at it
layout(location = 0) out vec4 o_0;   // peel: the layer (MIN-blended); surface pass: colour (added)
layout(location = 1) out vec4 o_1;   // surface pass: 1 per surface at the layer (added)

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    if (imageLoad(u_acc, px).a > u_threshold) {
        discard;                      // a terminated ray peels no further
    }
    vec3 origin, direction;
    pixel_ray(gl_FragCoord.xy, origin, direction);
    float layer = fragment_layer(origin, direction);
    if (u_surface_pass == 1) {
        if (layer != imageLoad(u_layer, px).r) {
            discard;
        }
        o_0 = surface_colour(direction);
        o_1 = vec4(1.0);
        return;
    }
    float prev = imageLoad(u_prev, px).r;
    if (layer == prev) {
        // A face of the layer just cast: the ray crosses this box's boundary there.
        if (v_object < N_VOLUMES) {
            atomicXor(masks[2 * pixel_index(px)], 1u << uint(v_object));
        }
        discard;
    }
    if (layer < prev) {
        discard;
    }
    o_0 = vec4(layer);
    o_1 = vec4(0.0);
}
"""

SAMPLING = """
uniform sampler3D u_volumes[VOLUME_SLOTS];
uniform vec2 u_value_maps[VOLUME_SLOTS];
uniform vec3 u_extents[VOLUME_SLOTS];
uniform float u_ref_steps[VOLUME_SLOTS];
uniform int u_tf_offsets[VOLUME_SLOTS];
uniform int u_tf_sizes[VOLUME_SLOTS];
uniform float u_sliver;               // overlaps this short (world) are not sampled
layout(std430, binding = 0) readonly buffer Tables { vec4 u_tables[]; };   // every volume's TF, in order
#ifdef SHADED
uniform sampler3D u_gradients[VOLUME_SLOTS];
uniform mat3 u_normals[VOLUME_SLOTS];   // object gradient -> world normal (A^-T)
""" + glsl.LIGHTING + """
// Blinn-Phong as renderers.gl.glsl.shade, with volume v's gradient texture.
vec3 shade_volume(int v, vec3 color, vec3 p, vec3 ray_dir) {
    return blinn_phong(color, u_normals[v] * texture(u_gradients[v], p).rgb, ray_dir);
}
#endif

vec4 classify_volume(int v, float s) {
    float x = s * float(u_tf_sizes[v] - 1);
    int i0 = min(int(floor(x)), u_tf_sizes[v] - 2);
    int base = u_tf_offsets[v] + i0;
    return mix(u_tables[base], u_tables[base + 1], x - float(i0));
}

// Volume v's premultiplied, opacity-corrected sample at texture point p; `ratio` = length / Δ0.
vec4 volume_sample(int v, vec3 p, float ratio, vec3 ray_dir) {
    vec2 value_map = u_value_maps[v];
    float s = clamp(texture(u_volumes[v], p).r * value_map.x + value_map.y, 0.0, 1.0);
    vec4 c = classify_volume(v, s);
    if (c.a <= 0.0) {
        return vec4(0.0);
    }
    float alpha = correct_opacity(c.a, ratio);
    vec3 rgb = c.rgb;
#ifdef SHADED
    rgb = shade_volume(v, rgb, p, ray_dir);
#endif
    return vec4(alpha * rgb, alpha);
}

vec3 o_tex[VOLUME_SLOTS];
vec3 d_tex[VOLUME_SLOTS];
vec2 spans[VOLUME_SLOTS];
float full_ratio[VOLUME_SLOTS];

// The ray in the texture space of every volume in `volumes`, its span and a whole step's ratio.
void prepare_volumes(uint volumes, vec3 origin, vec3 direction) {
    for (int v = 0; v < N_VOLUMES; v++) {
        if ((volumes & (1u << uint(v))) != 0u) {
            o_tex[v] = (u_w2t[v] * vec4(origin, 1.0)).xyz;
            d_tex[v] = mat3(u_w2t[v]) * direction;
            spans[v] = slab(o_tex[v], d_tex[v]);
            full_ratio[v] = length(d_tex[v] * u_extents[v]) * u_step / u_ref_steps[v];
        }
    }
}

// A volume's sample in the piece [lo, hi] of the reference's cell k (cut by surfaces, or whole):
// its parameter and overlap length (0: none). A whole cell inside the box samples at its middle.
float piece_sample(int k, float t_first, float lo, float hi, vec2 span, out float len) {
    float a = t_first + float(k) * u_step;
    float b = t_first + float(k + 1) * u_step;
    if (lo == a && hi == b && span.x <= a && b <= span.y) {
        len = u_step;
        return t_first + (float(k) + 0.5) * u_step;
    }
    float l = max(lo, span.x);
    float h = min(hi, span.y);
    len = h - l > u_sliver ? h - l : 0.0;
    return 0.5 * (l + h);
}

// The summed samples of the piece [lo, hi] of cell k of every volume in `volumes` (in volume order).
vec4 piece(int k, float t_first, float lo, float hi, uint volumes, vec3 direction) {
    vec4 sum = vec4(0.0);
    for (int v = 0; v < N_VOLUMES; v++) {
        if ((volumes & (1u << uint(v))) != 0u) {
            float len;
            float t = piece_sample(k, t_first, lo, hi, spans[v], len);
            if (len > 0.0) {
                sum += volume_sample(v, o_tex[v] + t * d_tex[v], full_ratio[v] * len / u_step, direction);
            }
        }
    }
    return sum;
}

void composite(inout vec4 acc, vec4 sum) {
    // Kainz blend: summed premultiplied samples, opacity clamped to 1 with the colour scaled alike.
    if (sum.a > 1.0) {
        sum /= sum.a;
    }
    acc += (1.0 - acc.a) * sum;
}
"""

RAYCAST_FRAGMENT = """
layout(r32f) uniform readonly image2D u_prev;
layout(r32f) uniform readonly image2D u_layer;
layout(rgba32f) uniform image2D u_acc;
layout(rgba32f) uniform image2D u_aux;
#ifdef MESHES
layout(rgba32f) uniform readonly image2D u_surf;
layout(r32f) uniform readonly image2D u_cuts;
#endif
uniform float u_threshold;

// The segment [previous layer, this layer) with the volumes whose boxes hold it, then the surfaces
// at this layer. A cell is sampled once its piece is closed (by the cell's end, or by a surface,
// which cuts it as the reference does), with every volume met in the piece, so cells that box
// faces cross sample as the reference's.
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    float ta = imageLoad(u_prev, px).r;
    float tb = imageLoad(u_layer, px).r;
    vec4 acc = imageLoad(u_acc, px);
    if (tb >= 3.0e38 || acc.a > u_threshold) {
        return;
    }
    int index = pixel_index(px);
    uint mask = masks[2 * index];
    uint seen = masks[2 * index + 1] | mask;
#ifdef MESHES
    bool at_surface = imageLoad(u_cuts, px).r > 0.0;
#else
    bool at_surface = false;
#endif
    if (seen == 0u && !at_surface) {
        return;
    }
    vec4 aux = imageLoad(u_aux, px);
    int pending = int(aux.x);
    float t_first = aux.y;
    float cut = aux.z;
    vec3 origin, direction;
    pixel_ray(gl_FragCoord.xy, origin, direction);
    if (seen != 0u) {
        prepare_volumes(seen, origin, direction);
        int k = pending >= 0 ? pending : max(int(floor((max(ta, t_first) - t_first) / u_step)), 0);
        int k_last = int(floor((tb - t_first) / u_step));
        pending = -1;
        for (; k <= k_last; k++) {
            float b = t_first + float(k + 1) * u_step;
            if (b > tb) {
                pending = k;          // open across this layer: later segments complete it
                break;
            }
            composite(acc, piece(k, t_first, max(t_first + float(k) * u_step, cut), b, seen, direction));
            seen = mask;
            if (mask == 0u || acc.a > u_threshold) {
                break;
            }
        }
        if (at_surface && pending >= 0) {
            float a = max(t_first + float(pending) * u_step, cut);
            composite(acc, piece(pending, t_first, a, tb, seen, direction));
            pending = -1;
        }
    }
#ifdef MESHES
    if (at_surface) {
        composite(acc, imageLoad(u_surf, px));
        cut = tb;
    }
#endif
    imageStore(u_acc, px, acc);
    imageStore(u_aux, px, vec4(float(pending), t_first, cut, 0.0));
    masks[2 * index + 1] = pending >= 0 ? seen : 0u;
}
"""

RESOLVE_FRAGMENT = """
layout(rgba32f) uniform image2D u_acc;
layout(rgba32f) uniform readonly image2D u_aux;

// The cell still open after the last layer (nothing lies behind it) is composited.
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 aux = imageLoad(u_aux, px);
    int pending = int(aux.x);
    if (pending < 0) {
        return;
    }
    uint seen = masks[2 * pixel_index(px) + 1];
    vec3 origin, direction;
    pixel_ray(gl_FragCoord.xy, origin, direction);
    prepare_volumes(seen, origin, direction);
    float a = max(aux.y + float(pending) * u_step, aux.z);
    vec4 acc = imageLoad(u_acc, px);
    composite(acc, piece(pending, aux.y, a, aux.y + float(pending + 1) * u_step, seen, direction));
    imageStore(u_acc, px, acc);
}
"""

DUAL_FRAGMENT = """
layout(rg32f) uniform readonly image2D u_depths;   // the previous pass's (-nearest, farthest) left to peel
uniform int u_dual_init;              // 1: the first pass, which only finds every pixel's nearest and farthest
layout(location = 0) out vec4 o_depths;   // all four MAX-blended: (-t, t) of the fragments still inside
layout(location = 1) out vec4 o_front;    // the nearest layer's premultiplied colour
layout(location = 2) out vec4 o_back;     // the farthest layer's
layout(location = 3) out vec4 o_flags;    // 1 where a nearest layer, 1 where a farthest layer was peeled

// Bavoil & Myers 2008: peel the nearest and the farthest remaining layer in one pass.
void main() {
    vec3 origin, direction;
    pixel_ray(gl_FragCoord.xy, origin, direction);
    float t = fragment_layer(origin, direction);
    o_depths = vec4(-3.0e38, -3.0e38, 0.0, 0.0);
    o_front = vec4(0.0);
    o_back = vec4(0.0);
    o_flags = vec4(0.0);
    if (u_dual_init == 1) {
        o_depths.xy = vec2(-t, t);
        return;
    }
    vec2 depths = imageLoad(u_depths, ivec2(gl_FragCoord.xy)).xy;
    float nearest = -depths.x;
    float farthest = depths.y;
    if (t < nearest || t > farthest) {
        discard;                      // peeled in an earlier pass
    }
    if (t > nearest && t < farthest) {
        o_depths.xy = vec2(-t, t);    // still inside: next pass's nearest and farthest
        return;
    }
    if (t == nearest) {
        o_front = surface_colour(direction);
        o_flags.x = 1.0;
    } else {
        o_back = surface_colour(direction);
        o_flags.y = 1.0;
    }
}
"""

DUAL_BLEND_FRAGMENT = """
layout(rgba32f) uniform readonly image2D u_front_layer;
layout(rgba32f) uniform readonly image2D u_back_layer;
layout(rg32f) uniform readonly image2D u_flags;
layout(rgba32f) uniform image2D u_front_acc;
layout(rgba32f) uniform image2D u_back_acc;

// The pass's nearest layer goes under the front colour, its farthest over the back colour; pixels
// without a farthest layer are discarded, so the pass's samples-passed query says whether any is left.
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec2 flags = imageLoad(u_flags, px).xy;
    if (flags.x > 0.0) {
        vec4 front = imageLoad(u_front_acc, px);
        imageStore(u_front_acc, px, front + (1.0 - front.a) * imageLoad(u_front_layer, px));
    }
    if (!(flags.y > 0.0)) {
        discard;
    }
    vec4 layer = imageLoad(u_back_layer, px);
    imageStore(u_back_acc, px, layer + (1.0 - layer.a) * imageLoad(u_back_acc, px));
}
"""

DUAL_FINAL_FRAGMENT = """
layout(rgba32f) uniform image2D u_front_acc;
layout(rgba32f) uniform readonly image2D u_back_acc;

// The front colour over the back colour: the frame.
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 front = imageLoad(u_front_acc, px);
    imageStore(u_front_acc, px, front + (1.0 - front.a) * imageLoad(u_back_acc, px));
}
"""
