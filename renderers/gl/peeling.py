"""Depth-peeling multi-volume ray casting with translucent meshes: the ``gl-peel`` backend (OpenGL 4.3, moderngl).

The shader-based multi-volume casters that Kainz et al. 2009 compare with (Roessler et al.
2008, Brecheisen et al. 2008; note 002 §1, §3.1–3.2, §4 item 8) split every ray into intervals
with a fixed set of active objects by **depth peeling**: the boundary geometry is rasterised
again for every depth layer, so a scene of depth complexity ``N`` costs ``N`` geometry passes
over all its fragments (``O(N²)`` fragments in all), and each interval between consecutive
layers is ray-cast with the objects active there. This backend is that baseline, built on the
GL infrastructure of :mod:`renderers.gl` (context, texture caches, pass timer). Its option
``peeling="dual"`` is the other baseline of Table 2, NVIDIA's **dual depth peeling** (Bavoil &
Myers 2008) for translucent geometry alone.

Front-to-back peeling (``peeling="front"``, the default), per frame:

1. **setup** (one full-screen pass): per pixel, the parity mask of the boxes that hold the ray's
   near-plane point (their entry faces are clipped, so never peeled; this is what lets the eye
   sit inside a box), the cell origin ``t_first`` (the ray's entry into the union of the boxes,
   as the reference's) and empty accumulators.
2. Per layer ``i``:

   * **peel**: all volume boxes and the triangles of every mesh with a surface material drawn
     in one call (world-space vertices, no culling); a fragment's layer value is the exact ray
     parameter of its crossing (a box face's from the slab test of its box, the entry or exit
     nearer the rasterised point; a triangle's from its plane). Fragments at or in front of the
     previous layer are discarded; box fragments exactly *at* it first toggle their box's bit
     in the per-pixel parity mask (``atomicXor`` on a per-pixel storage buffer, so coincident
     faces and grazing enter/exit pairs count right). The nearest remaining value is kept by
     ``GL_MIN`` blending into an ``R32F`` target (float, exact; no depth-buffer quantisation),
     which then becomes the previous layer for the next peel (a ping-pong of two float
     textures). A ``GL_SAMPLES_PASSED`` query counts the fragments behind the previous layer;
     none left, or ``max_layers`` reached, ends the loop.
   * **surface** (scenes with meshes): the meshes drawn again; the fragments exactly at the new
     layer add their shaded premultiplied colour (the material's colour and alpha, two-sided
     Blinn–Phong with the face normal and the material's terms under ``phong`` shading) and a
     count into two float targets.
   * **raycast** (full screen): the segment [previous layer, this layer) is sampled with every
     volume whose bit is set, at the reference's common world step on the reference's cells
     (origin ``t_first``, cell-midpoint samples, cells cut by a box sampled at the middle of
     their overlap with the opacity corrected for its length). Samples of several volumes in
     one cell are summed and clamped (the Kainz blend of :func:`renderers.reference.raycast._dvr_ray`)
     before front-to-back compositing. A cell is sampled once it is closed, with every volume
     met in it (a per-pixel mask of the open piece), so cells cut by box faces blend exactly as
     the reference's. A surface at the layer cuts the open cell there, as the reference's
     walk does: the piece in front of it is composited, then the surface, and the cell goes on
     as a new piece behind it.

3. **resolve**: the cell still open behind the last layer is composited.

Early ray termination (``opaque_threshold``): a ray whose opacity passes it takes no further
samples and its fragments are dropped from later peels (so layers stop once every ray ends).

Dual depth peeling (``peeling="dual"``), per frame, meshes only:

1. **init**: every triangle writes ``(−t, t)`` with ``GL_MAX`` blending into an ``RG32F``
   target: each pixel's nearest and farthest crossing.
2. Per pass, **peel**: every triangle again, into four targets, all ``GL_MAX``-blended (the
   demo's single blend state): fragments strictly between the pixel's nearest and farthest
   write ``(−t, t)`` (the next pass's pair); the fragment at the nearest writes its colour to a
   front layer, the one at the farthest to a back layer, each with a flag; those outside are
   discarded (peeled before). **blend** (full screen): the front layer goes *under* the front
   colour (front to back), the back layer *over* the back colour (back to front); its
   samples-passed query counts the pixels that peeled a farthest layer, and none ends the loop
   (a pass that peeled only nearest layers had one layer left per pixel).
3. **final**: the front colour over the back colour.

Two layers per geometry pass: about half the passes of front-to-back peeling. Coincident crossings
(equal ``t``) are one layer for both methods: front peeling sums their colours (the Kainz blend),
dual peeling keeps the per-channel maximum (the demo's behaviour); the reference composites them
one after the other. Dual peeling has no early termination (the back half is composited back to
front).

Limits and choices
------------------
* ``max_volumes = 32``: the parity mask is one 32-bit word per pixel, and each volume is its own
  3-D texture bound to a fragment texture unit (``GL_MAX_TEXTURE_IMAGE_UNITS``: 32 on llvmpipe and
  current NVIDIA drivers, 16 guaranteed by GL 4.3); Blinn–Phong needs a gradient texture per
  volume too, so shaded scenes take two units per volume. A scene that needs more units than the
  context has is refused by :meth:`GLPeelRenderer.check` (:class:`core.errors.UnsupportedFeatureError`,
  so the pipeline records a skip with the reason).
* Transfer functions (any sizes) and the meshes' materials are shader storage buffers, so they
  take no texture unit.
* Only what a layer's fragment tells is known per pixel: which boxes the ray is in and which
  surfaces it crosses there. CSG (each leaf's inside at every layer and the trees re-evaluated),
  homogeneous media (a mesh's inside along whole intervals) and polygonal volume boundaries (a
  volume's inside bounded by a mesh, not its box) are refused with that reason: the paper's
  point about the shader casters.
* Meshes are drawn as world-space triangles, uploaded once per set of instances (cached);
  the near plane clips a mesh crossing closer to the eye than it (the eye should be outside
  every mesh).
* Float32 throughout: overlaps shorter than ``SLIVER`` steps are not sampled (the reference's
  threshold is 1e-9 steps in double precision), as in ``gl-raycast``.

Timing and counters
-------------------
Stages (:mod:`renderers.gl.timing`): front peeling ``setup``, ``peel``, ``surface`` and ``raycast``
(summed over their passes; ``raycast`` includes the resolve pass); dual peeling ``init``, ``peel``,
``blend`` and ``final``; both ``readback``, ``total`` (frame wall clock, preparation excluded)
and, when something is built, ``upload`` and ``gradients``.
Counters: ``layers`` (the layers peeled: the largest depth complexity among the rays not yet
terminated), ``peel_passes`` (geometry passes that peel; front: one per layer and a last one
that finds none; dual: one per two layers, and the ``init`` pass besides), ``fragments``
(all fragments of the geometry, counted by the first geometry pass). Front peeling adds
``fragments_peeled`` (fragments behind the previous layer, summed over the peels: every peel
rasterises everything, so this grows as ``O(N²)`` with depth complexity ``N``), ``surface_passes``
and ``raycast_passes`` (the resolve pass included). Each pass's query is read before the next
pass is issued (one CPU–GPU round trip per layer, as in the occlusion-query loops of the peeling
casters). ``info["fragments_per_peel"]`` lists each front peel's count and
``info["fragments_per_layer"]`` the fragments of each layer (differences of consecutive peels).
"""

import time

import numpy as np

from core.errors import InputError, UnsupportedFeatureError
from renderers.base import Capabilities, Option, RenderResult, step_factor_option, world_step
from renderers.gl import context, glsl, peeling_glsl
from renderers.gl.base import TIMING, GLRenderer, set_uniforms
from renderers.gl.resources import Preparation
from renderers.gl.timing import PassTimer
from renderers.gl.view import NEAR_FRACTION, SLIVER, cube_triangles

MAX_VOLUMES = 32
"""Volumes per scene: the bits of the per-pixel parity mask (and the texture units of common drivers)."""

FAR_LAYER = 3.0e38
"""Value of the layer target where no fragment is left (cleared before every peel)."""

PEELING_METHODS = ("front", "dual")

IMAGE_UNITS = {"u_prev": 0, "u_layer": 1, "u_acc": 2, "u_aux": 3, "u_surf": 4, "u_cuts": 5}
DUAL_IMAGE_UNITS = {"u_depths": 0, "u_front_layer": 1, "u_back_layer": 2, "u_flags": 3, "u_front_acc": 4, "u_back_acc": 5}

VERTEX_FORMAT = ("3f 4f 1i", "in_world", "in_plane", "in_object")
"""Geometry vertices: world position, the triangle's plane (unit normal, offset), object index."""


def _draw_blended(ctx, drawn, vertices, equation, query):
    """Draw the peel geometry with blending by ``equation`` (MIN: nearest layer; MAX: dual peeling's
    min/max depths) under ``query``, then restore additive blending and make the image writes visible."""
    import moderngl

    ctx.enable_only(moderngl.BLEND)
    ctx.blend_equation = equation
    with query:
        drawn.render(vertices=vertices)
    ctx.enable_only(moderngl.NOTHING)
    ctx.blend_equation = moderngl.FUNC_ADD
    ctx.memory_barrier()


def _vertices(points, planes, objects):
    """Interleave ``(n, 3)`` points, ``(n, 4)`` planes and ``(n,)`` object indices as :data:`VERTEX_FORMAT`."""
    data = np.empty((len(points), 8), dtype=np.float32)
    data[:, :3] = points
    data[:, 3:7] = planes
    data[:, 7] = np.asarray(objects, dtype=np.int32).view(np.float32)
    return data


def geometry(scene):
    """World-space triangles of ``scene``'s boxes, then of its meshes with a surface, and their materials.

    Returns
    -------
    vertices : numpy.ndarray
        ``(n, 8)`` float32 in :data:`VERTEX_FORMAT`: 36 per volume box (object ``v``), 3 per mesh
        triangle (objects ``len(volumes) + j`` for the ``j``-th mesh with a surface), each
        triangle's unit plane on all three of its vertices (zero for boxes, which use their slab).
    materials : numpy.ndarray
        ``(2·meshes, 4)`` float32: per mesh, colour and alpha, then ambient, diffuse, specular,
        shininess.
    """
    parts = []
    cube = cube_triangles().astype(np.float64)
    for v, instance in enumerate(scene.volumes):
        model = instance.transform @ np.diag([*instance.volume.extent, 1.0])
        parts.append(_vertices(cube @ model[:3, :3].T + model[:3, 3], np.zeros((36, 4)), np.full(36, v)))
    surfaced = [m for m in scene.meshes if m.surface is not None]
    materials = []
    for j, instance in enumerate(surfaced):
        corners = instance.world_vertices()[instance.mesh.faces]             # (F, 3, 3)
        normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        lengths = np.linalg.norm(normals, axis=1)
        keep = lengths > 0  # a triangle of no area in world space has no fragments
        corners, normals = corners[keep], normals[keep] / lengths[keep, None]
        planes = np.c_[normals, np.einsum("ij,ij->i", normals, corners[:, 0])]
        parts.append(_vertices(corners.reshape(-1, 3), np.repeat(planes, 3, axis=0),
                               np.full(3 * len(corners), len(scene.volumes) + j)))
        surface = instance.surface
        materials += [[*surface.colour, surface.alpha],
                      [surface.ambient, surface.diffuse, surface.specular, surface.shininess]]
    vertices = np.concatenate(parts) if parts else np.zeros((0, 8), np.float32)
    return vertices, np.asarray(materials, dtype=np.float32).reshape(-1, 4)


class GLPeelRenderer(GLRenderer):
    """Depth-peeling multi-pass ray caster for overlapping volumes and translucent meshes (see the module notes)."""

    technique_stages = ("init", "peel", "raycast", "surface", "blend", "final")
    """The stages that are the technique itself: the GPU passes, timed on the device; not the readback."""

    name = "gl-peel"
    cached_volumes = MAX_VOLUMES
    description = ("depth-peeling multi-volume ray caster with translucent meshes (OpenGL; the shader baseline "
                   "of Kainz et al. 2009): one peel of all boxes and surfaces per depth layer, each interval "
                   "ray-cast with its active volumes; peeling='dual': dual depth peeling of meshes")
    capabilities = Capabilities(
        projections=frozenset({"orthographic", "perspective"}),
        shading=frozenset({"none", "phong"}),
        max_volumes=MAX_VOLUMES,
        transforms=True,
        meshes=True,
        translucent_geometry=True,
        camera_inside_volume=True,
        reasons={
            "modes": "depth-peeled intervals composite emission–absorption (dvr) only; mip and iso are served by "
                     "gl-raycast",
            "max_volumes": "the per-pixel parity mask is one 32-bit word and every volume takes a texture unit "
                           "(32 on common drivers, 16 guaranteed by OpenGL 4.3; two per volume with phong)",
            "gradient_opacity": "gradient-magnitude opacity modulation is not in the shaders",
            "csg": "a peeled layer tells a pixel only which boxes it is in and which surfaces it crosses; CSG "
                   "needs every leaf's inside at every layer and the trees re-evaluated per pixel, which the "
                   "shader casters cannot do (the paper's point)",
            "homogeneous_media": "a medium fills a mesh's inside over whole intervals; the peeled layers track "
                                 "the boxes' parity only, not the meshes'",
            "lenses": "the peeling caster cuts rays at mesh layers; a lens is one more convex boundary per ray, which "
                      "gl-raycast renders (segments, fused, per-sample)",
        },
    )
    BOUNDARY_REASON = ("a polygonal boundary bounds a volume by a mesh's inside; the peeled layers track the boxes' "
                       "parity only")
    option_table = (
        step_factor_option(0.5),
        Option("opaque_threshold", float, 0.99, "Early ray termination: a ray stops once its opacity exceeds this "
               "(1: never). Front peeling only.", low=0, high=1, low_open=True),
        Option("max_layers", int, 256, "Peel at most this many depth layers; whatever lies behind the last one is "
               "not rendered.", low=1),
        Option("peeling", str, "front", "Front-to-back depth peeling of boxes and surfaces, or dual depth peeling "
               "(two layers per pass) of scenes of meshes only.", choices=PEELING_METHODS),
        TIMING,
    )
    quality_sweep = tuple({"step_factor": factor} for factor in (1.0, 0.5, 0.25)) + ({"opaque_threshold": 1.0},)
    """Step sizes from coarse to fine, then early termination off."""

    def __init__(self, **options):
        super().__init__(**options)
        self._queries = []
        self._geometry_key = None
        self._geometry_vertices = 0

    def _forget(self):
        super()._forget()
        self._queries = []
        self._geometry_key = None

    # -----------------------------------------------------------------------------------------

    def check(self, scene):
        """Also refuse what the layers cannot hold (volume boundaries; volumes under dual peeling) and more
        volumes than this context's texture units hold (a device limit, so the pipeline records the pair
        as skipped, like a missing capability)."""
        super().check(scene)
        bounded = [instance.name for instance in scene.volumes if instance.boundary is not None]
        if bounded:
            raise UnsupportedFeatureError(self.name, f"polygonal boundary of volume {bounded[0]!r}",
                                          self.BOUNDARY_REASON)
        if self.peeling == "dual" and scene.volumes:
            raise UnsupportedFeatureError(
                self.name, f"{len(scene.volumes)} volumes with peeling='dual'",
                "dual depth peeling composites translucent surfaces only (its back half is blended back to front, "
                "so no interval between layers is ray-cast); use peeling='front' for volumes")
        ctx = self._context()
        units = int(ctx.info["GL_MAX_TEXTURE_IMAGE_UNITS"])
        per_volume = 2 if scene.shading.model == "phong" else 1
        if len(scene.volumes) * per_volume > units:
            shaded = " with phong shading (a gradient texture each)" if per_volume == 2 else ""
            raise UnsupportedFeatureError(
                self.name, f"{len(scene.volumes)} volumes",
                f"{ctx.info['GL_RENDERER']} has {units} texture units, so at most {units // per_volume} "
                f"volumes{shaded}")

    def _begin_frame(self, scene):
        """Context, every volume's size against the 3-D texture limit, pass timer, an empty :class:`Preparation`."""
        ctx = self._context()
        limit = context.max_3d_texture_size(ctx)
        for instance in scene.volumes:
            if max(instance.volume.shape_xyz) > limit:
                raise InputError(
                    f"volume {instance.name!r}: dimensions {instance.volume.shape_xyz} exceed GL_MAX_3D_TEXTURE_SIZE "
                    f"{limit} of {ctx.info['GL_RENDERER']}; resample the volume to at most {limit} voxels per axis")
        if self._timer is None:
            self._timer = PassTimer(ctx, self.timing_method)
        self._timer.start_frame()
        return ctx, Preparation(ctx)

    def _programs(self, ctx, count, phong, meshes):
        """The programs of this peeling method for ``count`` volumes (compiled once per process)."""
        defines = [f"N_VOLUMES {count}", f"VOLUME_SLOTS {max(count, 1)}"] + (["SHADED"] if phong else [])
        defines += ["MESHES"] if meshes else []
        vertex = glsl.VERSION + peeling_glsl.GEOMETRY_VERTEX

        def screen(*parts):
            return context.program(ctx, glsl.SCREEN_VERTEX, glsl.fragment_source(*parts, defines=defines))

        def drawn(main):
            return context.program(ctx, vertex, glsl.fragment_source(peeling_glsl.VOLUMES, peeling_glsl.SURFACES, main,
                                                                      defines=defines))

        if self.peeling == "dual":
            return {"peel": drawn(peeling_glsl.DUAL_FRAGMENT), "blend": screen(peeling_glsl.DUAL_BLEND_FRAGMENT),
                    "final": screen(peeling_glsl.DUAL_FINAL_FRAGMENT)}
        sampled = (peeling_glsl.VOLUMES, peeling_glsl.SAMPLING)
        return {
            "setup": screen(peeling_glsl.VOLUMES, peeling_glsl.SETUP_FRAGMENT),
            "peel": drawn(peeling_glsl.PEEL_FRAGMENT),
            "raycast": screen(*sampled, peeling_glsl.RAYCAST_FRAGMENT),
            "resolve": screen(*sampled, peeling_glsl.RESOLVE_FRAGMENT),
        }

    def _screen_fbo(self, texture):
        """A framebuffer that only sets the viewport: full-screen passes write images."""
        fbo = self._ctx.framebuffer([texture])
        fbo.color_mask = (False, False, False, False)
        return fbo

    def _frame_targets(self, width, height):
        def build():
            size = (width, height)
            targets = {f"layer{i}": self._float_texture(size, 1) for i in range(2)}
            targets.update({f"layer_fbo{i}": self._ctx.framebuffer([targets[f"layer{i}"]]) for i in range(2)})
            targets.update({"masks": self._ctx.buffer(reserve=8 * width * height), "acc": self._float_texture(size),
                            "aux": self._float_texture(size), "surf": self._float_texture(size),
                            "cuts": self._float_texture(size, 1)})
            targets["surface_fbo"] = self._ctx.framebuffer([targets["surf"], targets["cuts"]])
            targets["screen_fbo"] = self._screen_fbo(targets["acc"])
            return targets

        return self._target(("front", width, height), build)

    def _dual_targets(self, width, height):
        def build():
            size = (width, height)
            targets = {f"depths{i}": self._float_texture(size, 2) for i in range(2)}
            targets.update({name: self._float_texture(size) for name in ("front_layer", "back_layer", "front_acc", "back_acc")})
            targets["flags"] = self._float_texture(size, 2)
            targets["init_fbo"] = self._ctx.framebuffer([targets["depths0"]])
            targets["colours_fbo"] = self._ctx.framebuffer([targets["front_acc"], targets["back_acc"]])
            for i in range(2):
                targets[f"peel_fbo{i}"] = self._ctx.framebuffer(
                    [targets[f"depths{i}"], targets["front_layer"], targets["back_layer"], targets["flags"]])
            targets["screen_fbo"] = self._screen_fbo(targets["front_acc"])
            return targets

        return self._target(("dual", width, height), build)

    def _query(self, index):
        """The ``index``-th samples-passed query of the frame (one per pass: llvmpipe flushes on reuse)."""
        while len(self._queries) <= index:
            self._queries.append(self._ctx.query(samples=True))
        return self._queries[index]

    @staticmethod
    def _clip_planes(scene):
        """Near and far plane distances bracketing the scene (the near one as in :mod:`renderers.gl.view`)."""
        lo, hi = scene.bounds()
        corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        depths = -(corners @ scene.camera.view_matrix().T)[:, 2]
        _, radius = scene.bounding_sphere()
        margin = max(1e-3 * radius, 1e-6)
        far = max(float(depths.max()) + margin, 2 * margin)
        near = NEAR_FRACTION * radius if scene.camera.projection == "perspective" else min(margin, far / 2)
        return near, far

    @staticmethod
    def _ray_uniforms(scene):
        """The pixel rays' uniforms of :data:`renderers.gl.glsl.COMMON` and the light (as :func:`renderers.gl.view.make_view`)."""
        camera = scene.camera
        aspect = np.array([scene.width / scene.height, 1.0])
        if camera.projection == "perspective":
            half_size = np.tan(np.radians(camera.fov_y) / 2) * aspect
        else:
            half_size = camera.view_height / 2 * aspect
        right, up, back = camera.basis()
        lx, ly, lz = scene.shading.light_direction
        shading = scene.shading
        return {"u_eye": camera.eye, "u_right": right, "u_up": up, "u_back": back, "u_half_size": half_size,
                "u_perspective": int(camera.projection == "perspective"), "u_viewport": (scene.width, scene.height),
                "u_light": lx * right + ly * up + lz * back,
                "u_phong": (shading.ambient, shading.diffuse, shading.specular, shading.shininess)}

    def _uniforms(self, scene, scalars, offsets, step):
        """Every uniform of the programs: the pixel rays, the volumes' arrays, the options."""
        near, far = self._clip_planes(scene)
        camera = scene.camera
        viewproj = camera.projection_matrix(scene.width / scene.height, near, far) @ camera.view_matrix()
        uniforms = self._ray_uniforms(scene)
        uniforms.update(u_viewproj=viewproj, u_step=step, u_sliver=SLIVER * step, u_t_near=near,
                        u_threshold=self.opaque_threshold if self.opaque_threshold < 1 else 2.0)
        if not scene.volumes:
            return uniforms, {}
        models = [instance.transform @ np.diag([*instance.volume.extent, 1.0]) for instance in scene.volumes]
        normals = [np.linalg.inv(instance.transform[:3, :3]).T for instance in scene.volumes]
        arrays = {
            "u_w2t": np.stack([np.linalg.inv(m).T for m in models]).astype(np.float32),
            "u_normals": np.stack([m.T for m in normals]).astype(np.float32),
            "u_value_maps": np.array([s.value_map for s in scalars], dtype=np.float32),
            "u_extents": np.array([i.volume.extent for i in scene.volumes], dtype=np.float32),
            "u_ref_steps": np.array([i.reference_step for i in scene.volumes], dtype=np.float32),
            "u_tf_offsets": np.array(offsets, dtype=np.int32),
            "u_tf_sizes": np.array([i.transfer_function.size for i in scene.volumes], dtype=np.int32),
            "u_volumes": np.arange(len(scene.volumes), dtype=np.int32),
            "u_gradients": np.arange(len(scene.volumes), 2 * len(scene.volumes), dtype=np.int32),
        }
        return uniforms, arrays

    def _geometry(self, ctx, program, scene, prep):
        """``program``'s vertex array over :func:`geometry` of ``scene`` and the count of box vertices.

        Uploaded when the scene's instances change (the same instances under another camera reuse it).
        """
        key = scene.volumes + scene.meshes
        if self._geometry_key is None or len(key) != len(self._geometry_key) or any(
                a is not b for a, b in zip(key, self._geometry_key)):
            with prep.cpu("geometry"):
                vertices, materials = geometry(scene)
            for name in [name for name in self._vaos if isinstance(name, tuple) and name[1] == "geometry"]:
                self._vaos.pop(name).release()
            with prep.upload("geometry"):
                self._buffer("geometry", vertices)
                self._buffer("materials", materials if len(materials) else np.zeros((1, 4), np.float32))
            self._geometry_key = key
            self._geometry_vertices = len(vertices)
        buffer = self._buffers["geometry"]
        vao = self._vao((program, "geometry"), lambda: ctx.vertex_array(program, [(buffer, *VERTEX_FORMAT)]))
        self._buffers["materials"].bind_to_storage_buffer(2)
        return vao, 36 * len(scene.volumes), self._geometry_vertices

    def _render(self, scene):
        phong = scene.shading.model == "phong"
        ctx, prep = self._begin_frame(scene)
        cache = self._cache
        count = len(scene.volumes)
        meshes = any(m.surface is not None for m in scene.meshes)
        scalars = [cache.scalars(instance.volume, prep) for instance in scene.volumes]
        gradients = [cache.gradients(instance.volume, prep) for instance in scene.volumes] if phong else []
        tables, offsets = (cache.transfer_tables([instance.transfer_function for instance in scene.volumes], prep)
                           if count else (None, []))
        programs = self._programs(ctx, count, phong, meshes)
        shapes = self._geometry(ctx, programs["peel"], scene, prep)

        start = time.perf_counter()
        step = world_step(scene, self.step_factor)
        uniforms, arrays = self._uniforms(scene, scalars, offsets, 0.0 if step is None else step)
        for program in programs.values():
            set_uniforms(program, uniforms)
            for name, values in arrays.items():
                uniform = program.get(name, None)
                if uniform is not None:
                    uniform.write(np.ascontiguousarray(values).tobytes())
        for unit, texture in enumerate([s.texture for s in scalars] + gradients):
            texture.use(location=unit)
        if tables is not None:
            tables.bind_to_storage_buffer(0)
        if self.peeling == "dual":
            image, timings, counters, info = self._dual_frame(ctx, scene, programs, shapes)
        else:
            image, timings, counters, info = self._front_frame(ctx, scene, programs, shapes)
        timings.update(total=time.perf_counter() - start, **prep.timings)
        self._last_step = step
        info.update(step=step, step_factor=self.step_factor, peeling=self.peeling,
                    timing=self._timer.method, uploaded=list(prep.uploaded),
                    scalar_formats=[s.format for s in scalars], shading_applied=phong)
        return RenderResult(image=image, timings=timings, counters=counters, info=info)

    def _front_frame(self, ctx, scene, programs, shapes):
        """Front-to-back peeling of boxes and surfaces with ray casting between layers (module notes)."""
        import moderngl

        width, height = scene.width, scene.height
        targets = self._frame_targets(width, height)
        targets["masks"].bind_to_storage_buffer(1)
        for name in ("acc", "aux", "surf", "cuts"):
            targets[name].bind_to_image(IMAGE_UNITS[f"u_{name}"], read=True, write=True)
        for program in programs.values():
            for name, unit in IMAGE_UNITS.items():
                if program.get(name, None) is not None:
                    program[name].value = unit
        screen = {name: self._screen_vao(ctx, programs[name]) for name in ("setup", "raycast", "resolve")}
        drawn, boxes, vertices = shapes
        has_surfaces = vertices > boxes

        timer = self._timer
        ctx.enable_only(moderngl.NOTHING)
        prev, layer = 0, 1

        def bind_layers():
            targets[f"layer{prev}"].bind_to_image(IMAGE_UNITS["u_prev"], read=True, write=True)
            targets[f"layer{layer}"].bind_to_image(IMAGE_UNITS["u_layer"], read=True, write=False)

        def setup_pass():
            bind_layers()
            targets["screen_fbo"].use()
            screen["setup"].render()
            ctx.memory_barrier()

        def peel_pass(query):
            targets[f"layer_fbo{layer}"].clear(FAR_LAYER, FAR_LAYER, FAR_LAYER, FAR_LAYER)
            targets[f"layer_fbo{layer}"].use()
            programs["peel"]["u_surface_pass"].value = 0
            _draw_blended(ctx, drawn, vertices, moderngl.MIN, query)

        def surface_pass():
            targets["surface_fbo"].clear(0.0, 0.0, 0.0, 0.0)
            targets["surface_fbo"].use()
            programs["peel"]["u_surface_pass"].value = 1
            ctx.enable_only(moderngl.BLEND)
            ctx.blend_func = moderngl.ONE, moderngl.ONE
            drawn.render(first=boxes, vertices=vertices - boxes)
            ctx.enable_only(moderngl.NOTHING)
            ctx.blend_func = moderngl.DEFAULT_BLENDING
            ctx.memory_barrier()

        def raycast_pass(program):
            targets["screen_fbo"].use()
            screen[program].render()
            ctx.memory_barrier()

        timer.run("setup", setup_pass)
        per_peel = []
        layers = 0
        truncated = False
        while True:
            if layers == self.max_layers:
                truncated = True
                break
            query = self._query(len(per_peel))
            bind_layers()
            timer.run("peel", lambda: peel_pass(query))
            per_peel.append(int(query.samples))  # waits for the peel: the loop decides on it
            if per_peel[-1] == 0:
                break
            layers += 1
            if has_surfaces:
                timer.run("surface", surface_pass)
            timer.run("raycast", lambda: raycast_pass("raycast"))
            prev, layer = layer, prev
        timer.run("raycast", lambda: raycast_pass("resolve"))
        seconds, _ = timer.results()
        image, readback = self._readback(targets["acc"], height, width)

        timings = {stage: seconds.get(stage, 0.0) for stage in ("setup", "peel", "surface", "raycast")}
        timings["readback"] = readback
        counters = {
            "layers": layers,
            "peel_passes": len(per_peel),
            "fragments": per_peel[0],
            "fragments_peeled": int(sum(per_peel)),
            "surface_passes": layers if has_surfaces else 0,
            "raycast_passes": layers + 1,
        }
        info = {"fragments_per_peel": per_peel, "fragments_per_layer": [a - b for a, b in zip(per_peel, per_peel[1:])],
                "truncated": truncated}
        return image, timings, counters, info

    def _dual_frame(self, ctx, scene, programs, shapes):
        """Dual depth peeling of the surfaces (Bavoil & Myers 2008; module notes)."""
        import moderngl

        width, height = scene.width, scene.height
        targets = self._dual_targets(width, height)
        for name in ("front_layer", "back_layer", "flags", "front_acc", "back_acc"):
            targets[name].bind_to_image(DUAL_IMAGE_UNITS[f"u_{name}"], read=True, write=True)
        for program in programs.values():
            for name, unit in DUAL_IMAGE_UNITS.items():
                if program.get(name, None) is not None:
                    program[name].value = unit
        screen = {name: self._screen_vao(ctx, programs[name]) for name in ("blend", "final")}
        drawn, _, vertices = shapes
        peel = programs["peel"]
        timer = self._timer
        ctx.enable_only(moderngl.NOTHING)

        def geometry_pass(fbo, query, init):
            fbo.use()
            peel["u_dual_init"].value = int(init)
            _draw_blended(ctx, drawn, vertices, moderngl.MAX, query)

        def init_pass(query):
            targets["colours_fbo"].clear(0.0, 0.0, 0.0, 0.0)
            targets["init_fbo"].clear(-FAR_LAYER, -FAR_LAYER, 0.0, 0.0)
            geometry_pass(targets["init_fbo"], query, True)

        def peel_pass(query, source):
            targets[f"depths{source}"].bind_to_image(DUAL_IMAGE_UNITS["u_depths"], read=True, write=False)
            fbo = targets[f"peel_fbo{1 - source}"]
            fbo.clear(-FAR_LAYER, -FAR_LAYER, 0.0, 0.0)
            geometry_pass(fbo, query, False)

        def screen_pass(name, query=None):
            targets["screen_fbo"].use()
            if query is None:
                screen[name].render()
            else:
                with query:
                    screen[name].render()
            ctx.memory_barrier()

        queries = 0

        def next_query():
            nonlocal queries
            queries += 1
            return self._query(queries - 1)

        init_query = next_query()
        timer.run("init", lambda: init_pass(init_query))
        fragments = int(init_query.samples)
        layers = passes = 0
        truncated = False
        source = 0
        while fragments:
            if layers >= self.max_layers:
                truncated = True
                break
            peel_query, blend_query = next_query(), next_query()
            timer.run("peel", lambda: peel_pass(peel_query, source))
            timer.run("blend", lambda: screen_pass("blend", blend_query))
            passes += 1
            peeled, backs = int(peel_query.samples), int(blend_query.samples)  # the loop decides on them
            layers += (peeled > 0) + (backs > 0)
            source = 1 - source
            if backs == 0:
                break
        timer.run("final", lambda: screen_pass("final"))
        seconds, _ = timer.results()
        image, readback = self._readback(targets["front_acc"], height, width)
        timings = {stage: seconds.get(stage, 0.0) for stage in ("init", "peel", "blend", "final")}
        timings["readback"] = readback
        counters = {"layers": layers, "peel_passes": passes, "fragments": fragments}
        return image, timings, counters, {"truncated": truncated}
