"""GPU ray casting after Krüger & Westermann 2003: the ``gl-raycast`` backend (OpenGL 4.3, moderngl).

Variants (option ``variant``; note 000 §2.3–2.5, §4):

* ``rc``: the multi-pass caster without acceleration. Two setup passes — the box's front faces
  write each pixel's entry point into ``TMP``; its back faces read it and write ``DIR``
  (texture-space direction per world unit, ray length) and ``START`` — then ⌈K/M⌉ main passes
  (``K`` the longest ray in steps, ``M = samples_per_pass``) each composite ``M`` samples of
  every ray front to back into the float target ``RES``.
* ``rc-a``: + early ray termination. After every main pass but the last, an intermediate pass
  writes ``gl_FragDepth = 1`` where the ray is finished (``RES.a > opaque_threshold``, or its
  next segment starts past its end) and 0 elsewhere; main passes run with the depth test
  ``GREATER``, no depth writes and ``layout(early_fragment_tests)``, so the fragments of finished
  rays are dropped before their shader runs.
* ``rc-b``: + empty-space skipping. The intermediate pass also walks the blocks of a min–max grid
  (``block_size³`` voxels, one-voxel apron) under the ray's *next* segment and writes 1 where
  the CT(min, max) table (rebuilt when the transfer function changes) calls all of them empty
  (in ``iso`` mode: where no block's range reaches across the isovalue from the ray's entry
  state). Rays re-enter the depth test with 0 as soon as a segment is not empty.
* ``single-pass``: the modern caster (not in the paper): one draw, the ray's span by a slab
  test in the shader, a loop over its samples that stops at the end or at ``opaque_threshold``.

Sampling is the reference renderer's (:mod:`renderers.reference.raycast`): the ray from its
box entry (clipped to ``t >= 0``) is cut into cells of the world step ``Δ = step_factor ×`` the
smallest world voxel edge; a whole cell samples at its centre with opacity corrected for ``Δ``,
the last, partial cell at the midpoint of its part with opacity corrected for that length, so
path lengths count exactly. The trilinear sample, the classification, the correction and the
shading are the shared GLSL of :mod:`renderers.gl.glsl`.

Modes
-----
* ``dvr``: front-to-back emission–absorption, premultiplied.
* ``iso``: a crossing is a change of ``s < isovalue`` from its state at the box entry (the
  reference's definition); the hit is shaded (Blinn–Phong) and written with opacity 1, which ends
  the ray at the next intermediate pass. By default (``iso_hit='exact'``) each pass walks every
  lattice cell of its segment and resolves the first crossing on the trilinear interpolant, as the
  reference does (:mod:`renderers.gl.isocells`): nothing is stepped over, and the step only sets
  how many passes a ray takes. ``iso_hit='sampled'`` is the paper's caster (Sec. 2.2): within
  each main pass the ``M`` samples, at the cell ends ``min((k + 1)Δ, L)``, are visited back to
  front and the last crossing kept — the nearest one of the segment — then refined by
  ``iso_refine`` bisection steps inside its cell (the paper takes the sample itself) and shaded
  with the gradient texture; a crossing that lies between two samples (a sheet or vessel thinner
  than a step) is missed.
* ``mip``: passes keep the largest sampled scalar (cell samples plus both ends of the ray) with
  ``GL_MAX`` blending; a resolve pass classifies it (no correction, no shading, as the reference).
  Only ray exits end rays early: a block of transparent voxels can still hold the maximum, so
  ``rc-b`` skips no empty space in ``mip``.

Implementation gaps of the paper, decided here (note 000 §2.3)
--------------------------------------------------------------
1. **Depth functions.** Main passes: ``GL_GREATER``, depth writes off, early fragment tests.
   Intermediate passes: ``GL_ALWAYS`` with depth writes, so a pixel culled after one segment
   is re-enabled (z = 0) when a later segment is not empty. The depth buffer is cleared to 0
   before the first main pass; the setup passes run with the depth test off and leave it alone.
2. **Read-modify-write of RES.** Hardware blending into the RGBA32F target:
   ``glBlendFuncSeparate(ONE_MINUS_DST_ALPHA, ONE, ONE_MINUS_DST_ALPHA, ONE)`` with each pass
   writing its segment's premultiplied colour and opacity (the under operator); the intermediate
   pass reads RES as a texture through a depth-only framebuffer (no feedback loop).
3. **Ray exit.** The paper writes α = 1 into RES when a ray leaves the volume so that the
   opacity test stops it; that would put α = 1 in the image. Here RES keeps the true opacity and
   the intermediate pass compares the next segment's start with the ray length in ``DIR.a``
   itself — the same culling.
4. **Opacity correction, gradients, lighting** (unspecified in the paper): the conventions' (see
   above); gradients from a precomputed texture (RGB16F central differences, as the paper's
   gradient texture).
5. **Camera inside the volume.** Where the near plane clips the front faces no entry point is
   written; the back-face pass then starts the ray at its analytic box entry clipped to
   ``t >= 0`` (the eye). Main and intermediate passes rasterise the *back* faces, which cover
   every pixel whose ray meets the box in front of the eye (the paper draws front faces, the
   same pixels when the eye is outside).
6. **Which segment the empty-space test checks**: the upcoming one (it gates the next main pass),
   walked with a 3-D DDA over all blocks its sample positions lie in — exact, where sampling the
   grid every ``8·Δ`` (the paper's coarse step, OCR-uncertain) can step over a block the segment
   clips at a corner. An intermediate pass follows every main pass except the last.
7. **The occluder demonstration** (the paper's Sec. 1, note 000 E8; option ``occluder``): an
   opaque grey plane in front of the volume covering the left part ``f`` of the box's screen
   footprint (its bounding rectangle) is drawn after the setup passes, writing depth 1 where it
   covers a ray, as a finished ray does; every later main pass drops those fragments by early-z,
   so the frame time should fall with the covered area. Its fragments are counted
   (``rays_occluded``). Multi-pass variants and ``dvr``/``iso`` only: ``mip`` blends by maximum,
   which an opaque plane does not stop.
8. **Shader work per pass.** As in the paper, every main pass computes all ``M`` samples of every
   fragment that passes the depth test (samples past the ray's end add nothing), so the
   ``samples`` counter is ``M ×`` the fragments of the main passes (with ``iso_hit='exact'``: the
   cell segments the passes walked, counted in the shader).

Lenses (Ropinski et al. 2005)
-----------------------------
A lens scene (one lens, :mod:`core.lens`) renders in the ``single-pass`` variant, by option
``lens_method`` (:mod:`renderers.gl.lens` describes each; :mod:`renderers.gl.lens_passes` issues
the passes): ``segments`` (the paper: a geometry pass rasterising the lens into entry and exit
images, then a pass per region back to front, or ``region_order='front-to-back'``), ``fused`` (the
lens interval per ray, one loop over the three segments), ``per-sample`` (an inside test per
sample), ``per-sample-mask`` (a 3-D mask fetch per sample), ``frag-depth`` (per-sample depth
comparison, writing ``gl_FragDepth``). The samples stay on the no-lens lattice, so a lens with
the outside appearance changes nothing. ``mip`` and ``iso`` lenses need ``segments`` or ``fused``.
A lens scene rendered with the default options gets the ``single-pass`` variant, and its record says so
(``info["variant_chosen"]``); a multi-pass variant asked for by name refuses a lens
(:class:`~core.errors.UnsupportedFeatureError`) before any work. Lens frames add the stages ``lens_geometry``, ``region0``–``region2`` (or ``main``), the
preparation ``lens_mask`` (``per-sample-mask``) and the counters ``samples_region0``–``2``,
``lens_rays`` (rays whose lens segment inside the box is not empty; not for the per-sample
methods, which never compute it) and ``fragments_shaded`` (volume-pass shader invocations: with
an occluder, what early-z saved).

Timing and counters
-------------------
Stages (seconds, :mod:`renderers.gl.timing`): ``setup`` (the two setup passes and the clears),
``main``, ``intermediate`` and ``resolve`` (each summed over its passes), ``readback`` and
``total`` (wall clock of the frame, preparation excluded; with ``timing="finish"`` it includes
waiting for each pass, which on llvmpipe also stops it from rasterising several passes tile by
tile in one go: measured +10–20 % on 40–80-pass frames). Preparation, only in frames that
build something: ``upload`` (every transfer), ``gradients``, ``minmax``, ``ct_table``.
Counters: ``rays`` (pixels whose ray meets the box), ``fragments_main`` (fragments that passed the
depth test in the main passes, from ``GL_SAMPLES_PASSED``), ``fragments_intermediate``,
``fragments_culled`` (main-pass fragments dropped by early-z), ``passes_main``,
``passes_intermediate``, ``samples`` and, with an occluder, ``rays_occluded`` (its stage:
``occluder``); in ``iso`` also ``crossings`` (the pixels whose ray found the surface) and, with
``iso_hit='exact'``, ``iso_cells_solved`` (the cells whose range reaches across the isovalue,
solved; ``samples`` are the cells walked). ``info["fragments_per_main_pass"]`` lists the main
passes' counts.
"""

import math
import time

import numpy as np

from core.errors import InputError
from core.resources import check_memory
from renderers.base import Capabilities, Option, RenderResult, step_factor_option
from renderers.gl import context, emptyspace, glsl
from renderers.gl import lens as lenses
from renderers.gl import isocells, lens_passes, stencil
from renderers.gl.base import TIMING, GLRenderer, set_uniforms
from renderers.gl.view import SLIVER, make_view, ray_lengths

VARIANTS = ("rc", "rc-a", "rc-b", "single-pass")
ISO_HITS = ("sampled", "exact")
MULTI_PASS = ("rc", "rc-a", "rc-b")

# Texture units, fixed for every program of the backend.
UNITS = {"u_volume": 0, "u_tf": 1, "u_gradient": 2, "u_entry": 3, "u_dir": 4, "u_start": 5, "u_res": 6,
         "u_blocks": 7, "u_ct": 8, "u_lens_tf": 9, "u_lens_mask": 10, "u_lens_t": 11, "u_acc": 12,
         "u_transition0": 13, "u_transition1": 14}  # 15: the stencil sequence's box depth

ENTRY_FRAGMENT = """
in vec3 v_tex;
out vec4 o_entry;
void main() {
    o_entry = vec4(v_tex, 1.0);   // front face: where the ray enters (a = 1: written)
}
"""

DIRECTION_FRAGMENT = """
uniform sampler2D u_entry;
in vec3 v_tex;
layout(location = 0) out vec4 o_dir;
layout(location = 1) out vec4 o_start;
void main() {
    vec4 entry = texelFetch(u_entry, ivec2(gl_FragCoord.xy), 0);
    vec3 start = entry.xyz;
    if (entry.a == 0.0) {
        // The near plane clipped the front face: start at the box entry clipped to t >= 0.
        vec3 origin, direction;
        pixel_ray(gl_FragCoord.xy, origin, direction);
        vec3 o = (u_world_to_tex * vec4(origin, 1.0)).xyz;
        vec3 d = mat3(u_world_to_tex) * direction;
        vec2 span = slab(o, d);
        start = o + min(span.x, span.y) * d;
    }
    vec3 path = v_tex - start;                     // back face: where the ray leaves
    float len = length(u_tex_to_world * path);     // world length of the ray in the box
    o_dir = len > 0.0 ? vec4(path / len, len) : vec4(0.0);
    o_start = vec4(start, 1.0);
}
"""

OCCLUDER_FRAGMENT = """
uniform float u_cut;             // window x (pixels) left of which the occluder covers the box
in vec3 v_tex;
out vec4 o_res;
void main() {
    if (gl_FragCoord.x >= u_cut) discard;
    o_res = vec4(0.5, 0.5, 0.5, 1.0);   // opaque grey in front of the volume
    gl_FragDepth = 1.0;                 // as a finished ray: every main pass fails the depth test
}
"""

SAMPLING = """
uniform float u_sliver;          // a partial last cell this short (world) is not sampled

// Ray parameter of cell k's sample; `ratio` = its object-space length over the reference step
// (0: no sample), `full` that of a whole cell.
float cell_sample(int k, float len, float full, out float ratio) {
    float a = float(k) * u_step;
    if (a + u_step <= len) {
        ratio = full;
        return a + 0.5 * u_step;
    }
    float part = len - a;
    ratio = part > u_sliver ? full * part / u_step : 0.0;
    return 0.5 * (a + len);
}

#ifdef MODE_DVR
void composite_sample(vec3 start, vec3 dir, float t, float ratio, vec3 ray_dir, inout vec4 acc) {
    vec3 p = start + t * dir;
    vec4 c = classify(scalar_at(p));
    float alpha = ratio > 0.0 ? correct_opacity(c.a, ratio) : 0.0;
    if (alpha > 0.0) {
        vec3 rgb = c.rgb;
#ifdef PHONG
        rgb = shade(rgb, p, ray_dir);
#endif
        acc += (1.0 - acc.a) * vec4(alpha * rgb, alpha);
    }
}
#endif

#ifdef MODE_ISO
uniform float u_iso;
uniform int u_refine;
#ifdef ISO_EXACT
""" + isocells.CELL_WALK + """
#endif

bool crossed(vec3 start, vec3 dir, float t, bool below) {
    return (scalar_at(start + t * dir) < u_iso) != below;
}

// The surface at p: the transfer function's colour at the isovalue, shaded; opacity 1.
vec4 iso_shade(vec3 p, vec3 ray_dir) {
    vec3 rgb = classify(u_iso).rgb;
#if defined(PHONG) && defined(ISO_EXACT)
    rgb = blinn_phong(rgb, u_normal_matrix * gradient_exact(p), ray_dir);
#elif defined(PHONG)
    rgb = shade(rgb, p, ray_dir);
#endif
    return vec4(rgb, 1.0);
}

// The surface inside [lo, hi] (lo not crossed, hi crossed), refined and shaded; opacity 1.
vec4 iso_hit(vec3 start, vec3 dir, float lo, float hi, bool below, vec3 ray_dir) {
    for (int j = 0; j < u_refine; j++) {
        float mid = 0.5 * (lo + hi);
        if (crossed(start, dir, mid, below)) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    return iso_shade(start + 0.5 * (lo + hi) * dir, ray_dir);
}
#endif
"""

MAIN_FRAGMENT = """
layout(early_fragment_tests) in;
#ifdef ISO_EXACT
layout(std430, binding = 0) buffer Counters {
    uint cells_walked;           // the cell segments the passes walked (the frame's samples)
    uint cells_solved;           // of those, the cells solved (their range reaches across the isovalue)
};
#endif
uniform sampler2D u_start;
uniform sampler2D u_dir;
uniform int u_first;             // first cell of this pass
uniform int u_samples;           // M
out vec4 o_color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 start = texelFetch(u_start, px, 0).xyz;
    vec4 dir = texelFetch(u_dir, px, 0);
    vec3 origin, ray_dir;
    pixel_ray(gl_FragCoord.xy, origin, ray_dir);
#if defined(MODE_DVR)
    float full = length(dir.xyz * u_extent) * u_step / u_ref_step;
    vec4 acc = vec4(0.0);
    for (int i = 0; i < u_samples; i++) {
        float ratio;
        float t = cell_sample(u_first + i, dir.a, full, ratio);
        composite_sample(start, dir.xyz, t, ratio, ray_dir, acc);
    }
    o_color = acc;                                  // blended under RES
#elif defined(MODE_MIP)
    float best = u_first == 0 ? scalar_at(start) : 0.0;
    for (int i = 0; i < u_samples; i++) {
        float ratio;
        float t = cell_sample(u_first + i, dir.a, 1.0, ratio);
        float s = scalar_at(start + t * dir.xyz);
        best = ratio > 0.0 ? max(best, s) : best;
    }
    float end = float(u_first + u_samples) * u_step;
    if (end >= dir.a - u_sliver && float(u_first) * u_step < dir.a) {
        best = max(best, scalar_at(start + dir.a * dir.xyz));   // the exit face
    }
    o_color = vec4(best, 1.0, 0.0, 0.0);            // GL_MAX blending
#elif defined(ISO_EXACT)
    // Every cell of this pass's segment resolved: its first crossing, wherever it lies between samples.
    float a = float(u_first) * u_step;
    o_color = vec4(0.0);
    iso_cells = 0;
    iso_solved = 0;
    if (a < dir.a) {
        float t = iso_first_crossing(start, dir.xyz, a, min(a + float(u_samples) * u_step, dir.a),
                                     scalar_exact(start) < u_iso);
        if (t < ISO_FAR) {
            o_color = iso_shade(start + t * dir.xyz, ray_dir);
        }
    }
    atomicAdd(cells_walked, uint(iso_cells));
    atomicAdd(cells_solved, uint(iso_solved));
#else
    bool below = scalar_at(start) < u_iso;
    int hit = -1;
    for (int i = u_samples - 1; i >= 0; i--) {      // back to front: the last crossing is the nearest
        float a = float(u_first + i) * u_step;
        bool c = crossed(start, dir.xyz, min(a + u_step, dir.a), below);
        hit = (c && a < dir.a - u_sliver) ? i : hit;
    }
    o_color = vec4(0.0);
    if (hit >= 0) {
        float lo = float(u_first + hit) * u_step;
        o_color = iso_hit(start, dir.xyz, lo, min(lo + u_step, dir.a), below, ray_dir);
    }
#endif
}
"""

INTERMEDIATE_FRAGMENT = """
uniform sampler2D u_res;
uniform sampler2D u_dir;
uniform sampler2D u_start;
uniform int u_next_first;        // first cell of the next main pass
uniform int u_samples;
uniform float u_threshold;       // early ray termination: RES.a above it
uniform float u_sliver;
#ifdef SKIP_EMPTY
uniform usampler3D u_blocks;     // (min, max) levels per block, apron included
uniform usampler2D u_ct;         // CT[max][min] != 0: some visible scalar in [min, max]
uniform vec3 u_block_scale;      // texture coordinate -> block coordinate
uniform ivec3 u_block_count;
uniform float u_top_level;       // the level of scalar 1 in the block ranges
#ifdef MODE_ISO
uniform float u_iso;
#endif

bool block_visible(ivec3 cell, bool below) {
    uvec2 range = texelFetch(u_blocks, clamp(cell, ivec3(0), u_block_count - 1), 0).rg;
#ifdef MODE_ISO
    // A crossing needs a value on the other side of the isovalue from the entry state.
    return below ? float(range.y) >= u_iso * u_top_level - 1e-3 : float(range.x) <= u_iso * u_top_level + 1e-3;
#else
    return texelFetch(u_ct, ivec2(range.x, range.y), 0).r != 0u;
#endif
}

// Whether every block the segment [pa, pb] (texture space) passes through is empty (3-D DDA).
bool segment_empty(vec3 pa, vec3 pb, bool below) {
    vec3 a = pa * u_block_scale;
    vec3 d = pb * u_block_scale - a;
    ivec3 cell = ivec3(floor(a));
    ivec3 stride = ivec3(sign(d));
    vec3 inv = 1.0 / max(abs(d), vec3(1e-20));
    vec3 frac = a - floor(a);
    vec3 next = mix(1.0 - frac, frac, lessThan(d, vec3(0.0))) * inv;
    next = mix(next, vec3(1e30), equal(d, vec3(0.0)));
    int bound = int(abs(d.x)) + int(abs(d.y)) + int(abs(d.z)) + 4;
    for (int i = 0; i < bound; i++) {
        if (block_visible(cell, below)) {
            return false;
        }
        float t = min(next.x, min(next.y, next.z));
        if (t > 1.0) {
            return true;
        }
        if (next.x == t) {
            cell.x += stride.x;
            next.x += inv.x;
        } else if (next.y == t) {
            cell.y += stride.y;
            next.y += inv.y;
        } else {
            cell.z += stride.z;
            next.z += inv.z;
        }
    }
    return false;   // more blocks than the segment can cross (rounding): not empty
}
#endif

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 dir = texelFetch(u_dir, px, 0);
    float a = float(u_next_first) * u_step;
    bool done = texelFetch(u_res, px, 0).a > u_threshold || a >= dir.a - u_sliver;
#ifdef SKIP_EMPTY
    if (!done) {
        vec3 start = texelFetch(u_start, px, 0).xyz;
        float b = min(a + float(u_samples) * u_step, dir.a);
        bool below = true;
#ifdef MODE_ISO
        below = scalar_at(start) < u_iso;
#endif
        done = segment_empty(start + a * dir.xyz, start + b * dir.xyz, below);
    }
#endif
    gl_FragDepth = done ? 1.0 : 0.0;
}
"""

SINGLE_PASS_FRAGMENT = """
layout(std430, binding = 0) buffer Counters {
    uint samples_taken;
    uint cells_solved;           // exact iso: the cells whose range reaches across the isovalue
};
uniform float u_threshold;
out vec4 o_color;

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
#if defined(MODE_DVR)
    float full = length(d * u_extent) * u_step / u_ref_step;
    vec4 acc = vec4(0.0);
    for (int k = 0; k < cells && acc.a <= u_threshold; k++) {
        float ratio;
        float t = cell_sample(k, len, full, ratio);
        composite_sample(start, d, t, ratio, ray_dir, acc);
        taken++;
    }
    o_color = acc;
#elif defined(MODE_MIP)
    float best = max(scalar_at(start), scalar_at(start + len * d));
    for (int k = 0; k < cells; k++) {
        float ratio;
        best = max(best, scalar_at(start + cell_sample(k, len, 1.0, ratio) * d));
        taken++;
    }
    o_color = vec4(best, len > 0.0 ? 1.0 : 0.0, 0.0, 0.0);
#elif defined(ISO_EXACT)
    iso_cells = 0;
    iso_solved = 0;
    float t = len > 0.0 ? iso_first_crossing(start, d, 0.0, len, scalar_exact(start) < u_iso) : ISO_FAR;
    taken = uint(iso_cells);
    atomicAdd(cells_solved, uint(iso_solved));
    o_color = t < ISO_FAR ? iso_shade(start + t * d, ray_dir) : vec4(0.0);
#else
    bool below = scalar_at(start) < u_iso;
    o_color = vec4(0.0);
    for (int k = 0; k < cells; k++) {
        float t = min(float(k + 1) * u_step, len);
        taken++;
        if (crossed(start, d, t, below)) {
            o_color = iso_hit(start, d, float(k) * u_step, t, below, ray_dir);
            break;
        }
    }
#endif
    atomicAdd(samples_taken, taken);
}
"""


def occluder_cut(mvp, width, fraction):
    """Window x (pixels) left of which the occluder covers ``fraction`` of the box's footprint.

    The footprint is the bounding rectangle of the projected box corners, clamped to the image
    (the whole width when a corner lies behind the eye).
    """
    corners = np.array([[x, y, z, 1.0] for x in (0, 1) for y in (0, 1) for z in (0, 1)]) @ np.asarray(mvp).T
    if np.any(corners[:, 3] <= 0):
        left, right = 0.0, float(width)
    else:
        pixels = (corners[:, 0] / corners[:, 3] + 1.0) * 0.5 * width
        left, right = np.clip([pixels.min(), pixels.max()], 0.0, width)
    return float(left + fraction * (right - left))


class GLRaycastRenderer(GLRenderer):
    """Multi-pass GPU ray caster (Krüger & Westermann 2003) and a single-pass one, OpenGL 4.3."""

    technique_stages = ("intermediate", "main", "resolve", "occluder", "lens_geometry", "region0", "region1",
                        "region2")
    """The stages that are the technique itself: the GPU passes, timed on the device; not the readback."""

    name = "gl-raycast"
    description = ("OpenGL multi-pass GPU ray caster (Krüger & Westermann 2003): setup passes, M samples per main "
                   "pass, early ray termination and empty-space skipping by early-z; or single-pass")
    capabilities = Capabilities(
        projections=frozenset({"orthographic", "perspective"}),
        modes=frozenset({"dvr", "mip", "iso"}),
        shading=frozenset({"none", "phong"}),
        transforms=True,
        lenses=True,
        camera_inside_volume=True,
        reasons={
            "max_volumes": "the ray caster's setup passes rasterise one volume's box (one entry and exit per pixel)",
            "gradient_opacity": "gradient-magnitude opacity modulation is not in the shaders (the paper classifies "
                                "by scalar only)",
            "meshes": "no polygon pass (added with the Kainz 2009 issue)",
            "lenses": "one lens, in the single-pass variant, which a lens scene gets unless it asks for a variant "
                      "(every lens method's passes loop from an entry to an exit; the multi-pass variants' M samples "
                      "per pass are not cut at a lens, so they refuse one); mip and iso lenses with lens_method "
                      "segments or fused only (they need the lens segment whole)",
        },
    )
    option_table = (
        Option("variant", str, "rc-b", "``rc``: plain multi-pass; ``rc-a``: + early ray termination; ``rc-b``: + "
               "empty-space skipping (the paper's fastest); ``single-pass``: one loop-with-break draw (extension).",
               choices=VARIANTS),
        step_factor_option(0.5),
        Option("samples_per_pass", int, 8, "``M``, samples per ray per main pass (paper: 8); at most the shader's "
               "32-bit int (any count above a ray's steps makes one pass).", low=1, high=2 ** 31 - 1),
        Option("opaque_threshold", float, 0.95, "``T``: rays whose opacity exceeds it stop (``rc-a``, ``rc-b``, "
               "``single-pass``; 1 never stops a ray).", low=0, high=1, low_open=True),
        Option("block_size", int, 8, "Edge of the min–max grid's blocks in voxels (paper: 8; ``rc-b``).", low=1),
        Option("min_opacity", float, 0.0, "Transfer-function opacities at or below it count as empty for skipping "
               "(``rc-b``); the paper's 0 makes skipping exact.", low=0, high=1, high_open=True),
        Option("iso_hit", str, "exact", "How an iso-surface ray finds its hit: ``exact``, every lattice cell the ray "
               "crosses resolved on the trilinear interpolant, as the reference (:mod:`renderers.gl.isocells`; the "
               "step then only sets the passes, and a frame's ``samples`` counts the cell segments walked), an iso "
               "lens's crossing too; ``sampled``, the paper's test of ``s < isovalue`` at the cell ends, refined by "
               "``iso_refine`` (a crossing between two samples is missed).",
               choices=ISO_HITS, modes=frozenset({"iso"})),
        Option("iso_refine", int, 6, "Bisection steps refining a sampled iso hit (``iso_hit='sampled'``) inside its "
               "cell (0: the sample itself, as the paper); more than 24 refine below float32 resolution.", low=0,
               high=24,
               modes=frozenset({"iso"})),
        Option("occluder", float, 0.0, "Fraction of the box's screen footprint, from the left, hidden behind an "
               "opaque plane drawn before the main passes (the paper's early-z demonstration; 0: none). The "
               "covered pixels show the plane's grey, so images compare with the reference only at 0.",
               low=0, high=1),
        Option("lens_method", str, "segments", "How a lens scene is cut into regions (``single-pass``): "
               "``segments``: the paper's (Ropinski 2005) geometry pass and a pass per region; ``fused``: the lens "
               "interval per ray, analytically, one loop over the regions; ``per-sample``: an inside test at every "
               "sample; ``per-sample-mask``: a 3-D lens-mask fetch at every sample; ``frag-depth``: a depth "
               "comparison at every sample, writing gl_FragDepth. No effect without a lens.",
               choices=lenses.LENS_METHODS),
        Option("region_order", str, "back-to-front", "Order of the ``segments`` region passes: "
               "``back-to-front`` (the paper, blended over) or ``front-to-back`` (each pass continues the "
               "accumulation, so rays opaque in front of the lens stop there).", choices=lenses.REGION_ORDERS),
        TIMING,
    )
    quality_sweep = (tuple({"step_factor": factor} for factor in (1.0, 0.5, 0.25))
                     + ({"opaque_threshold": 0.8}, {"opaque_threshold": 1.0}, {"samples_per_pass": 2},
                        {"samples_per_pass": 32}, {"block_size": 16})
                     + tuple({"iso_hit": "sampled", "step_factor": factor} for factor in (1.0, 0.5, 0.25))
                     + ({"iso_hit": "sampled", "iso_refine": 0},))
    """Step sizes from coarse to fine for the default variant (``rc-b``), then at the default step each
    other option that trades speed for error or overhead: the early-termination threshold (0.8 drops
    up to 20 % of a ray's light, 1 none), the samples per pass M and the block size; on iso-surfaces
    (exact by default, where the step only sets the passes) also the paper's sampled hit at each step,
    and unrefined."""

    def __init__(self, **options):
        super().__init__(**options)
        lenses.check_region_order(self.region_order, self.lens_method, self.occluder)
        self._variant_given = "variant" in options
        self._ray_key = None
        self._ray_max = 0.0
        self._lens_key = None
        self._lens_tf = None

    def check(self, scene):
        """Also refuse, before any work, an empty-space block grid that only pads the volume or that
        this machine cannot build.

        :func:`emptyspace.block_minmax` pads the volume to whole blocks (``ceil(n / B)·B`` float32
        voxels per axis) after its apron filter's copies of the volume (four float32 arrays).
        """
        super().check(scene)
        variant = self._variant(scene)
        if scene.lenses:
            lenses.check_lens(self.name, variant, scene.lenses[0], variant == "single-pass", self.lens_method)
        elif self.occluder > 0 and variant not in MULTI_PASS:
            raise InputError(f"gl-raycast option occluder: the occluder demonstration needs early-z between passes; "
                             f"use a multi-pass variant ({', '.join(MULTI_PASS)}) or a lens scene, not "
                             f"{variant!r} without a lens")
        if variant != "rc-b" or scene.mode == "mip":
            return
        volume = scene.volumes[0].volume
        shape = "×".join(map(str, volume.shape_xyz))
        longest = max(volume.shape_xyz)
        if self.block_size > longest:
            raise InputError(f"gl-raycast option block_size: {self.block_size} is larger than volume {volume.name!r} "
                             f"({shape}), so one block covers it and the rest is padding; use block_size ≤ {longest}")
        padded = math.prod(-(-n // self.block_size) * self.block_size for n in volume.shape_xyz)
        check_memory(4 * padded + 16 * volume.data.size, what=f"gl-raycast option block_size {self.block_size}",
                     detail=f"volume {volume.name!r} ({shape}) padded to whole blocks, {padded} float32 voxels, "
                            "and four float32 copies of it",
                     fix="use a smaller block_size, or variant='rc' (no empty-space skipping)")

    # -----------------------------------------------------------------------------------------

    def _variant(self, scene):
        """The variant that renders ``scene``: the one asked for; where none was and the default (a multi-pass
        variant) cannot render the scene's lens, ``single-pass``, which the record says (``variant_chosen``)."""
        if scene.lenses and not self._variant_given and self.variant in MULTI_PASS:
            return "single-pass"
        return self.variant

    def _exact_iso(self, mode):
        """Whether frames of ``mode`` find the iso hit by the cell walk (:mod:`renderers.gl.isocells`)."""
        return mode == "iso" and self.iso_hit == "exact"

    def _programs(self, ctx, variant, mode, phong, lens=None):
        """The programs of ``variant`` for ``mode``, shading and ``lens`` (compiled once per process)."""
        if lens is not None:
            programs = lens_passes.programs(ctx, lens, self.lens_method, phong=phong, sampling=SAMPLING,
                                            front_to_back=self.region_order == "front-to-back",
                                            exact_iso=self.iso_hit == "exact")
        else:
            exact = ["ISO_EXACT"] if self._exact_iso(mode) else []
            main = glsl.fragment_source(SAMPLING, MAIN_FRAGMENT if variant in MULTI_PASS else
                                        SINGLE_PASS_FRAGMENT, phong=phong, mode=mode, defines=exact)
            programs = {"main": context.program(ctx, glsl.CUBE_VERTEX, main)}
        if variant in MULTI_PASS:
            programs["entry"] = context.program(ctx, glsl.CUBE_VERTEX, glsl.fragment_source(ENTRY_FRAGMENT))
            programs["direction"] = context.program(ctx, glsl.CUBE_VERTEX, glsl.fragment_source(DIRECTION_FRAGMENT))
        if variant in ("rc-a", "rc-b"):
            skip = variant == "rc-b" and mode != "mip"
            source = glsl.fragment_source(INTERMEDIATE_FRAGMENT, mode=mode, defines=["SKIP_EMPTY"] if skip else [])
            programs["intermediate"] = context.program(ctx, glsl.CUBE_VERTEX, source)
        if mode == "mip":
            programs["resolve"] = context.program(ctx, glsl.SCREEN_VERTEX, glsl.fragment_source(glsl.MIP_RESOLVE))
        if self.occluder > 0:
            programs["occluder"] = context.program(ctx, glsl.CUBE_VERTEX, glsl.fragment_source(OCCLUDER_FRAGMENT))
        return programs

    def _frame_targets(self, width, height):
        def build():
            size = (width, height)
            entry, direction, start, res, out, res2 = (self._float_texture(size) for _ in range(6))
            lens_t = self._float_texture(size, 2)
            depth = self._ctx.depth_texture(size)
            targets = {"entry": entry, "direction": direction, "start": start, "res": res, "out": out,
                       "depth": depth, "res2": res2, "lens_t": lens_t,
                       "res2_fbo": self._ctx.framebuffer([res2]),
                       "lens_fbo": self._ctx.framebuffer([lens_t]),
                       "entry_fbo": self._ctx.framebuffer([entry]),
                       "direction_fbo": self._ctx.framebuffer([direction, start]),
                       "main_fbo": self._ctx.framebuffer([res], depth),
                       "depth_fbo": self._ctx.framebuffer([], depth),
                       "out_fbo": self._ctx.framebuffer([out])}
            targets["main_fbo"].depth_mask = False
            return targets

        return self._target((width, height), build)

    def _lens_table(self, lens, instance):
        """The lens's table (:meth:`LensAppearance.classification`), kept while the appearance and the
        volume's table stay, so that the texture cache (keyed by the table object) does not rebuild it."""
        key = (lens.appearance, instance.transfer_function)
        if self._lens_key is None or any(a is not b for a, b in zip(key, self._lens_key)):
            self._lens_key = key
            self._lens_tf = lens.appearance.classification(instance.transfer_function)
        return self._lens_tf

    def _longest_ray(self, scene):
        """World length of the longest pixel ray inside the box (cached for the last view)."""
        instance = scene.volumes[0]
        key = (scene.camera, scene.width, scene.height, instance.transform.tobytes(), instance.volume.extent)
        if key != self._ray_key:
            self._ray_key, self._ray_max = key, float(ray_lengths(scene).max())
        return self._ray_max

    def _render(self, scene):
        import moderngl

        instance = scene.volumes[0]
        mode = scene.mode
        if mode == "mip" and self.occluder > 0:
            raise InputError("gl-raycast option occluder: an opaque plane does not stop a maximum-intensity "
                             "projection; use occluder=0 in mip mode")
        phong = scene.shading.model == "phong" and mode != "mip"
        variant = self._variant(scene)
        skip = variant == "rc-b" and mode != "mip"
        ctx, prep = self._begin_frame(scene)
        cache = self._cache
        scalars = cache.scalars(instance.volume, prep)
        textures = {"u_volume": scalars.texture,
                    "u_tf": cache.transfer_function(instance.transfer_function, prep)}
        if phong and not self._exact_iso(mode):  # the exact hit computes its own normal
            textures["u_gradient"] = cache.gradients(instance.volume, prep)
        block_count = (1, 1, 1)
        if skip:
            textures["u_blocks"], block_count = cache.blocks(instance.volume, self.block_size, prep)
            if mode == "dvr":
                textures["u_ct"] = cache.visibility_table(instance.transfer_function, self.min_opacity, prep)
        lens = scene.lenses[0] if scene.lenses else None
        if lens is not None and lens.appearance.mode != "clip":
            textures["u_lens_tf"] = cache.transfer_function(self._lens_table(lens, instance), prep)
        if lens is not None and self.lens_method == "per-sample-mask":
            textures["u_lens_mask"] = cache.lens_mask(instance, lens, prep)
        programs = self._programs(ctx, variant, mode, phong, lens)

        start = time.perf_counter()
        view = make_view(scene, self.step_factor)
        step = view.step
        width, height = scene.width, scene.height
        targets = self._frame_targets(width, height)
        textures.update(u_entry=targets["entry"], u_dir=targets["direction"], u_start=targets["start"],
                        u_res=targets["res"], u_lens_t=targets["lens_t"])
        nx, ny, nz = instance.volume.shape_xyz
        uniforms = {
            **view.uniforms, **UNITS,
            "u_mvp": view.mvp,
            "u_value_map": scalars.value_map,
            "u_tf_size": instance.transfer_function.size,
            "u_samples": self.samples_per_pass,
            "u_sliver": SLIVER * step,
            "u_threshold": self.opaque_threshold if mode != "mip" else 2.0,
            "u_iso": instance.isovalue if instance.isovalue is not None else 0.0,
            "u_refine": self.iso_refine,
            "u_block_scale": (nx / self.block_size, ny / self.block_size, nz / self.block_size),
            "u_block_count": block_count,
            "u_top_level": float(emptyspace.LEVELS - 1),
            "u_cut": occluder_cut(view.mvp, width, self.occluder),
        }
        if lens is not None:
            uniforms.update(lenses.uniforms(lens))
            uniforms["u_lens_refine"] = self.iso_refine
            if "u_lens_tf" in textures:
                uniforms["u_lens_tf_size"] = textures["u_lens_tf"].width
            for program in programs.values():
                planes = program.get("u_lens_planes", None)
                if planes is not None:
                    planes.write(lenses.planes(lens))
        for program in programs.values():
            set_uniforms(program, uniforms)
        for name, texture in textures.items():
            texture.use(location=UNITS[name])
        ctx.front_face = "cw" if view.mirrored else "ccw"

        timer = self._timer
        cells = int(np.ceil(max(self._longest_ray(scene) - SLIVER * step, 0.0) / step))
        lens_counts = {}
        if lens is not None:
            passes_main, passes_intermediate, counter = 1, 0, None
            output, lens_counts = self._lens_frame(ctx, timer, programs, targets, scene, view, lens)
        elif variant == "single-pass":
            passes_main, passes_intermediate = 1, 0
            counter = self._single_pass(ctx, timer, programs, targets)
        else:
            passes_main = -(-cells // self.samples_per_pass)
            passes_intermediate = max(passes_main - 1, 0) if variant != "rc" else 0
            counter = self._counter() if self._exact_iso(mode) else None
            self._multi_pass(ctx, timer, programs, targets, mode, passes_main, passes_intermediate)
            ctx.memory_barrier()
        if lens is None:
            output = targets["res"]
        if mode == "mip":
            ctx.enable_only(moderngl.NOTHING)
            targets["res"].use(location=UNITS["u_res"])
            targets["out_fbo"].use()
            timer.run("resolve", self._screen_vao(ctx, programs["resolve"]).render)
            output = targets["out"]
        seconds, fragments = timer.results()
        image, readback = self._readback(output, height, width)
        total = time.perf_counter() - start

        main_counts = fragments.get("main", [])
        # The direction pass draws every ray's back face once; so do the single pass and region₀'s.
        rays = (fragments.get("setup") or main_counts or fragments.get("region0") or [0])[0]
        if lens is not None:
            samples = lens_counts.pop("samples")
        elif counter is None:
            samples = sum(main_counts) * self.samples_per_pass  # every main-pass fragment takes M samples
        else:
            samples, solved = (int(v) for v in np.frombuffer(counter.read(8), dtype=np.uint32))
        self._last_step = step
        stages = ("setup", "main", "intermediate", "resolve")
        if lens is not None:
            stages = lenses.stages(self.lens_method)
        if self.occluder > 0:
            stages = ("occluder",) + stages
        timings = {stage: seconds.get(stage, 0.0) for stage in stages}
        timings.update(readback=readback, total=total, **prep.timings)
        counters = {
            "rays": int(rays),
            "fragments_main": int(sum(main_counts)),
            "fragments_intermediate": int(sum(fragments.get("intermediate", []))),
            "fragments_culled": int(passes_main * rays - sum(main_counts)) if variant in MULTI_PASS else 0,
            "passes_main": passes_main,
            "passes_intermediate": passes_intermediate,
            "samples": samples,
        }
        if self.occluder > 0:
            counters["rays_occluded"] = int(sum(fragments.get("occluder", [])))
        if mode == "iso":
            counters["crossings"] = int(np.count_nonzero(image[..., 3] > 0.5))  # a hit is opaque, a miss empty
            if counter is not None:
                counters["iso_cells_solved"] = solved
        if lens is not None:
            if self.lens_method not in lenses.INTERVAL_METHODS:
                del lens_counts["lens_rays"]  # a per-sample test never knows a ray's lens segment
            if self.lens_method != "segments-stencil":
                del lens_counts["hole_rays"]
            if self.lens_method not in lenses.WHOLE_SEGMENT_METHODS:
                for region in range(3):   # one loop over the ray: its samples are not told apart by region
                    del lens_counts[f"samples_region{region}"]
            counters.update(lens_counts)
            counters.update({f"fragments_{stage}": int(sum(fragments.get(stage, []))) for stage in stages
                             if stage.startswith("region")})
        info = {
            "variant": variant,
            "step": step,
            "step_factor": self.step_factor,
            "samples_per_pass": self.samples_per_pass,
            "longest_ray_steps": cells,
            "fragments_per_main_pass": [int(c) for c in main_counts],
            "timing": self._timer.method,
            "uploaded": list(prep.uploaded),
            "scalar_format": scalars.format,
            "empty_space_skipping": skip,
            "shading_applied": phong,
        }
        if mode == "iso":
            info["iso_hit"] = self.iso_hit
        if variant != self.variant:
            info["variant_chosen"] = (f"{variant}: the default variant {self.variant} renders no lens (its M samples "
                                      "per pass are not cut at one)")
        if lens is not None:
            info["lens"] = f"{lens.shape} {lens.appearance.mode}"
            info["lens_method"] = self.lens_method
            info["region_order"] = self.region_order
        return RenderResult(image=image, timings=timings, counters=counters, info=info)

    def _multi_pass(self, ctx, timer, programs, targets, mode, passes_main, passes_intermediate):
        """Setup passes, then main passes with an intermediate pass after each but the last."""
        import moderngl

        cube = {name: self._cube_vao(ctx, program) for name, program in programs.items() if name != "resolve"}

        def entry_pass():
            targets["entry_fbo"].clear(0.0, 0.0, 0.0, 0.0)
            targets["entry_fbo"].use()
            ctx.cull_face = "back"
            cube["entry"].render()

        def direction_pass():
            targets["direction_fbo"].clear(0.0, 0.0, 0.0, 0.0)
            targets["direction_fbo"].use()
            ctx.cull_face = "front"
            cube["direction"].render()

        def clear_targets():
            targets["main_fbo"].clear(0.0, 0.0, 0.0, 0.0)
            targets["depth_fbo"].clear(depth=0.0)

        ctx.enable_only(moderngl.CULL_FACE)
        timer.run("setup", entry_pass)
        timer.run("setup", direction_pass, count=True)  # its fragments are the rays
        timer.run("setup", clear_targets)
        if self.occluder > 0:
            self._occlude(ctx, timer, cube["occluder"], targets)
        ctx.cull_face = "front"  # main and intermediate passes rasterise the back faces
        main_state = moderngl.DEPTH_TEST | moderngl.BLEND | moderngl.CULL_FACE
        for index in range(passes_main):
            ctx.enable_only(main_state)
            ctx.depth_func = ">"
            if mode == "mip":
                ctx.blend_equation = moderngl.MAX
            else:
                ctx.blend_equation = moderngl.FUNC_ADD
                ctx.blend_func = (moderngl.ONE_MINUS_DST_ALPHA, moderngl.ONE,
                                  moderngl.ONE_MINUS_DST_ALPHA, moderngl.ONE)
            programs["main"]["u_first"].value = index * self.samples_per_pass
            targets["main_fbo"].use()
            timer.run("main", cube["main"].render, count=True)
            if index < passes_intermediate:
                ctx.enable_only(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
                ctx.depth_func = "1"
                programs["intermediate"]["u_next_first"].value = (index + 1) * self.samples_per_pass
                targets["depth_fbo"].use()
                timer.run("intermediate", cube["intermediate"].render, count=True)
        ctx.blend_equation = moderngl.FUNC_ADD

    def lens_images(self):
        """The last lens frame's per-pixel images, volbench row order, NaN where nothing was written.

        ``lens_entry``, ``lens_exit``: the world ray parameters where each pixel's ray enters and
        leaves the lens (the geometry pass: the paper's ``lens_front``/``lens_back`` before the box
        cuts them; ``lens_entry`` is −inf where the lens encloses the eye). ``segments-stencil``
        adds ``transition0`` and ``transition1`` (the paper's Fig. 3). For the report's figures and
        the tests; ``None`` before any lens frame with an image method.
        """
        if self._ctx is None or not self._targets or self.lens_method not in lenses.IMAGE_METHODS:
            return None
        targets = next(iter(self._targets.values()))
        width, height = targets["lens_t"].size
        raw = np.frombuffer(targets["lens_t"].read(), np.float32).reshape(height, width, 2)[::-1]
        entry = np.where(raw[..., 0] >= lenses.NO_HIT, -np.inf, raw[..., 0])
        missed = raw[..., 1] >= lenses.NO_HIT
        images = {"lens_entry": np.where(missed, np.nan, entry), "lens_exit": np.where(missed, np.nan, -raw[..., 1])}
        if "stencil" in targets:
            for name in ("transition0", "transition1"):
                image = np.frombuffer(getattr(targets["stencil"], name).read(), np.float32).reshape(height, width, 4)
                images[name] = np.where(image[::-1, :, 3] > 0, image[::-1, :, 0], np.nan)
        return images

    def _occlude(self, ctx, timer, vao, targets):
        """Draw the occluder into ``main_fbo``: grey, and depth 1 (a finished ray) where it covers a ray."""
        import moderngl

        def occluder_pass():
            targets["main_fbo"].depth_mask = True
            targets["main_fbo"].use()
            vao.render()
            targets["main_fbo"].depth_mask = False

        ctx.enable_only(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.depth_func = "1"
        ctx.cull_face = "front"  # the back faces: one fragment per ray, the camera inside the box too
        timer.run("occluder", occluder_pass, count=True)

    def _lens_frame(self, ctx, timer, programs, targets, scene, view, lens):
        """A lens frame (:mod:`renderers.gl.lens_passes`): ``(output texture, counters)``."""
        counter = self._buffer("lens_counters", np.zeros(len(lenses.COUNTERS), np.float32))  # uint zeros
        counter.bind_to_storage_buffer(0)
        targets["main_fbo"].clear(0.0, 0.0, 0.0, 0.0)
        targets["depth_fbo"].clear(depth=0.0)
        if self.occluder > 0:
            self._occlude(ctx, timer, self._cube_vao(ctx, programs["occluder"]), targets)
        # World → clip with near and far planes bracketing the lens too, for every pass that draws the lens.
        world_mvp = (lenses.geometry_projection(scene, view, lenses.geometry(lens)[:, :3])
                     if self.lens_method in lenses.IMAGE_METHODS else None)
        if "geometry" in programs:
            lens_passes.geometry_pass(self, ctx, timer, programs["geometry"], targets, world_mvp, lens)
        if self.lens_method == "segments-stencil":
            if "stencil" not in targets:  # made with the frame's targets, released with them
                targets["stencil"] = stencil.StencilTargets(ctx, (scene.width, scene.height))
            stencil.transition_passes(self, ctx, timer, programs, targets["stencil"], view, world_mvp, lens)
            targets["stencil"].transition0.use(location=UNITS["u_transition0"])
            targets["stencil"].transition1.use(location=UNITS["u_transition1"])
        output = lens_passes.volume_passes(self, ctx, timer, programs, targets, view, world_mvp, lens,
                                           self.lens_method, self.region_order == "front-to-back")
        ctx.memory_barrier()
        return output, lens_passes.counters(counter)

    def _counter(self):
        """The shaders' sample counter (storage buffer 0), set to 0."""
        counter = self._buffer("samples", np.zeros(2, np.float32))  # two uint 0: samples, cells solved
        counter.bind_to_storage_buffer(0)
        return counter

    def _single_pass(self, ctx, timer, programs, targets):
        """One loop-with-break draw of the back faces; returns the buffer counting its samples."""
        import moderngl

        counter = self._counter()
        targets["main_fbo"].clear(0.0, 0.0, 0.0, 0.0)
        ctx.enable_only(moderngl.CULL_FACE)
        ctx.cull_face = "front"
        targets["main_fbo"].use()
        timer.run("main", self._cube_vao(ctx, programs["main"]).render, count=True)
        ctx.memory_barrier()
        return counter

