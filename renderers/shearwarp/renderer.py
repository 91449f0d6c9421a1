"""Shear-warp volume rendering (Lacroute 1995), CPU, Numba: the ``shearwarp`` backend.

The parallel-projection algorithm of the thesis's §4.1 with its Ch. 6 multiprocessor scheme:

1. **View matrix.** ``M_view = M_image · V · T · S`` maps voxel indices to image pixels: ``S`` puts
   voxel ``(i, j, k)`` at its cell centre ``((i + ½)·s_x, …)`` (spacing folded in), ``T`` is the
   instance's object→world transform (any invertible affine map), ``V`` the camera's world→view
   matrix and ``M_image`` the orthographic projection onto pixels (``x`` right, ``y`` down, pixel
   centres at half-integers, the same rays as :meth:`core.camera.Camera.rays`). The framing
   therefore matches the reference renderer pixel for pixel.
2. **Factorization** (:mod:`.factor`): principal axis, permutation, shear, translation, warp.
3. **Classification** (:mod:`.classify`, cached per volume, classification and lens, timed as
   ``classify``): voxels are *pre-classified* at their centres (opacity ``α_tf(s)·g(u)``, colour
   index, 13-bit normal), where the reference renderer classifies after interpolation; this is
   shear-warp's documented difference (thesis §4.1.4). Three run-length encodings, one per
   principal axis, each with a run index (a cursor checkpoint every 32 voxels of a scanline) and
   each scanline's extent (``rle_build``); with ``rle=False`` three unencoded copies in the same
   format. With ``classification="octree"`` a min-max octree and the unclassified voxel array
   instead, the voxels classified where compositing reaches them (:mod:`.octree`).
4. **Per frame**, every kernel on ``workers`` threads: the opacity-correction table
   (``opacity_table``, ``Δ/Δ0`` from the world length of the ray step between two slices), the
   shading table (``shade_table``: Blinn–Phong over the 8193 normal codes, rebuilt every frame, as a
   new viewpoint needs), ``composite`` (:mod:`.composite`; each task clears its own rows of the
   intermediate image first), ``warp`` (:mod:`.warp`).

Choices and limits
------------------
* **Anisotropic spacing and affine transforms** are folded into ``M_view``; the factorization
  handles any affine view, so both are supported without resampling the volume. The thesis
  prescales anisotropic volumes instead: here the sampling stays one sample per slice along the
  principal axis and one per voxel inside a slice, so a strongly anisotropic or stretched volume
  is sampled more coarsely along its long axis than the reference's quarter-voxel steps.
* **Boundaries.** Outside a slice the classified volume is transparent (the bilinear footprint
  fades over half a voxel past the edge voxels), where the reference clamps to the edge up to the
  box face; images differ only where edge voxels are not transparent.
* **Sampling.** One sample per slice, on the slice plane, bilinear in the slice; intermediate
  pixels are one voxel apart and the warp (bilinear) resamples them to the picture.
* **Opacity quantisation.** Stored opacities are 8-bit (VolPack's layout); the correction table is
  indexed by them.
* ``mip`` and ``iso`` are not implemented (see :attr:`ShearWarpRenderer.capabilities`).

Perspective (thesis §4.2)
-------------------------
The projective view matrix is factored with the eye, a per-slice scale ``f_k <= 1`` (front slice
1) and a projective warp (:mod:`.factor`); slices are composited with the area-averaging box
filter, per-pixel opacity correction (interpolated tables) and the same run-length skipping and
early termination (:mod:`.perspective`), then warped projectively (:mod:`.warp`). Differences
from the reference, all the thesis's: decimated slices are averaged before compositing (the
visibility error of §4.2.5: thin opaque structures averaged with empty space let what lies
behind them show through); the LUT's specular half vector uses the central ray's view direction
for every pixel (the reference uses each ray's); where no single principal axis covers every
ray within 45° the thesis splits the volume, here one axis is kept (``info["max_ray_angle"]``),
and an eye inside the volume is refused.

Lenses (Ropinski et al. 2005, by per-voxel pre-classification)
--------------------------------------------------------------
The object-order contrast to the paper's per-ray segments (note 004): a lens scene's voxels are
classified once, each with the lens's appearance when its centre (placed in the world by the
instance transform) lies in the lens, else with the volume's table (:mod:`.classify`); a ``clip``
lens makes its voxels transparent, a ``dvr`` lens classifies them with its own opacity and
gradient-opacity tables and colours them from its own table (a record bit picks the colour row).
Compositing, early termination, the encodings and both projections are unchanged, so a ``dvr``
lens whose appearance equals the outside gives the no-lens image bit for bit, in every option
set. The classified volume depends on the lens, so the lens (the frozen :class:`~core.lens.Lens`
object: shape, placement, appearance) and the instance transform are part of the cache key:
moving the lens re-runs ``classify`` and ``rle_build`` (``sat_build`` with the octree), timed as
today; with the octree a node is transparent only where the volume's and a ``dvr`` lens's tables
both make it so, and the octree-built encodings stay byte-identical to the brute-force ones.

Where it differs from the reference, which classifies each sample by where it lies on the ray:
the lens boundary is the voxel grid's, resampled bilinearly in the slices, so it is off by about
a voxel. ``mip`` and ``iso`` lens appearances are refused (a segment's maximum or first crossing
is a per-ray quantity no voxel classification expresses), and so is a lens table with its own
reference step (one opacity-correction table per view). Measured against the reference
(``tests/test_shearwarp_lens.py``; a 32³ blob, 48², ``min_opacity=0``; PSNR, max abs error):

=============================  ====================  ==========================
scene                          orthographic, az 30°  perspective, az −50°, Phong
=============================  ====================  ==========================
no lens                        37.9 dB, 0.180        40.7 dB, 0.162
sphere, clip                   37.7 dB, 0.180        41.1 dB, 0.149
sphere, dvr ×0.2 opacity       38.0 dB, 0.180        41.4 dB, 0.149
sphere, dvr, gradient opacity  37.7 dB, 0.180        41.2 dB, 0.149
rotated box, highlight dvr     36.6 dB, 0.154        39.6 dB, 0.149
=============================  ====================  ==========================

The lens moves the PSNR by −1.3 to +0.7 dB (the box's highlight table changes colour across its
faces, where the voxel boundary shows most); the largest errors stay the box edges' of the
no-lens image. With the default ``min_opacity=0.05`` the ×0.2 transparency lens falls to 35.4 dB
(perspective) and 38.2 dB (orthographic) against 41.7 and 38.6 without a lens: its scaled
opacities drop under the threshold, shear-warp's own approximation, not the lens's. A clip lens
over a homogeneous medium (16³, ``σ = 0.105`` per voxel) against Beer–Lambert over the path
outside it: largest alpha error 0.043 head-on (0.006 without a lens) and 0.071 at azimuth 30°
(0.061 without a lens, at the box's edges), under one voxel of medium.
"""

import time
from dataclasses import dataclass

import numpy as np

from core.errors import InputError, UnsupportedFeatureError
from renderers.base import Capabilities, Option, RenderResult, Renderer
from renderers.base.probes import numba_probe

SCHEDULES = ("contiguous", "round-robin", "contiguous-steal", "round-robin-steal")
SHADING_OPTIONS = ("lut", "procedural")
UNIONS = ("path-compression", "rank")
CLASSIFICATIONS = ("rle", "octree")
OCTREE_CACHE_SIZE = 2
"""Min-max octrees kept per renderer (one per volume), most recent first."""
CLASSIFICATION_CACHE_SIZE = 4
"""Classified volumes (with their encodings) kept per renderer, most recent first."""


def view_matrix(scene, instance):
    """4×4 voxel-index → image-pixel matrix of ``instance`` in ``scene`` (module notes).

    Orthographic: affine, ``z`` the depth. Perspective: projective, image ``x = X/W``,
    ``y = Y/W`` with ``W`` the depth in front of the eye and ``z = −1/depth`` (increasing away from
    the eye, nonsingular); the rays are those of :meth:`core.camera.Camera.rays`.
    """
    camera = scene.camera
    if camera.projection not in ("orthographic", "perspective"):
        raise InputError(f"shearwarp: unknown camera projection {camera.projection!r}")
    sx, sy, sz = instance.volume.spacing
    index_to_object = np.array([[sx, 0, 0, 0.5 * sx], [0, sy, 0, 0.5 * sy], [0, 0, sz, 0.5 * sz], [0, 0, 0, 1.0]])
    if camera.projection == "perspective":
        # x_view/depth = px·tan(fov/2)·W/H over the picture, depth = −z_view (camera.rays).
        scale = 0.5 * scene.height / np.tan(np.radians(camera.fov_y) / 2)
        to_image = np.array([
            [scale, 0.0, -0.5 * scene.width, 0.0],
            [0.0, -scale, -0.5 * scene.height, 0.0],
            [0.0, 0.0, 0.0, -1.0],
            [0.0, 0.0, -1.0, 0.0],
        ])
        return to_image @ camera.view_matrix() @ instance.transform @ index_to_object
    scale = scene.height / camera.view_height  # pixels per world unit, the same along x and y
    to_image = np.array([
        [scale, 0.0, 0.0, 0.5 * scene.width],
        [0.0, -scale, 0.0, 0.5 * scene.height],
        [0.0, 0.0, -1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ])
    return to_image @ camera.view_matrix() @ instance.transform @ index_to_object


@dataclass
class _Classification:
    volume: object
    transfer_function: object
    gradient_opacity: object
    reference_step: float
    classified: object  # classify.Classified, or None when the octree classifies (classification="octree" etc.)
    encodings: dict  # (encoded: bool) -> tuple of 3 Encoding
    procedural: bool = False  # built with per-voxel gradients kept
    octree_classification: object = None  # octree.OctreeClassification (SAT + node statuses) or None
    lens: object = None  # the core.lens.Lens it was classified with (frozen: shape, placement, appearance)
    transform: object = None  # with a lens, the instance transform that placed the voxels in it

    def matches(self, instance, lens, procedural):
        """Whether this entry is ``instance``'s classification with ``lens`` (gradients kept if ``procedural``)."""
        return (self.volume is instance.volume and self.transfer_function is instance.transfer_function
                and self.gradient_opacity is instance.gradient_opacity
                and self.reference_step == instance.reference_step and (self.procedural or not procedural)
                and self.lens is lens and (lens is None or np.array_equal(self.transform, instance.transform)))


class ShearWarpRenderer(Renderer):
    """Shear-warp renderer (Lacroute 1995) with run-length-encoded volume and image, Numba.

    Notes
    -----
    Timings: ``classify`` and ``rle_build`` (only in the frame that builds them; cached per volume,
    classification and lens afterwards), ``shade_table``, ``opacity_table``, ``composite``,
    ``warp``, ``total``. Counters: ``samples`` (resampled and composited positions),
    ``voxel_runs`` (runs the scanline cursors walked; a skip over opaque pixels jumps by the run
    index instead), ``pixel_run_finds``, ``pixel_run_creates``, ``skipped_early_termination``
    (samples skipped because their pixel was opaque), ``rle_bytes`` (the three per-axis copies the
    frame reads: run lengths, 4-byte voxel records, per-scanline offsets and run index; with
    ``rle=False`` the unencoded copies), ``raw_bytes`` (the volume's scalars).
    With ``classification="octree"`` or ``octree_rle_build``: ``octree_build`` (once per volume: the
    octree and the unclassified voxel array) and ``sat_build`` (summed-area table and node statuses,
    once per classification) replace ``classify``; ``"octree"`` builds no ``rle_build`` and adds to
    every frame ``octree_runs`` (the view axis's candidate runs; the voxels are classified inside
    ``composite`` as it reaches them) or, with a perspective view, a lens or procedural shading,
    ``octree_classify`` (the runs and every candidate voxel classified before compositing). Counters
    then add ``octree_nodes``, ``octree_bytes``, ``classified_on_the_fly`` (voxels classified in this
    frame, 0 when nothing was built) and, in ``"octree"`` mode, ``candidate_voxels`` (voxels in the
    candidate runs) and ``voxel_array_bytes``; ``rle_bytes`` is then the one per-frame encoding.
    ``info["worker_tasks"]`` and ``info["worker_samples"]`` give each worker's share (a load-balance
    measure), ``info["worker_busy"]`` the workers' mean busy share over the compositing (CPU time of
    the process over wall time × workers; per-worker busy time is not measured inside the kernel).
    """

    technique_stages = ("octree_runs", "octree_classify", "opacity_table", "shade_table", "composite", "warp")
    """The stages that are the technique itself: the octree's runs (fast classification), the per-view
    opacity and shading tables, compositing (each task clears its rows first) and the warp: the kernels;
    not the view factorisation, buffers or Python around them."""

    name = "shearwarp"
    description = ("Shear-warp factorization (Lacroute 1995), CPU Numba: pre-classified RLE volume ×3, "
                   "RLE image with early termination, bilinear slices + 2-D warp")
    capabilities = Capabilities(
        projections=frozenset({"orthographic", "perspective"}),
        shading=frozenset({"none", "phong"}),
        gradient_opacity=True,
        transforms=True,
        lenses=True,
        reasons={
            "modes": "only dvr compositing is implemented (mip would need a max operator in the slice loop)",
            "max_volumes": ("shear-warp composites one volume's slices in storage order; several overlapping "
                            "volumes would need a shared slice order (not in the thesis)"),
            "meshes": "shear-warp has no polygon pass (thesis §7.4 sketches one, not implemented)",
            "lenses": ("one clip or dvr lens, by per-voxel pre-classification: a voxel whose centre lies in the lens "
                       "is classified with the lens's appearance, so the lens boundary is the voxel grid's, resampled "
                       "bilinearly in the slices (about a voxel from the reference's per-sample boundary); moving the "
                       "lens re-classifies and re-encodes the volume; mip and iso lens appearances are refused (they "
                       "are per-ray quantities)"),
            "camera_inside_volume": ("perspective shear-warp needs every ray to cross the slices from one side of the "
                                     "volume (thesis §4.2.5 would split the volume into pyramidal sub-volumes "
                                     "around the eye; not implemented): move the camera out of the volume"),
        },
    )
    option_table = (
        Option("rle", bool, True, "Skip transparent voxels with the run-length-encoded classified volume (three "
               "copies). ``False``: brute force over the whole classified volume, every voxel resampled."),
        Option("early_termination", bool, True,
               "Skip opaque intermediate pixels with the run-length-encoded image (skip links, FIND)."),
        Option("opaque_threshold", float, 0.95, "A pixel whose opacity is at or above it is opaque (thesis: 0.95).",
               low=0, high=1, low_open=True),
        Option("min_opacity", float, 0.05,
               "Voxels with ``α <= min_opacity`` are transparent for the encoding (thesis: 0.05).",
               low=0, high=1, high_open=True),
        Option("opacity_correction", bool, True,
               "Correct opacities for the per-view sample spacing, ``1 − (1 − α)^(Δ/Δ0)``."),
        Option("shading", str, "lut", "Phong through a per-frame table over 13-bit quantised normals, or computed "
               "per voxel from its gradient (applies when the scene's shading model is ``phong``).",
               choices=SHADING_OPTIONS),
        Option("workers", int, None, "Threads; ``None``: the threads Numba may use in this thread now "
               "(``numba.get_num_threads()``: the cores the job was given), which ``options`` records.", low=1),
        Option("schedule", str, "round-robin-steal",
               "How intermediate-image scanline tasks are dealt to the workers (thesis Ch. 6).", choices=SCHEDULES),
        Option("task_size", int, 8, "Intermediate-image scanlines per task.", low=1),
        Option("union", str, "path-compression", "Union-find variant of the run-length-encoded image (§4.1.3).",
               choices=UNIONS),
        Option("classification", str, "rle",
               "``rle``: classify the volume and build the three RLE copies once per volume and classification "
               "(viewing mode). ``octree``: the thesis's fast classification (§4.3): a min-max octree and an "
               "unclassified voxel array (16 bytes a voxel) once per volume, a summed-area table per "
               "classification, and every frame the view axis's voxel runs from the octree with their voxels "
               "classified where compositing reaches them (same image as ``rle``, more samples; for interactive "
               "transfer-function edits). Needs ``rle=True``.", choices=CLASSIFICATIONS),
        Option("octree_rle_build", bool, False,
               "Build the three RLE copies from the min-max octree (the thesis's mode switch, §4.4): transparent "
               "octree nodes are skipped without classifying their voxels; the encodings are byte-identical to the "
               "brute-force build. Off by default so that the ``classify`` and ``rle_build`` stages keep measuring "
               "the plain build; applies to ``classification=\"rle\"`` with ``rle=True``."),
        Option("octree_threshold", int, 4, "Octree nodes whose scalar and gradient-magnitude ranges are both within "
               "this many of 256 bins keep no children (thesis: 4).", low=0),
        Option("octree_base_size", int, 4, "Voxels per side of the smallest octree node (thesis: 4).", low=1),
    )
    quality_sweep = (
        {},
        {"early_termination": False},
        {"rle": False, "early_termination": False},
        {"opaque_threshold": 0.99},
        {"opaque_threshold": 0.999, "min_opacity": 0.0},
    )
    """Option sets from fast to exact: thesis defaults; no early termination (exact up to the
    encoding); brute force (same image as the previous one); a stricter opaque threshold; and
    nothing skipped but exactly-zero voxels. (``classification="octree"`` is not a quality level:
    it renders the same image as the default, only its speed differs.)"""
    scheduling_dependent = ("worker_tasks", "worker_samples", "worker_busy")
    """With a ``-steal`` schedule a worker that finishes its queue takes tasks from the others', so
    each worker's share follows which thread ran when (on a busy machine one worker may do all of
    it); the image and the totals do not change."""

    def __init__(self, **options):
        import numba

        super().__init__(**options)
        if not self.rle and (self.classification == "octree" or self.octree_rle_build):
            raise InputError("shearwarp option rle=False (brute force over every voxel) cannot be combined with "
                             f"classification={self.classification!r}, octree_rle_build={self.octree_rle_build!r}: "
                             "the octree only builds run-length encodings; use rle=True or classification='rle' "
                             "without octree_rle_build")
        if self.classification == "octree" and self.octree_rle_build:
            raise InputError("shearwarp option octree_rle_build=True does nothing with classification='octree' "
                             "(no RLE copies are built); drop it or use classification='rle'")
        limit = numba.config.NUMBA_NUM_THREADS
        if self.workers is None:
            # Not NUMBA_NUM_THREADS: a warm render worker is started with every core's threads and
            # lowered to the job's share (one core for an untimed job) before each request.
            self.workers = numba.get_num_threads()
        elif self.workers > limit:
            raise InputError(f"shearwarp option workers: {self.workers} is more than Numba's {limit} threads "
                             "(NUMBA_NUM_THREADS); choose at most that many or raise NUMBA_NUM_THREADS")
        self._cache = []
        self._octrees = []
        self._buffers = {}
        self._queues = {}
        self._last_octree_classified = 0
        self._last_info = {}
        # Importing the kernels compiles them (or loads numba's cache) here, not in the first frame.
        from renderers.shearwarp import classify, composite, factor, octree, perspective, warp

        self._classify_module, self._composite_module, self._factor_module, self._warp_module = (
            classify, composite, factor, warp)
        self._octree_module = octree
        self._perspective_module = perspective

    def check(self, scene):
        """Also refuse, before any work, a lens appearance pre-classification cannot render."""
        super().check(scene)
        if not scene.lenses:
            return
        lens = scene.lenses[0]
        appearance = lens.appearance
        if appearance.mode in ("mip", "iso"):
            raise UnsupportedFeatureError(
                self.name, f"a {appearance.mode!r} lens appearance",
                "shear-warp composites pre-classified voxel colours slice by slice; a lens segment's "
                f"{'maximum' if appearance.mode == 'mip' else 'first isovalue crossing'} is a per-ray quantity that no "
                "voxel classification expresses; use a clip or dvr lens")
        instance = scene.volumes[0]
        tf = appearance.classification(instance.transfer_function)
        if tf is None:
            return
        inside = instance.volume.min_spacing if tf.reference_step is None else tf.reference_step
        if inside != instance.reference_step:
            raise UnsupportedFeatureError(
                self.name, f"lens {lens.name!r} with reference step {inside:g}",
                "shear-warp corrects every stored opacity with one per-view table, for the volume's reference step "
                f"{instance.reference_step:g}; give the lens's transfer function the volume's reference_step")

    @classmethod
    def probe(cls):
        return numba_probe()

    def environment(self):
        import numba

        return {"numba": numba.__version__, "numba_threads": numba.get_num_threads(),
                "numba_threading_layer": numba.config.THREADING_LAYER}

    caches_preprocessing = True

    def drop_caches(self):
        self._cache = []
        self._octrees = []

    def close(self):
        self.drop_caches()
        self._buffers = {}

    # -----------------------------------------------------------------------------------------
    # Cached preprocessing

    def _classification(self, instance, procedural, timings, lens=None):
        """The cached classified volume of ``instance`` with ``lens`` (built and timed as ``classify`` if new).

        A lens is part of the key (the same :class:`~core.lens.Lens` object, which is frozen: its
        shape, placement and appearance; and the instance transform that placed the voxels in
        it): a moved or re-dressed lens is a new classification and new encodings.
        """
        volume, tf, go = instance.volume, instance.transfer_function, instance.gradient_opacity
        step = instance.reference_step
        for entry in self._cache:
            if entry.matches(instance, lens, procedural):
                self._cache.remove(entry)
                self._cache.insert(0, entry)
                return entry
        transform = None if lens is None else instance.transform.copy()
        if self._uses_octree:
            tree = self._octree(volume, timings)
            start = time.perf_counter()
            lensed = self._lens_classification(lens, instance)
            sat = self._octree_module.classify_octree(tree, tf, go, step, self.min_opacity, lens=lensed)
            timings["sat_build"] = time.perf_counter() - start
            entry = _Classification(volume, tf, go, step, None, {}, procedural, sat, lens, transform)
        else:
            start = time.perf_counter()
            lensed = self._lens_classification(lens, instance)
            classified = self._classify_module.classify(
                volume.normalized(np.float32), volume.spacing, tf, go, step, self.min_opacity, gradients=procedural,
                lens=lensed)
            timings["classify"] = time.perf_counter() - start
            entry = _Classification(volume, tf, go, step, classified, {}, procedural, lens=lens, transform=transform)
        self._cache.insert(0, entry)
        del self._cache[CLASSIFICATION_CACHE_SIZE:]
        return entry

    def _lens_classification(self, lens, instance):
        """``lens`` placed over ``instance``'s voxels for the classification kernels (``None`` without one)."""
        if lens is None:
            return None
        return self._classify_module.lens_classification(lens, instance.transform, instance.volume.spacing,
                                                         instance.transfer_function)

    @property
    def _uses_octree(self):
        return self.classification == "octree" or self.octree_rle_build

    def _octree(self, volume, timings):
        """The cached min-max octree of ``volume`` (built and timed as ``octree_build`` if new)."""
        for tree_volume, tree in self._octrees:
            if tree_volume is volume:
                return tree
        start = time.perf_counter()
        tree = self._octree_module.build_octree(volume.normalized(np.float32), volume.spacing,
                                                base_size=self.octree_base_size, threshold=self.octree_threshold)
        timings["octree_build"] = time.perf_counter() - start
        self._octrees.insert(0, (volume, tree))
        del self._octrees[OCTREE_CACHE_SIZE:]
        return tree

    def _encodings(self, entry, timings):
        """The three per-axis copies (RLE, or unencoded for ``rle=False``), built and timed as ``rle_build``."""
        copies = entry.encodings.get(self.rle)
        if copies is None and entry.classified is None:  # the mode switch: RLE copies from the octree
            start = time.perf_counter()
            tree = self._octree(entry.volume, timings)
            built = [self._octree_module.encode(tree, entry.octree_classification, axis, exact=True,
                                                gradients=entry.procedural) for axis in range(3)]
            copies = tuple(enc for enc, _ in built)
            entry.encodings[self.rle] = copies
            timings["rle_build"] = time.perf_counter() - start
            self._last_octree_classified = sum(stats.classified for _, stats in built)
            return copies
        if copies is None:
            start = time.perf_counter()
            build = self._classify_module.encode if self.rle else self._classify_module.dense_encoding
            copies = tuple(build(entry.classified, axis) for axis in range(3))
            entry.encodings[self.rle] = copies
            timings["rle_build"] = time.perf_counter() - start
        return copies

    # -----------------------------------------------------------------------------------------
    # Per-frame buffers

    def _buffer(self, name, size, dtype):
        buffer = self._buffers.get(name)
        if buffer is None or buffer.size < size:
            buffer = np.empty(max(size, 1), dtype=dtype)
            self._buffers[name] = buffer
        return buffer[:size]

    def _task_queues(self, n_tasks):
        key = (n_tasks, self.workers, self.schedule)
        queues = self._queues.get(key)
        if queues is None:
            workers = self.workers
            if self.schedule.startswith("contiguous"):
                bounds = [w * n_tasks // workers for w in range(workers + 1)]
                lists = [list(range(bounds[w], bounds[w + 1])) for w in range(workers)]
            else:
                lists = [list(range(w, n_tasks, workers)) for w in range(workers)]
            tasks = np.array([t for lst in lists for t in lst], dtype=np.int64)
            start = np.cumsum([0] + [len(lst) for lst in lists]).astype(np.int64)
            queues = (tasks, start)
            self._queues = {key: queues}
        return queues

    # -----------------------------------------------------------------------------------------

    def _render(self, scene):
        import numba

        # Every kernel of the frame (the octree's runs, the tables, compositing, the warp) runs on
        # ``workers`` threads: a one-worker frame takes one core, whatever else the machine runs.
        previous_threads = numba.get_num_threads()
        numba.set_num_threads(self.workers)
        try:
            return self._frame(scene)
        finally:
            numba.set_num_threads(previous_threads)

    def _frame(self, scene):
        composite = self._composite_module
        start = time.perf_counter()
        timings = {}
        instance = scene.volumes[0]
        phong = scene.shading.model == "phong"
        procedural = phong and self.shading == "procedural"
        m_view = view_matrix(scene, instance)
        perspective = scene.camera.projection == "perspective"
        fact = self._factor_module.factorize(m_view, instance.volume.shape_xyz, perspective=perspective)
        lens = scene.lenses[0] if scene.lenses else None
        entry = self._classification(instance, procedural, timings, lens)
        self._last_octree_classified = 0
        # Fast classification (§4.3): this view axis's candidate runs from the octree every frame. Lazily
        # (the thesis's Fig. 4.17 with a parallel projection) the compositing loop classifies only the voxels
        # it reaches; a perspective view, a lens or procedural shading classify every candidate first.
        lazy = self.classification == "octree" and not (perspective or lens is not None or procedural)
        nontransparent = None
        if lazy:
            tree = self._octree(instance.volume, timings)
            t0 = time.perf_counter()
            voxel_runs = self._octree_module.voxel_runs(tree, entry.octree_classification, fact.axis)
            timings["octree_runs"] = time.perf_counter() - t0
            encodings = (voxel_runs,)
        elif self.classification == "octree":
            tree = self._octree(instance.volume, timings)
            t0 = time.perf_counter()
            enc, octree_stats = self._octree_module.encode(tree, entry.octree_classification, fact.axis, exact=False,
                                                           gradients=procedural)
            timings["octree_classify"] = time.perf_counter() - t0
            encodings = (enc,)
            self._last_octree_classified = octree_stats.classified
            nontransparent = octree_stats.nontransparent
        else:
            encodings = self._encodings(entry, timings)
            enc = encodings[fact.axis]
            nontransparent = (entry.classified.nontransparent if entry.classified is not None
                              else int(encodings[0].voxels.size))
        colour_table = (entry.classified.colour_table if entry.classified is not None
                        else entry.octree_classification.colour_table)
        n_i, n_j, n_k = fact.shape_ijk
        height, width = fact.intermediate_shape

        slices = fact.slices_front_to_back().astype(np.int64)
        linear = instance.transform[:3, :3]
        if perspective:
            # Per-slice scale and offset; per-pixel opacity correction (interpolated tables, §4.2.3).
            scales = np.ascontiguousarray(fact.slice_scale(np.arange(n_k)))
            u0, v0 = (np.ascontiguousarray(a) for a in fact.slice_offset(np.arange(n_k)))
            fmax = 2 + int(np.ceil(1.0 / scales.min()))
            t0 = time.perf_counter()
            vv, uu = np.mgrid[0:height, 0:width]
            step_ijk = fact.ray_step_ijk(uu, vv)
            step_xyz = np.empty_like(step_ijk)
            step_xyz[..., list(self._factor_module.axes_ijk(fact.axis))] = step_ijk
            step_world = (step_xyz * np.asarray(instance.volume.spacing)) @ linear.T
            ratios = np.linalg.norm(step_world, axis=-1) / instance.reference_step
            optabs, pix_table, pix_weight = self._perspective_module.opacity_tables(ratios, self.opacity_correction)
            t1 = time.perf_counter()
            timings["opacity_table"] = t1 - t0
            ratio = float(ratios.mean()) if ratios.size else 1.0
        else:
            # Per-slice offsets and bilinear weights (constant over a slice).
            u0, v0 = fact.slice_offset(np.arange(n_k))
            iu = np.floor(u0).astype(np.int64)
            iv = np.floor(v0).astype(np.int64)
            fu = u0 - iu
            fv = v0 - iv
            weights = np.ascontiguousarray(np.stack([(1 - fu) * (1 - fv), (1 - fu) * fv, fu * (1 - fv), fu * fv],
                                                    axis=1))

            # Opacity correction: world length of the ray step between two slices over Δ0.
            step_world = linear @ (np.asarray(instance.volume.spacing) * fact.step_xyz())
            ratio = float(np.linalg.norm(step_world) / instance.reference_step)
            t0 = time.perf_counter()
            optab = composite.opacity_table(ratio, self.opacity_correction)
            t1 = time.perf_counter()
            timings["opacity_table"] = t1 - t0

        # Shading: light and half vector in world space, normals by the normal matrix A^{-T}.
        right, up, back = scene.camera.basis()
        lx, ly, lz = scene.shading.light_direction
        light = lx * right + ly * up + lz * back
        half = light + back
        half_norm = np.linalg.norm(half)
        has_half = bool(half_norm > 0)
        half = half / half_norm if has_half else half
        normal_matrix = np.ascontiguousarray(np.linalg.inv(linear).T)
        params = np.array([scene.shading.ambient, scene.shading.diffuse, scene.shading.specular,
                           scene.shading.shininess])
        shade_mode = composite.SHADE_NONE
        shadetab = self._buffer("shade", composite.NORMAL_CODES * 2, np.float64).reshape(-1, 2)
        if phong:
            if self.shading == "lut":
                shade_mode = composite.SHADE_LUT
                t0 = time.perf_counter()
                composite.shade_table(normal_matrix, light, half, has_half, params, out=shadetab,
                                      workers=self.workers)
                timings["shade_table"] = time.perf_counter() - t0
            else:
                shade_mode = composite.SHADE_PROCEDURAL
        timings.setdefault("shade_table", 0.0)

        image = self._buffer("image", height * width * 4, np.float32).reshape(height, width, 4)
        link = self._buffer("link", height * (width + 1), np.int32).reshape(height, width + 1)
        rank = self._buffer("rank", height * (width + 1), np.uint8).reshape(height, width + 1)
        runend = self._buffer("runend", height * (width + 1), np.int32).reshape(height, width + 1)
        n_tasks = -(-height // self.task_size)
        counters = self._buffer("counters", n_tasks * composite.N_COUNTERS, np.int64).reshape(n_tasks, -1)
        queue_tasks, queue_start = self._task_queues(n_tasks)
        queue_next = queue_start[:-1].copy()
        worker_stats = np.zeros((self.workers, 2), dtype=np.int64)
        # Each feature an option turns off is passed to the kernels as None: they are compiled without its code.
        gradients = enc.gradients if shade_mode == composite.SHADE_PROCEDURAL and not lazy else None
        if lazy:
            # Runs and extents per block of scanlines, no records (classified from the voxel array as
            # compositing reaches them) and no run index (a block's few runs are walked).
            scan_k, scan_j = voxel_runs.scanline_tables()
            blocks = voxel_runs.extents.shape[0]
            lengths, run_offsets, extents = voxel_runs.lengths, voxel_runs.run_offsets, voxel_runs.extents
            data_offsets = np.zeros(blocks + 1, np.int64)
            run_index = np.zeros((blocks, 0, 3), np.uint16)
            records = np.zeros(0, np.uint32)
            octree_classification = entry.octree_classification
            raw_voxels = tree.voxels.reshape(-1)
            classification_tables = (octree_classification.alpha_table, octree_classification.gradient_table,
                                     octree_classification.reference_step, octree_classification.min_opacity,
                                     octree_classification.voxel_visible)
            _, ny, nx = tree.voxels.shape  # padded
            object_strides = (1, nx, nx * ny)  # of x, y, z in the [z, y, x] voxel array
            strides = tuple(object_strides[a] for a in self._factor_module.axes_ijk(fact.axis))
        else:
            scan_k, scan_j = np.arange(n_k, dtype=np.int64) * n_j, np.arange(n_j + 1, dtype=np.int64)
            lengths, run_offsets, data_offsets, run_index, records = (enc.lengths, enc.run_offsets, enc.data_offsets,
                                                                      enc.run_index, enc.voxels)
            extents = enc.extents if enc.encoded else None  # brute force: every position
            raw_voxels = None
            classification_tables = (np.zeros(2), np.zeros(0), 1.0, 0.0, np.zeros((0, 0), np.uint8))
            strides = (0, 0, 0)

        t1 = time.perf_counter()
        cpu1 = time.process_time()
        if perspective:
            row_extents = None  # the warp finds them
            self._perspective_module.composite(
                self.workers, self.schedule.endswith("-steal"), self.task_size, queue_tasks, queue_start,
                queue_next, worker_stats, slices, scales, u0, v0, fmax, n_i, n_j, enc.lengths, enc.run_offsets,
                enc.data_offsets, enc.voxels, np.zeros((0, 3), np.float32) if gradients is None else gradients,
                optabs, pix_table, pix_weight, colour_table, shadetab,
                shade_mode, normal_matrix, light, half, has_half, params, self.early_termination,
                self.opaque_threshold, self.union == "rank", enc.encoded, image, link, rank, runend, counters)
        else:
            early = self.early_termination
            by_rank = early and self.union == "rank"
            row_extents = self._buffer("row_extents", height * 2, np.int64).reshape(height, 2)
            composite.composite(
                self.workers, self.schedule.endswith("-steal"), self.task_size, queue_tasks, queue_start,
                queue_next, worker_stats, slices, iu, iv, weights, n_i, n_j, scan_k, scan_j, lengths, run_offsets,
                data_offsets, run_index, extents, records, gradients, optab, colour_table,
                shadetab if shade_mode == composite.SHADE_LUT else None, normal_matrix, light, half, has_half, params,
                self.opaque_threshold, raw_voxels, *classification_tables, *strides, image, link if early else None,
                rank if by_rank else None, runend if by_rank else None, row_extents, counters)
        t2 = time.perf_counter()
        cpu2 = time.process_time()
        output = self._warp_module.warp_image(image, fact.warp, (scene.height, scene.width), row_extents=row_extents)
        t3 = time.perf_counter()
        timings["composite"] = t2 - t1
        timings["warp"] = t3 - t2
        timings["total"] = t3 - start

        totals = counters.sum(axis=0)
        counters_out = {
            "samples": int(totals[composite.C_SAMPLES]),
            "voxel_runs": int(totals[composite.C_RUNS]),
            "pixel_run_finds": int(totals[composite.C_FINDS]),
            "pixel_run_creates": int(totals[composite.C_CREATES]),
            "skipped_early_termination": int(totals[composite.C_SKIPPED]),
            "rle_bytes": int(sum(e.nbytes for e in encodings)),
            "raw_bytes": int(instance.volume.data.nbytes),
        }
        if self._uses_octree:
            tree = self._octree(instance.volume, timings)
            counters_out["octree_nodes"] = tree.nodes
            counters_out["octree_bytes"] = tree.nbytes
            counters_out["classified_on_the_fly"] = int(totals[composite.C_CLASSIFIED] if lazy
                                                        else self._last_octree_classified)
        if self.classification == "octree":
            counters_out["voxel_array_bytes"] = tree.voxel_bytes
            counters_out["candidate_voxels"] = voxel_runs.candidates if lazy else int(octree_stats.classified)
        voxels = int(np.prod(instance.volume.shape_xyz))
        info = {
            "principal_axis": "xyz"[fact.axis],
            "shear": list(fact.shear_ij),
            "slice_order": fact.slice_order,
            "intermediate_shape": list(fact.intermediate_shape),
            "sample_spacing_ratio": ratio,
            "projection": scene.camera.projection,
            # Lazily classified, the frame never counts every non-transparent voxel.
            "nontransparent_fraction": None if nontransparent is None else nontransparent / voxels,
            "classification": "pre-classified at voxel centres (shear-warp), 8-bit opacity, 13-bit normals",
            "worker_tasks": worker_stats[:, 0].tolist(),
            "worker_samples": worker_stats[:, 1].tolist(),
            # CPU time of every thread over the compositing wall time and workers: 1 when each worker
            # was busy all along, less when they waited for work or for a core another program held.
            "worker_busy": (cpu2 - cpu1) / (self.workers * (t2 - t1)) if t2 > t1 else None,
        }
        if lens is not None:
            info["lens"] = f"{lens.shape} {lens.appearance.mode}, pre-classified per voxel"
        if perspective:
            info["max_ray_angle"] = fact.max_ray_angle
            info["slice_scale_range"] = [float(scales.min()), float(scales.max())]
            info["opacity_correction"] = (f"{optabs.shape[0]} tables over Δ/Δ0 in [{ratios.min():.4f}, "
                                          f"{ratios.max():.4f}], interpolated per pixel")
        return RenderResult(image=output, timings=timings, counters=counters_out, info=info)
