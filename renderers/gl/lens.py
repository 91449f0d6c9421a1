"""Lens volumes (Ropinski, Steinicke & Hinrichs 2005) in the single-pass ray caster: GLSL and uniforms.

The semantics are :mod:`core.lens`'s and the reference's (:func:`renderers.reference.raycast.render_lens`):
the samples stay on the no-lens lattice, and a sample at ``t`` with ``t_Lin <= t <= t_Lout`` is
classified with the lens's appearance (``clip``: skipped; ``dvr``: the lens's table, a second TF
texture), every other sample with the volume's. Two ways to decide which samples are inside
(option ``lens_method`` of ``gl-raycast``):

* ``fused`` (note 004 §2.8): the lens interval is computed once per ray, analytically (a sphere's
  quadratic; a box's slabs or a convex mesh's faces as half-spaces in the lens frame, Cyrus–Beck),
  turned into the cells where the ray enters and leaves the lens, and one loop runs over the
  three segments in front of, inside and behind the lens, each with its own classification.
* ``per-sample``: the baseline the paper argues against: every sample tests its own position
  against the lens (inside the sphere, or inside every half-space) and picks its classification.

A box or mesh lens is at most :data:`MAX_LENS_PLANES` half-spaces (a uniform array).
"""

import numpy as np

from core.errors import UnsupportedFeatureError

LENS_METHODS = ("fused", "per-sample")
MAX_LENS_PLANES = 256
"""Half-spaces a box or mesh lens may have: the uniform array's length (256 vec4, 4 KiB, well inside
any OpenGL 4.3 fragment stage's uniform space)."""

LENS_MODES = ("clip", "dvr")
"""Lens appearances the caster renders; ``mip`` and ``iso`` lenses are refused (see :func:`check_lens`)."""

LENS_GLSL = f"""
#define MAX_LENS_PLANES {MAX_LENS_PLANES}
uniform int u_lens_kind;                      // 0: sphere; 1: half-spaces in the lens frame
uniform vec4 u_lens_sphere;                   // world centre, radius
uniform mat4 u_lens_w2o;                      // world -> lens frame
uniform int u_lens_plane_count;
uniform vec4 u_lens_planes[MAX_LENS_PLANES];  // inside: dot(xyz, x) <= w
uniform sampler2D u_lens_tf;                  // the lens appearance's table (dvr)
uniform int u_lens_tf_size;

// The parameters [t0, t1] where the world line o + t d is inside the lens (t0 >= t1: empty).
vec2 lens_interval(vec3 o, vec3 d) {{
    if (u_lens_kind == 0) {{
        // The cancellation-free roots of the reference (sphere_interval): the discriminant from
        // the centre's distance to the line, the second root from Vieta.
        vec3 f = o - u_lens_sphere.xyz;
        float a = dot(d, d);
        float bh = dot(f, d);
        vec3 p = f - (bh / a) * d;
        float r = u_lens_sphere.w;
        float disc = a * (r * r - dot(p, p));
        if (!(disc > 0.0)) {{
            return vec2(1.0, -1.0);
        }}
        float q = -(bh + (bh < 0.0 ? -sqrt(disc) : sqrt(disc)));
        float t0 = q / a;
        float t1 = (dot(f, f) - r * r) / q;
        return vec2(min(t0, t1), max(t0, t1));
    }}
    // Cyrus-Beck in the lens frame; d is carried unnormalised, so t stays the world ray's.
    vec3 lo_ = (u_lens_w2o * vec4(o, 1.0)).xyz;
    vec3 ld = mat3(u_lens_w2o) * d;
    float lo = -1e30;
    float hi = 1e30;
    for (int i = 0; i < u_lens_plane_count; i++) {{
        float den = dot(u_lens_planes[i].xyz, ld);
        float num = u_lens_planes[i].w - dot(u_lens_planes[i].xyz, lo_);
        if (den == 0.0) {{
            if (num < 0.0) {{
                return vec2(1.0, -1.0);
            }}
        }} else if (den > 0.0) {{
            hi = min(hi, num / den);
        }} else {{
            lo = max(lo, num / den);
        }}
    }}
    return vec2(lo, hi);
}}

// Whether the world point x is inside the lens (the per-sample test).
bool inside_lens(vec3 x) {{
    if (u_lens_kind == 0) {{
        vec3 f = x - u_lens_sphere.xyz;
        return dot(f, f) <= u_lens_sphere.w * u_lens_sphere.w;
    }}
    vec3 p = (u_lens_w2o * vec4(x, 1.0)).xyz;
    for (int i = 0; i < u_lens_plane_count; i++) {{
        if (dot(u_lens_planes[i].xyz, p) > u_lens_planes[i].w) {{
            return false;
        }}
    }}
    return true;
}}

vec4 classify_lens(float s) {{
    float x = s * float(u_lens_tf_size - 1);
    int i0 = min(int(floor(x)), u_lens_tf_size - 2);
    return mix(texelFetch(u_lens_tf, ivec2(i0, 0), 0), texelFetch(u_lens_tf, ivec2(i0 + 1, 0), 0), x - float(i0));
}}

// composite_sample (raycast.SAMPLING) with the lens's table where `inside`.
void composite_lens_sample(vec3 start, vec3 dir, float t, float ratio, vec3 ray_dir, bool inside, inout vec4 acc) {{
    vec3 p = start + t * dir;
    float s = scalar_at(p);
    vec4 c = inside ? classify_lens(s) : classify(s);
    float alpha = ratio > 0.0 ? correct_opacity(c.a, ratio) : 0.0;
    if (alpha > 0.0) {{
        vec3 rgb = c.rgb;
#ifdef PHONG
        rgb = shade(rgb, p, ray_dir);
#endif
        acc += (1.0 - acc.a) * vec4(alpha * rgb, alpha);
    }}
}}
"""
"""Lens interval, inside test, the lens's classification and its compositing (needs raycast.SAMPLING)."""

SINGLE_PASS_FRAGMENT = """
layout(std430, binding = 0) buffer Counters {
    uint samples_taken;
};
uniform float u_threshold;
out vec4 o_color;

#ifdef LENS_FUSED
// The first cell whose sample lies past x (at or past it unless `strict`); `cells` if none.
int first_cell_past(float x, bool strict, float len, int cells) {
    float ratio;
    // From whole cells' centres, one cell early against rounding; the walk settles it, and the last,
    // partial cell (sampled at the middle of its part, not at a whole cell's centre) with it.
    int k = max(int(ceil(clamp(x / u_step - 0.5, 0.0, float(cells)))) - 1, 0);
    while (k < cells && (strict ? cell_sample(k, len, 1.0, ratio) <= x : cell_sample(k, len, 1.0, ratio) < x)) {
        k++;
    }
    return k;
}
#endif

void main() {
    vec3 origin, ray_dir;
    pixel_ray(gl_FragCoord.xy, origin, ray_dir);
    vec3 o = (u_world_to_tex * vec4(origin, 1.0)).xyz;
    vec3 d = mat3(u_world_to_tex) * ray_dir;       // texture displacement per world unit
    vec2 span = slab(o, d);
    float len = max(span.y - span.x, 0.0);
    vec3 start = o + span.x * d;
    int cells = len > u_sliver ? int(ceil((len - u_sliver) / u_step)) : 0;
    uint taken = 0u;
    float full = length(d * u_extent) * u_step / u_ref_step;
    vec4 acc = vec4(0.0);
#ifdef LENS_FUSED
    // The lens segment in the ray's cells, from the analytic interval (relative to the box entry).
    vec2 lens = lens_interval(origin, ray_dir);
    float lo = max(lens.x, span.x) - span.x;
    float hi = min(lens.y, span.y) - span.x;
    int k_in = cells;
    int k_out = cells;
    if (hi - lo > u_sliver) {
        k_in = first_cell_past(lo, false, len, cells);
        k_out = first_cell_past(hi, true, len, cells);
    }
    int ends[3] = int[3](k_in, k_out, cells);
    int k = 0;
    for (int segment = 0; segment < 3; segment++) {
        bool inside = segment == 1;
#ifdef LENS_CLIP
        if (inside) {
            k = ends[segment];
            continue;
        }
#endif
        for (; k < ends[segment] && acc.a <= u_threshold; k++) {
            float ratio;
            float t = cell_sample(k, len, full, ratio);
            composite_lens_sample(start, d, t, ratio, ray_dir, inside, acc);
            taken++;
        }
        k = ends[segment];
    }
#else
    for (int k = 0; k < cells && acc.a <= u_threshold; k++) {
        float ratio;
        float t = cell_sample(k, len, full, ratio);
        bool inside = inside_lens(origin + (span.x + t) * ray_dir);
#ifdef LENS_CLIP
        if (inside) {
            continue;
        }
#endif
        composite_lens_sample(start, d, t, ratio, ray_dir, inside, acc);
        taken++;
    }
#endif
    o_color = acc;
    atomicAdd(samples_taken, taken);
}
"""
"""The single-pass caster's ``dvr`` loop with a lens (defines ``LENS_FUSED`` or not, ``LENS_CLIP`` or not)."""


def defines(lens, method):
    """The preprocessor names of :data:`SINGLE_PASS_FRAGMENT` for ``lens`` and ``method``."""
    names = ["LENS_FUSED"] if method == "fused" else []
    if lens.appearance.mode == "clip":
        names.append("LENS_CLIP")
    return names


def check_lens(backend, variant, lens, single_pass):
    """Refuse, before any work, a lens this caster cannot render.

    Raises
    ------
    UnsupportedFeatureError
        A multi-pass ``variant`` (``single_pass`` false), a ``mip`` or ``iso`` appearance, a
        gradient opacity in the appearance, or more half-spaces than :data:`MAX_LENS_PLANES`.
    """
    if not single_pass:
        raise UnsupportedFeatureError(backend, f"a lens with variant {variant!r}",
                                      "the multi-pass variants do not cut rays at a lens yet (the `segments` "
                                      "method is to come); use variant='single-pass'")
    mode = lens.appearance.mode
    if mode not in LENS_MODES:
        raise UnsupportedFeatureError(backend, f"a {mode!r} lens appearance",
                                      f"only {' and '.join(LENS_MODES)} lenses are in the single-pass shader")
    if lens.appearance.gradient_opacity is not None:
        raise UnsupportedFeatureError(backend, "a lens appearance's gradient_opacity",
                                      "gradient-magnitude opacity modulation is not in the shaders")
    planes = len(lens.half_spaces()[1])
    if planes > MAX_LENS_PLANES:
        raise UnsupportedFeatureError(backend, f"a lens of {planes} half-spaces",
                                      f"the shader holds at most {MAX_LENS_PLANES}; use the mesh's convex hull "
                                      "with fewer faces, a box or a sphere")


def uniforms(lens):
    """The lens's scalar, vector and matrix uniforms (the half-spaces: :func:`planes`)."""
    return {
        "u_lens_kind": 0 if lens.shape == "sphere" else 1,
        "u_lens_sphere": (*lens.center, lens.radius or 0.0),
        "u_lens_w2o": np.linalg.inv(lens.object_to_world()),
        "u_lens_plane_count": len(lens.half_spaces()[1]),
    }


def planes(lens):
    """The bytes of ``u_lens_planes``: ``(n, c)`` rows, float32, zero-padded to :data:`MAX_LENS_PLANES`."""
    normals, offsets = lens.half_spaces()
    rows = np.zeros((MAX_LENS_PLANES, 4), np.float32)
    rows[:len(offsets), :3] = normals
    rows[:len(offsets), 3] = offsets
    return rows.tobytes()
