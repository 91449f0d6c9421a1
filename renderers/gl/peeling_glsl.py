"""GLSL of the depth-peeling multi-volume ray caster ``gl-peel`` (:mod:`renderers.gl.peeling`).

Every program is compiled with ``N_VOLUMES`` defined (the sampler and uniform arrays' size) and
uses :data:`renderers.gl.glsl.COMMON` for the pixel ray (:func:`pixel_ray`), the unit-box slab
test and the opacity correction. Per-pixel state lives in images, read and written in place (one
fragment per pixel and pass, a memory barrier between passes):

* ``masks`` (a storage buffer, one ``uint`` per pixel, row-major from the bottom row): bit ``v``
  set while the ray is inside volume ``v``'s box (parity, toggled with ``atomicXor`` by every
  fragment of a peeled layer; a buffer, as llvmpipe 15 fails to compile ``imageAtomicXor``);
* ``u_acc`` (``rgba32f``): the composited premultiplied colour;
* ``u_pend`` (``rgba32f``) and ``u_aux`` (``rg32f``: pending cell index or −1, ``t_first``): the
  summed samples of the cell that straddles the last layer, which later segments complete;
* ``u_prev`` (``r32f``): the previous layer's ray parameter (ping-pong with the peel target).

A layer's value is the exact ray parameter of its face from the slab test of the fragment's own
box (its entry or exit, whichever is nearer the rasterised point), so segment ends, peel order
and the volumes' spans agree bit for bit.
"""

from renderers.gl import glsl

VOLUME_VERTEX = """
uniform mat4 u_viewproj;
uniform mat4 u_models[N_VOLUMES];    // unit cube (texture coordinates) -> world, per volume
in vec3 in_tex;
out vec3 v_world;
flat out int v_object;
void main() {
    v_object = gl_InstanceID;
    vec4 world = u_models[gl_InstanceID] * vec4(in_tex, 1.0);
    v_world = world.xyz;
    gl_Position = u_viewproj * world;
}
"""

VOLUMES = """
uniform mat4 u_w2t[N_VOLUMES];       // world -> texture coordinate, per volume
uniform float u_t_near;              // ray parameter of the near plane along the view axis
layout(std430, binding = 1) coherent buffer Masks { uint masks[]; };   // per-pixel parity of the boxes

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

SETUP_FRAGMENT = """
layout(rgba32f) uniform writeonly image2D u_acc;
layout(rgba32f) uniform writeonly image2D u_pend;
layout(rg32f) uniform writeonly image2D u_aux;
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
    masks[pixel_index(px)] = mask;
    imageStore(u_acc, px, vec4(0.0));
    imageStore(u_pend, px, vec4(0.0));
    imageStore(u_aux, px, vec4(-1.0, t_first, 0.0, 0.0));
    imageStore(u_prev, px, vec4(-1.0));
}
"""

PEEL_FRAGMENT = """
layout(r32f) uniform readonly image2D u_prev;
layout(rgba32f) uniform readonly image2D u_acc;
uniform float u_threshold;
in vec3 v_world;
flat in int v_object;
out vec4 o_layer;                     // MIN-blended into the layer target

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    if (imageLoad(u_acc, px).a > u_threshold) {
        discard;                      // a terminated ray peels no further
    }
    vec3 origin, direction;
    pixel_ray(gl_FragCoord.xy, origin, direction);
    vec2 span = box_span(v_object, origin, direction);
    float lo = min(span.x, span.y);
    float hi = max(span.x, span.y);
    float t = dot(v_world - origin, direction);
    float layer = t < 0.5 * (lo + hi) ? lo : hi;
    float prev = imageLoad(u_prev, px).r;
    if (layer == prev) {
        // A face of the layer just cast: the ray crosses this box's boundary there.
        atomicXor(masks[pixel_index(px)], 1u << uint(v_object));
        discard;
    }
    if (layer < prev) {
        discard;
    }
    o_layer = vec4(layer);
}
"""

SAMPLING = """
uniform sampler3D u_volumes[N_VOLUMES];
uniform vec2 u_value_maps[N_VOLUMES];
uniform vec3 u_extents[N_VOLUMES];
uniform float u_ref_steps[N_VOLUMES];
uniform int u_tf_offsets[N_VOLUMES];
uniform int u_tf_sizes[N_VOLUMES];
uniform float u_sliver;               // overlaps this short (world) are not sampled
layout(std430, binding = 0) readonly buffer Tables { vec4 u_tables[]; };   // every volume's TF, in order
#ifdef SHADED
uniform sampler3D u_gradients[N_VOLUMES];
uniform mat3 u_normals[N_VOLUMES];   // object gradient -> world normal (A^-T)
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

// The reference's cell k of a volume spanning [lo, hi]: sample parameter, overlap length (0: none).
float cell_sample(int k, float t_first, float lo, float hi, out float len) {
    float a = t_first + float(k) * u_step;
    float b = t_first + float(k + 1) * u_step;
    if (lo <= a && b <= hi) {
        len = u_step;
        return t_first + (float(k) + 0.5) * u_step;
    }
    float l = max(a, lo);
    float h = min(b, hi);
    len = h - l > u_sliver ? h - l : 0.0;
    return 0.5 * (l + h);
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
layout(rgba32f) uniform image2D u_pend;
layout(rg32f) uniform image2D u_aux;
uniform float u_threshold;

// Cast the segment [previous layer, this layer) with the volumes whose boxes hold it. Each
// volume's sample of a cell belongs to the segment holding its sample point, and a cell is
// composited once its end is reached, so cells cut by layers blend as the reference's.
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    float ta = imageLoad(u_prev, px).r;
    float tb = imageLoad(u_layer, px).r;
    vec4 acc = imageLoad(u_acc, px);
    vec2 aux = imageLoad(u_aux, px).rg;
    int pending = int(aux.x);
    uint mask = masks[pixel_index(px)];
    if (tb >= 3.0e38 || acc.a > u_threshold || (mask == 0u && pending < 0)) {
        return;
    }
    float t_first = aux.y;
    vec4 pend = imageLoad(u_pend, px);
    if (mask == 0u) {
        // Nothing inside: only the open cell may end here.
        if (t_first + float(pending + 1) * u_step <= tb) {
            composite(acc, pend);
            imageStore(u_acc, px, acc);
            imageStore(u_aux, px, vec4(-1.0, t_first, 0.0, 0.0));
        }
        return;
    }
    vec3 origin, direction;
    pixel_ray(gl_FragCoord.xy, origin, direction);
    vec3 o_tex[N_VOLUMES];
    vec3 d_tex[N_VOLUMES];
    vec2 span[N_VOLUMES];
    float full[N_VOLUMES];
    for (int v = 0; v < N_VOLUMES; v++) {
        if ((mask & (1u << uint(v))) != 0u) {
            o_tex[v] = (u_w2t[v] * vec4(origin, 1.0)).xyz;
            d_tex[v] = mat3(u_w2t[v]) * direction;
            span[v] = slab(o_tex[v], d_tex[v]);
            full[v] = length(d_tex[v] * u_extents[v]) * u_step / u_ref_steps[v];
        }
    }
    int k_first = pending >= 0 ? pending : max(int(floor((max(ta, t_first) - t_first) / u_step)), 0);
    int k_last = int(floor((tb - t_first) / u_step));
    for (int k = k_first; k <= k_last; k++) {
        vec4 sum = k == pending ? pend : vec4(0.0);
        for (int v = 0; v < N_VOLUMES; v++) {
            if ((mask & (1u << uint(v))) == 0u) {
                continue;
            }
            float len;
            float t = cell_sample(k, t_first, span[v].x, span[v].y, len);
            if (len > 0.0 && t >= ta && t < tb) {
                sum += volume_sample(v, o_tex[v] + t * d_tex[v], full[v] * len / u_step, direction);
            }
        }
        if (t_first + float(k + 1) * u_step <= tb) {
            composite(acc, sum);
            pending = -1;
            if (acc.a > u_threshold) {
                break;
            }
        } else {
            pend = sum;
            pending = k;
        }
    }
    imageStore(u_acc, px, acc);
    imageStore(u_pend, px, pend);
    imageStore(u_aux, px, vec4(float(pending), t_first, 0.0, 0.0));
}
"""

RESOLVE_FRAGMENT = """
layout(rgba32f) uniform image2D u_acc;
layout(rgba32f) uniform readonly image2D u_pend;
layout(rg32f) uniform readonly image2D u_aux;

// The cell still open after the last layer (nothing lies behind it) is composited.
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 acc = imageLoad(u_acc, px);
    if (imageLoad(u_aux, px).r >= 0.0) {
        composite(acc, imageLoad(u_pend, px));
        imageStore(u_acc, px, acc);
    }
}
"""
