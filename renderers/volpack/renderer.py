"""The ``volpack`` backend: Lacroute's own shear-warp library (VolPack 1.0b3) driven through ctypes.

It renders the scene every other backend renders, with VolPack doing all the volume work
(gradients and normals, classification, run-length encoding or the min-max octree, shading
table, compositing and warp); Python only builds the tables and the matrices and converts the
image. It is the peer against which volbench's own shear-warp (``shearwarp``) is checked.

How the scene maps onto VolPack
-------------------------------
* **Volume.** The normalised scalars are quantised to 8-bit densities ``round(255·s)`` (exact
  for uint8 data with the default range; 16-bit and float data lose precision here).
  ``vpVolumeNormals`` fills a 4-byte voxel ``{uint16 normal, uint8 density, uint8 gradient}``
  (VolPack's example layout): central differences on the densities, gradient magnitude
  ``floor(255·|∇s|)`` on VolPack's 0..221 scale and a 13-bit normal index. VolPack sets both to
  0 on the outermost voxel layer (the reference clamps to the edge instead).
* **Classification.** Opacity is VolPack's product of lookup tables: the density table is our
  transfer function's α at ``s = v/255``; with a :class:`~core.transfer.GradientOpacity` the
  gradient table is ``g(u)`` at the centre ``u = (k + ½)/(255·√3/2)`` of the interval that
  VolPack's truncated index ``k`` stands for (so ``u = 1`` is 220.8, "221"). The α in our
  tables is per reference step Δ0; VolPack's classified α is per voxel and it corrects it per
  view with ``1 − (1 − α)^√(1 + s_i² + s_j²)`` (the slice-to-slice distance in voxels), which is
  our opacity correction when Δ0 is the voxel size. A transfer function with another
  ``reference_step`` is pre-corrected to one voxel (possible only without gradient opacity,
  since VolPack multiplies the two tables afterwards). Voxels at or below ``min_opacity`` are
  transparent (``VP_MIN_VOXEL_OPACITY``). VolPack classifies voxels and then resamples the
  classified, shaded voxels bilinearly in each slice (pre-classification); the reference
  classifies after trilinear interpolation. That, the slice-wise bilinear (not trilinear)
  reconstruction, the 8-bit opacity index and the 8-bit image are the sources of difference.
* **Colour and shading.** VolPack's lookup-table shader: a colour table indexed by the normal
  and, where the transfer function's colour varies, one material per colour channel weighted by
  a table indexed by the density (``vpSetLookupShader`` with a weight field). ``phong`` fills
  the colour table with ``vpShadeTable``: one directional light, ``VP_LIGHT_BOTH_SIDES`` (our
  two-sided ``|N·L|``, ``|N·H|``), materials ``ambient·c``, ``diffuse·c`` and a white
  ``specular`` with our shininess, the light given in view space (VolPack's eye space after the
  model matrix, viewer at +z, as in our :class:`~core.scene.Shading`); VolPack's zero-normal
  entry is ambient only, as ours. With a constant transfer-function colour a single material
  does it and VolPack's clamp of each table entry is our per-sample clamp; with a varying colour
  the specular is a fourth (white) material and the clamp applies to each material's entry, not
  to their sum. ``none`` fills the colour table with the constant colour (emission–absorption).
* **View.** VolPack's object space is the volume scaled by ``1/max(n)`` and centred on
  ``n/2`` in voxel-index units (voxel ``i`` at index ``i``), half a voxel off our cell-centred
  box. ``VP_MODEL`` is the camera rotation alone (``vpShadeTable`` solves the model matrix for
  the light and eye vectors, so it must stay a rotation); ``VP_VIEW`` scales by ``max(n)·s`` and
  translates by half a voxel and the camera target; ``VP_PROJECT`` is the orthographic window
  shifted by half a pixel, because VolPack's viewport puts pixel centres on integer
  coordinates while ours are at half-integers. VolPack's image has row 0 at the bottom, so the
  rows are flipped. Found by rendering single off-centre voxels in both renderers: the
  projected centroids agree to < 0.03 pixel at any view (see ``tests/test_volpack.py``).
* **Perspective.** VolPack 1.0b3's ``FactorPerspectiveView`` is an empty stub
  (``#ifdef notdef``) and its render calls return ``VPERROR_BAD_OPTION`` for a perspective
  matrix, so the backend is orthographic only.

Timing: VolPack's ``vpGetTimer`` counters exist in the API but Debian's build is compiled
without ``USE_TIMER`` (every timer reads 0, checked at run time and recorded in ``info``), so
stages are wall-clock times around the library calls: ``volume`` (quantisation and
``vpVolumeNormals``, per volume), ``classify`` (``vpClassifyVolume``, mode ``rle``, per volume
and classification) or ``octree`` (``vpCreateMinMaxOctree``, mode ``octree``, per volume),
reported only in the frame that builds them, and per frame ``shade`` (``vpShadeTable``),
``render`` (``vpRenderClassifiedVolume`` / ``vpRenderRawVolume``: compositing and warp, plus
the on-the-fly classification in modes ``octree`` and ``raw``), ``readback`` (8-bit image to
float) and ``total`` (everything in the call, preprocessing included when it happens). VolPack
is single-threaded.
"""

import hashlib
import time

import numpy as np

from core.errors import BackendUnavailableError, InputError
from core.transfer import MAX_GRADIENT
from renderers.base import Capabilities, Option, RenderResult, Renderer
from renderers.volpack import library as vp

MODES = ("rle", "octree", "raw")
"""``rle``: classify once into VolPack's run-length-encoded volume (``vpClassifyVolume``) and
render it (``vpRenderClassifiedVolume``); ``octree``: the thesis's fast classification, a min-max
octree over the unclassified voxels (``vpCreateMinMaxOctree``) used by ``vpRenderRawVolume`` to
skip transparent regions while classifying every frame; ``raw``: ``vpRenderRawVolume`` without
an octree (classify every voxel every frame, VolPack's slowest path)."""

VOXEL_BYTES = 4
NORMAL_FIELD, DENSITY_FIELD, GRADIENT_FIELD = 0, 1, 2
NORMAL_OFFSET, DENSITY_OFFSET, GRADIENT_OFFSET = 0, 2, 3
DENSITY_PARAM, GRADIENT_PARAM = 0, 1
GRADIENT_SCALE = 255.0 * MAX_GRADIENT
"""VolPack's gradient index of a unit-range signal's largest central difference: 255·√3/2 ≈ 220.8."""
MAX_OCTREE_NODE_SIZE = 512
"""The largest ``octree_base_node_size`` (VolPack's limit)."""


def check_power_of_two(value, *, name):
    """``value`` if it is a power of two (octree node edges halve down to it), else an :class:`InputError`."""
    if value & (value - 1):
        raise InputError(f"{name}: expected a power of two (1, 2, 4, … {MAX_OCTREE_NODE_SIZE}), got {value!r}")
    return value


def density_alpha_table(transfer_function, voxel_step, reference_step):
    """VolPack's density opacity table: α at ``s = v/255``, corrected from Δ0 to one voxel."""
    alpha = transfer_function.lookup(np.arange(vp.VP_SCALAR_MAX + 1) / vp.VP_SCALAR_MAX)[:, 3]
    if voxel_step != reference_step:
        alpha = 1.0 - np.power(1.0 - np.clip(alpha, 0.0, 1.0), voxel_step / reference_step)
    return np.ascontiguousarray(alpha, dtype=np.float32)


def gradient_table(gradient_opacity):
    """VolPack's gradient opacity table over its index ``k = floor(255·|∇s|)``, 0..221."""
    u = (np.arange(vp.VP_GRAD_MAX + 1) + 0.5) / GRADIENT_SCALE
    return np.ascontiguousarray(gradient_opacity.lookup(u), dtype=np.float32)


def quantise(volume):
    """8-bit densities ``round(255·s)`` of the normalised scalars, C order ``[z, y, x]``."""
    if volume.data.dtype == np.uint8 and tuple(volume.value_range) == (0.0, 255.0):
        return np.ascontiguousarray(volume.data)
    scaled = np.rint(volume.normalized(np.float64) * 255.0)
    return np.ascontiguousarray(scaled.astype(np.uint8))


def view_matrices(scene, instance):
    """``(model, view, project)`` for VolPack so that its image matches our camera's pixels.

    VolPack maps voxel index ``p`` to ``viewport · project · view · model · pre · p`` with
    ``pre = scale(1/m) · translate(−n/2)`` (``m = max(n)``) and a viewport putting clip −1..1
    on pixel coordinates 0..W with pixel ``q`` centred at ``q`` (row 0 at the bottom). Our voxel
    ``p`` sits at world ``(p + ½ − n/2)·s`` and our pixel ``q`` is centred at ``q + ½``.
    """
    camera = scene.camera
    volume = instance.volume
    right, up, back = camera.basis()
    rotation = np.stack([right, up, back])
    spacing = volume.spacing[0]
    longest = max(volume.shape_xyz)
    model = np.eye(4)
    model[:3, :3] = rotation
    view = np.eye(4)
    view[:3, :3] *= longest * spacing
    # voxel centres half a voxel up from VolPack's lattice, then the camera target to the origin
    world_offset = instance.transform[:3, 3] + 0.5 * np.asarray(volume.extent) + 0.5 * spacing
    view[:3, 3] = rotation @ (world_offset - np.asarray(camera.target))
    half_h = camera.view_height / 2
    half_w = half_h * scene.width / scene.height
    depth = longest * spacing
    project = np.eye(4)
    project[0, 0] = 1.0 / half_w
    project[1, 1] = 1.0 / half_h
    project[2, 2] = -1.0 / depth  # nearer is larger z after VolPack's viewport (its front)
    project[0, 3] = -1.0 / scene.width  # pixel centres: half a pixel
    project[1, 3] = -1.0 / scene.height
    return model, view, project


class _Prepared:
    """VolPack state for one volume: the context, its voxel buffer and what has been built."""

    def __init__(self, volume, gradient):
        self.volume = volume
        self.gradient = gradient
        self.context = vp.Context()
        self.classification = None  # key of the tables now set
        self.built = None  # key of the classified volume (rle) or octree (octree) built
        self.shading_key = None
        self.raw_bytes = 0


class VolPackRenderer(Renderer):
    """VolPack 1.0b3 (Lacroute's shear-warp library) through ctypes.

    Notes
    -----
    See the module notes for how the scene maps onto VolPack. Counters: ``voxels``,
    ``pixels``, ``intermediate_pixels`` (VolPack's intermediate image), ``view_axis`` (0/1/2:
    x/y/z principal axis VolPack chose), ``raw_bytes`` (the unclassified 4-byte voxels),
    ``rle_bytes`` (the three run-length-encoded copies, mode ``rle``), ``octree_bytes`` (mode
    ``octree``).
    """

    technique_stages = ("shade", "render")
    """The stages that are the technique itself: the library's calls per frame (vpShadeTable, then vpRenderClassifiedVolume or vpRenderRawVolume); not the quantisation to 8 bits or the conversion of its 8-bit image to float."""

    name = "volpack"
    description = "VolPack 1.0b3 shear-warp (Lacroute's library, ctypes): RLE or min-max octree, lookup-table shading, 8-bit"
    capabilities = Capabilities(
        shading=frozenset({"none", "phong"}),
        gradient_opacity=True,
        anisotropic_spacing=False,
        reasons={
            "projections": "VolPack 1.0b3 cannot render perspective: its FactorPerspectiveView is an "
                           "empty stub and vpRender* return VPERROR_BAD_OPTION for a perspective view",
            "modes": "VolPack composites classified voxels (dvr) only; it has no MIP or isosurface mode",
            "max_volumes": "a VolPack context renders one volume",
            "transforms": "VolPack's model matrix must stay a rotation (vpShadeTable solves it for the "
                          "light and eye vectors); placements other than the centred box are not mapped",
            "anisotropic_spacing": "VolPack's voxels are cubes: it scales every axis by 1/max(n) and "
                                   "computes gradients and normals per voxel index",
            "camera_inside_volume": "orthographic only (VolPack has no perspective)",
            "meshes": "VolPack renders volumes only",
            "lenses": "VolPack renders volumes only",
        },
    )
    option_table = (
        Option("mode", str, "rle", "``rle``: classified run-length-encoded volume; ``octree``: min-max octree with "
               "classification on the fly (the thesis's fast classification); ``raw``: classify every voxel every "
               "frame (see :data:`MODES`).", choices=MODES),
        Option("opaque_threshold", float, 0.95, "Early ray termination at this accumulated opacity "
               "(``VP_MAX_RAY_OPACITY``; 0.95 as in the thesis and VolPack's examples); 1 disables it.",
               low=0, high=1, low_open=True),
        Option("min_opacity", float, 0.05, "Voxels with opacity at or below it are transparent "
               "(``VP_MIN_VOXEL_OPACITY``; 0.05 as in VolPack's examples).", low=0, high=1, high_open=True),
        Option("octree_base_node_size", int, 4, "Edge of the octree's smallest nodes in voxels, a power of two "
               "(4 as in VolPack's ``makeoctree`` example). Mode ``octree`` only.",
               low=1, high=MAX_OCTREE_NODE_SIZE, check=check_power_of_two),
        Option("octree_threshold", int, 4, "Range of each classification field below which an octree node is not "
               "subdivided (``vpMinMaxOctreeThreshold``; 4 as in the example); 8-bit fields span 0..255. Mode "
               "``octree`` only.", low=0, high=vp.VP_SCALAR_MAX),
    )
    quality_sweep = ({"min_opacity": 0.05, "opaque_threshold": 0.95},
                     {"min_opacity": 0.01, "opaque_threshold": 0.99},
                     {"min_opacity": 0.0, "opaque_threshold": 1.0})
    """Thresholds from the thesis's defaults to none (VolPack's reconstruction is fixed)."""

    def __init__(self, **options):
        super().__init__(**options)
        self._prepared = None
        self._timers_compiled = None
        ok, reason = self.probe()
        if not ok:
            raise BackendUnavailableError(f"backend 'volpack' is not available here: {reason}")

    @classmethod
    def probe(cls):
        try:
            vp.load()
        except vp.VolPackUnavailable as exc:
            return False, str(exc)
        return True, ""

    def environment(self):
        return {"volpack_package": vp.package_version(), "volpack_header_version": vp.HEADER_VERSION,
                "volpack_library": vp.library_path(),
                "volpack_timers": ("compiled in" if self._timers_compiled else
                                   "not compiled in (vpGetTimer reads 0; stages are wall-clock)"
                                   if self._timers_compiled is False else "not checked yet"),
                "volpack_threads": 1}

    caches_preprocessing = True

    def drop_caches(self):
        self.close()

    def close(self):
        if self._prepared is not None:
            self._prepared.context.close()
            self._prepared = None

    # ------------------------------------------------------------------------------------------
    def _check_scene(self, scene):
        instance = scene.volumes[0]
        volume = instance.volume
        too_big = [n for n in volume.shape_xyz if n > vp.VP_MAX_VOLUME_DIM]
        if too_big:
            raise InputError(f"volume {volume.name!r}: VolPack handles at most {vp.VP_MAX_VOLUME_DIM} voxels "
                             f"per axis (VP_MAX_VOLUME_DIM), got {volume.shape_xyz}; resample the volume")
        if instance.gradient_opacity is not None and instance.reference_step != volume.spacing[0]:
            raise InputError(
                f"transfer function {instance.transfer_function.name!r} reference_step: VolPack multiplies the "
                f"density and gradient opacity tables per voxel and corrects the product for the voxel step, so "
                f"a reference step ({instance.reference_step:g}) other than the voxel size ({volume.spacing[0]:g}) "
                "cannot be folded into its tables with gradient opacity; leave reference_step unset"
            )
        # VolPack renders the whole box; the reference starts orthographic rays on the eye plane.
        right, up, back = scene.camera.basis()
        depth = (instance.world_corners() - scene.camera.eye) @ back
        if np.any(depth > 0):
            raise InputError(
                f"camera distance {scene.camera.distance:g}: the orthographic eye plane cuts volume "
                f"{instance.name!r}, and VolPack cannot clip it; move the camera back (distance > "
                f"{float(np.max(np.linalg.norm(instance.world_corners() - scene.camera.target, axis=1))):g}) "
                "or leave distance unset"
            )

    def _prepare(self, instance, stages):
        """The context for this volume, with its voxels computed (cached per Volume)."""
        volume = instance.volume
        gradient = instance.gradient_opacity is not None
        prepared = self._prepared
        if prepared is not None and prepared.volume is volume and prepared.gradient == gradient:
            return prepared
        self.close()
        start = time.perf_counter()
        prepared = _Prepared(volume, gradient)
        ctx = prepared.context
        nx, ny, nz = volume.shape_xyz
        ctx.call("vpSetVolumeSize", nx, ny, nz)
        # {uint16 normal, uint8 density, uint8 gradient}: normal and density are the shading
        # fields (first, as VolPack requires), density (and gradient) classify.
        ctx.call("vpSetVoxelSize", VOXEL_BYTES, 3, 2, 2 if gradient else 1)
        ctx.call("vpSetVoxelField", NORMAL_FIELD, 2, NORMAL_OFFSET, vp.VP_NORM_MAX)
        ctx.call("vpSetVoxelField", DENSITY_FIELD, 1, DENSITY_OFFSET, vp.VP_SCALAR_MAX)
        ctx.call("vpSetVoxelField", GRADIENT_FIELD, 1, GRADIENT_OFFSET, vp.VP_GRAD_MAX)
        voxels = np.zeros(nx * ny * nz * VOXEL_BYTES, dtype=np.uint8)
        density = quantise(volume)
        ctx.keep["voxels"] = voxels
        ctx.call("vpSetRawVoxels", voxels.ctypes.data, voxels.nbytes, VOXEL_BYTES, nx * VOXEL_BYTES,
                 nx * ny * VOXEL_BYTES)
        ctx.call("vpVolumeNormals", density.ctypes.data, density.size, DENSITY_FIELD, GRADIENT_FIELD, NORMAL_FIELD)
        ctx.call("vpSetd", vp.VP_MIN_VOXEL_OPACITY, self.min_opacity)
        ctx.call("vpSetd", vp.VP_MAX_RAY_OPACITY, self.opaque_threshold)
        ctx.call("vpEnable", vp.VP_LIGHT_BOTH_SIDES, 1)
        ctx.call("vpEnable", vp.VP_DEPTH_CUE, 0)
        prepared.raw_bytes = voxels.nbytes
        self._prepared = prepared
        stages["volume"] = time.perf_counter() - start
        return prepared

    def _classify(self, prepared, instance, stages):
        """Set the classifier tables; build the RLE volume or the octree where needed."""
        ctx = prepared.context
        volume = instance.volume
        alpha = density_alpha_table(instance.transfer_function, volume.spacing[0], instance.reference_step)
        tables = [alpha]
        if prepared.gradient:
            tables.append(gradient_table(instance.gradient_opacity))
        digest = hashlib.sha256(b"".join(t.tobytes() for t in tables)).hexdigest()
        if prepared.classification != digest:
            for param, (field, table) in enumerate(zip((DENSITY_FIELD, GRADIENT_FIELD), tables)):
                ctx.keep[f"classifier{param}"] = table
                ctx.call("vpSetClassifierTable", param, field, table.ctypes.data, table.nbytes)
            prepared.classification = digest
        if self.mode == "rle" and prepared.built != digest:
            start = time.perf_counter()
            if prepared.built is not None:
                ctx.call("vpDestroyClassifiedVolume")
            ctx.call("vpClassifyVolume")
            prepared.built = digest
            stages["classify"] = time.perf_counter() - start
        elif self.mode == "octree" and prepared.built is None:
            # The octree holds min/max of the classification fields, not opacities: it is built
            # once per volume and serves every classification.
            start = time.perf_counter()
            for param in range(len(tables)):
                ctx.call("vpMinMaxOctreeThreshold", param, self.octree_threshold)
            ctx.call("vpCreateMinMaxOctree", 0, self.octree_base_node_size)
            prepared.built = "octree"
            stages["octree"] = time.perf_counter() - start

    def _shader(self, prepared, instance, shading):
        """Set the lookup shader (colour table, material weights) for this classification."""
        ctx = prepared.context
        colors = instance.transfer_function.lookup(np.arange(vp.VP_SCALAR_MAX + 1) / vp.VP_SCALAR_MAX)[:, :3]
        constant = bool(np.all(colors == colors[0]))
        key = (shading, hashlib.sha256(colors.tobytes()).hexdigest())
        if prepared.shading_key == key:
            return
        entries = vp.VP_NORM_MAX + 1
        if constant:
            materials = 1
            weights = None
        else:
            # one material per colour channel weighted by the density's colour (+ white specular)
            materials = 4 if shading.model == "phong" else 3
            weights = np.ones((vp.VP_SCALAR_MAX + 1, materials), dtype=np.float32)
            weights[:, :3] = colors
        table = np.zeros((entries, materials, 3), dtype=np.float32)
        if shading.model == "none":
            if constant:
                table[:] = 255.0 * colors[0]
            else:
                for channel in range(3):
                    table[:, channel, channel] = 255.0
        ctx.keep["colour_table"] = table
        ctx.keep["weight_table"] = weights
        # materials exist once the shader declares them, so the shader comes first
        ctx.call("vpSetLookupShader", 3, materials, NORMAL_FIELD, table.ctypes.data, table.nbytes,
                 DENSITY_FIELD if weights is not None else 0,
                 None if weights is None else weights.ctypes.data, 0 if weights is None else weights.nbytes)
        if shading.model == "phong":
            color_rows = [colors[0]] if constant else [np.eye(3)[c] for c in range(3)]
            for m, color in enumerate(color_rows):
                specular = (shading.specular,) * 3 if constant else (0.0, 0.0, 0.0)
                self._material(ctx, m, shading.ambient * np.asarray(color), shading.diffuse * np.asarray(color),
                               specular, shading.shininess)
            if not constant:
                self._material(ctx, 3, (0, 0, 0), (0, 0, 0), (shading.specular,) * 3, shading.shininess)
            # the light is given in eye space: set it while the model matrix is the identity
            ctx.call("vpCurrentMatrix", vp.VP_MODEL)
            ctx.call("vpIdentityMatrix")
            ctx.call("vpSetLight", vp.VP_LIGHT0, vp.VP_DIRECTION, *shading.light_direction)
            ctx.call("vpSetLight", vp.VP_LIGHT0, vp.VP_COLOR, 1.0, 1.0, 1.0)
            ctx.call("vpEnable", vp.VP_LIGHT0, 1)
        prepared.shading_key = key

    @staticmethod
    def _material(ctx, index, ambient, diffuse, specular, shininess):
        material = vp.VP_MATERIAL0 + index
        ctx.call("vpSetMaterial", material, vp.VP_AMBIENT, vp.VP_BOTH_SIDES, *map(float, ambient))
        ctx.call("vpSetMaterial", material, vp.VP_DIFFUSE, vp.VP_BOTH_SIDES, *map(float, diffuse))
        ctx.call("vpSetMaterial", material, vp.VP_SPECULAR, vp.VP_BOTH_SIDES, *map(float, specular))
        ctx.call("vpSetMaterial", material, vp.VP_SHINYNESS, vp.VP_BOTH_SIDES, float(shininess), 0.0, 0.0)

    def _render(self, scene):
        start = time.perf_counter()
        self._check_scene(scene)
        instance = scene.volumes[0]
        stages = {}
        prepared = self._prepare(instance, stages)
        ctx = prepared.context
        self._classify(prepared, instance, stages)
        self._shader(prepared, instance, scene.shading)

        model, view, project = view_matrices(scene, instance)
        ctx.set_matrix(vp.VP_MODEL, model)
        ctx.set_matrix(vp.VP_VIEW, view)
        ctx.set_matrix(vp.VP_PROJECT, project)
        width, height = scene.width, scene.height
        image = ctx.keep.get("image")
        if image is None or image.shape != (height, width, 4):
            image = np.zeros((height, width, 4), dtype=np.uint8)
            ctx.keep["image"] = image
            ctx.call("vpSetImage", image.ctypes.data, width, height, width * 4, vp.VP_RGBA)

        shade_start = time.perf_counter()
        if scene.shading.model == "phong":
            ctx.call("vpShadeTable")
        rendered_start = time.perf_counter()
        if self.mode == "rle":
            ctx.call("vpRenderClassifiedVolume")
        else:
            ctx.call("vpRenderRawVolume")
        rendered = time.perf_counter()
        result = np.ascontiguousarray(image[::-1], dtype=np.float32)
        result *= np.float32(1.0 / 255.0)
        done = time.perf_counter()

        if self._timers_compiled is None:
            self._timers_compiled = any(ctx.timer_us(code) for code in range(len(vp.VPTIMER_NAMES)))
        timings = dict(stages)
        timings.update({"shade": rendered_start - shade_start, "render": rendered - rendered_start,
                        "readback": done - rendered, "total": done - start})
        nx, ny, nz = instance.volume.shape_xyz
        counters = {
            "voxels": nx * ny * nz,
            "pixels": width * height,
            "intermediate_pixels": ctx.geti(vp.VP_INTERMEDIATE_WIDTH) * ctx.geti(vp.VP_INTERMEDIATE_HEIGHT),
            "view_axis": ctx.geti(vp.VP_VIEW_AXIS),
            "raw_bytes": prepared.raw_bytes,
        }
        if self.mode == "rle":
            counters["rle_bytes"] = sum(ctx.geti(option) for option in
                                        (vp.VP_VIEW_X_SIZE, vp.VP_VIEW_Y_SIZE, vp.VP_VIEW_Z_SIZE))
        elif self.mode == "octree":
            counters["octree_bytes"] = ctx.geti(vp.VP_MMOCTREE_SIZE)
        info = {
            "library": "VolPack (ctypes)",
            "density_quantisation": "8-bit round(255·s)",
            "image_quantisation": "8-bit RGBA (VolPack's VP_RGBA image), premultiplied",
            "classification": "pre-classified voxels (VolPack), bilinear resampling within slices",
            "volpack_timers": bool(self._timers_compiled),
            "stage_timing": "VolPack timers" if self._timers_compiled else "wall clock around the library calls",
            "threads": 1,
        }
        return RenderResult(image=result, timings=timings, counters=counters, info=info)
