"""Depth-peeling multi-volume ray casting: the ``gl-peel`` backend (OpenGL 4.3, moderngl).

The shader-based multi-volume casters that Kainz et al. 2009 compare with (Roessler et al.
2008, Brecheisen et al. 2008; note 002 §1, §3.1–3.2, §4 item 8) split every ray into intervals
with a fixed set of active objects by **depth peeling**: the boundary geometry is rasterised
again for every depth layer, so a scene of depth complexity ``N`` costs ``N`` geometry passes
over all its fragments (``O(N²)`` fragments in all), and each interval between consecutive
layers is ray-cast with the objects active there. This backend is that baseline, built on the
GL infrastructure of :mod:`renderers.gl` (context, texture caches, pass timer).

Per frame:

1. **setup** (one full-screen pass): per pixel, the parity mask of the boxes that hold the ray's
   near-plane point (their entry faces are clipped, so never peeled; this is what lets the eye
   sit inside a box), the cell origin ``t_first`` (the ray's entry into the union of the boxes,
   as the reference's) and empty accumulators.
2. Per layer ``i``:

   * **peel**: all volume boxes drawn (instanced, no culling); a fragment's layer value is the
     exact ray parameter of its box's entry or exit (slab test in the box's texture space, the
     nearer of the two to the rasterised point). Fragments at or in front of the previous
     layer are discarded; those exactly *at* it first toggle their box's bit in the per-pixel
     parity mask (``atomicXor`` on a per-pixel storage buffer, so coincident faces and grazing
     enter/exit pairs count right). The nearest remaining value is kept by ``GL_MIN`` blending into an ``R32F`` target
     (float, exact; no depth-buffer quantisation), which then becomes the previous layer for the
     next peel (a ping-pong of two float textures). A ``GL_SAMPLES_PASSED`` query counts the
     fragments behind the previous layer; none left, or ``max_layers`` reached, ends the loop.
   * **raycast** (full screen): the segment [previous layer, this layer) is sampled with every
     volume whose bit is set, at the reference's common world step on the reference's cells
     (origin ``t_first``, cell-midpoint samples, cells cut by a box sampled at the middle of
     their overlap with the opacity corrected for its length). Samples of several volumes in
     one cell are summed and clamped (the Kainz blend of :func:`renderers.reference.raycast._dvr_ray`)
     before front-to-back compositing. A layer can cut a cell: each volume's sample belongs to
     the segment holding its sample point, and the cell's sum stays pending in a per-pixel
     image until a segment reaches the cell's end, so cut cells blend exactly as the
     reference's.

3. **resolve**: the cell still open behind the last layer is composited.

Early ray termination (``opaque_threshold``): a ray whose opacity passes it takes no further
samples and its fragments are dropped from later peels (so layers stop once every ray ends).

Limits and choices
------------------
* ``max_volumes = 32``: the parity mask is one 32-bit word per pixel, and each volume is its own
  3-D texture bound to a fragment texture unit (``GL_MAX_TEXTURE_IMAGE_UNITS``: 32 on llvmpipe and
  current NVIDIA drivers, 16 guaranteed by GL 4.3); Blinn–Phong needs a gradient texture per
  volume too, so shaded scenes take two units per volume. A scene that needs more units than the
  context has is refused by :meth:`GLPeelRenderer.check` (:class:`core.errors.UnsupportedFeatureError`,
  so the pipeline records a skip with the reason).
* Transfer functions (any sizes) are one shader storage buffer, so they take no texture unit.
* Only volume boxes are peeled: meshes, polygonal boundaries, CSG and homogeneous media are not
  drawn (see the capabilities' reasons).
* Float32 throughout: overlaps shorter than ``SLIVER`` steps are not sampled (the reference's
  threshold is 1e-9 steps in double precision), as in ``gl-raycast``.

Timing and counters
-------------------
Stages (:mod:`renderers.gl.timing`): ``setup``, ``peel`` and ``raycast`` (summed over their
passes; ``raycast`` includes the resolve pass), ``readback``, ``total`` (frame wall clock,
preparation excluded) and, when something is built, ``upload`` and ``gradients``.
Counters: ``layers`` (peels that found fragments: the largest depth complexity among the rays
not yet terminated), ``fragments`` (all box fragments, the first peel's count), ``fragments_peeled``
(fragments behind the previous layer, summed over the peels: every peel rasterises all boxes, so
this grows as ``O(N²)`` with depth complexity ``N``), ``peel_passes``, ``raycast_passes`` (the
resolve pass included). Each peel's query is read before the next pass is issued (one CPU–GPU
round trip per layer, as in the occlusion-query loops of the peeling casters).
``info["fragments_per_peel"]`` lists each peel's count and ``info["fragments_per_layer"]`` the
fragments of each layer (differences of consecutive peels).
"""

import time

import numpy as np

from core.errors import InputError, UnsupportedFeatureError
from core.validation import check_positive_int, check_scalar
from renderers.base import Capabilities, RenderResult
from renderers.gl import context, glsl, peeling_glsl
from renderers.gl.base import GLRenderer, set_uniforms
from renderers.gl.view import NEAR_FRACTION, SLIVER, make_view

MAX_VOLUMES = 32
"""Volumes per scene: the bits of the per-pixel parity mask (and the texture units of common drivers)."""

FAR_LAYER = 3.0e38
"""Value of the layer target where no fragment is left (cleared before every peel)."""

IMAGE_UNITS = {"u_prev": 0, "u_layer": 1, "u_acc": 2, "u_pend": 3, "u_aux": 4}


class GLPeelRenderer(GLRenderer):
    """Depth-peeling multi-pass ray caster for several overlapping volumes (see the module notes).

    Parameters
    ----------
    step_factor : float
        World step as a fraction of the smallest world-space voxel edge (the reference's meaning).
    opaque_threshold : float
        Early ray termination: a ray stops once its opacity exceeds this (1: never).
    max_layers : int
        Peel at most this many depth layers; whatever lies behind the last one is not rendered.
    timing : {"auto", "query", "finish"}
        How passes are timed (:mod:`renderers.gl.timing`).
    """

    name = "gl-peel"
    cached_volumes = MAX_VOLUMES
    description = ("depth-peeling multi-volume ray caster (OpenGL; the shader baseline of Kainz et al. 2009): "
                   "one peel of all boxes per depth layer, each interval ray-cast with its active volumes")
    capabilities = Capabilities(
        projections=frozenset({"orthographic", "perspective"}),
        modes=frozenset({"dvr"}),
        shading=frozenset({"none", "phong"}),
        max_volumes=MAX_VOLUMES,
        gradient_opacity=False,
        transforms=True,
        anisotropic_spacing=True,
        meshes=False,
        lenses=False,
        camera_inside_volume=True,
        reasons={
            "modes": "depth-peeled intervals composite emission–absorption (dvr) only; mip and iso are served by "
                     "gl-raycast",
            "max_volumes": "the per-pixel parity mask is one 32-bit word and every volume takes a texture unit "
                           "(32 on common drivers, 16 guaranteed by OpenGL 4.3; two per volume with phong)",
            "gradient_opacity": "gradient-magnitude opacity modulation is not in the shaders",
            "meshes": "only the volumes' boxes are peeled; mesh instances and polygonal boundaries are not "
                      "rasterised into the layers",
            "csg": "CSG needs per-object inside tests of mesh leaves, which are not peeled",
            "translucent_geometry": "mesh surfaces are not peeled",
            "homogeneous_media": "mesh interiors are not peeled",
            "lenses": "lens volumes belong to the Ropinski 2005 issue",
        },
    )
    quality_sweep = tuple({"step_factor": factor} for factor in (1.0, 0.5, 0.25)) + ({"opaque_threshold": 1.0},)
    """Step sizes from coarse to fine, then early termination off."""

    def __init__(self, *, step_factor=0.5, opaque_threshold=0.99, max_layers=256, timing="auto"):
        super().__init__(step_factor=step_factor, timing=timing)
        self.opaque_threshold = check_scalar(opaque_threshold, name="gl-peel option opaque_threshold", low=0,
                                             high=1, low_open=True)
        self.max_layers = check_positive_int(max_layers, name="gl-peel option max_layers")
        self._queries = []

    @property
    def options(self):
        return {"step_factor": self.step_factor, "opaque_threshold": self.opaque_threshold,
                "max_layers": self.max_layers, "timing": self.timing,
                "effective_step": self._last_step, "effective_timing": self._effective_timing}

    def _forget(self):
        super()._forget()
        self._queries = []

    # -----------------------------------------------------------------------------------------

    def check(self, scene):
        """Also refuse more volumes than this context's texture units hold (a device limit, so the
        pipeline records the pair as skipped, like a missing capability)."""
        super().check(scene)
        ctx = self._context()
        units = int(ctx.info["GL_MAX_TEXTURE_IMAGE_UNITS"])
        per_volume = 2 if scene.shading.model == "phong" else 1
        if len(scene.volumes) * per_volume > units:
            shaded = " with phong shading (a gradient texture each)" if per_volume == 2 else ""
            raise UnsupportedFeatureError(
                self.name, f"{len(scene.volumes)} volumes",
                f"{ctx.info['GL_RENDERER']} has {units} texture units, so at most {units // per_volume} "
                f"volumes{shaded}")

    def _check_sizes(self, ctx, scene):
        """Refuse a volume larger than a 3-D texture can be, naming the limit (before any work)."""
        limit = context.max_3d_texture_size(ctx)
        for instance in scene.volumes:
            if max(instance.volume.shape_xyz) > limit:
                raise InputError(
                    f"volume {instance.name!r}: dimensions {instance.volume.shape_xyz} exceed GL_MAX_3D_TEXTURE_SIZE "
                    f"{limit} of {ctx.info['GL_RENDERER']}; resample the volume to at most {limit} voxels per axis")

    def _programs(self, ctx, count, phong):
        """Setup, peel, raycast and resolve programs for ``count`` volumes (compiled once per process)."""
        defines = [f"N_VOLUMES {count}"] + (["SHADED"] if phong else [])
        vertex = glsl.VERSION + f"#define N_VOLUMES {count}\n" + peeling_glsl.VOLUME_VERTEX

        def screen(*parts):
            return context.program(ctx, glsl.SCREEN_VERTEX, glsl.fragment_source(*parts, defines=defines))

        return {
            "setup": screen(peeling_glsl.VOLUMES, peeling_glsl.SETUP_FRAGMENT),
            "peel": context.program(ctx, vertex, glsl.fragment_source(peeling_glsl.VOLUMES, peeling_glsl.PEEL_FRAGMENT,
                                                                      defines=defines)),
            "raycast": screen(peeling_glsl.VOLUMES, peeling_glsl.SAMPLING, peeling_glsl.RAYCAST_FRAGMENT),
            "resolve": screen(peeling_glsl.SAMPLING, peeling_glsl.RESOLVE_FRAGMENT),
        }

    def _frame_targets(self, width, height):
        def build():
            size = (width, height)
            targets = {f"layer{i}": self._float_texture(size, 1) for i in range(2)}
            targets.update({f"layer_fbo{i}": self._ctx.framebuffer([targets[f"layer{i}"]]) for i in range(2)})
            targets.update({"masks": self._ctx.buffer(reserve=4 * width * height), "acc": self._float_texture(size),
                       "pend": self._float_texture(size), "aux": self._float_texture(size, 2)})
            # Full-screen passes write images only; the framebuffer just sets the viewport.
            targets["screen_fbo"] = self._ctx.framebuffer([targets["pend"]])
            targets["screen_fbo"].color_mask = (False, False, False, False)
            return targets

        return self._target((width, height), build)

    def _query(self, index):
        """The ``index``-th samples-passed query of the frame (one per pass: llvmpipe flushes on reuse)."""
        while len(self._queries) <= index:
            self._queries.append(self._ctx.query(samples=True))
        return self._queries[index]

    @staticmethod
    def _clip_planes(scene):
        """Near and far plane distances bracketing every box (the near one as in :mod:`renderers.gl.view`)."""
        view_matrix = scene.camera.view_matrix()
        corners = np.concatenate([instance.world_corners() for instance in scene.volumes])
        depths = -(np.c_[corners, np.ones(len(corners))] @ view_matrix.T)[:, 2]
        _, radius = scene.bounding_sphere()
        margin = max(1e-3 * radius, 1e-6)
        far = max(float(depths.max()) + margin, 2 * margin)
        near = NEAR_FRACTION * radius if scene.camera.projection == "perspective" else min(margin, far / 2)
        return near, far

    def _uniforms(self, scene, scalars, offsets, step):
        """Every uniform of the four programs: the pixel rays, the volumes' arrays, the options."""
        view = make_view(scene, self.step_factor)
        near, far = self._clip_planes(scene)
        camera = scene.camera
        viewproj = camera.projection_matrix(scene.width / scene.height, near, far) @ camera.view_matrix()
        models, inverses, normals = [], [], []
        for instance in scene.volumes:
            model = instance.transform @ np.diag([*instance.volume.extent, 1.0])
            models.append(model)
            inverses.append(np.linalg.inv(model))
            normals.append(np.linalg.inv(instance.transform[:3, :3]).T)
        ray_keys = ("u_eye", "u_right", "u_up", "u_back", "u_half_size", "u_perspective", "u_viewport", "u_light",
                    "u_phong")
        uniforms = {key: view.uniforms[key] for key in ray_keys}
        uniforms.update(u_viewproj=viewproj, u_step=step, u_sliver=SLIVER * step, u_t_near=near,
                        u_threshold=self.opaque_threshold if self.opaque_threshold < 1 else 2.0)
        arrays = {
            "u_models": np.stack([m.T for m in models]).astype(np.float32),
            "u_w2t": np.stack([m.T for m in inverses]).astype(np.float32),
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

    def _render(self, scene):
        import moderngl

        phong = scene.shading.model == "phong"
        self._check_sizes(self._context(), scene)
        ctx, prep = self._begin_frame(scene)
        cache = self._cache
        count = len(scene.volumes)
        scalars = [cache.scalars(instance.volume, prep) for instance in scene.volumes]
        gradients = [cache.gradients(instance.volume, prep) for instance in scene.volumes] if phong else []
        tables, offsets = cache.transfer_tables([instance.transfer_function for instance in scene.volumes], prep)
        programs = self._programs(ctx, count, phong)

        start = time.perf_counter()
        step = self.step_factor * scene.min_world_voxel_size()
        width, height = scene.width, scene.height
        targets = self._frame_targets(width, height)
        uniforms, arrays = self._uniforms(scene, scalars, offsets, step)
        for program in programs.values():
            set_uniforms(program, uniforms)
            for name, values in arrays.items():
                uniform = program.get(name, None)
                if uniform is not None:
                    uniform.write(np.ascontiguousarray(values).tobytes())
        for unit, texture in enumerate([s.texture for s in scalars] + gradients):
            texture.use(location=unit)
        tables.bind_to_storage_buffer(0)
        targets["masks"].bind_to_storage_buffer(1)
        for name in ("acc", "pend", "aux"):
            targets[name].bind_to_image(IMAGE_UNITS[f"u_{name}"])
        for program in programs.values():
            for name, unit in IMAGE_UNITS.items():
                if program.get(name, None) is not None:
                    program[name].value = unit
        screen = {name: self._screen_vao(ctx, programs[name]) for name in ("setup", "raycast", "resolve")}
        boxes = self._cube_vao(ctx, programs["peel"])

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
            ctx.enable_only(moderngl.BLEND)
            ctx.blend_equation = moderngl.MIN
            with query:
                boxes.render(instances=count)
            ctx.enable_only(moderngl.NOTHING)
            ctx.blend_equation = moderngl.FUNC_ADD
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
            timer.run("raycast", lambda: raycast_pass("raycast"))
            prev, layer = layer, prev
        timer.run("raycast", lambda: raycast_pass("resolve"))
        seconds, _ = timer.results()
        image, readback = self._readback(targets["acc"], height, width)
        total = time.perf_counter() - start

        self._last_step = step
        timings = {stage: seconds.get(stage, 0.0) for stage in ("setup", "peel", "raycast")}
        timings.update(readback=readback, total=total, **prep.timings)
        per_layer = [a - b for a, b in zip(per_peel, per_peel[1:])]
        counters = {
            "layers": layers,
            "fragments": per_peel[0],
            "fragments_peeled": int(sum(per_peel)),
            "peel_passes": len(per_peel),
            "raycast_passes": layers + 1,
        }
        info = {
            "step": step,
            "step_factor": self.step_factor,
            "fragments_per_peel": per_peel,
            "fragments_per_layer": per_layer,
            "truncated": truncated,
            "timing": timer.method,
            "uploaded": list(prep.uploaded),
            "scalar_formats": [s.format for s in scalars],
            "shading_applied": phong,
        }
        return RenderResult(image=image, timings=timings, counters=counters, info=info)
