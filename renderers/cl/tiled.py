"""The tile-based multi-volume ray caster of Kainz et al. 2009 on OpenCL: the ``cl-tiled`` backend.

Per frame (note 002 §2.2, §2.9):

1. **Boundaries.** Every volume instance is an object bounded by a closed triangle mesh in its
   object space: its box (12 triangles) or, with ``empty_space="hull"``, the tight hull around
   its non-empty ``brick_size³`` bricks (:mod:`renderers.cl.resources`, built on the device and
   rebuilt when the transfer function changes). A volume that is a CSG operand keeps its box,
   since its inside decides where other leaves are carved or kept even where its data is
   transparent. Every mesh instance is an object with its mesh and transform (a mesh's
   triangles are uploaded once, whatever the number of its instances), and so is every volume's
   polygonal ``boundary`` (in the volume's object space). All go into one triangle list with the
   object each triangle bounds: at most 64 objects, one bit each of the inside mask.
2. **Binning** (``kernels/binning.cl``): one work-item per triangle transforms it, stores its
   world plane and a code (object, front/back, triangle), and appends a 64-bit coverage mask per
   8×8 tile to the tile's chunked record list (64 records per chunk from a pool, at most 64 chunks
   per tile, chunks allocated with atomics). Masks are exact (integer edge functions, a
   canonical tie rule), so a closed mesh covers each pixel once per crossing. The pool grows and
   the binning reruns when a frame needs more chunks than it has.
3. **Pixel kernel** (``kernels/pixel.cl``): one 64-work-item group per tile. Each pixel gathers
   its fragments (depth from the triangle's plane) into a depth-sorted list in local memory
   (insertion sort, interleaved slots, at most ``depth_cap`` entries: the nearest are kept),
   then walks the fragments front to back toggling each object's inside bit (parity; the
   objects around the ray origin come from the crossings behind it, or from the host for a
   perspective eye, see below). After each group of
   fragments at one depth the leaves' state is evaluated (:mod:`renderers.cl.scene`): a volume
   leaf is inside its box or hull and its boundary, and the CSG forest (a postfix program over
   the leaves' inside mask, uploaded once per frame) says which leaves contribute and which
   trees' roots are inside. A segment runs until the contributing set changes or a surface is
   shown; empty segments are skipped. In a segment every contributing volume is sampled at one
   common world step, and contributing homogeneous media (extinctions added, colours
   ``σ``-weighted) join each cell part's sum with ``1 − exp(−σL)`` of its length, or are
   composited analytically over the whole segment when no volume contributes. A mesh's surface
   is composited at a crossing where its tree's root changes inside/outside (every crossing of
   a standalone mesh): two-sided Blinn–Phong with the triangle's normal, or its flat colour,
   at its alpha. Everything is composited front to back in depth order, as the reference does.
   With ``fragments="global"`` the lists live in global memory, sized exactly by a counting pass
   (``count_fragments``): no fragment is dropped, the ground truth for the depth cap's error.

Sampling matches :mod:`renderers.reference` in float32: the world step ``Δ = step_factor ×`` the
smallest world voxel edge; cells ``[t_a + kΔ, t_a + (k + 1)Δ]`` from ``t_a``, the first entry
into a volume's box or hull object (the reference's entry into the union of the boxes, when
boundaries are boxes); a whole cell samples at its centre, a cell that a segment boundary cuts at
the midpoint of its part with opacity corrected for the part's length, so path lengths count exactly; cell parts
of at most 10⁻³ Δ are skipped. Every volume samples the cells it overlaps; corrected premultiplied
samples are summed, the opacity clamped to 1 (colour scaled alike), and composited front to back.
With hulls, the cells are anchored at the first hull face instead of the box, which moves sample
positions by a fraction of a step where that differs (an ``O(Δ²)`` difference for smooth data).
The reference cuts cells only at visible surfaces and medium ends and samples each volume over
its own interval; here a cell is also cut where another volume starts or stops contributing
(again ``O(Δ²)``). Mesh vertices are float32 on the device, and fragment depths come from each
triangle's float32 plane: pixels whose centre passes within ~1/256 pixel of a silhouette edge
may be covered differently than by the reference's exact test.
Trilinear reconstruction, classification, gradient opacity and Blinn–Phong are the reference's.
Early ray termination stops a ray whose opacity passes ``opaque_threshold``.

**Maximum intensity projection** (``mode="mip"``; the reference's definition, sampled): each
contributing volume samples both ends of every segment and the cells above, and the ray keeps the
largest normalised scalar of all volumes (the nearer sample on ties, then the lower instance);
the pixel is that value classified by its own volume's transfer function, premultiplied, without
opacity correction, shading or gradient opacity (as the reference and VTK). The reference finds
the exact maximum of the trilinear field; sampling at ``Δ`` can only miss a peak between samples.
The raw scalar is compared, not its opacity, so the maximum may lie in voxels that an opacity hull
leaves out: every volume is bounded by its box in this mode. No early termination but at a
maximum of 1, the top of the range, which no later sample can replace (counted in
``early_terminations``); ``opaque_threshold`` does not apply. Meshes, boundaries and CSG are
``dvr`` and ``iso`` only (:class:`core.scene.Scene` refuses them in ``mip``, for every backend).

**Iso-surfaces** (``mode="iso"``; the reference's definition, exact, ``kernels/iso.cl``): no samples
and no step. In each segment every contributing volume's span is walked through the cells of its
voxel lattice (a 3-D DDA, the clamp-to-edge half voxels included, as
:func:`renderers.reference.raycast._walk_volume` walks them); a cell whose eight corners reach across
the volume's isovalue from the ray's state is solved: the trilinear field along the segment is a
cubic, cut at the roots of its derivative into monotone pieces, and the crossing bisected in the
first piece that changes state, to float32's resolution of the segment (Marmitt et al. 2004). So no
crossing can fall between two samples: a one-voxel sheet or a vessel thinner than any step is hit.
A crossing is a change of ``s < isovalue`` from the state where the ray entered that volume (kept
per volume across segments, so a surface is seen from inside as well); the nearest crossing of
all volumes wins (the lower instance on a tie), in its transfer function's colour at its
isovalue, shaded with the reference's normal (central differences one voxel apart of the same
field) and opaque. Every volume is bounded by its box in this mode: its state is taken where the
ray enters its box (``iso_entry_states`` in ``kernels/iso.cl``), so where a boundary or CSG opens
a volume inside its surface the cut face is the hit (a cap), as the reference draws it; surfaces
and media in front of the hit composite as in ``dvr``. Counters: ``samples`` are the cell segments walked,
``iso_cells_solved`` those solved, ``crossings`` the pixels with a hit; ``early_terminations``
counts only the rays that surfaces and media in front of the surface made opaque (a hit ends the
ray too, and is counted as a crossing).

**A perspective eye inside volumes or meshes.** The parity walk of a perspective ray starts with
the objects that hold the eye (:func:`renderers.cl.scene.eye_inside`: a point-in-box test per
volume, the winding number of each mesh instance and volume boundary); a volume whose box holds
the eye is bounded by its box. Its rays start at the eye, as the reference's do (``t >= 0``, no
near plane), with the cells anchored at ``t = 0``. Triangles reaching behind the eye cannot be
projected, so such a frame is binned with homogeneous edge functions (Olano and Greer 1997;
``kernels/binning.cl``, ``HOMOGENEOUS``): float32 instead of snapped integers, the same
exactly-once tie rule, every triangle counted only where it lies in front of the eye (info
``rasterisation``: ``"homogeneous"`` or ``"integer"``; ``coverage`` applies to the integer one).
An orthographic ray starts on the image plane and finds the objects around it from the crossings
behind it, wherever the eye is.

Timings (seconds, OpenCL profiling events): ``upload`` (atlas, first use of a set of volumes),
``bricks`` (brick ranges, first use of a volume and brick size), ``hull`` (hull build, first use
of a classification), these three only in a frame that built them (the preprocessing, which
:meth:`drop_caches` forgets: the timing harness times it once per view), ``setup`` (the frame's
triangle list, object table and cleared tile lists),
``binning``, ``count`` (global lists only), ``pixel``, ``readback``; ``total`` is the wall clock of
the frame. Counters: ``rays``, ``rays_hit`` (pixels with a fragment), ``triangles``, ``records``
(tile records), ``records_per_tile_max``, ``records_per_tile_mean`` (over tiles with records),
``records_dropped`` (past 4096 per tile), ``pool_chunks``, ``pool_chunks_used`` (see
:data:`SCHEDULING_COUNTERS`),
``fragments`` (kept, depth ≥ 0), ``fragments_max``, ``fragments_mean`` (over hit pixels),
``fragments_dropped`` (past the depth cap), ``sort_moves`` (entries the insertion sorts shifted:
0 for fragments arriving in depth order, ``n(n − 1)/2`` per pixel for ``n`` in reverse),
``samples`` (volume samples), ``medium_steps`` (media composited without a volume: one per
segment analytically, one per cell part sampled) and ``early_terminations``; with
``fragments="global"`` also ``unpaired_pixels``, the pixels whose front- and back-facing fragment
counts differ (0 when every boundary is closed and in front of the eye: the watertightness check;
every pixel whose ray starts inside a closed object, too). Info adds ``objects`` (inside-mask bits
used), ``csg_nodes``, ``rasterisation`` and ``eye_inside`` (the mask of the objects holding a
perspective eye). A scene without volumes has no
step (``info["step"]`` is ``None``) and no atlas.

Ablation switches (note 002 §5): ``triangle_order`` submits the triangles to binning in scene
order or sorted by view depth (E7: the insertion sort meets sorted or reversed input; the image
does not change, since fragments are ordered by depth and triangle id whatever their arrival);
``stop_after="sort"`` ends the pixel kernel after gathering and sorting (E7: its time is the
gather and sort share; the image is left transparent); ``media="sampled"`` composites segments of
media alone cell by cell at the common step instead of analytically (E9: the same image up to
float rounding, cells shorter than 10⁻³ Δ and early termination at a cell end; a scene needs a
volume for the step); ``coverage="edge"`` computes the binning's masks by evaluating the edge
functions at each pixel centre of the tile instead of by bit shifts (E11: the same masks). The
depth order is computed per frame (a kernel for the centroids' depths, a host sort) and timed
as ``setup``.
"""

import time
from dataclasses import dataclass

import numpy as np

from core.errors import InputError, UnsupportedFeatureError
from renderers.base import Capabilities, Option, RenderResult, Renderer, step_factor_option, world_step
from renderers.cl import context
from renderers.cl import scene as scene_arrays
from renderers.cl.resources import DeviceCache, Stages

TILE = 8
CHUNK = 64
MAX_CHUNKS = 64
EMPTY_CHUNK = 0xFFFFFFFF
MAX_TRIANGLES = 1 << 23
"""Triangle ids have 23 bits in a fragment code (object << 24 | front << 23 | triangle)."""

INITIAL_POOL_CHUNKS = 8192
"""Chunks in the first pool: the paper's 6 MB (8192 × 64 records of 12 bytes)."""

FRAGMENT_STORES = ("local", "global")
EMPTY_SPACE = ("hull", "box")
TRIANGLE_ORDERS = ("scene", "front-to-back", "back-to-front")
MEDIA = ("analytic", "sampled")
SCHEDULING_COUNTERS = ("pool_chunks_used", "pool_bytes_used", "sort_moves")
"""Counters (and ``info["pool_bytes_used"]``, from the chunks used) that follow the order in which the device ran its work-items, not only the scene:
a tile's records are appended through an atomic index, so their order (and the insertion sort's
moves) can change from frame to frame, and the loser of a race for a tile's next chunk leaves the
chunk it took unused. The image does not change (fragments are ordered by depth and triangle id)."""
COVERAGE = ("bitmask", "edge")
PREPROCESSING = ("upload", "bricks", "hull")
"""Stages a frame runs only when it builds what later frames reuse: the atlas, brick ranges and hulls."""
STOP_AFTER = ("composite", "sort")
STATS = 8
"""Per-pixel counters the pixel kernel writes (a ``uint8``): kept, dropped, samples (``iso``: cells
walked), terminated, sort moves, medium steps, and in ``iso`` the cells solved and the crossing found."""
BLENDING = {
    "dvr": "sum of premultiplied samples and media, opacity clamped to 1 (Kainz et al. 2009); surfaces composited at "
           "their depth",
    "mip": "the largest scalar of all volumes, classified by its volume's transfer function",
    "iso": "the nearest first crossing of any volume's iso-surface, exact, in its transfer function's colour at its "
           "isovalue, opaque",
}


def _atlas_defines(dtype):
    """Build options for the atlas element type: uint8 scaled by 1/255, or normalised float32."""
    if dtype == np.uint8:
        return ["-DATLAS_T=uchar", "-DATLAS_SCALE=(1.0f/255.0f)"]
    return ["-DATLAS_T=float", "-DATLAS_SCALE=1.0f"]


@dataclass
class Binned:
    """A frame up to the pixel kernel (:meth:`ClTiledRenderer._bin`)."""

    pixel: dict
    atlas: object
    hulls: list
    triangles: int
    object_buffer: object
    transfer: np.ndarray
    gradient_tables: np.ndarray
    camera: tuple
    tile_lists: tuple
    global_size: tuple
    passes: int
    bin_counters: np.ndarray
    phong: bool
    leaves: scene_arrays.Leaves
    eye_inside: np.uint64
    homogeneous: bool


class ClTiledRenderer(Renderer):
    """Tile-based multi-volume ray caster with polygonal boundaries (Kainz et al. 2009), OpenCL.

    ``options`` also records ``effective_step``, the world step of the last frame.
    """

    technique_stages = ("binning", "count", "pixel")
    """The stages that are the technique itself: the three kernels (binning, fragment counting, the pixel kernel), timed on the device; not uploads, brick and hull builds or the readback."""

    name = "cl-tiled"
    description = ("OpenCL tile-based multi-volume ray caster (Kainz et al. 2009): polygonal boundaries and meshes "
                   "binned into 8x8 tiles, per-pixel depth-sorted fragments, segment walk over overlapping volumes, "
                   "surfaces, homogeneous media and CSG")
    capabilities = Capabilities(
        projections=frozenset({"orthographic", "perspective"}),
        modes=frozenset({"dvr", "mip", "iso"}),
        shading=frozenset({"none", "phong"}),
        max_volumes=64,
        gradient_opacity=True,
        transforms=True,
        meshes=True,
        csg=True,
        translucent_geometry=True,
        homogeneous_media=True,
        camera_inside_volume=True,
        reasons={
            "max_volumes": "the active-object set is one 64-bit mask",
            "lenses": "a lens would be the volume twice under CSG boundaries (box minus lens with the outside "
                      "appearance, lens ∩ box with the inside one); not built: boundaries are polygon meshes, so a "
                      "sphere lens would be a tessellation, and a boundary test per sample is the per-sample method "
                      "gl-raycast already measures",
        },
    )
    option_table = (
        step_factor_option(0.5, "World step as a fraction of the smallest world-space voxel edge (``iso`` has none: "
                           "it walks the voxel lattice's cells).", modes=frozenset({"dvr", "mip"})),
        Option("depth_cap", int, 63, "Fragments kept per pixel in local memory (paper: 63); the farthest are "
               "dropped.", low=1),
        Option("fragments", str, "local", "``local``: the paper's capped lists in local memory. ``global``: "
               "unbounded lists in global memory (the ground truth for the cap's error; ``depth_cap`` does not "
               "apply).", choices=FRAGMENT_STORES),
        Option("opaque_threshold", float, 0.99, "Early ray termination when the accumulated opacity exceeds it (1 "
               "never stops a ray). 0.99: the paper gives no value, and this bounds the error to 1 % of a pixel. "
               "``mip`` does not composite, so it does not apply there; in ``iso`` it applies to the surfaces and "
               "media in front of the iso-surface.", low=0, high=1, low_open=True, modes=frozenset({"dvr", "iso"})),
        Option("empty_space", str, "hull", "Boundaries: tight hulls around the non-empty bricks (paper) or the "
               "volumes' boxes. Volumes that are CSG operands or hold a perspective eye use their boxes, and so does "
               "every volume in ``mip`` and ``iso``.", choices=EMPTY_SPACE, modes=frozenset({"dvr"})),
        Option("brick_size", int, 8, "Brick edge in voxels for the hulls (paper: 8).", low=1, modes=frozenset({"dvr"})),
        Option("min_opacity", float, 0.0, "Transfer-function opacities at or below it count as empty for the hulls "
               "(paper: 0, exact).", low=0, high=1, high_open=True, modes=frozenset({"dvr"})),
        Option("triangle_order", str, "scene", "The order the triangles are submitted to binning: as the scene "
               "lists them, or sorted by the view depth of their centroid (E7's best and worst case for the "
               "insertion sort).", choices=TRIANGLE_ORDERS),
        Option("media", str, "analytic", "Segments of homogeneous media alone: composited analytically (paper) or "
               "sampled at the common step (the shortcut's ablation, E9).", choices=MEDIA),
        Option("coverage", str, "bitmask", "Coverage masks by bit-shifted row/column masks (paper) or by per-pixel "
               "edge functions (E11).", choices=COVERAGE, attribute="coverage_method"),
        Option("stop_after", str, "composite", "``sort`` ends the pixel kernel after gathering and sorting the "
               "fragments: an ablation that times them (E7); the image is transparent.", choices=STOP_AFTER),
        Option("device", str, None, "OpenCL device selector such as ``0:0`` or ``pocl`` "
               "(:mod:`renderers.cl.context`); ``None``: ``$VOLBENCH_CL_DEVICE``, else the first device whose "
               "compiler builds kernels, GPUs first. A device that cannot build makes the backend unavailable "
               "here, when it is made, with its compiler's message."),
    )
    quality_sweep = tuple({"step_factor": factor} for factor in (1.0, 0.5, 0.25))
    """Step sizes from coarse to fine."""
    scheduling_dependent = SCHEDULING_COUNTERS

    def __init__(self, **options):
        super().__init__(**options)
        self._entry = None
        self._cache = None
        self._buffers = {}
        self._pool_chunks = INITIAL_POOL_CHUNKS
        self._last_step = None
        # The device is chosen now, so that one that cannot build is unavailable before any run.
        entry = self._device()
        if self.fragments == "local":
            needed = self.depth_cap * TILE * TILE * 8 + CHUNK * 12
            if needed > entry.device.local_mem_size:
                most = (entry.device.local_mem_size - CHUNK * 12) // (TILE * TILE * 8)
                raise InputError(f"cl-tiled option depth_cap: {self.depth_cap} fragments per pixel need {needed} "
                                 f"bytes of local memory, {entry.device.name.strip()} has "
                                 f"{entry.device.local_mem_size}; use at most {most}, or fragments='global'")

    @classmethod
    def probe(cls):
        return context.probe(context.selector_for(None))

    @property
    def options(self):
        return {**super().options, "effective_step": self._last_step}

    def environment(self):
        return context.environment(context.selector_for(self.device))

    def check(self, scene):
        """Also refuse a scene with more objects than the inside mask has bits, before any work
        (the capabilities count volumes only; meshes and boundaries take bits too)."""
        super().check(scene)
        boundaries = sum(instance.boundary is not None for instance in scene.volumes)
        objects = len(scene.volumes) + len(scene.meshes) + boundaries
        if objects > scene_arrays.MAX_OBJECTS:
            raise UnsupportedFeatureError(
                self.name, f"{objects} objects",
                f"volume instances, mesh instances and volume boundaries are one bit each of a 64-bit inside mask; "
                f"this scene has {len(scene.volumes)} + {len(scene.meshes)} + {boundaries}")

    caches_preprocessing = True

    def drop_caches(self):
        """Forget the atlases, brick ranges, hulls and uploaded meshes: the next frame builds and times them."""
        if self._cache is not None:
            self._cache.clear()

    def close(self):
        self._cache = None
        self._buffers = {}

    def _device(self):
        if self._entry is None:
            self._entry = context.shared(context.selector_for(self.device))
            self._cache = DeviceCache(self._entry)
        return self._entry

    # -----------------------------------------------------------------------------------------

    def _programs(self, entry, atlas_dtype, fragments, phong, gradient_opacity, csg, mode, homogeneous):
        """``(binning, hull, pixel)`` kernels by name for this frame's variant, built once per process."""
        atlas_defines = _atlas_defines(atlas_dtype)
        binning_defines = ["-DEDGE_COVERAGE"] if self.coverage_method == "edge" else []
        if self.triangle_order != "scene":
            binning_defines.append("-DORDERED")
        if homogeneous:
            binning_defines.append("-DHOMOGENEOUS")
        binning = context.kernels(entry, context.kernel_source("common.cl", "binning.cl"), binning_defines)
        hull = context.kernels(entry, context.kernel_source("common.cl", "hull.cl"), atlas_defines)
        defines = list(atlas_defines)
        defines.append("-DGLOBAL_FRAGMENTS" if fragments == "global" else f"-DMAXF={self.depth_cap}")
        if phong:
            defines.append("-DPHONG")
        if gradient_opacity:
            defines.append("-DGRADIENT_OPACITY")
        if csg:
            defines.append("-DCSG")
        if self.media == "sampled":
            defines.append("-DSAMPLED_MEDIA")
        if self.stop_after == "sort":
            defines.append("-DSORT_ONLY")
        if mode != "dvr":
            defines.append(f"-D{mode.upper()}")
        pixel = context.kernels(entry, context.kernel_source("common.cl", "iso.cl", "pixel.cl"), defines)
        return binning, hull, pixel

    def _buffer(self, name, nbytes):
        """A device buffer kept across frames, reallocated when it must grow."""
        import pyopencl as cl

        buffer = self._buffers.get(name)
        if buffer is None or buffer.size < nbytes:
            buffer = cl.Buffer(self._entry.context, cl.mem_flags.READ_WRITE, size=max(int(nbytes), 16))
            self._buffers[name] = buffer
        return buffer

    def _upload(self, name, array, stages, stage):
        """Copy ``array`` into the kept buffer ``name`` (timed as ``stage``)."""
        import pyopencl as cl

        array = np.ascontiguousarray(array)
        buffer = self._buffer(name, array.nbytes)
        stages.add(stage, cl.enqueue_copy(self._entry.queue, buffer, array, is_blocking=True))
        return buffer

    def _fill(self, name, value, count, stages):
        import pyopencl as cl

        buffer = self._buffer(name, count * value.itemsize)
        stages.add("setup", cl.enqueue_fill_buffer(self._entry.queue, buffer, value, 0, count * value.itemsize))
        return buffer

    def _bin(self, scene, fragments, stages):
        """Everything up to the pixel kernel: resources, the frame's triangle list, binned tile lists."""
        import pyopencl as cl
        import pyopencl.cltypes as cltypes

        homogeneous, problem = scene_arrays.rasterisation(scene)
        if problem:
            raise UnsupportedFeatureError(self.name, "this view", problem)
        if self.media == "sampled" and not scene.volumes and any(m.medium is not None for m in scene.meshes):
            raise InputError(f"cl-tiled option media: 'sampled' steps media at the volumes' common step, and scene "
                             f"{scene.name!r} has no volume; use media='analytic'")
        entry = self._device()
        queue = entry.queue
        mode = scene.mode
        # mip classifies one value per ray: no shading; mip and iso have no gradient opacity (the reference).
        phong = scene.shading.model == "phong" and mode != "mip"
        gradient_opacity = mode == "dvr" and any(instance.gradient_opacity is not None for instance in scene.volumes)
        leaves = scene_arrays.leaves(scene)

        volumes, volume_index = scene_arrays.distinct_volumes(scene)
        atlas = self._cache.atlas(volumes, stages) if volumes else None
        binning, hull_kernels, pixel = self._programs(entry, atlas.dtype if atlas else np.dtype(np.uint8), fragments,
                                                      phong, gradient_opacity, bool(scene.csg), mode, homogeneous)
        # Boxes where a hull would be wrong: a CSG operand's inside is its box (∩ boundary) wherever
        # its data is transparent too; mip's maximum may lie in transparent voxels, and an iso
        # crossing is relative to the state where the ray enters the box; and an eye inside a box
        # is inside that object (eye_inside tests boxes, not hulls).
        boxed = {name for tree in scene.csg for name in tree.leaves()}
        if scene.camera.projection == "perspective":
            boxed.update(scene.camera_inside_volume())
        brick = self.brick_size if self.empty_space == "hull" and mode == "dvr" else None
        hulls = [self._cache.hull(hull_kernels, atlas, instance, None if instance.name in boxed else brick,
                                  self.min_opacity, stages)
                 for instance in scene.volumes]
        # Objects in order (renderers.cl.scene): volume boxes or hulls, mesh instances, volume boundaries.
        parts = hulls + [self._cache.mesh(instance.mesh, stages) for instance in scene.meshes]
        parts += [self._cache.mesh(scene.volumes[i].boundary, stages) for i in leaves.boundary_volumes]
        triangles = sum(part.triangles for part in parts)
        if triangles >= MAX_TRIANGLES:
            raise InputError(f"scene {scene.name!r}: {triangles} boundary triangles exceed the {MAX_TRIANGLES} a "
                             "fragment code can name; use a larger brick_size, empty_space='box' or coarser meshes")

        vertex_buffer = self._buffer("vertices", 48 * max(triangles, 1))
        offset = 0
        for part in parts:
            if part.triangles:
                stages.add("setup", cl.enqueue_copy(queue, vertex_buffer, part.buffer,
                                                    byte_count=48 * part.triangles, dst_offset=48 * offset))
            offset += part.triangles
        owners = np.repeat(np.arange(len(parts), dtype=np.uint32), [part.triangles for part in parts])
        owner_buffer = self._upload("owners", owners if triangles else np.zeros(1, np.uint32), stages, "setup")
        transfer, tf_offsets, gradient_tables, g_offsets = scene_arrays.tables(scene)
        slots = [atlas.layout.origins[i] for i in volume_index]
        objects = scene_arrays.object_records(scene, slots, tf_offsets, g_offsets)
        object_buffer = self._upload("objects", objects, stages, "setup")

        width, height = scene.width, scene.height
        tiles_x, tiles_y = -(-width // TILE), -(-height // TILE)
        tiles = tiles_x * tiles_y
        eye, right, up, back, half_size, perspective = scene_arrays.camera_arguments(scene)
        camera = (cltypes.make_float4(*eye, 0), cltypes.make_float4(*right, 0), cltypes.make_float4(*up, 0),
                  cltypes.make_float4(*back, 0), cltypes.make_float2(*half_size), np.int32(perspective),
                  np.int32(width), np.int32(height), np.int32(tiles_x))
        planes = self._buffer("planes", 16 * max(triangles, 1))
        codes = self._buffer("codes", 4 * max(triangles, 1))
        order = ()
        if self.triangle_order != "scene" and triangles:
            order = (self._submission_order(binning, vertex_buffer, owner_buffer, object_buffer, triangles, camera,
                                            stages),)

        # Binning, again with a larger pool if this frame ran out of chunks.
        passes = 0
        while True:
            passes += 1
            tile_count = self._fill("tile_count", np.uint32(0), tiles, stages)
            tile_chunks = self._fill("tile_chunks", np.uint32(EMPTY_CHUNK), tiles * MAX_CHUNKS, stages)
            counters = self._fill("bin_counters", np.uint32(0), 2, stages)
            pool_mask = self._buffer("pool_mask", 8 * CHUNK * self._pool_chunks)
            pool_triangle = self._buffer("pool_triangle", 4 * CHUNK * self._pool_chunks)
            if triangles:
                stages.add("binning", binning["bin_triangles"](
                    queue, (-(-triangles // 64) * 64,), (64,), vertex_buffer, owner_buffer, object_buffer,
                    np.uint32(triangles), *camera, planes, codes, tile_count, tile_chunks, pool_mask, pool_triangle,
                    np.uint32(self._pool_chunks), counters, *order))
            bin_counters = np.empty(2, np.uint32)
            stages.add("binning", cl.enqueue_copy(queue, bin_counters, counters))
            if bin_counters[0] <= self._pool_chunks:
                break
            self._pool_chunks = int(max(2 * self._pool_chunks, bin_counters[0]))
        return Binned(pixel=pixel, atlas=atlas, hulls=hulls, triangles=triangles, object_buffer=object_buffer,
                      transfer=transfer, gradient_tables=gradient_tables, camera=camera,
                      tile_lists=(tile_count, tile_chunks, pool_mask, pool_triangle, planes, codes),
                      global_size=(tiles_x * TILE, tiles_y * TILE), passes=passes, bin_counters=bin_counters,
                      phong=phong, leaves=leaves, eye_inside=scene_arrays.eye_inside(scene, leaves),
                      homogeneous=homogeneous)

    def _submission_order(self, binning, vertex_buffer, owner_buffer, object_buffer, triangles, camera, stages):
        """The triangles sorted by view depth (stable), nearest or farthest first, uploaded as uint32."""
        import pyopencl as cl

        depths = self._buffer("view_depths", 4 * triangles)
        eye, _right, _up, back = camera[:4]
        stages.add("setup", binning["view_depths"](self._entry.queue, (-(-triangles // 64) * 64,), (64,), vertex_buffer,
                                                   owner_buffer, object_buffer, np.uint32(triangles), eye, back,
                                                   depths))
        keys = np.empty(triangles, np.float32)
        stages.add("setup", cl.enqueue_copy(self._entry.queue, keys, depths))
        if self.triangle_order == "back-to-front":
            keys = -keys
        return self._upload("order", np.argsort(keys, kind="stable").astype(np.uint32), stages, "setup")

    def _fragment_counts(self, binned, pixels, stages):
        """Front- and back-facing fragments at depth >= 0 per pixel, ``(pixels, 2)`` uint32."""
        import pyopencl as cl

        counts = self._buffer("counts", 8 * pixels)
        stages.add("count", binned.pixel["count_fragments"](self._entry.queue, binned.global_size, (TILE, TILE),
                                                            *binned.tile_lists, *binned.camera, counts))
        per_pixel = np.empty((pixels, 2), np.uint32)
        stages.add("count", cl.enqueue_copy(self._entry.queue, per_pixel, counts))
        return per_pixel

    def boundary_mesh(self, scene, index=0):
        """The boundary of volume instance ``index`` as the kernels bin it: ``(T, 3, 3)`` object-space vertices.

        The tight hull around the instance's non-empty bricks (``empty_space="hull"``) or its
        box, triangles counter-clockwise seen from outside.
        """
        import pyopencl as cl

        self.check(scene)
        if not 0 <= index < len(scene.volumes):
            raise InputError(f"boundary_mesh index: {index} is not an instance of scene {scene.name!r} "
                             f"(it has {len(scene.volumes)})")
        stages = Stages()
        entry = self._device()
        volumes, _ = scene_arrays.distinct_volumes(scene)
        atlas = self._cache.atlas(volumes, stages)
        hull_kernels = context.kernels(entry, context.kernel_source("common.cl", "hull.cl"), _atlas_defines(atlas.dtype))
        brick = self.brick_size if self.empty_space == "hull" else None
        hull = self._cache.hull(hull_kernels, atlas, scene.volumes[index], brick, self.min_opacity, stages)
        vertices = np.empty((max(hull.triangles, 1) * 3, 4), np.float32)
        cl.enqueue_copy(self._entry.queue, vertices, hull.buffer, is_blocking=True)
        return vertices[:3 * hull.triangles, :3].reshape(hull.triangles, 3, 3)

    def coverage(self, scene):
        """Fragments per pixel of ``scene``'s boundaries, front- and back-facing: ``(H, W, 2)`` uint32.

        The binning's watertightness check (note 002, E11): a closed mesh in front of the camera
        gives every pixel as many front as back fragments, one of each per crossing.
        """
        self.check(scene)
        stages = Stages()
        binned = self._bin(scene, "global", stages)
        return self._fragment_counts(binned, scene.width * scene.height, stages).reshape(scene.height, scene.width, 2)

    def _render(self, scene):
        import pyopencl as cl
        import pyopencl.cltypes as cltypes

        start = time.perf_counter()
        stages = Stages()
        binned = self._bin(scene, self.fragments, stages)
        queue = self._entry.queue
        width, height = scene.width, scene.height
        pixels = width * height
        transfer_buffer = self._upload("transfer", binned.transfer, stages, "setup")
        gradient_buffer = self._upload("gradient_tables", binned.gradient_tables, stages, "setup")
        image = self._buffer("image", 16 * pixels)
        stats = self._buffer("stats", 4 * STATS * pixels)
        # Without volumes nothing is sampled: the step and the atlas are placeholders.
        step = world_step(scene, self.step_factor)
        shading = scene.shading
        light = scene_arrays.light_direction(scene)
        atlas = binned.atlas
        leaves = binned.leaves
        shade_args = (binned.object_buffer, atlas.buffer if atlas else self._buffer("no_atlas", 16),
                      cltypes.make_int4(*(atlas.layout.shape_xyz if atlas else (1, 1, 1)), 0),
                      transfer_buffer, gradient_buffer, np.float32(step or 1.0), np.float32(self.opaque_threshold),
                      cltypes.make_float4(*light, 0),
                      cltypes.make_float4(shading.ambient, shading.diffuse, shading.specular, shading.shininess))
        boundary_volume = np.array(leaves.boundary_volumes or (0,), np.int32)
        leaf_args = (self._upload("materials", leaves.materials, stages, "setup"),
                     self._upload("boundary_volume", boundary_volume, stages, "setup"), np.int32(leaves.count),
                     np.int32(len(leaves.boundary_volumes)),
                     self._upload("csg_nodes", leaves.nodes if len(leaves.nodes) else np.zeros((1, 4), np.int32),
                                  stages, "setup"),
                     self._upload("csg_children", leaves.children if len(leaves.children) else np.zeros(1, np.int32),
                                  stages, "setup"), np.int32(len(leaves.nodes)),
                     *(leaves.masks[key] for key in ("leaves", "volumes", "surfaces", "media", "trees")),
                     binned.eye_inside)
        list_args = ()
        unpaired = None
        if self.fragments == "global":
            facing = self._fragment_counts(binned, pixels, stages)
            unpaired = int(np.count_nonzero(facing[:, 0] != facing[:, 1]))
            offsets = np.concatenate([[0], np.cumsum(facing.sum(axis=1))])
            total = int(offsets[-1])
            list_args = (self._upload("offsets", offsets.astype(np.uint32), stages, "count"),
                         self._buffer("list_depth", 4 * total), self._buffer("list_code", 4 * total))
        stages.add("pixel", binned.pixel["cast_tiles"](queue, binned.global_size, (TILE, TILE), *binned.tile_lists,
                                                       *binned.camera, *shade_args, *leaf_args, *list_args, image,
                                                       stats))
        result = np.empty((height, width, 4), np.float32)
        per_pixel = np.empty((pixels, STATS), np.uint32)
        records_per_tile = np.empty(binned.global_size[0] * binned.global_size[1] // (TILE * TILE), np.uint32)
        stages.add("readback", cl.enqueue_copy(queue, result, image, is_blocking=False))
        stages.add("readback", cl.enqueue_copy(queue, per_pixel, stats, is_blocking=False))
        stages.add("readback", cl.enqueue_copy(queue, records_per_tile, binned.tile_lists[0], is_blocking=False))
        queue.finish()
        seconds = stages.seconds()
        total_time = time.perf_counter() - start

        self._last_step = None if scene.mode == "iso" else step
        kept = per_pixel[:, 0]
        hit = kept > 0
        records = np.minimum(records_per_tile, CHUNK * MAX_CHUNKS)
        chunks_used = int(binned.bin_counters[0])
        # The preprocessing stages only where this frame built them (the timing harness times them once).
        timings = {stage: seconds[stage] for stage in PREPROCESSING if stage in seconds}
        timings.update({stage: seconds.get(stage, 0.0) for stage in ("setup", "binning", "count", "pixel", "readback")})
        timings["total"] = total_time
        counters = {
            "rays": pixels,
            "rays_hit": int(hit.sum()),
            "triangles": binned.triangles,
            "records": int(records.sum()),
            "records_per_tile_max": int(records.max(initial=0)),
            "records_per_tile_mean": float(records[records > 0].mean()) if records.any() else 0.0,
            "records_dropped": int(binned.bin_counters[1]),
            "pool_chunks": self._pool_chunks,
            "pool_chunks_used": chunks_used,
            "fragments": int(kept.sum()),
            "fragments_max": int(kept.max(initial=0)),
            "fragments_mean": float(kept[hit].mean()) if hit.any() else 0.0,
            "fragments_dropped": int(per_pixel[:, 1].sum()),
            "sort_moves": int(per_pixel[:, 4].sum(dtype=np.int64)),
            "samples": int(per_pixel[:, 2].sum()),
            "medium_steps": int(per_pixel[:, 5].sum()),
            "early_terminations": int(per_pixel[:, 3].sum()),
        }
        if unpaired is not None:
            counters["unpaired_pixels"] = unpaired
        if scene.mode == "iso":
            counters["iso_cells_solved"] = int(per_pixel[:, 6].sum(dtype=np.int64))
            counters["crossings"] = int(per_pixel[:, 7].sum())
        iso = scene.mode == "iso"
        info = {
            "step": None if iso else step,
            "step_factor": self.step_factor,
            "fragments": self.fragments,
            "depth_cap": self.depth_cap if self.fragments == "local" else None,
            "tile": TILE,
            "empty_space": self.empty_space,
            "triangle_order": self.triangle_order,
            "media": self.media,
            "coverage": self.coverage_method,
            "stop_after": self.stop_after,
            "hull_triangles": [h.triangles for h in binned.hulls],
            "objects": leaves.objects,
            "csg_nodes": len(leaves.nodes),
            "binning_passes": binned.passes,
            "pool_bytes_used": chunks_used * CHUNK * 12,
            "atlas_shape_xyz": list(atlas.layout.shape_xyz) if atlas else None,
            "atlas_dtype": str(atlas.dtype) if atlas else None,
            "atlas_bytes": atlas.nbytes if atlas else 0,
            "blending": BLENDING[scene.mode],
            "rasterisation": "homogeneous" if binned.homogeneous else "integer",
            "eye_inside": int(binned.eye_inside),
            "shading_applied": binned.phong,
            "built": sorted(stage for stage in ("upload", "bricks", "hull") if stage in seconds),
        }
        return RenderResult(image=result, timings=timings, counters=counters, info=info)
