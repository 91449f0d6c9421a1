"""View-aligned 3D-texture slicing (SBVR, note 000 §2.1): the ``gl-slicer`` backend, the
baseline the GPU ray caster of Krüger & Westermann 2003 is measured against.

Planes perpendicular to the viewing direction, ``Δ = step_factor ×`` the smallest world voxel
edge apart in view depth, are cut with the volume's box on the CPU (each slice a convex polygon
of 3–6 vertices, triangulated as a fan) and drawn in one call, back to front with the "over"
operator (the paper's order) or front to back with "under" (option ``order``; the images agree
to float rounding). Every fragment samples the 3-D texture at its point, classifies, corrects
opacity, shades (gradient texture, the shared GLSL of :mod:`renderers.gl.glsl`) and is blended.

Sampling, compared with the reference's constant step along each ray
--------------------------------------------------------------------
* **Orthographic**: along every ray the slices are ``Δ`` apart, as the reference's samples, but
  at fixed view depths instead of from each ray's own entry point. Each slice stands for the
  part of its ray within half a slice of it; the first slice a ray meets inside the box also
  takes the part back to the box entry, the last the part up to the exit, and opacity is
  corrected for that length. Path lengths therefore count exactly (a homogeneous box is exact),
  and the remaining difference is where the samples sit: a shift of at most ``Δ/2`` along each
  ray, and the end slices sample off the centre of their longer cells.
* **Perspective**: planar slices are ``Δ / cos θ`` apart along a ray at angle ``θ`` to the
  viewing axis — that is the method (Fig. 2 of the paper). Opacity is corrected per fragment for
  the actual distance ``Δ / cos θ``, so optical depth stays right, but rays towards the image
  corners are sampled more coarsely than the reference's constant ``Δ`` (at a 30° field of view,
  ``1/cos θ`` reaches 1.06 in the corners of a square image), which shows where the classified
  field varies quickly.
* **Camera inside the volume**: the slices start half a spacing beyond the near plane (instead
  of the box's nearest corner, which lies behind the eye); the nearest one takes each ray's part
  back to the eye.

Modes: ``dvr``, and ``mip`` (slices blended with ``GL_MAX``, classified by a resolve pass; only
the slice points are sampled). No early termination and no empty-space skipping: every
fragment of every slice is shaded, which is the cost the ray caster avoids.

Stages: ``slices`` (CPU polygon construction, wall clock), ``draw`` and ``resolve`` (device, see
:mod:`renderers.gl.timing`), ``readback`` and ``total`` (the frame's wall clock, preparation
excluded); preparation as in :mod:`renderers.gl.resources` (``upload``, ``gradients``).
Counters: ``slices``, ``triangles``, ``fragments`` (from ``GL_SAMPLES_PASSED``) and ``samples``
(one per fragment).

Contributing fragments (the paper's "0.2%–4%", note 000 E3): with ``count_contributing`` (``dvr``),
after the frame and outside ``total``, a counting pass walks every pixel's ray through the
slice planes front to back with the slices' own sampling and opacities and counts a fragment as
contributing when its opacity is above 0 and the transmittance in front of it is above
:data:`VISIBLE_TRANSMITTANCE`; counter ``fragments_contributing``, stage ``count_contributing``,
and ``info["fragments_walked"]`` (the fragments the walk met, ≈ ``fragments``).
"""

import math
import time

import numpy as np

from core.resources import check_memory
from renderers.base import Capabilities, Option, RenderResult, step_factor_option, world_step
from renderers.gl import context, glsl
from renderers.gl.base import TIMING, GLRenderer, set_uniforms
from renderers.gl.view import make_view

ORDERS = ("back-to-front", "front-to-back")

UNITS = {"u_volume": 0, "u_tf": 1, "u_gradient": 2, "u_res": 3}

VISIBLE_TRANSMITTANCE = 1.0 / 255.0
"""A fragment contributes if its opacity is above 0 and more than this much light reaches it
from the front (note 000, E3: what an 8-bit display can still show)."""

_CORNERS = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)])
_EDGES = np.array([(a, b) for a in range(8) for b in range(8) if a < b and bin(a ^ b).count("1") == 1])

SLICE_SAMPLE = """
uniform vec4 u_depth_plane;      // view depth of a texture point: dot(xyz, p) + w
uniform vec2 u_slice_range;      // view depths of the first and last slices drawn

// Ray parameter of slice k on a ray at cos_theta to the viewing axis. Every fragment computes
// its own and its neighbours' from the slice index, so neighbours agree to the bit.
float slice_t(float k, float cos_theta) {
    return (u_slice_range.x + k * u_step) / cos_theta;
}

// Opacity exponent of the slice at view depth w on a ray (world direction ray_dir, texture
// direction d, span in the box `span`): the length of ray the slice stands for — from midway to
// its neighbours, or to the box's face where the neighbour is outside — over the reference step.
float slice_ratio(float w, vec3 ray_dir, vec3 d, vec2 span) {
    float cos_theta = dot(ray_dir, -u_back);
    float k = round((w - u_slice_range.x) / u_step);
    float last = round((u_slice_range.y - u_slice_range.x) / u_step);
    float t = slice_t(k, cos_theta);
    if (t < span.x || t > span.y) {
        return 0.0;  // rasterised, but outside the box on this ray (a pixel on the box's edge)
    }
    float before = slice_t(k - 1.0, cos_theta);
    float after = slice_t(k + 1.0, cos_theta);
    float lo = (k == 0.0 || before < span.x) ? span.x : 0.5 * (before + t);
    float hi = (k == last || after > span.y) ? span.y : 0.5 * (t + after);
    return length(d * u_extent) * (hi - lo) / u_ref_step;
}
"""

SLICE_FRAGMENT = """
in vec3 v_tex;
out vec4 o_color;
#ifdef EXTRA_TAPS
uniform vec3 u_tap_offset;
uniform float u_tap_weight;
#endif

void main() {
#if defined(MODE_DVR)
    vec3 origin, ray_dir;
    pixel_ray(gl_FragCoord.xy, origin, ray_dir);
    vec3 d = mat3(u_world_to_tex) * ray_dir;
    vec2 span = slab((u_world_to_tex * vec4(origin, 1.0)).xyz, d);
    float w = dot(u_depth_plane.xyz, v_tex) + u_depth_plane.w;
    vec4 c = classify(scalar_at(v_tex));
    float alpha = correct_opacity(c.a, slice_ratio(w, ray_dir, d, span));
    vec3 rgb = c.rgb;
#ifdef PHONG
    if (alpha > 0.0) {
        rgb = shade(rgb, v_tex, ray_dir);
    }
#endif
#ifdef EXTRA_TAPS
    // A heavier shader (iSBVR's complexity knob): taps the compiler must keep, weighted 0 at run time.
    float taps = 0.0;
    for (int i = 1; i <= EXTRA_TAPS; i++) {
        taps += texture(u_volume, v_tex + float(i) * u_tap_offset).r;
    }
    rgb += u_tap_weight * taps;
#endif
    o_color = vec4(alpha * rgb, alpha);             // premultiplied
#else
    o_color = vec4(scalar_at(v_tex), 1.0, 0.0, 0.0);    // GL_MAX blending
#endif
}
"""

COUNT_FRAGMENT = """
layout(std430, binding = 0) buffer Counters {
    uint generated;
    uint contributing;
};
uniform float u_visible;         // transmittance a fragment needs in front of it to be seen

// Walks the pixel's ray through the slice planes front to back, as the slices' fragments
// composite, and counts the fragments that are generated and those that contribute.
void main() {
    vec3 origin, ray_dir;
    pixel_ray(gl_FragCoord.xy, origin, ray_dir);
    vec3 o = (u_world_to_tex * vec4(origin, 1.0)).xyz;
    vec3 d = mat3(u_world_to_tex) * ray_dir;
    vec2 span = slab(o, d);
    float cos_theta = dot(ray_dir, -u_back);
    int slices = int(round((u_slice_range.y - u_slice_range.x) / u_step)) + 1;
    uint made = 0u;
    uint seen = 0u;
    float transmittance = 1.0;
    for (int j = 0; j < slices; j++) {
        float w = u_slice_range.x + float(j) * u_step;
        float t = slice_t(float(j), cos_theta);
        if (t < span.x || t > span.y) {
            continue;
        }
        made++;
        float alpha = correct_opacity(classify(scalar_at(o + t * d)).a, slice_ratio(w, ray_dir, d, span));
        if (alpha > 0.0 && transmittance > u_visible) {
            seen++;
        }
        transmittance *= 1.0 - alpha;
    }
    atomicAdd(generated, made);
    atomicAdd(contributing, seen);
}
"""


SLICE_BYTES = 2560
"""Peak memory of :func:`slice_polygons` per slice: its float64 edge intersections, their angular
order and the fan's triangles (tracemalloc: 2414 bytes a slice)."""


def slice_polygons(model, eye, forward, near, step):
    """Triangles of the view-aligned slices of the volume's box, nearest slice first.

    Parameters
    ----------
    model : numpy.ndarray
        4×4 texture coordinate → world.
    eye, forward : numpy.ndarray
        Eye position and unit viewing direction (world).
    near : float
        Slices start beyond this view depth (the near plane) when the box reaches in front of it.
    step : float
        View-depth spacing of the slices.

    Returns
    -------
    triangles : numpy.ndarray
        ``(T, 3, 3)`` float32 texture coordinates, slice by slice from the nearest.
    depths : numpy.ndarray
        View depths of the slices, nearest first.
    """
    corners_world = _CORNERS @ model[:3, :3].T + model[:3, 3]
    depth = (corners_world - eye) @ forward
    # From the box's nearest corner, or from the near plane when the eye is inside the box.
    first = max(depth.min(), near)
    count = int(np.ceil((depth.max() - first) / step))
    depths = first + (np.arange(count) + 0.5) * step
    if depths.size == 0:
        return np.zeros((0, 3, 3), np.float32), depths
    wa, wb = depth[_EDGES[:, 0]], depth[_EDGES[:, 1]]
    span = wb - wa
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = (depths[:, None] - wa) / span
    valid = (span != 0) & (lam >= 0) & (lam <= 1)
    lam = np.where(valid, lam, 0.0)[..., None]
    points = _CORNERS[_EDGES[:, 0]] + lam * (_CORNERS[_EDGES[:, 1]] - _CORNERS[_EDGES[:, 0]])  # (S, 12, 3)
    # Order each polygon's points by angle around its centroid, in world space.
    world = points @ model[:3, :3].T
    counts = valid.sum(axis=1)
    centre = (world * valid[..., None]).sum(axis=1) / np.maximum(counts, 1)[:, None]
    helper = np.array([1.0, 0.0, 0.0]) if abs(forward[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    axis_u = np.cross(forward, helper)
    axis_u /= np.linalg.norm(axis_u)
    axis_v = np.cross(forward, axis_u)
    offset = world - centre[:, None]
    angle = np.where(valid, np.arctan2(offset @ axis_v, offset @ axis_u), np.inf)
    order = np.argsort(angle, axis=1)
    points = np.take_along_axis(points, order[..., None], axis=1)
    # Fan triangles (0, i, i + 1) for i + 1 < count.
    fan = np.arange(1, _EDGES.shape[0] - 1)
    keep = fan[None, :] + 1 < counts[:, None]
    triangles = np.stack([np.broadcast_to(points[:, :1], (len(depths), fan.size, 3)),
                          points[:, fan], points[:, fan + 1]], axis=2)
    return np.ascontiguousarray(triangles[keep], dtype=np.float32), depths


class GLSlicerRenderer(GLRenderer):
    """View-aligned 3D-texture slicing (SBVR), OpenGL 4.3."""

    technique_stages = ("slices", "draw", "resolve")
    """The stages that are the technique itself: slicing the proxy geometry, drawing the slices (timed on the device) and the resolve; not the fragment-count pass or the readback."""

    name = "gl-slicer"
    description = "OpenGL view-aligned 3D-texture slicing (SBVR): plane ∩ box polygons, per-fragment classification"
    capabilities = Capabilities(
        projections=frozenset({"orthographic", "perspective"}),
        modes=frozenset({"dvr", "mip"}),
        shading=frozenset({"none", "phong"}),
        transforms=True,
        camera_inside_volume=True,
        reasons={
            "modes": "slices composite classified samples; iso-surfaces by slicing come with the iSBVR backend",
            "max_volumes": "slices of one volume's box only (several volumes need interleaved slice sets)",
            "gradient_opacity": "gradient-magnitude opacity modulation is not in the shaders",
            "meshes": "no polygon pass (added with the Kainz 2009 issue)",
            "lenses": "a slice is composited whole, so a lens would be an inside test per fragment of every slice (the "
                      "per-sample method the paper argues against, measured in gl-raycast, which renders lenses)",
        },
    )
    option_table = (
        step_factor_option(0.5, "Slice spacing in view depth as a fraction of the smallest world-space voxel edge "
                                "(the default is the ray caster's step)."),
        Option("order", str, "back-to-front", "Drawing order and blend operator (\"over\" / \"under\").",
               choices=ORDERS),
        Option("count_contributing", bool, True, "After each frame (outside its timings), count the fragments that "
               "contribute (counter ``fragments_contributing``, see the module notes)."),
        TIMING,
    )
    quality_sweep = tuple({"step_factor": factor} for factor in (1.0, 0.5, 0.25))
    """Slice spacings from coarse to fine."""

    def check(self, scene):
        """Also refuse, before any work, more slices than this machine can build (:func:`slice_polygons`
        holds :data:`SLICE_BYTES` a slice; a fine step across a large or strongly anisotropic box makes many)."""
        super().check(scene)
        corners = scene.volumes[0].world_corners()
        diagonal = float(np.linalg.norm(corners.max(axis=0) - corners.min(axis=0)))
        slices = math.ceil(diagonal / world_step(scene, self.step_factor)) + 1
        check_memory(slices * SLICE_BYTES, what=f"gl-slicer: scene {scene.name!r} at step_factor {self.step_factor:g}",
                     detail=f"up to {slices} slices across the box's {diagonal:.3g} diagonal × {SLICE_BYTES} bytes",
                     fix="use a larger step_factor")

    def _frame_targets(self, width, height):
        def build():
            res, out = self._float_texture((width, height)), self._float_texture((width, height))
            return {"res": res, "out": out, "res_fbo": self._ctx.framebuffer([res]),
                    "out_fbo": self._ctx.framebuffer([out]), "count_fbo": self._ctx.empty_framebuffer((width, height))}

        return self._target((width, height), build)

    def _render(self, scene):
        import moderngl

        instance = scene.volumes[0]
        mode = scene.mode
        phong = scene.shading.model == "phong" and mode == "dvr"
        ctx, prep = self._begin_frame(scene)
        scalars = self._cache.scalars(instance.volume, prep)
        textures = {"u_volume": scalars.texture,
                    "u_tf": self._cache.transfer_function(instance.transfer_function, prep)}
        if phong:
            textures["u_gradient"] = self._cache.gradients(instance.volume, prep)
        program = context.program(ctx, glsl.CUBE_VERTEX,
                                  glsl.fragment_source(SLICE_SAMPLE, SLICE_FRAGMENT, phong=phong, mode=mode))

        start = time.perf_counter()
        view = make_view(scene, self.step_factor)
        targets = self._frame_targets(scene.width, scene.height)
        eye = np.asarray(scene.camera.eye)
        forward = -np.asarray(scene.camera.basis()[2])
        triangles, depths = slice_polygons(view.model, eye, forward, view.near, view.step)
        if self.order == "back-to-front":
            triangles = triangles[::-1]
        buffer = self._buffer("slices", triangles.reshape(-1, 3))
        sliced = time.perf_counter()

        depth_plane = (*(forward @ view.model[:3, :3]), float(forward @ (view.model[:3, 3] - eye)))
        uniforms = {**view.uniforms, **UNITS, "u_mvp": view.mvp, "u_value_map": scalars.value_map,
                    "u_tf_size": instance.transfer_function.size, "u_depth_plane": depth_plane,
                    "u_slice_range": (depths[0], depths[-1]) if depths.size else (0.0, -1.0),
                    "u_visible": VISIBLE_TRANSMITTANCE}
        set_uniforms(program, uniforms)
        for name, texture in textures.items():
            texture.use(location=UNITS[name])
        # A new vertex array each frame: the slice buffer is reallocated when it grows.
        vao = ctx.vertex_array(program, [(buffer, "3f", "in_tex")])

        timer = self._timer
        targets["res_fbo"].clear(0.0, 0.0, 0.0, 0.0)
        targets["res_fbo"].use()
        ctx.enable_only(moderngl.BLEND)
        if mode == "mip":
            ctx.blend_equation = moderngl.MAX
        elif self.order == "back-to-front":
            ctx.blend_func = (moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA, moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA)
        else:
            ctx.blend_func = (moderngl.ONE_MINUS_DST_ALPHA, moderngl.ONE, moderngl.ONE_MINUS_DST_ALPHA, moderngl.ONE)
        timer.run("draw", lambda: vao.render(vertices=3 * len(triangles)), count=True)
        ctx.blend_equation = moderngl.FUNC_ADD
        output = targets["res"]
        if mode == "mip":
            resolve = context.program(ctx, glsl.SCREEN_VERTEX, glsl.fragment_source(glsl.MIP_RESOLVE))
            set_uniforms(resolve, uniforms)
            targets["res"].use(location=UNITS["u_res"])
            targets["out_fbo"].use()
            ctx.enable_only(moderngl.NOTHING)
            timer.run("resolve", self._screen_vao(ctx, resolve).render)
            output = targets["out"]
        seconds, fragments = timer.results()
        vao.release()
        image, readback = self._readback(output, scene.height, scene.width)
        total = time.perf_counter() - start

        self._last_step = view.step
        drawn = int(sum(fragments.get("draw", [0])))
        timings = {"slices": sliced - start, "draw": seconds.get("draw", 0.0), "resolve": seconds.get("resolve", 0.0),
                   "readback": readback, "total": total, **prep.timings}
        counters = {"slices": int(depths.size), "triangles": int(len(triangles)), "fragments": drawn,
                    "samples": drawn}
        info = {"step": view.step, "step_factor": self.step_factor, "order": self.order,
                "timing": timer.method, "uploaded": list(prep.uploaded), "scalar_format": scalars.format,
                "shading_applied": phong}
        if self.count_contributing and mode == "dvr":
            counted = time.perf_counter()
            generated, contributing = self._count_fragments(ctx, targets, uniforms)
            timings["count_contributing"] = time.perf_counter() - counted
            counters["fragments_contributing"] = contributing
            info["fragments_walked"] = generated
        return RenderResult(image=image, timings=timings, counters=counters, info=info)

    def _count_fragments(self, ctx, targets, uniforms):
        """``(generated, contributing)`` fragments of the frame, by walking each pixel's ray (module notes)."""
        import moderngl

        program = context.program(ctx, glsl.CUBE_VERTEX, glsl.fragment_source(SLICE_SAMPLE, COUNT_FRAGMENT))
        set_uniforms(program, uniforms)
        counters = self._buffer("contributing", np.zeros(2, np.float32))  # two uint 0
        counters.bind_to_storage_buffer(0)
        targets["count_fbo"].use()
        ctx.enable_only(moderngl.CULL_FACE)
        ctx.front_face = "cw" if np.linalg.det(uniforms["u_tex_to_world"]) < 0 else "ccw"
        ctx.cull_face = "front"  # the back faces cover every pixel whose ray meets the box
        self._cube_vao(ctx, program).render()
        ctx.memory_barrier()
        generated, contributing = np.frombuffer(counters.read(8), dtype=np.uint32)
        return int(generated), int(contributing)
