"""The reference ray caster: the ground truth every other backend is measured against.

It favours correctness over speed: double-precision numba kernels (:mod:`.raycast`), a step of
a quarter voxel by default, no early ray termination and no empty-space skipping that could
change a bit of the result.

Choices where the conventions leave room
----------------------------------------
* **Step.** One world step ``Δ`` for the whole scene: ``step_factor`` times the smallest
  world-space voxel edge over all volumes (``|A·e_i|·s_i``, ``A`` the linear part of the
  object→world transform), or the absolute ``step``. Each volume corrects opacity with its own
  object-space step ``|A⁻¹·d|·Δ`` against its own ``Δ0`` (``VolumeInstance.reference_step``).
* **Cells.** Each ray is cut into cells of length ``Δ`` from ``t_first``, the entry into the
  union of the volume boxes (clipped to ``t >= 0``, so an eye inside a volume just starts
  there): cell ``k`` is ``[t_first + k·Δ, t_first + (k + 1)·Δ]``, and cells run until the
  union's exit ``t_last`` is covered, the last one reaching past it. Each volume takes one
  sample in every cell that overlaps its own box span ``[t_entry, t_exit]`` (slab test in its
  object space, clipped to ``t >= 0``): a cell inside the box samples at its centre
  ``t_k = t_first + (k + ½)·Δ`` and corrects opacity for a full step; a cell that the box cuts
  (where the ray enters or leaves that box) samples at the midpoint of the overlap
  ``[lo, hi]`` and corrects for its length ``hi − lo`` (``α' = 1 − (1 − α)^((hi − lo)·|A⁻¹d|/Δ0)``).
  Each box's span is thus covered exactly once: a homogeneous box has the exact
  ``1 − (1 − α)^(L/Δ0)`` for any path length ``L``, and a medium whose classified field is
  smooth converges with the second order of the midpoint rule (a sharp transfer-function edge
  inside a box still converges as ``O(Δ)``). Overlaps no longer than ``MIN_OVERLAP·Δ``
  (rounding slivers where a depth is a whole number of steps) are skipped.
* **Several volumes.** Every volume that samples a cell contributes to it; premultiplied
  colours and corrected opacities are summed, the opacity sum clamped to 1 with the colour
  scaled by the same factor, and the sum composited front to back (Kainz et al. 2009, "Ray
  casting of multiple volumetric datasets with polyhedral boundaries on manycore GPUs").
* **Modes.** ``dvr`` as above. ``mip`` and ``iso`` do not sample at all: they are exact for the
  trilinear field and independent of the step. Each volume's span is walked through the cells
  of its voxel lattice (a 3-D DDA between voxel-centre planes, the clamp-to-edge half voxels at
  the faces included); inside one cell the field along the ray is a cubic in ``t``, built from
  the cell's 8 corners. ``mip`` takes the largest normalised scalar over the segment ends and
  the stationary points of each cubic (closed-form roots of its derivative), over all volumes,
  and classifies it with the transfer function of the volume it came from, without opacity
  correction, shading or gradient opacity (as VTK does); ties go to the nearer maximum, then to
  the earlier volume. ``iso`` finds, per instance, the first place where ``s < isovalue``
  changes from its state at the box entry (from below to ``>= isovalue`` or back, so a voxel
  or plateau exactly at the isovalue is hit where the field reaches it, and a box face is not a
  surface): each cubic is cut at its stationary points into monotone pieces and the crossing
  bisected in the first piece that changes state, to ``ISO_TOLERANCE`` of the cell segment;
  the nearest instance's hit wins and is shaded with its transfer function's colour at the
  isovalue (alpha 1; gradient opacity does not apply). Volumes whose span is a rounding
  sliver (``<= MIN_OVERLAP·Δ``) are skipped, as in ``dvr``.
* **Meshes and CSG** (Kainz et al. 2009; semantics in :mod:`core.scene`). A scene with mesh
  instances, volume boundaries or CSG goes through :mod:`.geometry`: exact watertight
  ray–triangle intersection, every fragment of every ray kept (no depth limit), sorted and
  walked with the active-object set and the CSG forest; volumes are sampled only where they
  contribute, on the cells above (a volume no geometry cuts gets the same samples bit for bit),
  the cells cut at visible surfaces and medium ends; translucent surfaces are composited at
  their depth and homogeneous media analytically. In ``iso`` a volume contributes its first
  crossing inside the intervals where it contributes, from its state at its box entry (so a cut
  through the inside of its surface shows the cut face), found by the same cell walk, opaque,
  behind whatever surfaces and media lie in front. A scene without them takes the volume-only
  kernel unchanged.
* **Lenses** (Ropinski et al. 2005; semantics in :mod:`core.lens`). A lens scene (one volume,
  ``dvr``) goes through :func:`.raycast.render_lens`: per ray the lens's interval on the whole
  line, from the sphere's quadratic or from clipping the ray against the half-spaces of the
  box's slabs or the convex mesh's faces in the lens's own frame, intersected with the box span;
  the samples are the cells above, each classified by the lens appearance when it lies in that
  interval (so a lens with the outside appearance gives the no-lens image bit for bit); a
  ``clip`` lens skips its samples, and a ``mip`` or ``iso`` lens contributes the exact maximum or
  the bisected crossing of its segment, as the scene-wide modes do, composited in depth order.
* **Non-finite rays.** A ray whose origin or direction is not finite (or whose direction is
  zero) gives a transparent pixel with depth NaN; every loop in the kernels is bounded.
* **Shading.** :class:`core.scene.Shading` exactly; the light direction is turned from view
  to world space with the camera basis and normals are world-space (normal matrix ``A^{-T}``).
* **Pre-classification** (``classification="pre"``, ``dvr`` only; not the ground truth). Each
  voxel is classified and shaded at its centre (central-difference gradient there, one half
  vector from the camera's view direction) and the ray interpolates the premultiplied RGBA,
  correcting the interpolated opacity for its step. This is the trilinear ray caster of
  Levoy 1988 that the shear-warp thesis compares its images with (Figs 5.9, 5.10), so the
  error of shear-warp's resampling can be told apart from the error of classifying before
  interpolating, which every pre-classified method shares.
"""

import functools
import os
import time
import weakref
from concurrent import futures

import numpy as np

from core.errors import InputError
from core.resources import check_memory, format_bytes
from core.scene import VolumeInstance
from renderers.base import Capabilities, Option, RenderResult, Renderer, step_factor_option, world_step
from renderers.base.probes import numba_probe

ROW_INTERLEAVE = 16
"""Rows are handed to threads as residue classes modulo this (see :func:`interleaved_rows`)."""

ISO_TOLERANCE = 1e-13
"""Iso bisection stops when the bracket is at most this fraction of its lattice-cell segment.

The segment is at most a cell diagonal (``√3`` voxels) long, so the surface is located to
``~2e-13`` voxels, far below the float32 rounding of the data."""

MIN_OVERLAP = 1e-9
"""A volume skips a cell whose overlap with its box is at most this fraction of the world step.

Such slivers come from rounding where a box depth is a whole number of steps (the slab test and
``t_first + k·Δ`` each carry ~1e-16 relative error); skipping one changes the optical depth by at
most ``1e-9·Δ/Δ0`` of a reference step, and keeps sample counts and images free of
rounding-sized extra samples.
"""

CLASSIFICATIONS = ("post", "pre")
"""Values of the ``classification`` option: classify the interpolated scalar, or the voxels."""

MAX_SAMPLES = 10 ** 11
"""Default of the ``max_samples`` option: the most samples one frame may take (see :meth:`ReferenceRenderer.work`).

The full profile's largest reference frame takes about 2e9 (a 256³ skull at 1/16 voxel, 512²), so
this leaves fifty times that and refuses a step that would keep the machine busy for hours or days
(``step_factor=1e-7`` on a 64³ phantom: ~7e13)."""

BYTES_PER_PIXEL = 80
"""Memory of a frame per pixel: the image (16 bytes), the depth (8), the ray origins and
directions (48) and the temporaries that build them (tracemalloc: 72.6 bytes at 512²)."""

BYTES_PER_VOXEL = {"post": 4, "pre": 20}
"""Memory per voxel besides the volume: its normalised float32 copy, and with
``classification="pre"`` the classified, shaded RGBA as well (tracemalloc: 4 and 16 bytes); a
scene of several volumes packs the copies into one more array of 4 bytes a voxel."""

_NORMALISED = weakref.WeakKeyDictionary()
"""Volume → flat float32 normalised scalars; ``Volume`` is frozen, so its data is not expected to change."""


def normalised_scalars(volume):
    """The volume's scalars normalised by its value range, float32, flattened, cached per Volume."""
    flat = _NORMALISED.get(volume)
    if flat is None:
        flat = np.ascontiguousarray(volume.normalized(np.float32)).ravel()
        _NORMALISED[volume] = flat
    return flat


def interleaved_rows(height):
    """Rows ordered by residue modulo :data:`ROW_INTERLEAVE`, so each contiguous block spans the image."""
    return np.concatenate([np.arange(start, height, ROW_INTERLEAVE) for start in range(ROW_INTERLEAVE)])


@functools.cache
def _kernel_thread():
    """The one thread that runs the kernels (one, so Numba's thread pool for it is made once)."""
    return futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="reference-kernels")


os.register_at_fork(after_in_child=_kernel_thread.cache_clear)  # a forked child has no such thread


def run_stoppable(launch):
    """Call ``launch(stop)`` in the kernel thread and wait; on Ctrl-C, stop it and re-raise.

    A Numba kernel cannot be interrupted, and the interpreter acts on SIGINT only between
    bytecodes of the main thread: a frame run there ends only when the kernel does. So the
    kernel runs in another thread (the kernels release the GIL) while this one waits, where
    KeyboardInterrupt does arrive; then ``stop[0]`` is set, which the kernel checks before each
    pixel (or slice), and once it has returned the interrupt goes on. The kernel is the same
    single call with the same rows per thread, so images and speed are those of a call in this
    thread.
    """
    import numba

    stop = np.zeros(1, dtype=np.int64)
    threads = numba.get_num_threads()  # Numba's thread count is per calling thread: take the caller's

    def call():
        numba.set_num_threads(threads)
        launch(stop)

    done = _kernel_thread().submit(call)
    try:
        done.result()
    except BaseException:
        stop[0] = 1
        futures.wait([done])
        raise


class ReferenceRenderer(Renderer):
    """Double-precision CPU ray caster (numba), the accuracy reference.

    ``options`` also records ``effective_step``, the world step of the last render.

    Notes
    -----
    Timings: ``prepare`` (normalised arrays, from a per-volume cache after the first frame;
    packed tables, transforms and camera rays; with ``classification="pre"`` the per-frame
    classification and shading of every voxel), ``render`` (the kernel) and ``total``.
    Counters: ``rays``, ``rays_hit`` (rays entering any volume box, or meeting a mesh), ``samples``
    and ``early_terminations`` (always 0); scenes with meshes add ``fragments`` (mesh crossings
    in front of the ray origins) and ``max_fragments`` (the largest number on one ray, the
    depth complexity). ``samples`` is, in ``dvr``, the volume samples taken: one
    per volume and cell it overlaps, so a box of depth ``L`` starting on a cell boundary gets
    ``ceil(L/Δ)``; in ``mip`` and ``iso`` it is the lattice-cell segments evaluated, one per
    volume and voxel-lattice cell the ray walks through (head-on through ``n`` voxels: ``n + 1``,
    the two clamped half voxels included; ``iso`` stops at the hit; bisection steps excluded).

    Sampling (see the module notes): the ray is cut into cells ``[t_first + k·Δ, t_first +
    (k + 1)·Δ]`` from the entry into the union of the boxes; a volume samples a cell inside its
    box at the centre with opacity corrected for ``Δ``, and a cell its box cuts at the midpoint
    of the overlap with opacity corrected for the overlap's length, so path lengths count
    exactly and the error falls as ``Δ²`` where the classified field is smooth.
    """

    technique_stages = ("render",)
    """The stages that are the technique itself: the ray-marching kernel; not the per-frame preparation of rays and tables."""

    name = "reference"
    description = "Double-precision CPU ray caster (numba): trilinear, post-classified, step ≤ 1/4 voxel, no early termination"
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
        lenses=True,
        camera_inside_volume=True,
    )
    option_table = (
        step_factor_option(0.25, limited_precision=False),
        Option("step", float, None, "Absolute world step; overrides ``step_factor``.", low=0, low_open=True),
        Option("classification", str, "post",
               "``post`` (CONVENTIONS): classify the interpolated scalar. ``pre``: classify and shade the voxels, "
               "interpolate their colours (``dvr`` only; see the module notes).", choices=CLASSIFICATIONS),
        Option("depth", bool, False,
               "Also return ``info[\"depth\"]``: an ``(H, W)`` float64 array of the ray parameter (world distance "
               "from the ray origin) of the first contributing sample (``dvr``: the nearest sample of the first "
               "cell that contributes), the first place the exact maximum is reached (``mip``) or the surface "
               "(``iso``), NaN where there is none."),
        Option("max_samples", float, MAX_SAMPLES,
               "The most samples a frame may take: :meth:`check` refuses a scene whose estimate (:meth:`work`) is "
               "larger, before any work. Raise it for a frame that should take that long.", low=1),
    )
    quality_sweep = tuple({"step_factor": factor} for factor in (1.0, 0.5, 0.25, 0.125))
    """Speed-versus-accuracy settings, coarse to fine; the default quarter voxel is among them."""

    def __init__(self, **options):
        super().__init__(**options)
        self._last_step = None
        self._packed = None
        # Importing the kernels compiles them (or loads numba's cache) here, not in the first frame.
        from renderers.reference import geometry, raycast

        self._raycast = raycast
        self._geometry = geometry

    @classmethod
    def probe(cls):
        return numba_probe()

    @property
    def options(self):
        """Options as given, plus ``effective_step``: the world step of the last render."""
        return {**super().options, "effective_step": self._last_step}

    def environment(self):
        import numba

        return {"numba": numba.__version__, "numba_threads": numba.get_num_threads()}

    def close(self):
        self._packed = None

    def check(self, scene):
        """Also refuse, before any work, a frame this machine cannot hold or that takes more than
        ``max_samples`` samples (:meth:`work`)."""
        super().check(scene)
        pixels = scene.width * scene.height
        voxels = [instance.volume.data.size for instance in scene.volumes]
        per_voxel = BYTES_PER_VOXEL[self.classification] + (4 if len(voxels) > 1 else 0)
        held = sum(instance.volume.data.nbytes for instance in scene.volumes)
        check_memory(held + pixels * BYTES_PER_PIXEL + sum(voxels) * per_voxel,
                     what=f"reference: scene {scene.name!r} at {scene.width}×{scene.height}",
                     detail=f"the volumes' {format_bytes(held)}, {BYTES_PER_PIXEL} bytes a pixel and {per_voxel} a voxel",
                     fix="render fewer pixels or smaller volumes")
        samples, how = self.work(scene)
        if samples > self.max_samples:
            advice = "render fewer pixels"
            if scene.mode == "dvr":
                option, value = ("step_factor", self.step_factor) if self.step is None else ("step", self.step)
                advice = f"use a larger step ({option} ≥ {value * samples / self.max_samples:.3g}) or fewer pixels"
            raise InputError(f"reference: scene {scene.name!r} takes about {samples:.3g} samples a frame ({how}), more "
                             f"than max_samples={self.max_samples:.3g}; {advice}, or raise the cap with the option "
                             "max_samples (--option max_samples=N) if the frame should take that long")

    def work(self, scene):
        """An upper estimate of the samples one frame of ``scene`` takes, and how it is made.

        ``dvr``: every pixel's ray walks cells of the world step across the box bounding all
        volumes (a scene without volumes samples nothing). ``mip`` and ``iso`` walk each volume's
        voxel lattice instead, independent of the step: at most ``nx + ny + nz + 3`` cells a ray; a
        ``mip`` or ``iso`` lens adds that walk to the ``dvr`` steps.

        Returns
        -------
        (float, str)
        """
        pixels = scene.width * scene.height
        if not scene.volumes:
            return 0.0, "no volume to sample"
        if scene.mode != "dvr":
            cells = sum(sum(instance.volume.shape_xyz) + 3 for instance in scene.volumes)
            return float(pixels) * cells, f"{pixels} pixels × up to {cells} voxel-lattice cells a ray"
        corners = np.concatenate([instance.world_corners() for instance in scene.volumes])
        diagonal = float(np.linalg.norm(corners.max(axis=0) - corners.min(axis=0)))
        step = self.world_step(scene)
        steps = diagonal / step + 1
        if scene.lenses and scene.lenses[0].appearance.mode in ("mip", "iso"):
            cells = sum(scene.volumes[0].volume.shape_xyz) + 3
            return float(pixels) * (steps + cells), (f"{pixels} pixels × ({steps:.3g} steps of {step:.3g} across the "
                                                     f"volume's {diagonal:.3g} diagonal + up to {cells} voxel-lattice "
                                                     "cells in the lens)")
        return float(pixels) * steps, (f"{pixels} pixels × {steps:.3g} steps of {step:.3g} across the volumes' "
                                       f"{diagonal:.3g} diagonal")

    def world_step(self, scene):
        """The world step this renderer uses for ``scene`` (``None``: no volume to sample)."""
        return self.step if self.step is not None else world_step(scene, self.step_factor)

    def _check_scene(self, scene):
        if self.classification == "pre" and scene.mode != "dvr":
            raise InputError(f"reference option classification='pre' applies to dvr only, the scene's mode is "
                             f"{scene.mode!r}; use classification='post' (mip and iso classify one value per ray)")
        if self.classification == "pre" and scene.lenses:
            raise InputError(f"reference option classification='pre' cannot render scene {scene.name!r}'s lens: a "
                             "lens classifies each sample by where it lies, after interpolation; use "
                             "classification='post'")

    def _pack_volumes(self, volumes):
        """Concatenated normalised scalars and offsets, cached for the last set of volumes."""
        if self._packed is not None and len(self._packed[0]) == len(volumes) and all(
            a is b for a, b in zip(self._packed[0], volumes)
        ):
            return self._packed[1], self._packed[2]
        # A Volume placed twice (a lens's second classification of it) is stored once.
        distinct = list({id(volume): volume for volume in volumes}.values())
        arrays = [normalised_scalars(volume) for volume in distinct]
        starts = dict(zip((id(volume) for volume in distinct),
                          np.cumsum([0] + [a.size for a in arrays], dtype=np.int64)[:-1]))
        offsets = np.array([starts[id(volume)] for volume in volumes], dtype=np.int64)
        data = arrays[0] if len(arrays) == 1 else np.concatenate(arrays or [np.zeros(1, np.float32)])
        # Strong references keep the identity check valid while the entry lives.
        self._packed = (tuple(volumes), data, offsets)
        return data, offsets

    def _scene_arguments(self, scene, step, instances=None):
        """The kernel's inputs for ``scene``, in :func:`raycast.render`'s order (outputs excluded).

        ``instances`` replaces the scene's volumes (a lens scene's two classification slots).
        """
        instances = scene.volumes if instances is None else instances
        n = len(instances)
        data, offsets = self._pack_volumes([instance.volume for instance in instances])
        dims = np.array([instance.volume.shape_xyz for instance in instances], dtype=np.int64).reshape(n, 3)
        spacing = np.array([instance.volume.spacing for instance in instances], dtype=np.float64).reshape(n, 3)
        inverse = np.array([np.linalg.inv(instance.transform) for instance in instances]).reshape(n, 4, 4)
        world_to_object = np.ascontiguousarray(inverse[:, :3, :])
        normal_matrix = np.ascontiguousarray(np.transpose(inverse[:, :3, :3], (0, 2, 1)))
        tf_size = np.array([instance.transfer_function.size for instance in instances], dtype=np.int64)
        tf = np.zeros((n, tf_size.max(initial=2), 4))
        gtab_size = np.array([0 if instance.gradient_opacity is None else instance.gradient_opacity.table.size
                              for instance in instances], dtype=np.int64)
        gtab = np.zeros((n, max(int(gtab_size.max(initial=0)), 2)))
        for i, instance in enumerate(instances):
            tf[i, :tf_size[i]] = instance.transfer_function.table
            if gtab_size[i]:
                gtab[i, :gtab_size[i]] = instance.gradient_opacity.table
        ref_step = np.array([instance.reference_step for instance in instances], dtype=np.float64)
        isovalue = np.array([np.nan if instance.isovalue is None else instance.isovalue for instance in instances])
        shading = scene.shading
        right, up, back = scene.camera.basis()
        lx, ly, lz = shading.light_direction
        light = lx * right + ly * up + lz * back  # orthonormal basis: still a unit vector
        origins, directions = (np.ascontiguousarray(a) for a in scene.camera.rays(scene.width, scene.height))
        phong = int(shading.model == "phong")
        parameters = np.array([shading.ambient, shading.diffuse, shading.specular, shading.shininess])
        pre = np.zeros((4, 0), dtype=np.float32)
        if self.classification == "pre":
            half = light + back
            half_norm = np.linalg.norm(half)
            pre = np.empty((4, data.size), dtype=np.float32)
            run_stoppable(lambda stop: self._raycast.preclassify(
                data, offsets, dims, spacing, tf, tf_size, gtab, gtab_size, ref_step, normal_matrix, phong, parameters,
                light, half / half_norm if half_norm > 0 else half, bool(half_norm > 0), stop, pre))
        return (self._raycast.MODE_CODES[scene.mode], interleaved_rows(scene.height), origins, directions,
                data, offsets, dims, spacing, world_to_object, normal_matrix, tf, tf_size, gtab, gtab_size,
                ref_step, isovalue, step, MIN_OVERLAP * step, phong, parameters, light, ISO_TOLERANCE, pre)

    def _geometry_arguments(self, scene, volume_arguments):
        """The geometry kernel's inputs: :func:`geometry.render`'s order, outputs excluded."""
        (mode, row_order, origins, directions, data, offsets, dims, spacing, world_to_object, normal_matrix, tf, tf_size,
         gtab, gtab_size, ref_step, isovalue, step, min_overlap, phong, parameters, light, tolerance,
         pre) = volume_arguments
        nvol = len(scene.volumes)
        # Surface objects: every mesh instance, then every volume boundary; each is a leaf's mesh.
        placed = [(m.mesh, m.transform, nvol + i) for i, m in enumerate(scene.meshes)]
        placed += [(v.boundary, v.transform, i) for i, v in enumerate(scene.volumes) if v.boundary is not None]
        meshes = list({id(mesh): mesh for mesh, _, _ in placed}.values())
        vertex_start = np.cumsum([0] + [mesh.vertices.shape[0] for mesh in meshes])
        face_start = np.cumsum([0] + [mesh.faces.shape[0] for mesh in meshes])
        index = {id(mesh): i for i, mesh in enumerate(meshes)}
        verts = np.concatenate([mesh.vertices for mesh in meshes]) if meshes else np.zeros((0, 3))
        faces = (np.concatenate([mesh.faces + vertex_start[i] for i, mesh in enumerate(meshes)]) if meshes
                 else np.zeros((0, 3), np.int64))
        face_normals = np.concatenate([mesh.face_normals() for mesh in meshes]) if meshes else np.zeros((0, 3))
        nobj = len(placed)
        inverse = np.array([np.linalg.inv(transform) for _, transform, _ in placed]).reshape(nobj, 4, 4)
        obj_faces = np.array([[face_start[index[id(mesh)]], face_start[index[id(mesh)] + 1]] for mesh, _, _ in placed],
                             dtype=np.int64).reshape(nobj, 2)
        lo = np.array([mesh.bounds()[0] for mesh, _, _ in placed]).reshape(nobj, 3)
        hi = np.array([mesh.bounds()[1] for mesh, _, _ in placed]).reshape(nobj, 3)
        # Padding keeps triangles lying in a face of the box from being culled by rounding.
        pad = 1e-9 * np.maximum(hi - lo, 1.0)
        obj_leaf = np.array([leaf for _, _, leaf in placed], dtype=np.int64)

        nleaf = nvol + len(scene.meshes)
        leaf_box = np.array([i if i < nvol else -1 for i in range(nleaf)], dtype=np.int64)
        leaf_obj = np.full(nleaf, -1, dtype=np.int64)
        leaf_obj[obj_leaf] = np.arange(nobj)
        leaf_surface = np.zeros((nleaf, 8))
        leaf_medium = np.zeros((nleaf, 4))
        leaf_has_surface = np.zeros(nleaf, dtype=np.bool_)
        leaf_has_medium = np.zeros(nleaf, dtype=np.bool_)
        for i, instance in enumerate(scene.meshes):
            if instance.surface is not None:
                material = instance.surface
                leaf_surface[nvol + i] = (*material.colour, material.alpha, material.ambient, material.diffuse,
                                          material.specular, material.shininess)
                leaf_has_surface[nvol + i] = True
            if instance.medium is not None:
                leaf_medium[nvol + i] = (*instance.medium.colour, instance.medium.extinction)
                leaf_has_medium[nvol + i] = True
        forest = geometry_forest(scene)
        return (origins, directions, data, offsets, dims, spacing, world_to_object, normal_matrix, tf, tf_size, gtab,
                gtab_size, ref_step, pre, step, min_overlap, phong, parameters, light,
                mode == self._raycast.MODE_CODES["iso"], isovalue, tolerance, verts, faces, face_normals, np.ascontiguousarray(inverse[:, :3, :]),
                np.ascontiguousarray(np.transpose(inverse[:, :3, :3], (0, 2, 1))), lo - pad, hi + pad, obj_faces,
                obj_leaf, leaf_box, leaf_obj, leaf_surface, leaf_has_surface, leaf_medium, leaf_has_medium,
                *forest, row_order)

    def _render(self, scene):
        start = time.perf_counter()
        self._check_scene(scene)
        if scene.has_geometry():
            return self._render_geometry(scene, start)
        if scene.lenses:
            return self._render_lens(scene, start)
        step = self.world_step(scene)
        arguments = self._scene_arguments(scene, step)
        image = np.zeros((scene.height, scene.width, 4), dtype=np.float32)
        depth = np.empty((scene.height, scene.width))
        row_hits = np.zeros(scene.height, dtype=np.int64)
        row_samples = np.zeros(scene.height, dtype=np.int64)
        prepared = time.perf_counter()
        run_stoppable(lambda stop: self._raycast.render(*arguments, stop, image, depth, row_hits, row_samples))
        rendered = time.perf_counter()

        self._last_step = step
        info = {
            "step": step,
            "classification": self.classification,
            "step_factor": step / scene.min_world_voxel_size(),
            "reference_steps": [instance.reference_step for instance in scene.volumes],
            "blending": "sum of premultiplied samples, opacity clamped to 1 (Kainz et al. 2009)",
            "shading_applied": scene.shading.model != "none" and scene.mode != "mip",
        }
        if self.depth:
            info["depth"] = depth
        counters = {
            "rays": scene.width * scene.height,
            "rays_hit": int(row_hits.sum()),
            "samples": int(row_samples.sum()),
            "early_terminations": 0,
        }
        timings = {"prepare": prepared - start, "render": rendered - prepared, "total": rendered - start}
        return RenderResult(image=image, timings=timings, counters=counters, info=info)

    def _lens_arguments(self, scene, step):
        """:func:`raycast.render_lens`'s inputs, outputs excluded: the volume in two slots, then the lens."""
        instance = scene.volumes[0]
        lens = scene.lenses[0]
        appearance = lens.appearance
        tf = appearance.classification(instance.transfer_function)
        # Slot 1: the same voxels and placement with the lens's classification (clip: an unused copy of slot 0).
        view = VolumeInstance(instance.volume, instance.transfer_function if tf is None else tf,
                              transform=instance.transform, gradient_opacity=appearance.gradient_opacity,
                              isovalue=appearance.isovalue, name=f"{instance.name} in {lens.name}")
        (_, row_order, origins, directions, data, offsets, dims, spacing, world_to_object, normal_matrix, tf, tf_size,
         gtab, gtab_size, ref_step, _, step, min_overlap, phong, parameters, light, tolerance,
         pre) = self._scene_arguments(scene, step, instances=(instance, view))
        kind = self._raycast.LENS_SPHERE if lens.shape == "sphere" else self._raycast.LENS_PLANES
        sphere = np.array([*lens.center, lens.radius or 0.0])
        normals, plane_offsets = lens.half_spaces()
        lens_w2o = np.ascontiguousarray(np.linalg.inv(lens.object_to_world())[:3, :])
        return (row_order, origins, directions, data, offsets, dims, spacing, world_to_object, normal_matrix, tf,
                tf_size, gtab, gtab_size, ref_step, step, min_overlap, phong, parameters, light, tolerance, pre,
                kind, self._raycast.LENS_MODE_CODES[appearance.mode], sphere, lens_w2o,
                np.ascontiguousarray(normals, dtype=np.float64), np.ascontiguousarray(plane_offsets, dtype=np.float64),
                np.nan if appearance.isovalue is None else appearance.isovalue)

    def _render_lens(self, scene, start):
        step = self.world_step(scene)
        arguments = self._lens_arguments(scene, step)
        image = np.zeros((scene.height, scene.width, 4), dtype=np.float32)
        depth = np.empty((scene.height, scene.width))
        row_hits = np.zeros(scene.height, dtype=np.int64)
        row_samples = np.zeros(scene.height, dtype=np.int64)
        prepared = time.perf_counter()
        run_stoppable(lambda stop: self._raycast.render_lens(*arguments, stop, image, depth, row_hits, row_samples))
        rendered = time.perf_counter()

        self._last_step = step
        lens = scene.lenses[0]
        info = {
            "step": step,
            "classification": self.classification,
            "step_factor": step / scene.min_world_voxel_size(),
            "reference_steps": [instance.reference_step for instance in scene.volumes],
            "blending": "front to back; samples classified by the lens appearance inside the lens interval",
            "shading_applied": scene.shading.model != "none",
            "lens": f"{lens.shape} {lens.appearance.mode}",
        }
        if self.depth:
            info["depth"] = depth
        counters = {
            "rays": scene.width * scene.height,
            "rays_hit": int(row_hits.sum()),
            "samples": int(row_samples.sum()),
            "early_terminations": 0,
        }
        timings = {"prepare": prepared - start, "render": rendered - prepared, "total": rendered - start}
        return RenderResult(image=image, timings=timings, counters=counters, info=info)

    def _render_geometry(self, scene, start):
        step = self.world_step(scene)
        arguments = self._geometry_arguments(scene, self._scene_arguments(scene, 1.0 if step is None else step))
        height, width = scene.height, scene.width
        image = np.zeros((height, width, 4), dtype=np.float32)
        depth = np.empty((height, width))
        rows = [np.zeros(height, dtype=np.int64) for _ in range(4)]
        prepared = time.perf_counter()
        run_stoppable(lambda stop: self._geometry.render(*arguments, stop, image, depth, *rows))
        rendered = time.perf_counter()

        self._last_step = step
        info = {
            "step": step,
            "classification": self.classification,
            "step_factor": step / scene.min_world_voxel_size() if scene.volumes else None,
            "reference_steps": [instance.reference_step for instance in scene.volumes],
            "blending": "sum of premultiplied samples and media, opacity clamped to 1 (Kainz et al. 2009); "
                        "surfaces composited at their depth",
            "shading_applied": scene.shading.model != "none",
            "triangles": sum(m.mesh.triangle_count for m in scene.meshes)
            + sum(v.boundary.triangle_count for v in scene.volumes if v.boundary is not None),
        }
        if self.depth:
            info["depth"] = depth
        hits, samples, fragments, most = rows
        counters = {
            "rays": width * height,
            "rays_hit": int(hits.sum()),
            "samples": int(samples.sum()),
            "early_terminations": 0,
            "fragments": int(fragments.sum()),
            "max_fragments": int(most.max()),
        }
        timings = {"prepare": prepared - start, "render": rendered - prepared, "total": rendered - start}
        return RenderResult(image=image, timings=timings, counters=counters, info=info)


def geometry_forest(scene):
    """The scene's CSG forest as the flat arrays :func:`geometry.render` walks, postfix order.

    Leaves are numbered volumes first, then mesh instances; an instance in no tree is a root of
    its own. Returns ``(leaf_node, leaf_root, node_op, node_leaf, node_parent, node_first,
    node_children, node_child_start, node_child_count)``.
    """
    from renderers.reference.geometry import OP_LEAF, OPERATION_CODES

    names = [v.name for v in scene.volumes] + [m.name for m in scene.meshes]
    in_trees = {name for tree in scene.csg for name in tree.leaves()}
    op, leaf_of, parent, first, children, child_start, child_count = [], [], [], [], [], [], []

    def add(code, leaf):
        op.append(code)
        leaf_of.append(leaf)
        parent.append(-1)
        first.append(False)
        child_start.append(len(children))
        child_count.append(0)
        return len(op) - 1

    def emit(node):
        if isinstance(node, str):
            return add(OP_LEAF, names.index(node))
        ids = [emit(child) for child in node.children]
        j = add(OPERATION_CODES[node.operation], -1)
        child_count[j] = len(ids)
        children.extend(ids)
        for position, child in enumerate(ids):
            parent[child] = j
            first[child] = position == 0
        return j

    for tree in scene.csg:
        emit(tree)
    for leaf, name in enumerate(names):
        if name not in in_trees:
            add(OP_LEAF, leaf)
    leaf_of = np.array(leaf_of, dtype=np.int64)
    parent = np.array(parent, dtype=np.int64)
    leaf_node = np.empty(len(names), dtype=np.int64)
    leaf_node[leaf_of[leaf_of >= 0]] = np.flatnonzero(leaf_of >= 0)
    root_of = np.arange(len(op))
    for j in range(len(op) - 1, -1, -1):  # parents come after their children
        if parent[j] >= 0:
            root_of[j] = root_of[parent[j]]
    return (leaf_node, root_of[leaf_node], np.array(op, dtype=np.int64), leaf_of, parent,
            np.array(first, dtype=np.bool_), np.array(children, dtype=np.int64),
            np.array(child_start, dtype=np.int64), np.array(child_count, dtype=np.int64))
