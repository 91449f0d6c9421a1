"""iSBVR (Xue, Zhang & Crawfis 2005, note 001): view-aligned slicing whose fragments the depth test culls
before they are shaded, against depth written by a few cheap passes over cube-set surfaces.

The slices, their sampling, classification, shading and compositing are ``gl-slicer``'s
(:mod:`renderers.gl.slicer`), so with nothing culled the image is the slicer's to the bit. Before the
volume pass, depth-only passes (colour writes off) draw surfaces of the classified volume
(:mod:`renderers.gl.isosurfaces`) into a depth buffer; the volume pass then tests every slice fragment
against it with depth writes off, and the rasterizer's early depth test drops the culled ones before
their shader runs. Nothing is skipped explicitly: every slice is still drawn.

Depth-init modes (option ``zinit``, note 001 §2.4; the volume pass's test in brackets):

* ``none``: Basic SBVR, no depth test (the paper's "Basic").
* ``ert``: Φ_p's front faces with ``LESS`` [``LESS``]: pseudo early ray termination.
* ``front``: Φ_t's front faces with ``LESS`` [``GREATER``]: front-based space leaping (§3.2); rays
  that miss Φ_t keep depth 1 and lose every fragment.
* ``ess``: the box's front faces with ``LESS``, then Φ_t's back faces with ``GREATER`` [``LESS``]:
  exit-based space leaping and empty-ray removal (§3.3–3.4, Table 1's "ESS").
* ``ess+ert``: ``ess``, then Φ_p's front faces with ``LESS`` [``LESS``] (Table 1's "ESS+ERT").
* ``cull-all``: depth cleared to 0 [``LESS``]: every fragment is culled, which times the early depth
  test alone (T_z of the cost model, E2); not a rendering mode.
* ``slice-ert``: the generic two-pass early termination the paper's cost model starts from (§2, Eqs. 3–6;
  Krüger & Westermann's, with slices): every slice is drawn twice, front to back. First a simple pass
  over the slice (a copy of the accumulated image read back, the slice's fragments kept where its
  opacity is at least ``opaque_threshold``, depth written, colour off), then the volume pass over the
  slice, tested ``LESS`` against that depth: from the slice where a pixel turned opaque on, its
  fragments are culled. F_s = F; needs ``order`` ``front-to-back``; no surfaces.

Surfaces (option ``surfaces``): ``reduced``, the paper's cube sets (Φ_t's at ``phi_t_node``³ voxels, 8
in the paper, Φ_p's at ``phi_p_node``³, 2), lossless; ``coarse``, marching cubes on the same levels'
block maxima (Φ_t) and minima (Φ_p), the paper's "original" surfaces that cut holes (Fig. 4a, E7);
``full``, marching cubes on the full-resolution field (E8: over a million triangles at 256³).
The Φ_p surface is pushed ``depth_offset`` slices back along each ray so that the first sample inside
an opaque cube, which carries the final colour, is drawn (note 001 §2.7); 0 is the paper's placement.

Stages: ``slices`` (CPU polygons), ``init`` (the depth passes, T_a) and ``draw`` (the volume pass, T_m)
on the device (:mod:`renderers.gl.timing`), ``readback``, ``total``; preparation ``phi_t`` and
``phi_p`` (CPU: min–max level, classification, cube set, mesh: the paper's 10 ms and 210 ms), rebuilt
when the volume, the transfer function or a surface option changes, and ``upload``.

Counters: ``fragments`` (F'_c: fragments that passed the volume pass's depth test and were shaded;
with ``zinit`` ``none`` every generated fragment, F), ``init_fragments`` (fragments the init passes
wrote), ``cubes_t``/``cubes_p`` (the cube sets of Figs. 5 and 8), ``surface_triangles_t``/``_p``,
``slices``, ``triangles``. With ``count_fragments`` (after the frame, outside its timings, stage
``count_fragments``): ``fragments_generated`` (F, every slice fragment) and ``surface_fragments_t``/``_p``
(F_t and F_p of Eq. 7: the fragments the Φ_t and Φ_p passes generate).

llvmpipe (Mesa's CPU rasterizer) tests depth early per 4×2-pixel block when the shader writes no depth
and no memory; the volume shader writes neither, so its culling is real there too (issue 23).
"""

import time
from dataclasses import dataclass

import numpy as np

from core.errors import InputError
from renderers.base import Capabilities, Option, RenderResult, step_factor_option
from renderers.gl import context, glsl, isosurfaces
from renderers.gl.base import TIMING, set_uniforms
from renderers.gl.emptyspace import LEVELS, block_minmax
from renderers.gl.slicer import (SLICE_FRAGMENT, SLICE_SAMPLE, UNITS, VISIBLE_TRANSMITTANCE, GLSlicerRenderer,
                                 slice_polygons)
from renderers.gl.view import cube_triangles, make_view

ZINIT_MODES = ("none", "ert", "front", "ess", "ess+ert", "cull-all", "slice-ert")
SURFACES = ("reduced", "coarse", "full")
SHADERS = ("volume", "simple")

PUSHED_VERTEX = glsl.VERSION + """
uniform mat4 u_model;            // texture coordinate -> world
uniform mat4 u_view_projection;  // world -> clip space
uniform vec3 u_eye;
uniform vec3 u_forward;
uniform int u_perspective;
uniform float u_push;            // view depth added to every vertex, along its own eye ray
in vec3 in_tex;
void main() {
    vec3 p = (u_model * vec4(in_tex, 1.0)).xyz;
    if (u_perspective == 1) {
        float depth = dot(p - u_eye, u_forward);
        p = u_eye + (p - u_eye) * ((depth + u_push) / depth);
    } else {
        p += u_push * u_forward;
    }
    gl_Position = u_view_projection * vec4(p, 1.0);
}
"""

TIE_OFFSET = (0.0, 4.0)
"""Polygon offset ``(factor, units)`` that breaks depth ties between Φ_t's faces and the slices (``_init_passes``):
a few units of depth resolution (a slope factor would move faces seen at a grazing angle by up to a voxel, culling
less)."""

OPAQUE_FRAGMENT = glsl.VERSION + """
uniform sampler2D u_accumulated;  // the image composited so far (front to back), premultiplied
uniform float u_threshold;
out vec4 o_color;
void main() {
    if (texelFetch(u_accumulated, ivec2(gl_FragCoord.xy), 0).a < u_threshold) {
        discard;                  // not opaque yet: no depth, the volume pass shades this pixel
    }
    o_color = vec4(0.0);
}
"""
"""The first pass of ``slice-ert``: a slice's fragments where the pixel is already opaque write depth."""

SIMPLE_FRAGMENT = glsl.VERSION + """
out vec4 o_color;
void main() {
    o_color = vec4(0.0);
}
"""
"""The trivial shader of the init passes and of the ``simple`` volume pass (T_s of the cost model)."""


@dataclass(frozen=True)
class Surfaces:
    """One classification's depth-init geometry: ``(T, 3, 3)`` texture-space triangles (``None``: not drawn,
    the mode does not use it or the transfer function has no such surface) and counts."""

    phi_t: np.ndarray | None
    phi_p: np.ndarray | None
    cubes_t: int
    cubes_p: int
    iso_t: float | None
    iso_p: float | None


OPAQUE_UNIT = max(UNITS.values()) + 1
"""The texture unit of ``slice-ert``'s copy of the accumulated image."""


def slice_ranges(triangles, model, eye, forward, depths):
    """``[(first triangle, count)]`` of each slice, in drawing order: ``triangles`` (texture coordinates) hold the
    slices one after the other, each slice's triangles at its view depth (one of ``depths``)."""
    if not len(triangles):
        return []
    world = triangles[:, 0].astype(np.float64) @ model[:3, :3].T + model[:3, 3]
    index = np.rint(np.interp((world - eye) @ forward, depths, np.arange(depths.size))).astype(np.int64)
    starts = np.flatnonzero(np.diff(index, prepend=index[0] - 1))
    return list(zip(starts.tolist(), np.diff(np.append(starts, len(triangles))).tolist()))


SURFACE_RULES = {
    # surface: (its cube set, the region the set bounds, its iso-value, the coarse grid's column: min 0, max 1)
    "phi_t": (isosurfaces.phi_t_cubes, "visible", "iso_t", 1),
    "phi_p": (isosurfaces.phi_p_cubes, "opaque", "iso_p", 0),
}
"""Φ_t is built from the block maxima (it must hold every visible sample), Φ_p from the minima (only opaque ones)."""


def build_surface(surface, normalised, table_alpha, *, node_size, surfaces):
    """``(triangles, cubes, iso)`` of ``surface`` (``"phi_t"`` or ``"phi_p"``): the cube set's faces
    (``surfaces`` ``reduced``), or marching cubes on the coarse grid (``coarse``) or the full field (``full``)."""
    cube_set, region, iso_name, column = SURFACE_RULES[surface]
    classes = isosurfaces.node_classes(normalised, table_alpha, node_size)
    cubes = cube_set(classes)
    iso = getattr(isosurfaces.analyse(table_alpha), iso_name)
    if surfaces == "reduced" or iso is None:
        triangles = isosurfaces.boundary_faces(cubes, node_size, normalised.shape, region=getattr(classes, region))
    elif surfaces == "coarse":
        grid = block_minmax(normalised, node_size)[..., column] / (LEVELS - 1)
        triangles = isosurfaces.marching_cubes_surface(grid, iso, cell=node_size, shape=normalised.shape)
    else:
        triangles = isosurfaces.marching_cubes_surface(normalised, iso)
    return triangles, int(cubes.sum()), iso


def _node_size(value, *, name):
    try:
        return isosurfaces.check_node_size(value, name=name)
    except ValueError as exc:
        raise InputError(str(exc)) from None  # ``name`` is already "gl-isbvr option <name>"


def _slicer_option(name):
    return next(option for option in GLSlicerRenderer.option_table if option.name == name)


class GLIsbvrRenderer(GLSlicerRenderer):
    """iSBVR: view-aligned slicing with isosurface-aided early depth culling, OpenGL 4.3."""

    technique_stages = ("slices", "init", "draw")
    """The technique's stages: the slice polygons, the depth-init passes (T_a) and the volume pass (T_m)."""

    name = "gl-isbvr"
    description = "OpenGL iSBVR: view-aligned slicing with cube-set depth passes culling fragments by early-z"
    capabilities = Capabilities(
        projections=frozenset({"orthographic", "perspective"}),
        modes=frozenset({"dvr"}),
        shading=frozenset({"none", "phong"}),
        transforms=True,
        reasons={
            "modes": "the depth passes cull by opacity along a composited ray; MIP and iso-surfaces have neither "
                     "(gl-slicer renders MIP)",
            "max_volumes": "the surfaces and slices of one volume's box only",
            "gradient_opacity": "gradient-magnitude opacity modulation is not in the shaders",
            "meshes": "no polygon pass (the Kainz 2009 caster has one)",
            "lenses": "the culling surfaces Φ_t and Φ_p come from one classification of the whole volume; a lens "
                      "reclassifies its inside, so they would not bound it (gl-raycast renders lenses)",
            "camera_inside_volume": "the box's front faces, which exit-based leaping starts from, lie behind an eye "
                                    "inside the box",
        },
    )
    option_table = (
        step_factor_option(1.0, "Slice spacing in view depth as a fraction of the smallest world-space voxel edge "
                                "(the paper: one voxel)."),
        _slicer_option("order"),
        Option("zinit", str, "ess+ert", "Depth-init passes before the volume pass (module notes).", choices=ZINIT_MODES),
        Option("surfaces", str, "reduced", "The surfaces the init passes draw: the paper's cube sets, marching cubes "
               "on the coarse grids (its Fig. 4a failure case) or at full resolution.", choices=SURFACES,
               attribute="surface_kind"),
        Option("phi_t_node", int, 8, "Octree node size (voxels a side) of Φ_t's cube set (the paper: 8).",
               low=1, high=8, check=_node_size),
        Option("phi_p_node", int, 2, "Octree node size (voxels a side) of Φ_p's cube set (the paper: 2).",
               low=1, high=8, check=_node_size),
        Option("depth_offset", float, 1.0, "Slices by which Φ_p's surface is pushed back along each ray, so that the "
               "first opaque sample is drawn (0: the paper's placement).", low=0.0, high=16.0),
        Option("shader", str, "volume", "The volume pass's fragment shader: the slicer's (classify, correct, shade) "
               "or a trivial one (T_s of the cost model).", choices=SHADERS),
        Option("extra_taps", int, 0, "Further volume-texture fetches per fragment in the volume shader (weighted 0): "
               "the shader-complexity knob that sweeps γ.", low=0, high=64),
        Option("opaque_threshold", float, 0.99, "``slice-ert``: a pixel whose accumulated opacity reaches it is "
               "culled from the next slice on (its error is at most 1 − the threshold).", low=0.0, high=1.0,
               low_open=True),
        Option("count_fragments", bool, True, "After each frame (outside its timings), count every slice fragment "
               "(F) and the fragments of the Φ_t and Φ_p surfaces (F_t, F_p)."),
        TIMING,
    )
    quality_sweep = tuple({"step_factor": factor} for factor in (1.0, 0.5, 0.25))

    def __init__(self, **options):
        super().__init__(**options)
        if self.zinit == "slice-ert" and self.order != "front-to-back":
            raise InputError("gl-isbvr: zinit 'slice-ert' reads the opacity composited in front of each slice; "
                             "set order='front-to-back'")
        self._surfaces = None  # (key, Surfaces, buffers)

    caches_preprocessing = True

    def drop_caches(self):
        """Forget the surfaces (timed as ``phi_t``, ``phi_p`` when extracted again) and the textures
        (``gradients``, ``upload``, ...): the next frame builds all of a cold frame's preprocessing."""
        self._release_surfaces()
        if self._cache is not None and self._ctx is not None and context.activate(self._ctx):
            self._cache.release()

    def _release_surfaces(self):
        if self._surfaces is not None:
            for buffer in self._surfaces[2].values():
                buffer.release()
        self._surfaces = None

    def _forget(self):
        super()._forget()
        self._surfaces = None

    def _release(self):
        self._release_surfaces()
        super()._release()

    # ------------------------------------------------------------------------------------------ surfaces
    def _needs(self, analysis):
        """``(phi_t, phi_p)``: which surfaces this frame's ``zinit`` draws for a transfer function's
        :class:`~renderers.gl.isosurfaces.OpacityAnalysis`. A function without fully transparent values has no
        Φ_t and one that is never opaque no Φ_p: their passes are left out (the paper's "no surfaces, no
        overhead"), rather than drawing the box's own faces, which cull nothing."""
        return (self.zinit in ("front", "ess", "ess+ert") and analysis.has_empty,
                self.zinit in ("ert", "ess+ert") and analysis.has_opaque)

    def surfaces(self, instance, prep):
        """The :class:`Surfaces` of ``instance`` (volume and transfer function), built when either changes."""
        key = (instance.volume, instance.transfer_function, self.surface_kind, self.phi_t_node, self.phi_p_node)
        cached = self._surfaces
        if cached is not None and len(cached[0]) == len(key) and all(a is b or a == b for a, b in zip(cached[0], key)):
            return cached[1], cached[2]
        self._release_surfaces()
        normalised = instance.volume.normalized(np.float32)
        alpha = instance.transfer_function.table[:, 3]
        want_t, want_p = self._needs(isosurfaces.analyse(alpha))
        phi_t, cubes_t, iso_t = None, 0, None
        phi_p, cubes_p, iso_p = None, 0, None
        if want_t:
            with prep.cpu("phi_t"):
                phi_t, cubes_t, iso_t = build_surface("phi_t", normalised, alpha, node_size=self.phi_t_node,
                                                      surfaces=self.surface_kind)
        if want_p:
            with prep.cpu("phi_p"):
                phi_p, cubes_p, iso_p = build_surface("phi_p", normalised, alpha, node_size=self.phi_p_node,
                                                      surfaces=self.surface_kind)
        found = Surfaces(phi_t, phi_p, cubes_t, cubes_p, iso_t, iso_p)
        buffers = {}
        for name, triangles in (("phi_t", phi_t), ("phi_p", phi_p)):
            if triangles is not None and len(triangles):
                with prep.upload(name):
                    buffers[name] = self._ctx.buffer(np.ascontiguousarray(triangles, np.float32).tobytes())
        self._surfaces = (key, found, buffers)
        return found, buffers

    # --------------------------------------------------------------------------------------------- frame
    def _frame_targets(self, width, height):
        def build():
            res = self._float_texture((width, height))
            depth = self._ctx.depth_texture((width, height))
            target = {"res": res, "depth": depth, "res_fbo": self._ctx.framebuffer([res], depth),
                      "count_fbo": self._ctx.framebuffer([self._float_texture((width, height))], depth),
                      "accumulated": self._float_texture((width, height))}
            # Copied by a framebuffer blit: a copy into the texture itself went through 8 bits here (llvmpipe).
            target["accumulated_fbo"] = self._ctx.framebuffer([target["accumulated"]])
            return target

        return self._target(("isbvr", width, height), build)

    def _render(self, scene):
        import moderngl

        instance = scene.volumes[0]
        phong = scene.shading.model == "phong"
        ctx, prep = self._begin_frame(scene)
        scalars = self._cache.scalars(instance.volume, prep)
        textures = {"u_volume": scalars.texture,
                    "u_tf": self._cache.transfer_function(instance.transfer_function, prep)}
        if phong and self.shader == "volume":
            textures["u_gradient"] = self._cache.gradients(instance.volume, prep)
        surfaces, buffers = self.surfaces(instance, prep)
        if self.shader == "volume":
            defines = [f"EXTRA_TAPS {self.extra_taps}"] if self.extra_taps else []
            volume_program = context.program(ctx, glsl.CUBE_VERTEX, glsl.fragment_source(
                SLICE_SAMPLE, SLICE_FRAGMENT, phong=phong, mode="dvr", defines=defines))
        else:
            volume_program = context.program(ctx, glsl.CUBE_VERTEX, SIMPLE_FRAGMENT)
        init_program = context.program(ctx, PUSHED_VERTEX, SIMPLE_FRAGMENT)

        start = time.perf_counter()
        view = make_view(scene, self.step_factor)
        targets = self._frame_targets(scene.width, scene.height)
        eye = np.asarray(scene.camera.eye, dtype=np.float64)
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
                    "u_visible": VISIBLE_TRANSMITTANCE, "u_tap_offset": (0.5 / np.asarray(instance.volume.shape_xyz)),
                    "u_tap_weight": 0.0}
        set_uniforms(volume_program, uniforms)
        set_uniforms(init_program, {"u_model": view.model, "u_view_projection": view.mvp @ np.linalg.inv(view.model),
                                    "u_eye": eye, "u_forward": forward, "u_perspective": view.uniforms["u_perspective"],
                                    "u_push": 0.0})
        for name, texture in textures.items():
            texture.use(location=UNITS[name])
        vao = ctx.vertex_array(volume_program, [(buffer, "3f", "in_tex")])
        surface_vaos = {name: ctx.vertex_array(init_program, [(data, "3f", "in_tex")]) for name, data in buffers.items()}
        box_vao = ctx.vertex_array(init_program, [(self._buffer("box", cube_triangles()), "3f", "in_tex")])

        timer = self._timer
        fbo = targets["res_fbo"]
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=0.0 if self.zinit == "cull-all" else 1.0)
        fbo.use()
        ctx.front_face = "cw" if np.linalg.det(view.uniforms["u_tex_to_world"]) < 0 else "ccw"
        push = self.depth_offset * view.step
        init_passes = self._init_passes(surfaces, surface_vaos, box_vao, push)
        if init_passes:
            fbo.color_mask = (False, False, False, False)
            fbo.depth_mask = True
            ctx.enable_only(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
            for cull, func, offset, tie, draw in init_passes:
                ctx.cull_face, ctx.depth_func = cull, func
                ctx.polygon_offset = (tie * TIE_OFFSET[0], tie * TIE_OFFSET[1])
                init_program["u_push"].value = offset
                timer.run("init", draw, count=True)
            ctx.polygon_offset = (0.0, 0.0)
            fbo.color_mask = (True, True, True, True)
        # The volume pass: depth tested (not written) against the init passes' depth.
        fbo.depth_mask = False
        flags = moderngl.BLEND | (moderngl.DEPTH_TEST if self.zinit != "none" else 0)
        ctx.enable_only(flags)
        ctx.depth_func = ">" if self.zinit == "front" and surfaces.phi_t is not None else "<"
        if self.order == "back-to-front":
            ctx.blend_func = (moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA, moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA)
        else:
            ctx.blend_func = (moderngl.ONE_MINUS_DST_ALPHA, moderngl.ONE, moderngl.ONE_MINUS_DST_ALPHA, moderngl.ONE)
        if self.zinit == "slice-ert":
            self._slice_by_slice(ctx, targets, vao, slice_ranges(triangles, view.model, eye, forward, depths),
                                 uniforms)
        else:
            timer.run("draw", lambda: vao.render(vertices=3 * len(triangles)), count=True)
        fbo.depth_mask = True
        seconds, fragments = timer.results()
        image, readback = self._readback(targets["res"], scene.height, scene.width)
        total = time.perf_counter() - start

        self._last_step = view.step
        drawn = int(sum(fragments.get("draw", [0])))
        timings = {"slices": sliced - start, "init": seconds.get("init", 0.0), "draw": seconds.get("draw", 0.0),
                   "readback": readback, "total": total, **prep.timings}
        counters = {"slices": int(depths.size), "triangles": int(len(triangles)), "fragments": drawn,
                    "samples": drawn, "init_fragments": int(sum(fragments.get("init", [0]))),
                    "cubes_t": surfaces.cubes_t, "cubes_p": surfaces.cubes_p,
                    "surface_triangles_t": len(surfaces.phi_t if surfaces.phi_t is not None else ()),
                    "surface_triangles_p": len(surfaces.phi_p if surfaces.phi_p is not None else ())}
        info = {"step": view.step, "step_factor": self.step_factor, "order": self.order, "zinit": self.zinit,
                "timing": timer.method, "uploaded": list(prep.uploaded), "scalar_format": scalars.format,
                "shading_applied": phong and self.shader == "volume", "iso_t": surfaces.iso_t, "iso_p": surfaces.iso_p}
        if self.count_fragments:
            counted = time.perf_counter()
            simple = context.program(ctx, glsl.CUBE_VERTEX, SIMPLE_FRAGMENT)
            set_uniforms(simple, uniforms)
            counters.update(self._count(ctx, targets, simple, buffer, len(triangles), surface_vaos, init_program, push))
            timings["count_fragments"] = time.perf_counter() - counted
        vao.release()
        box_vao.release()
        for surface_vao in surface_vaos.values():
            surface_vao.release()
        return RenderResult(image=image, timings=timings, counters=counters, info=info)

    def _slice_by_slice(self, ctx, targets, vao, ranges, uniforms):
        """``slice-ert``'s two passes per slice, front to back (module notes): the first, with the copy of the
        image it reads, is timed as ``init``, the volume pass as ``draw``."""
        fbo, accumulated, timer = targets["res_fbo"], targets["accumulated"], self._timer
        opaque = context.program(ctx, glsl.CUBE_VERTEX, OPAQUE_FRAGMENT)
        set_uniforms(opaque, {"u_mvp": uniforms["u_mvp"], "u_accumulated": OPAQUE_UNIT,
                              "u_threshold": self.opaque_threshold})
        opaque_vao = ctx.vertex_array(opaque, [(self._buffers["slices"], "3f", "in_tex")])
        accumulated.use(location=OPAQUE_UNIT)

        # A framebuffer's masks take effect when it is bound (use()), and the copy binds others.
        def first_pass(first, count):
            ctx.copy_framebuffer(targets["accumulated_fbo"], fbo)
            fbo.color_mask, fbo.depth_mask = (False, False, False, False), True
            fbo.use()
            opaque_vao.render(vertices=3 * count, first=3 * first)

        def volume_pass(first, count):
            fbo.color_mask, fbo.depth_mask = (True, True, True, True), False
            fbo.use()
            vao.render(vertices=3 * count, first=3 * first)

        for first, count in ranges:
            timer.run("init", lambda: first_pass(first, count), count=True)
            timer.run("draw", lambda: volume_pass(first, count), count=True)
        opaque_vao.release()

    def _init_passes(self, surfaces, vaos, box_vao, push):
        """``[(cull_face, depth_func, push, tie, draw)]``: the depth-init sequence of ``zinit`` (note 001 §2.4),
        without the passes of a surface the transfer function does not have (:meth:`_needs`).

        ``tie`` is the sign of the polygon offset (:data:`TIE_OFFSET`) that moves Φ_t's faces to the side they
        do not cull: where visible material touches the box's faces, a slice can meet a face at the same depth
        up to rounding (perspective depth has few bits there), and the test would cull its visible sample.
        Moving a face that way only culls less, and it is not clipped as a moved vertex could be.
        """
        def draw(name):
            vao = vaos.get(name)
            return (lambda: vao.render()) if vao is not None else (lambda: None)

        box = ("back", "<", 0.0, 0, box_vao.render)
        exit_faces = ("front", ">", 0.0, 1, draw("phi_t"))       # back faces of Φ_t, the farthest wins
        opaque_front = ("back", "<", push, 0, draw("phi_p"))     # front faces of Φ_p, the nearest wins
        leaping = surfaces.phi_t is not None
        terminating = [opaque_front] if surfaces.phi_p is not None else []
        return {"none": [], "cull-all": [], "slice-ert": [], "ert": terminating,
                "front": [("back", "<", 0.0, -1, draw("phi_t"))] if leaping else [],
                "ess": [box, exit_faces] if leaping else [],
                "ess+ert": ([box, exit_faces] if leaping else []) + terminating}[self.zinit]

    def _count(self, ctx, targets, simple, buffer, slice_triangles, surface_vaos, program, push):
        """F (every slice fragment) and F_t, F_p (the surfaces' fragments), by occlusion queries without depth tests."""
        import moderngl

        fbo = targets["count_fbo"]
        fbo.use()
        fbo.color_mask = (False, False, False, False)
        fbo.depth_mask = False
        counts = {}
        query = ctx.query(samples=True)
        ctx.enable_only(moderngl.NOTHING)
        vao = ctx.vertex_array(simple, [(buffer, "3f", "in_tex")])
        with query:
            vao.render(vertices=3 * slice_triangles)
        vao.release()
        counts["fragments_generated"] = int(query.samples)
        ctx.enable_only(moderngl.CULL_FACE)
        for name, cull, offset in (("phi_t", "front", 0.0), ("phi_p", "back", push)):
            counts[f"surface_fragments_{name[-1]}"] = 0
            if name in surface_vaos:
                ctx.cull_face = cull
                program["u_push"].value = offset
                with query:
                    surface_vaos[name].render()
                counts[f"surface_fragments_{name[-1]}"] = int(query.samples)
        fbo.color_mask = (True, True, True, True)
        fbo.depth_mask = True
        return counts

    def init_depth(self, scene):
        """The depth buffer after the init passes of one frame of ``scene`` (row 0 at the top), in [0, 1]."""
        self.render(scene)
        targets = self._frame_targets(scene.width, scene.height)
        raw = np.frombuffer(targets["depth"].read(), dtype=np.float32).reshape(scene.height, scene.width)
        return np.ascontiguousarray(raw[::-1])
