"""Lens volumes (Ropinski, Steinicke & Hinrichs 2005) in the ray caster: GLSL, geometry and uniforms.

The semantics are :mod:`core.lens`'s and the reference's (:func:`renderers.reference.raycast.render_lens`):
the samples stay on the no-lens lattice, and a sample at ``t`` with ``t_Lin <= t <= t_Lout`` is
classified with the lens's appearance (``clip``: skipped; ``dvr``: the lens's table, a second TF
texture), every other sample with the volume's; a ``mip`` or ``iso`` lens contributes its
segment's one value (the largest sample, or the first crossing) where the segment starts.
How the caster finds which samples are inside is option ``lens_method`` of ``gl-raycast``:

* ``segments`` (the paper, note 004 §2.3–2.8): the lens is rasterised first (the geometry pass,
  stage ``lens_geometry``): every fragment of the lens's faces writes the ray parameter where the
  pixel's ray crosses that face, into an RG32F image with ``GL_MIN`` blending — red the entry
  (front faces), green minus the exit (back faces), front and back told apart by the face's
  outward normal, so no winding or depth test is involved. These are the paper's ``lens_front``
  and ``lens_back`` images; intersected with the box span per pixel they give ``transition₀``,
  ``transition₁`` and the regions (the guide's §2.7/2.8 resolve, which also closes the guide's
  fully-behind hole: a ray whose lens lies outside the box has an empty region₁ and region₀ is
  its whole span). Then three region passes (stages ``region0``, ``region1``, ``region2``), back
  to front by default, each a loop over its region's lattice cells with its own appearance,
  blended with premultiplied "over" (``ONE, ONE_MINUS_SRC_ALPHA``). A ``clip`` lens's region₁
  pass is not drawn. A sphere is rasterised as its circumscribed cube whose fragments solve the
  ray–sphere quadratic (an impostor), so its surface is exact, not a tessellation's.
* ``segments-stencil``: the same region passes, bounded by ``transition₀`` and ``transition₁``
  built as the paper builds them — the stencil buffer and a second depth test
  (:mod:`renderers.gl.stencil`, which also says how the guide's hole is closed and counted).
* ``fused``: the lens interval is computed once per ray, analytically (a sphere's quadratic; a
  box's slabs or a convex mesh's faces as half-spaces in the lens frame, Cyrus–Beck), and one
  loop runs over the three segments.
* ``per-sample``: the baseline the paper argues against: every sample tests its own position
  against the lens (inside the sphere, or inside every half-space).
* ``per-sample-mask``: every sample fetches a 3-D lens mask (the lens voxelised at the volume's
  resolution, linear filtering, inside where it reads ≥ ½: Weiskopf et al.'s volumetric
  clipping), so the lens boundary is the voxel grid's, not the lens's.
* ``frag-depth``: depth-based clipping: the geometry pass's images are compared with every
  sample's ray parameter (a depth comparison per sample) and the fragment writes
  ``gl_FragDepth`` (the depth of its first visible sample), which turns the early depth test off.

Option ``region_order`` (``segments`` only): ``back-to-front`` (the paper) or ``front-to-back``
(the guide's E9 ablation): region₂, region₁, region₀, each pass continuing the accumulation of
the passes before it (read from the other of two targets), so rays that are opaque in front of
the lens take no samples behind it.

``mip`` and ``iso`` lenses need the lens segment whole: ``fused`` and ``segments`` render them,
the per-sample methods refuse them. A box or mesh lens is at most :data:`MAX_LENS_PLANES`
half-spaces (a uniform array).
"""

import functools

import numpy as np

from core.errors import InputError, UnsupportedFeatureError
from renderers.gl import isocells
from renderers.gl.view import cube_triangles

LENS_METHODS = ("segments", "segments-stencil", "fused", "per-sample", "per-sample-mask", "frag-depth")
SEGMENT_METHODS = ("segments", "segments-stencil")
IMAGE_METHODS = SEGMENT_METHODS + ("frag-depth",)
"""Methods that rasterise the lens into per-pixel entry and exit images before the volume pass."""
WHOLE_SEGMENT_METHODS = SEGMENT_METHODS + ("fused",)
"""Methods that know a ray's lens segment whole, which ``mip`` and ``iso`` lenses need."""
INTERVAL_METHODS = IMAGE_METHODS + ("fused",)
"""Methods that compute each ray's lens interval (and count ``lens_rays``)."""
REGION_ORDERS = ("back-to-front", "front-to-back")
MAX_LENS_PLANES = 256
"""Half-spaces a box or mesh lens may have: the uniform array's length (256 vec4, 4 KiB, well inside
any OpenGL 4.3 fragment stage's uniform space)."""
NO_HIT = 1e30
"""The lens images' clear value: a channel still holding it was written by no face."""

LENS_GLSL = f"""
#define MAX_LENS_PLANES {MAX_LENS_PLANES}
uniform int u_lens_kind;                      // 0: sphere; 1: half-spaces in the lens frame
uniform vec4 u_lens_sphere;                   // world centre, radius
uniform mat4 u_lens_w2o;                      // world -> lens frame
uniform int u_lens_plane_count;
uniform vec4 u_lens_planes[MAX_LENS_PLANES];  // inside: dot(xyz, x) <= w

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
"""
"""The lens's analytic interval along a world ray (the fused method, the sphere impostor, the per-sample test)."""

GEOMETRY_VERTEX = """#version 430
uniform mat4 u_world_mvp;        // world -> clip, near and far planes bracketing the lens
in vec3 in_world;
in vec3 in_normal;               // the face's outward normal (world)
out vec3 v_world;
flat out vec3 v_normal;
void main() {
    v_world = in_world;
    v_normal = in_normal;
    gl_Position = u_world_mvp * vec4(in_world, 1.0);
}
"""

GEOMETRY_FRAGMENT = f"""
in vec3 v_world;
flat in vec3 v_normal;
out vec4 o_lens;
// GL_MIN blending into a target cleared to {NO_HIT:g}: r = the entry, g = minus the exit.
void main() {{
    vec3 origin, ray_dir;
    pixel_ray(gl_FragCoord.xy, origin, ray_dir);
    if (u_lens_kind == 0) {{
        vec2 t = lens_interval(origin, ray_dir);   // the impostor: the sphere itself
        if (!(t.y > t.x)) {{
            discard;
        }}
        o_lens = vec4(t.x, -t.y, 0.0, 0.0);
    }} else {{
        float t = dot(v_world - origin, ray_dir);
        o_lens = dot(v_normal, ray_dir) < 0.0 ? vec4(t, {NO_HIT:g}, 0.0, 0.0) : vec4({NO_HIT:g}, -t, 0.0, 0.0);
    }}
}}
"""
"""The geometry pass: the lens's entry and exit along every pixel's ray (``lens_front``, ``lens_back``)."""

MARCH_GLSL = """
layout(std430, binding = 0) buffer Counters {
    uint samples_taken;
    uint samples_region[3];      // behind the lens (region 0), inside it (1), in front of it (2)
    uint lens_rays;              // rays whose lens segment inside the box is not empty
    uint fragments_shaded;       // fragment shader invocations of the volume passes
    uint hole_rays;              // segments-stencil: rays the paper's images give no region (note 004 §2.8)
};
uniform float u_threshold;
uniform sampler2D u_lens_tf;     // the lens appearance's table (dvr, iso, mip)
uniform int u_lens_tf_size;
uniform float u_lens_iso;
uniform int u_lens_refine;

vec4 classify_lens(float s) {
    float x = s * float(u_lens_tf_size - 1);
    int i0 = min(int(floor(x)), u_lens_tf_size - 2);
    return mix(texelFetch(u_lens_tf, ivec2(i0, 0), 0), texelFetch(u_lens_tf, ivec2(i0 + 1, 0), 0), x - float(i0));
}

#ifdef ISO_EXACT
#define ISO_VALUE u_lens_iso
""" + isocells.CELL_WALK + """
#endif

// Blend one classified sample at texture point `p` into `acc` (front to back, premultiplied).
void composite_classified(vec4 c, vec3 p, float ratio, vec3 ray_dir, inout vec4 acc) {
    float alpha = ratio > 0.0 ? correct_opacity(c.a, ratio) : 0.0;
    if (alpha > 0.0) {
        vec3 rgb = c.rgb;
#ifdef PHONG
        rgb = shade(rgb, p, ray_dir);
#endif
        acc += (1.0 - acc.a) * vec4(alpha * rgb, alpha);
    }
}

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

// The samples of cells [first, last) with the volume's table, or the lens's where `inside`.
void march(int first, int last, bool inside, vec3 start, vec3 d, float len, float full, vec3 ray_dir,
           inout vec4 acc, inout uint taken) {
    for (int k = first; k < last && acc.a <= u_threshold; k++) {
        float ratio;
        float t = cell_sample(k, len, full, ratio);
        vec3 p = start + t * d;
        float s = scalar_at(p);
#ifdef REGION_OUTSIDE
        composite_classified(classify(s), p, ratio, ray_dir, acc);
#else
        composite_classified(inside ? classify_lens(s) : classify(s), p, ratio, ray_dir, acc);
#endif
        taken++;
    }
}

#if defined(LENS_MIP) || defined(LENS_ISO)
// A mip or iso lens's one contribution on its segment [lo, hi] (relative to the box entry): mip the
// largest of the segment's lattice samples and both ends, classified without opacity correction;
// iso the first change of s < iso from the segment's start, on the step grid from lo, refined by
// bisection (ISO_EXACT: the exact first crossing of the cell walk), shaded, opaque (a = 0: no crossing).
vec4 lens_segment(int first, int last, float lo, float hi, vec3 start, vec3 d, float len, vec3 ray_dir,
                  inout uint taken) {
#ifdef LENS_MIP
    float best = max(scalar_at(start + lo * d), scalar_at(start + hi * d));
    for (int k = first; k < last; k++) {
        float ratio;
        best = max(best, scalar_at(start + cell_sample(k, len, 1.0, ratio) * d));
    }
    taken += uint(last - first + 2);
    vec4 c = classify_lens(best);
    return vec4(c.rgb * c.a, c.a);
#elif defined(ISO_EXACT)
    // Every lattice cell of the segment resolved (renderers/gl/isocells.py), from the state at its start.
    iso_cells = 0;
    float t = iso_first_crossing(start, d, lo, hi, scalar_exact(start + lo * d) < u_lens_iso);
    taken += uint(iso_cells);
    if (t >= ISO_FAR) {
        return vec4(0.0);
    }
    vec3 rgb = classify_lens(u_lens_iso).rgb;
#ifdef PHONG
    rgb = blinn_phong(rgb, u_normal_matrix * gradient_exact(start + t * d), ray_dir);
#endif
    return vec4(rgb, 1.0);
#else
    bool below = scalar_at(start + lo * d) < u_lens_iso;
    float a = lo;
    taken++;
    while (a < hi) {
        float b = min(a + u_step, hi);
        taken++;
        if ((scalar_at(start + b * d) < u_lens_iso) != below) {
            for (int j = 0; j < u_lens_refine; j++) {
                float mid = 0.5 * (a + b);
                if ((scalar_at(start + mid * d) < u_lens_iso) != below) {
                    b = mid;
                } else {
                    a = mid;
                }
            }
            vec3 rgb = classify_lens(u_lens_iso).rgb;
#ifdef PHONG
            rgb = shade(rgb, start + 0.5 * (a + b) * d, ray_dir);
#endif
            return vec4(rgb, 1.0);
        }
        a = b;
    }
    return vec4(0.0);
#endif
}
#endif

// Region `region` of the ray (0 behind the lens: cells [k_out, cells); 1 inside: [k_in, k_out);
// 2 in front: [0, k_in)) composited into `acc`; `seg` the lens segment relative to the box entry.
void march_region(int region, int k_in, int k_out, int cells, vec2 seg, vec3 start, vec3 d, float len,
                  float full, vec3 ray_dir, inout vec4 acc, inout uint taken) {
    int first = region == 2 ? 0 : (region == 1 ? k_in : k_out);
    int last = region == 2 ? k_in : (region == 1 ? k_out : cells);
    if (region == 1) {
#if defined(LENS_CLIP)
        return;
#elif defined(LENS_MIP) || defined(LENS_ISO)
        if (seg.y - seg.x > u_sliver && acc.a <= u_threshold) {
            acc += (1.0 - acc.a) * lens_segment(first, last, seg.x, seg.y, start, d, len, ray_dir, taken);
        }
        return;
#endif
    }
    march(first, last, region == 1, start, d, len, full, ray_dir, acc, taken);
}
"""
"""Classification with the lens's table, the cells of a segment, and one region's march (needs raycast.SAMPLING)."""

VOLUME_FRAGMENT = """
#ifndef FRAG_DEPTH
// Side effects (the counters) would otherwise move the depth test after the shader.
layout(early_fragment_tests) in;
#endif
#ifdef LENS_IMAGES
uniform sampler2D u_lens_t;      // the geometry pass: r the lens entry, g minus its exit (NO_HIT: none)
#endif
#ifdef LENS_REGION
uniform int u_region;            // the region this pass renders
#endif
#ifdef FRONT_TO_BACK
uniform sampler2D u_acc;         // what the passes in front of this region accumulated
#endif
#ifdef LENS_STENCIL
uniform sampler2D u_transition0; // the entry of region 0 (a = 0: none), by the stencil sequence
uniform sampler2D u_transition1; // the exit of region 2 (a = 0: none), by the second depth test
#endif
#ifdef LENS_MASK
uniform sampler3D u_lens_mask;   // the lens voxelised: 1 inside, linear filtering
#endif
#ifdef FRAG_DEPTH
uniform mat4 u_mvp;
#endif
out vec4 o_color;

// The lens interval on this pixel's world ray (t0 >= t1: no lens).
vec2 lens_on_ray(vec3 origin, vec3 ray_dir) {
#ifdef LENS_IMAGES
    vec2 lens = texelFetch(u_lens_t, ivec2(gl_FragCoord.xy), 0).rg;
    if (lens.g >= NO_HIT) {
        return vec2(1.0, -1.0);             // no back face: the ray misses the lens
    }
    return vec2(lens.r >= NO_HIT ? -NO_HIT : lens.r, -lens.g);   // no front face: the lens encloses the eye
#else
    return lens_interval(origin, ray_dir);
#endif
}

void main() {
    atomicAdd(fragments_shaded, 1u);
    vec3 origin, ray_dir;
    pixel_ray(gl_FragCoord.xy, origin, ray_dir);
    vec3 o = (u_world_to_tex * vec4(origin, 1.0)).xyz;
    vec3 d = mat3(u_world_to_tex) * ray_dir;       // texture displacement per world unit
    vec2 span = slab(o, d);
    float len = max(span.y - span.x, 0.0);
    vec3 start = o + span.x * d;
    int cells = len > u_sliver ? int(ceil((len - u_sliver) / u_step)) : 0;
    float full = length(d * u_extent) * u_step / u_ref_step;
    uint taken = 0u;
    vec4 acc = vec4(0.0);
#ifdef FRONT_TO_BACK
    acc = texelFetch(u_acc, ivec2(gl_FragCoord.xy), 0);
#endif
#if defined(LENS_REGION) || defined(LENS_FUSED)
    vec2 lens = lens_on_ray(origin, ray_dir);
    vec2 seg = vec2(max(lens.x, span.x), min(lens.y, span.y)) - span.x;
    int k_in = 0;                // no lens: region 0 is the whole ray, as the paper's transition 0 makes it
    int k_out = 0;
    bool has_lens = seg.y - seg.x > u_sliver;
    if (has_lens) {
        k_in = first_cell_past(seg.x, false, len, cells);
        k_out = first_cell_past(seg.y, true, len, cells);
    }
#ifdef LENS_STENCIL
    // The paper's images bound region 2 (transition 1) and region 0 (transition 0); lens ∩ box only
    // says whether region 1 exists where transition 0 is unmarked: to the box's exit, or the hole.
    vec4 t0 = texelFetch(u_transition0, ivec2(gl_FragCoord.xy), 0);
    vec4 t1 = texelFetch(u_transition1, ivec2(gl_FragCoord.xy), 0);
    k_in = t1.a > 0.0 ? first_cell_past(t1.r - span.x, false, len, cells) : (has_lens ? 0 : k_in);
    k_out = t0.a > 0.0 ? first_cell_past(t0.r - span.x, true, len, cells) : (has_lens ? cells : 0);
    k_out = max(k_out, k_in);
    if (u_region == 0 && t0.a == 0.0 && !has_lens) {
        atomicAdd(hole_rays, 1u);
    }
#endif
#ifdef LENS_REGION
    if (u_region == 0 && has_lens) {
        atomicAdd(lens_rays, 1u);
    }
    march_region(u_region, k_in, k_out, cells, seg, start, d, len, full, ray_dir, acc, taken);
    atomicAdd(samples_region[u_region], taken);
#else
    if (has_lens) {
        atomicAdd(lens_rays, 1u);
    }
    for (int region = 2; region >= 0; region--) {
        uint before = taken;
        march_region(region, k_in, k_out, cells, seg, start, d, len, full, ray_dir, acc, taken);
        atomicAdd(samples_region[region], taken - before);
    }
#endif
#else
    // One loop over the ray with a lens test per sample.
#ifdef FRAG_DEPTH
    vec2 lens = lens_on_ray(origin, ray_dir);
    if (min(lens.y, span.y) - max(lens.x, span.x) > u_sliver) {
        atomicAdd(lens_rays, 1u);
    }
    float depth = gl_FragCoord.z;
    bool found = false;
#endif
    for (int k = 0; k < cells && acc.a <= u_threshold; k++) {
        float ratio;
        float t = cell_sample(k, len, full, ratio);
        vec3 p = start + t * d;
#if defined(FRAG_DEPTH)
        float world_t = span.x + t;
        bool inside = lens.x <= world_t && world_t <= lens.y;   // the per-sample depth comparison
#elif defined(LENS_MASK)
        bool inside = texture(u_lens_mask, p).r >= 0.5;
#else
        bool inside = inside_lens(origin + (span.x + t) * ray_dir);
#endif
#ifdef LENS_CLIP
        if (inside) {
            continue;
        }
#endif
        float s = scalar_at(p);
        vec4 c = inside ? classify_lens(s) : classify(s);
#ifdef FRAG_DEPTH
        if (!found && c.a > 0.0) {
            vec4 clip = u_mvp * vec4(p, 1.0);
            depth = clamp(0.5 * clip.z / clip.w + 0.5, 0.0, 1.0);
            found = true;
        }
#endif
        composite_classified(c, p, ratio, ray_dir, acc);
        taken++;
    }
#ifdef FRAG_DEPTH
    gl_FragDepth = depth;        // what a clipping renderer writes to merge with geometry: early-z is off
#endif
#endif
    o_color = acc;
    atomicAdd(samples_taken, taken);
}
"""
"""The lens volume pass: a region pass (``LENS_REGION``), the fused loop (``LENS_FUSED``) or one loop
with a per-sample test (analytic, ``LENS_MASK`` or ``FRAG_DEPTH``)."""

INSIDE_GLSL = """
// Whether the world point x is inside the lens (the per-sample test).
bool inside_lens(vec3 x) {
    if (u_lens_kind == 0) {
        vec3 f = x - u_lens_sphere.xyz;
        return dot(f, f) <= u_lens_sphere.w * u_lens_sphere.w;
    }
    vec3 p = (u_lens_w2o * vec4(x, 1.0)).xyz;
    for (int i = 0; i < u_lens_plane_count; i++) {
        if (dot(u_lens_planes[i].xyz, p) > u_lens_planes[i].w) {
            return false;
        }
    }
    return true;
}
"""

COUNTERS = ("samples", "samples_region0", "samples_region1", "samples_region2", "lens_rays", "fragments_shaded",
            "hole_rays")
"""The storage buffer's uints, in order."""


def defines(lens, method, *, outside=False, front_to_back=False, exact_iso=False):
    """The preprocessor names of the lens volume pass for ``lens`` and ``method``; ``outside``: the segment
    methods' pass for region₀ and region₂, which never classifies with the lens (one program for every
    appearance, so those passes cost the same whatever the lens shows); ``exact_iso``: an iso lens finds its
    crossing by the cell walk (:mod:`renderers.gl.isocells`)."""
    names = [f"LENS_{lens.appearance.mode.upper()}", f"NO_HIT {NO_HIT:g}"]
    if exact_iso and lens.appearance.mode == "iso" and not outside:
        names.append("ISO_EXACT")
    if method in SEGMENT_METHODS:
        names += ["LENS_REGION", "LENS_IMAGES"]
        if method == "segments-stencil":
            names.append("LENS_STENCIL")
        if outside:
            names.append("REGION_OUTSIDE")
        if front_to_back:
            names.append("FRONT_TO_BACK")
    elif method == "fused":
        names.append("LENS_FUSED")
    elif method == "frag-depth":
        names += ["FRAG_DEPTH", "LENS_IMAGES"]
    elif method == "per-sample-mask":
        names.append("LENS_MASK")
    return names


def stages(method):
    """The GL stages of a lens frame with ``method`` (besides ``readback`` and ``total``)."""
    passes = ("region0", "region1", "region2") if method in SEGMENT_METHODS else ("main",)
    return (("lens_geometry",) if method in IMAGE_METHODS else ()) + passes


def check_lens(backend, variant, lens, single_pass, method):
    """Refuse, before any work, a lens this caster cannot render.

    Raises
    ------
    UnsupportedFeatureError
        A multi-pass ``variant`` (``single_pass`` false), a ``mip`` or ``iso`` appearance with a
        per-sample ``method``, a gradient opacity in the appearance, or more half-spaces than
        :data:`MAX_LENS_PLANES`.
    """
    if not single_pass:
        raise UnsupportedFeatureError(backend, f"a lens with variant {variant!r}",
                                      "the lens methods' passes (segments, fused, per-sample) are single-pass loops "
                                      "between their entry and exit; the multi-pass variants' M samples per pass are "
                                      "not cut at a lens: use variant='single-pass'")
    mode = lens.appearance.mode
    if mode in ("mip", "iso") and method not in WHOLE_SEGMENT_METHODS:
        raise UnsupportedFeatureError(backend, f"a {mode!r} lens appearance with lens_method {method!r}",
                                      "a per-sample test classifies samples one at a time, and a mip or iso lens "
                                      f"needs its segment whole: use lens_method {', '.join(WHOLE_SEGMENT_METHODS)}")
    if lens.appearance.gradient_opacity is not None:
        raise UnsupportedFeatureError(backend, "a lens appearance's gradient_opacity",
                                      "gradient-magnitude opacity modulation is not in the shaders")
    planes = len(lens.half_spaces()[1])
    if planes > MAX_LENS_PLANES:
        raise UnsupportedFeatureError(backend, f"a lens of {planes} half-spaces",
                                      f"the shader holds at most {MAX_LENS_PLANES}; use the mesh's convex hull "
                                      "with fewer faces, a box or a sphere")


def check_region_order(order, method, occluder):
    """Refuse a ``region_order`` the method has no regions for, or front to back with an occluder."""
    if order == "front-to-back" and method not in SEGMENT_METHODS:
        raise InputError(f"gl-raycast option region_order: {order!r} orders the passes of the segment methods "
                         f"({', '.join(SEGMENT_METHODS)}); lens_method {method!r} has one pass")
    if order == "front-to-back" and occluder > 0:
        raise InputError("gl-raycast option region_order: 'front-to-back' copies the accumulation from pass to pass "
                         "and an occluder's covered pixels are not drawn; use occluder=0 or 'back-to-front'")


def uniforms(lens):
    """The lens's scalar, vector and matrix uniforms (the half-spaces: :func:`planes`)."""
    isovalue = lens.appearance.isovalue
    return {
        "u_lens_kind": 0 if lens.shape == "sphere" else 1,
        "u_lens_sphere": (*lens.center, lens.radius or 0.0),
        "u_lens_w2o": np.linalg.inv(lens.object_to_world()),
        "u_lens_plane_count": len(lens.half_spaces()[1]),
        "u_lens_iso": 0.0 if isovalue is None else isovalue,
    }


def planes(lens):
    """The bytes of ``u_lens_planes``: ``(n, c)`` rows, float32, zero-padded to :data:`MAX_LENS_PLANES`."""
    normals, offsets = lens.half_spaces()
    rows = np.zeros((MAX_LENS_PLANES, 4), np.float32)
    rows[:len(offsets), :3] = normals
    rows[:len(offsets), 3] = offsets
    return rows.tobytes()


@functools.lru_cache(maxsize=8)
def geometry(lens):
    """The lens's triangles for the geometry pass: ``(T·3, 6)`` float32 rows of world position and the
    face's outward world normal (read-only; cached per lens, which is immutable: a frame's passes and
    the frames of a view all reuse one).

    A box or mesh is its own faces (each half-space's polygon is the mesh's triangles, a box's
    the cube's); a sphere its circumscribed cube (the fragments solve the quadratic).
    """
    if lens.shape == "mesh":
        mesh = lens.mesh
        triangles = mesh.vertices[mesh.faces].reshape(-1, 3)
        normals, _ = lens.half_spaces()
        per_vertex = np.repeat(normals, 3, axis=0)
        matrix = lens.object_to_world()
    else:
        triangles = cube_triangles().astype(np.float64) - 0.5                      # unit cube about 0
        faces = triangles.reshape(-1, 3, 3)
        per_vertex = np.repeat(np.cross(faces[:, 1] - faces[:, 0], faces[:, 2] - faces[:, 0]), 3, axis=0)
        size = np.full(3, 2 * lens.radius) if lens.shape == "sphere" else np.asarray(lens.size)
        matrix = lens.object_to_world() @ np.diag([*size, 1.0])
    world = triangles @ matrix[:3, :3].T + matrix[:3, 3]
    normals = per_vertex @ np.linalg.inv(matrix[:3, :3])       # normals transform by the inverse transpose
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    rows = np.hstack([world, normals]).astype(np.float32)
    rows.flags.writeable = False
    return rows


def geometry_projection(scene, view, world):
    """World → clip for the geometry pass: the camera's projection with near and far planes that
    bracket the box and the lens's vertices ``world`` (the lens may reach far behind the box; its
    faces in front of the near plane are clipped, as the rays start there)."""
    camera = scene.camera
    view_matrix = camera.view_matrix()
    depths = -(np.c_[world, np.ones(len(world))] @ view_matrix.T)[:, 2]
    far = max(view.far, float(depths.max()) * 1.01 + view.near)
    projection = camera.projection_matrix(scene.width / scene.height, view.near, far)
    return projection @ view_matrix


def lens_mask(volume, transform, lens):
    """The lens voxelised on ``volume``'s grid placed by ``transform`` (:meth:`core.lens.Lens.voxel_mask`):
    uint8, 255 inside, ``(nz, ny, nx)`` (the per-sample-mask method's 3-D texture)."""
    return np.where(lens.voxel_mask(volume, transform), 255, 0).astype(np.uint8)
