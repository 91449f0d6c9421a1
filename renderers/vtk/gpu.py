"""The ``vtk-gpu`` backend: VTK's ``vtkOpenGLGPUVolumeRayCastMapper`` as a peer of our ray casters.

VTK does all the volume work (texture upload, ray setup, sampling, classification, shading,
compositing) in its own shaders; Python builds the VTK objects from the scene and reads the
float image back (:mod:`.common`).

How the scene maps onto VTK, and what differs
---------------------------------------------
Measured against the reference (``tests/test_vtk.py`` has the numbers) with VTK 9.7.2:

* **Cell data.** Each volume is an ``(n + 1)``-point grid with the ``n`` scalars per axis as cell
  data, so VTK's box and its clamp-to-edge texture equal ours. VTK's usual point layout (a
  point per voxel, which ``vtk-cpu`` must use) makes the box half a voxel smaller on every side
  (a 24³ homogeneous box at two pixels per voxel: 13.7 dB). Scalars are our normalised float32
  values (a ``GL_R32F`` texture).
* **Sampling.** ``AutoAdjustSampleDistances`` off, ``ImageSampleDistance`` 1, jittering off,
  linear interpolation, ``SampleDistance`` = ``step_factor`` times the smallest voxel edge in
  the volume's object space, where VTK steps (its ray direction is normalised in data
  coordinates); with several volumes VTK steps through their world-aligned bounding box, so the
  step is ``step_factor`` times the smallest world-space voxel edge. VTK samples at
  ``entry + k·Δ`` for ``k = 1, 2, ...`` up to the exit and drops the partial step left there
  (a sample landing on the exit face counts or not as rounding decides); ours samples at cell
  midpoints and weighs the partial cells at the box faces by their length. The difference is
  small but systematic (through 24 homogeneous voxels at Δ = 0.35 voxel VTK composites 68
  samples, 23.8 voxels of path); it is recorded, not corrected.
* **Classification.** Post-classified through lookup textures over the data range: the
  transfer function is given as 1024 (or more) nodes that fill VTK's texture with our table at
  its texel centres (:func:`.common.dense_functions`). ``ScalarOpacityUnitDistance`` is the
  reference step Δ0. VTK corrects opacity per table entry (before interpolation, ours after)
  and skips the correction for entries ≤ 1e-4, so faint rims come out brighter.
* **Gradient opacity.** VTK's gradient measure is central differences of the normalised scalar
  over one texel step per mean voxel edge (:func:`.common.gradient_function` maps our ``u``
  onto it) and its table covers ``[0, ¼·data range]``, clamped beyond: ``g`` is evaluated
  correctly only where ``u <= data range/(4·√3/2)``, about 0.29 for data spanning [0, 1].
  VTK's texel step is ``1/(n − 1)`` of the texture, slightly more than one voxel.
* **Early ray termination.** VTK stops a ray when its opacity exceeds ``1 − 1/255`` (a
  constant in its shader). ``early_termination=True`` (default) keeps that, as VTK is used;
  ``False`` replaces the constant by 2 (a fragment-shader replacement, never reached) for runs
  that compare accuracy with the reference, which never terminates early.
* **Depth pass** (``depth_pass``, iSBVR's nearest peer, note 001): VTK first renders a contour of
  the data at the transfer function's Φ_t (the lowest value whose opacity leaves 0) and starts each
  ray at that surface's depth (``UseDepthPass``, ``DepthPassContourValues``). VTK contours point
  scalars and the volume is uploaded as cell data, with which the contour is empty and every ray is
  dropped; so the image also carries point scalars (``vtkCellDataToPointData``: each grid corner the
  mean of its eight cells, the trilinear field there) for the contour while the rays still sample the
  cell data. The pass draws its contour without the volume's user matrix (measured: with one, the
  contour is misplaced and rays start in the wrong place), so the placement goes into the data's
  origin and spacing instead, which allows a scale along the axes and a translation only. The
  contour is of the corner field with linear edges, not a conservative bound, so visible samples in
  front of it are lost: the pass is lossy and is judged by its error as well as its speed. One
  volume, ``dvr`` only.
* **Modes.** ``dvr`` is VTK's composite blend; ``mip`` its maximum-intensity blend, the maximum
  over the samples (ours is the exact maximum of the trilinear field), classified without
  opacity correction or shading; ``iso`` its isosurface blend, which detects the crossing
  between two samples and composites the transfer-function colour at the isovalue with
  opacity 1 at the sample after the crossing (ours bisects to the exact crossing), shaded there;
  a thin feature that exceeds the isovalue for less than a step is missed (the 32³ skull's bone
  at Δ = ¼ voxel: 90 of the reference's 103 pixels hit). Gradient opacity applies to ``dvr``
  only, as in the reference.
* **Shading.** Two-sided, ambient and diffuse as ours. With our default headlight the light is
  VTK's headlight, which VTK's shader places at the eye (a point light): for orthographic views
  the VTK camera is moved :data:`FAR_EYE` times further out along the view axis, which changes
  nothing in the image but makes that light directional; in perspective the eye cannot move,
  so the light direction differs from ours by the pixel's angle off the view axis. Any other
  light direction is a directional camera light, which takes VTK's multi-light path, where the
  ambient term is ``ambient · light colour`` instead of ``ambient · sample colour`` (they agree
  for white transfer-function colours). VTK's specular term is Phong (the reflected light
  vector against the view vector), ours Blinn–Phong (the half vector); this is not matched.
  VTK's shading gradient is taken one texel step (``1/(n − 1)`` of the texture) apart.
* **Several volumes.** A ``vtkMultiVolume`` with one input port per volume, composite blending
  only. VTK composites the volumes one after the other at each sample (in input order), ours
  sums their premultiplied samples (Kainz et al. 2009); the two differ at second order where
  volumes overlap. VTK shades several volumes with its headlight only, and its shader declares
  gradient opacity for all inputs or none (after the first), so volumes without one get
  ``g = 1``.

Lenses
------
One ``clip`` or ``dvr`` lens (:mod:`core.lens`) by option ``lens_method``, each as VTK users have
it. The reference keeps the no-lens samples and classifies each by whether it lies in the lens's
exact interval ``[t_Lin, t_Lout]`` along the ray; what each method does instead, measured against
it (``tests/test_vtk_lens.py``; orthographic 48² views at 30°/20°, early termination off,
perspective views within 2 dB; VTK without a lens: 54.8 dB on the homogeneous 24³ cube of opacity
6/255 per voxel, 54.7 dB on the 32³ ``ct_skull`` with its ``bone`` preset):

* ``label-map`` (``clip`` and ``dvr``): the lens voxelised at the volume's resolution (label 1
  where a voxel centre lies in the closed lens, placed as the volume is: :func:`lens_mask`) is the
  mapper's label-map mask, a ``uint8`` cell-data image beside the volume. VTK fetches it once per
  sample, nearest-filtered, so a sample takes its voxel's label: the lens's boundary is a staircase
  on the voxel grid (up to half a voxel off the surface), not resolved to the sample. Label 0 keeps
  the volume's classification; label 1 gets the lens's table
  (:meth:`~core.lens.LensAppearance.classification`) through VTK 9's per-label functions
  (``SetLabelColor``, ``SetLabelScalarOpacity``, ``SetLabelGradientOpacity`` for the lens's
  gradient opacity), or zero opacity for ``clip``. VTK fills the label tables into a 1024-texel
  texture looked up nearest (ours: linear) and does not correct them for the step, so the opacity
  is corrected here, per texel (``Δ/Δ0`` with the lens table's ``Δ0``, no 1e-4 floor). A lens
  enclosing the volume (no boundary) with another table: 64.5 dB, with a gradient opacity 52.9 dB.
  With a boundary the voxel edge dominates: on the cube a box clip lens through its +x face off
  the voxel grid 51.9 dB, a box inside it 46.7 dB, a sphere (r = 9 voxels) 46.8 dB; on the skull a
  sphere ``dvr`` lens of another table (opacity ×2) 33.5 dB (max 0.79 on its rim; 35.1 dB with
  Phong), the same sphere as a ``clip`` lens 46.4 dB. Faces on voxel boundaries cost nothing (the
  images equal cropping's).
* ``cropping`` (``clip``, a box along the volume's axes, in any placement of both): the cropping
  planes are the lens box in the volume's data coordinates (:func:`cropping_planes`), the region
  flags every region but the centre one. VTK tests each sample's region and skips the sample, on
  the no-lens lattice, so it differs from the reference only on samples exactly on a face (VTK's
  region is half-open, the lens interval closed): the +x box 55.9 dB and the inner one 55.0 dB
  (the no-lens level), on the skull a box 49.6 dB and a slab 53.4 dB.
* ``clipping-planes`` (``clip``, a lens that alone cuts the box with one face: :func:`clipping_plane`
  finds the face whose inner side of the box lies in the lens, so that the box minus the lens is
  the box beyond that plane; VTK's planes keep an intersection of half-spaces, so nothing else fits,
  and a sphere never does): one plane on that face, normal out of the lens. VTK moves the ray's
  entry (or exit) to the plane and samples from there (``entry + k·Δ``): the lattice behind the
  plane shifts and its partial step is dropped. The +x box 54.2 dB, a box turned 25° cutting the
  cube 55.0 dB (the label map: 47.3), the skull's slab 54.5 dB.

``mip`` and ``iso`` lenses are refused (VTK applies the label map in its composite blend only), as
are ``dvr`` lenses with ``cropping`` or ``clipping-planes`` (they only remove samples) and the depth
pass with a lens. The voxelisation and the mask's upload are part of ``setup``.

Timing
------
Stages: ``setup`` (building the VTK objects for a new volume set, lens, classification, mode,
shading, projection or image size, and VTK's first ``Render()`` with it, which uploads the
textures and compiles the shader), measured when the pipeline is built and reported with every
frame that uses it, so that the timing harness's median over repeated frames keeps it; it is
not part of ``total``. Per frame: ``render`` (``Render()`` forced to finish with ``glFinish``,
wall clock), ``readback`` (the float colour texture to our image) and ``total`` (the frame,
camera and light updates included, setup excluded). Counters: ``pixels``, ``voxels``
(summed over volumes), ``volumes``.
"""

import numpy as np

from core.errors import UnsupportedFeatureError
from core.scene import VolumeInstance
from renderers.base import Capabilities, Option, RenderResult, step_factor_option, world_step
from renderers.vtk import common

MAX_VOLUMES = 7
"""Largest ``vtkMultiVolume`` offered. Each input binds up to four textures (volume, colour,
opacity and gradient-opacity tables) plus a few shared ones; 7 fit the 32 fragment-shader
texture units of Mesa's and the GPU vendors' drivers (measured on llvmpipe: 7 shaded volumes
with gradient opacity link, 8 fail with "too many fragment shader texture samplers"). A driver
with fewer units fails to link the shader, which the backend raises as an error."""

FAR_EYE = 1000.0
"""How much further out the VTK camera sits in orthographic views with the headlight."""

MIN_TABLE_WIDTH = 1024
"""VTK's smallest lookup texture (``vtkOpenGLVolumeLookupTable``)."""

TERMINATION = "const float g_opacityThreshold = 1.0 - 1.0 / 255.0;"
"""VTK's early-termination constant, as its shader composer writes it (VTK 9.3 to 9.7)."""

NO_TERMINATION = "const float g_opacityThreshold = 2.0;"

BLEND_MODES = {"dvr": "SetBlendModeToComposite", "mip": "SetBlendModeToMaximumIntensity",
               "iso": "SetBlendModeToIsoSurface"}

LENS_METHODS = ("label-map", "cropping", "clipping-planes")
"""How a lens scene maps onto VTK (option ``lens_method``; the module notes say what each renders)."""

LENS_LABEL = 1
"""The label of the voxels inside the lens in the label-map mask; 0 keeps the volume's own classification."""

LENS_VTK = {
    "label-map": "label-map mask (SetMaskInput, MaskTypeToLabelMap): label 1 at voxel centres inside the lens, "
                 "fetched nearest per sample; label 1's table nearest-filtered, opacity corrected by volbench",
    "cropping": "cropping regions: every region but the centre one (the lens box in data coordinates), tested "
                "per sample",
    "clipping-planes": "one clipping plane on a lens face: the ray segment shortened, samples restart at the plane",
}
"""What each lens method gives VTK (the records' ``lens_vtk``)."""

LABEL_TABLE_WIDTH = 1024
"""Width of VTK's label-map lookup texture (``vtkOpenGLVolumeMaskTransferFunction2D``: always 1024)."""

ALL_REGIONS = 0x7FFFFFF
"""Cropping-region flags of all 27 regions: bit ``i`` is region ``i + 1`` of ``x + 3·(y − 1) + 9·(z − 1)``,
each coordinate 1, 2 or 3 for below, between and above the cropping planes of that axis."""

CENTRE_REGION = 0x2000
"""The flag of the region between all six cropping planes (VTK's ``VTK_CROP_SUBVOLUME``): the lens."""

AXIS_TOLERANCE = 1e-9
"""How large, relative to a lens box edge's length, its components off the volume's axis may be for cropping."""

PLANE_TOLERANCE = 1e-9
"""How far, relative to the volume box's diameter, a point may lie outside a lens face and count as inside."""


def table_width(transfer_function):
    """The lookup-texture width VTK picks for :func:`.common.dense_functions`: a power of two, >= 1024."""
    return max(MIN_TABLE_WIDTH, 1 << (transfer_function.size - 1).bit_length())


class VtkGpuRenderer(common.VtkRenderer):
    """VTK's OpenGL GPU ray caster (``vtkOpenGLGPUVolumeRayCastMapper``), offscreen through EGL.

    ``options`` also records ``effective_step``, the ``SampleDistance`` of the last render.

    Notes
    -----
    See the module notes for how the scene maps onto VTK, what differs from the reference,
    and the timing stages.
    """

    name = "vtk-gpu"
    description = ("VTK vtkOpenGLGPUVolumeRayCastMapper (offscreen EGL): cell-data textures, "
                   "post-classified, early termination at 1 - 1/255 unless disabled")
    capabilities = Capabilities(
        projections=frozenset({"orthographic", "perspective"}),
        modes=frozenset({"dvr", "mip", "iso"}),
        shading=frozenset({"none", "phong"}),
        max_volumes=MAX_VOLUMES,
        gradient_opacity=True,
        transforms=True,
        lenses=True,
        camera_inside_volume=True,
        reasons={
            "max_volumes": f"VTK's vtkMultiVolume binds up to four textures per volume: {MAX_VOLUMES} volumes "
                           "fit the 32 fragment-shader texture units of common drivers",
            "meshes": "the backend renders volumes only (VTK's polygon mappers are not wired in)",
            "lenses": "one clip or dvr lens by lens_method: label-map (the lens voxelised at the volume's "
                      "resolution into a mask, label 1 classified by the lens's table, nearest-filtered), cropping "
                      "(a clip box lens along the volume's axes, tested per sample) or clipping-planes (a clip lens "
                      "whose cut of the box is one half-space: the ray segment shortened); mip and iso lenses and "
                      "other scenes are refused with the method that fits",
        },
    )
    option_table = (
        step_factor_option(0.25, "``SampleDistance`` as a fraction of the smallest voxel edge, in object space "
                                 "for one volume, in world space for several; the default is the reference's."),
        Option("early_termination", bool, True, "Keep VTK's early ray termination at opacity ``1 − 1/255`` (VTK as "
               "used). ``False`` disables it through a shader replacement, for accuracy runs."),
        Option("depth_pass", bool, False, "Start rays at a contour of the data at the transfer function's Φ_t "
               "(VTK's depth pass, see the module notes; lossy)."),
        Option("lens_method", str, "label-map", "How a lens scene maps onto VTK: ``label-map`` (a voxelised lens "
               "mask with a transfer function per label: clip and dvr lenses), ``cropping`` (cropping regions: a clip "
               "box lens along the volume's axes) or ``clipping-planes`` (one clipping plane: a clip lens that cuts "
               "the volume's box with one face). See the module notes. No effect without a lens.",
               choices=LENS_METHODS),
    )
    quality_sweep = tuple({"step_factor": factor} for factor in (1.0, 0.5, 0.25))
    """Sample distance from one voxel to the reference's quarter voxel."""

    def __init__(self, **options):
        super().__init__(**options)
        self._open()

    def environment(self):
        return {**super().environment(), "vtk_mapper": "vtkOpenGLGPUVolumeRayCastMapper"}

    def check(self, scene):
        """Also refuse what the capabilities cannot express: several volumes outside ``dvr``, or
        lit by another light than the headlight."""
        super().check(scene)
        if self.depth_pass and (len(scene.volumes) > 1 or scene.mode != "dvr"):
            raise UnsupportedFeatureError(self.name, f"the depth pass with {len(scene.volumes)} volumes in mode "
                                          f"{scene.mode!r}", "VTK's depth pass contours one volume, for dvr")
        if self.depth_pass:
            linear = scene.volumes[0].transform[:3, :3]
            if not (np.allclose(linear, np.diag(np.diag(linear)), rtol=0.0, atol=1e-12) and (np.diag(linear) > 0).all()):
                raise UnsupportedFeatureError(self.name, "the depth pass with a rotated or mirrored volume",
                                              "VTK's depth pass draws its contour without the volume's user matrix, so "
                                              "only a scale along the axes and a translation can be placed in the data")
        if scene.lenses:
            check_lens(self.name, self.lens_method, scene.lenses[0], scene.volumes[0], depth_pass=self.depth_pass)
        if len(scene.volumes) > 1:
            if scene.mode != "dvr":
                raise UnsupportedFeatureError(
                    self.name, f"{len(scene.volumes)} volumes in mode {scene.mode!r}",
                    "VTK's multi-volume rendering (vtkMultiVolume) composites only (dvr)")
            if scene.shading.model == "phong" and not common.is_headlight(scene.shading):
                raise UnsupportedFeatureError(
                    self.name, f"{len(scene.volumes)} volumes lit from {scene.shading.light_direction}",
                    "VTK's multi-volume shader shades with its headlight only")

    # ------------------------------------------------------------------------------------------
    def _key(self, scene):
        """Everything that needs new VTK objects or a new shader (not the camera's pose).

        Volumes and classifications compare by identity (they are immutable), and the key holds
        them, so an identity cannot be reused by another object while the key lives.
        """
        instances = tuple((i.volume, i.transfer_function, i.gradient_opacity, i.isovalue, i.transform.tobytes())
                          for i in scene.volumes)
        if len(scene.volumes) == 1:
            step = self.step_factor * scene.volumes[0].volume.min_spacing
        else:
            step = world_step(scene, self.step_factor)
        return (instances, scene.lenses, scene.mode, scene.shading, scene.camera.projection, scene.width,
                scene.height, step)

    def _build(self, scene, key):
        modules = common.vtk_modules()
        step = key[-1]
        mapper = modules.vtkOpenGLGPUVolumeRayCastMapper()
        mapper.SetAutoAdjustSampleDistances(0)
        mapper.SetLockSampleDistanceToInputSpacing(0)
        mapper.SetImageSampleDistance(1.0)
        mapper.SetUseJittering(0)
        mapper.SetSampleDistance(step)
        getattr(mapper, BLEND_MODES[scene.mode])()
        any_gradient = scene.mode == "dvr" and any(i.gradient_opacity is not None for i in scene.volumes)
        images = {}
        volumes = []
        for port, instance in enumerate(scene.volumes):
            image, _, (lo, hi) = self._image(instance.volume, images)
            placed = instance.transform
            if self.depth_pass:
                image, placed = self._with_point_scalars(image, instance.transform, modules), np.eye(4)
                mapper.SetScalarModeToUseCellData()
                mapper.SetUseDepthPass(1)
                mapper.GetDepthPassContourValues().SetValue(0, self._contour_value(instance, lo, hi))
            mapper.SetInputDataObject(port, image)
            volume = modules.vtkVolume()
            volume.SetProperty(self._property(instance, scene, lo, hi, any_gradient))
            volume.SetUserMatrix(common.vtk_matrix(placed))
            volumes.append(volume)
        if len(volumes) == 1:
            prop3d = volumes[0]
        else:
            prop3d = modules.vtkMultiVolume()
            for port, volume in enumerate(volumes):
                prop3d.SetVolume(volume, port)
        prop3d.SetMapper(mapper)
        if not self.early_termination:
            prop3d.GetShaderProperty().AddFragmentShaderReplacement(TERMINATION, False, NO_TERMINATION, False)
        keep = list(volumes)
        if scene.lenses:
            keep += self._apply_lens(scene.lenses[0], scene.volumes[0], volumes[0].GetProperty(), mapper, step,
                                     images[scene.volumes[0].volume][2])
        return common.Pipeline(key, prop3d, mapper, step, images, keep)

    def _apply_lens(self, lens, instance, prop, mapper, step, data_range):
        """Give ``mapper`` (and the volume's ``prop``) the lens by :attr:`lens_method`; returns what must stay alive."""
        modules = common.vtk_modules()
        if self.lens_method == "cropping":
            mapper.CroppingOn()
            mapper.SetCroppingRegionPlanes(*cropping_planes(lens, instance))
            mapper.SetCroppingRegionFlags(ALL_REGIONS & ~CENTRE_REGION)
            return []
        if self.lens_method == "clipping-planes":
            normal, offset = clipping_plane(lens, instance)
            plane = modules.vtkPlane()
            plane.SetOrigin(*(offset * normal))
            plane.SetNormal(*normal)  # VTK keeps normal·(x − origin) >= 0: outside the lens's face
            planes = modules.vtkPlaneCollection()
            planes.AddItem(plane)
            mapper.SetClippingPlanes(planes)
            return [planes]
        labels = lens_mask(lens, instance)
        array = modules.numpy_to_vtk(labels.ravel(), deep=False)
        array.SetName("lens")
        mask = modules.vtkImageData()
        mask.SetSpacing(*instance.volume.spacing)
        mask.SetDimensions(*(n + 1 for n in instance.volume.shape_xyz))
        mask.GetCellData().SetScalars(array)
        mapper.SetMaskInput(mask)
        mapper.SetMaskTypeToLabelMap()
        mapper.SetMaskBlendFactor(1.0)
        lo, hi = data_range
        inside = lens.appearance.classification(instance.transfer_function)
        if inside is None:  # clip: the label's samples are transparent (VTK gives it the volume's colours, unused)
            prop.SetLabelScalarOpacity(LENS_LABEL, common.constant_function(0.0))
            return [mask, labels]
        # VTK corrects the volume's own table for the step, not the label tables: done here.
        reference_step = VolumeInstance(instance.volume, inside).reference_step
        colour, opacity = common.dense_functions(inside, lo, hi, LABEL_TABLE_WIDTH, step=step,
                                                 reference_step=reference_step)
        prop.SetLabelColor(LENS_LABEL, colour)
        prop.SetLabelScalarOpacity(LENS_LABEL, opacity)
        if lens.appearance.gradient_opacity is not None:
            prop.SetLabelGradientOpacity(LENS_LABEL, common.gradient_function(
                lens.appearance.gradient_opacity, reference_step, instance.volume.spacing))
        return [mask, labels, colour, opacity]

    @staticmethod
    def _with_point_scalars(image, transform, modules):
        """``image`` (cell scalars) with point scalars beside them for the depth pass's contour, placed in world
        space by ``transform`` (an axis-aligned scale and a translation: the pass ignores a user matrix)."""
        to_points = modules.vtkCellDataToPointData()
        to_points.SetInputData(image)
        to_points.PassCellDataOn()
        to_points.Update()
        placed = to_points.GetOutput()
        scale = np.diag(transform)[:3]
        placed.SetSpacing(*(scale * np.asarray(image.GetSpacing())))
        placed.SetOrigin(*(transform[:3, 3] + scale * np.asarray(image.GetOrigin())))
        return placed

    @staticmethod
    def _contour_value(instance, lo, hi):
        """Φ_t in the image's values: the lowest table entry whose opacity is above 0, on the scalar range ``[lo, hi]``."""
        alpha = instance.transfer_function.table[:, 3]
        visible = np.flatnonzero(alpha > 0)
        first = visible[0] / (alpha.size - 1) if visible.size else 1.0
        return float(lo + first * (hi - lo))

    def _property(self, instance, scene, lo, hi, any_gradient):
        transfer_function = instance.transfer_function
        colour, opacity = common.dense_functions(transfer_function, lo, hi, table_width(transfer_function))
        gradient = None
        if scene.mode == "iso":
            # VTK composites the hit with the opacity table at the isovalue; ours is opaque.
            opacity = common.constant_function(1.0)
        elif any_gradient:  # dvr only; all inputs or none (module notes), g = 1 where a volume has none
            gradient = (common.constant_function(1.0) if instance.gradient_opacity is None else
                        common.gradient_function(instance.gradient_opacity, instance.reference_step,
                                                 instance.volume.spacing))
        prop = common.volume_property(colour=colour, opacity=opacity, unit_distance=instance.reference_step,
                                      shading=scene.shading if scene.mode != "mip" else None, gradient=gradient)
        if scene.mode == "iso":
            prop.GetIsoSurfaceValues().SetValue(0, instance.isovalue)
        return prop

    def _render(self, scene):
        headlight = common.is_headlight(scene.shading)
        orthographic = scene.camera.projection == "orthographic"
        pipeline, image, timings = self._frame(scene, headlight=headlight,
                                               eye_factor=FAR_EYE if headlight and orthographic else 1.0)
        counters = {"pixels": scene.width * scene.height,
                    "voxels": sum(int(np.prod(i.volume.shape_xyz)) for i in scene.volumes),
                    "volumes": len(scene.volumes)}
        if scene.shading.model == "none" or scene.mode == "mip":
            light = None
        elif headlight:
            light = "VTK headlight, " + ("eye moved out: directional" if orthographic else "a point light at the eye")
        else:
            light = "directional camera light (VTK's multi-light path: ambient not tinted by the colour)"
        info = {
            "step": pipeline.step,
            "step_space": "object" if len(scene.volumes) == 1 else "world (the multi-volume bounding box)",
            "early_termination": 1 - 1 / 255 if self.early_termination else None,
            "data_layout": "cell data on an (n+1)-point grid: box and clamp-to-edge as ours",
            "sampling": "entry + k*step for k >= 1, last partial step dropped (ours: cell midpoints)",
            "light": light,
            "specular": "Phong reflection vector (ours: Blinn-Phong half vector)",
            "readback": "float32 framebuffer-pass texture, premultiplied RGBA",
            "timing": "wall clock around Render() + glFinish",
        }
        if scene.lenses:
            lens = scene.lenses[0]
            info.update(lens=f"{lens.shape} {lens.appearance.mode}", lens_method=self.lens_method,
                        lens_vtk=LENS_VTK[self.lens_method])
        return RenderResult(image=image, timings=timings, counters=counters, info=info)


# -- lenses ------------------------------------------------------------------------------------

def check_lens(backend, method, lens, instance, *, depth_pass):
    """Refuse, before any work, a lens that ``method`` cannot render (see the module notes).

    Raises
    ------
    UnsupportedFeatureError
        With the depth pass; a ``mip`` or ``iso`` appearance; a ``dvr`` appearance with
        ``cropping`` or ``clipping-planes``; a box lens not along the volume's axes or another
        shape with ``cropping``; a sphere, or a lens whose cut of the volume's box is not one
        half-space of it, with ``clipping-planes``. Each names the method that fits.
    """
    if depth_pass:
        raise UnsupportedFeatureError(backend, f"lens {lens.name!r} with the depth pass",
                                      "the depth pass starts rays at a contour of the volume's own classification, "
                                      "which a lens does not follow; use depth_pass=False")
    mode = lens.appearance.mode
    if mode in ("mip", "iso"):
        raise UnsupportedFeatureError(backend, f"lens {lens.name!r} with a {mode!r} appearance",
                                      "VTK applies a second classification per voxel (the label map) in its "
                                      "composite blend only; it has no blend mode for one segment of a ray; use a "
                                      "clip or dvr appearance, or the reference backend")
    if method == "label-map":
        return
    if mode != "clip":
        raise UnsupportedFeatureError(backend, f"lens {lens.name!r} with a {mode!r} appearance and lens_method "
                                      f"{method!r}", f"VTK's {method} only remove samples (a clip lens); use "
                                      "lens_method='label-map' for a dvr lens")
    if method == "cropping":
        if lens.shape != "box":
            raise UnsupportedFeatureError(backend, f"{lens.shape} lens {lens.name!r} with lens_method 'cropping'",
                                          "VTK's cropping regions are boxes along the volume's axes; use "
                                          "lens_method='label-map'")
        cropping_planes(lens, instance, backend=backend)
    else:
        clipping_plane(lens, instance, backend=backend)


def lens_to_object(lens, instance):
    """The lens's object→volume-object matrix: where the lens lies in the volume's data coordinates."""
    return np.linalg.inv(instance.transform) @ lens.object_to_world()


def cropping_planes(lens, instance, *, backend="vtk-gpu"):
    """VTK's cropping-region planes ``(x0, x1, y0, y1, z0, z1)``: the box lens in the volume's data coordinates.

    Raises
    ------
    UnsupportedFeatureError
        The lens's edges are not along the volume's axes (a rotated lens or volume).
    """
    matrix = lens_to_object(lens, instance)
    edges = np.abs(matrix[:3, :3])  # column j: the lens's j-th axis in the volume's frame
    off_axis = edges.sum(axis=0) - edges.max(axis=0)
    if (off_axis > AXIS_TOLERANCE * edges.max(axis=0)).any():
        raise UnsupportedFeatureError(backend, f"box lens {lens.name!r} with lens_method 'cropping' rotated against "
                                      f"volume {instance.name!r}", "VTK's cropping regions are boxes along the "
                                      "volume's axes; give the lens the volume's orientation, or use "
                                      "lens_method='label-map'")
    half = np.asarray(lens.size) / 2
    corners = np.array([[x, y, z, 1.0] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * [*half, 1.0]
    placed = (corners @ matrix.T)[:, :3]
    lo, hi = placed.min(axis=0), placed.max(axis=0)
    return tuple(float(v) for pair in zip(lo, hi) for v in pair)


BOX_EDGES = tuple((a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1)
"""The twelve edges of a box as pairs of :meth:`VolumeInstance.world_corners` indices (one bit apart)."""


def clipping_plane(lens, instance, *, backend="vtk-gpu"):
    """``(n, c)``: a face of a clip lens such that the box minus the lens is the box where ``n·x > c``.

    VTK's clipping planes keep the intersection of their half-spaces, so they render the box minus
    a convex lens exactly only when that is one half-space of the box: when the part of the box
    on the inner side of one of the lens's face planes lies wholly inside the lens (a lens cutting
    the box with one face; also one that misses the box across a face plane, or encloses it).
    That part is a convex polytope, inside the lens when its vertices are (the box corners on the
    inner side and the box edges' crossings of the plane).

    Raises
    ------
    UnsupportedFeatureError
        A sphere, or a lens no face of which cuts the box alone.
    """
    if lens.shape == "sphere":
        raise UnsupportedFeatureError(backend, f"sphere lens {lens.name!r} with lens_method 'clipping-planes'",
                                      "VTK's clipping planes keep an intersection of half-spaces, and the box minus "
                                      "a sphere is none; use lens_method='label-map'")
    normals, offsets = lens.world_half_spaces()
    corners = instance.world_corners()
    tolerance = PLANE_TOLERANCE * float(np.linalg.norm(np.ptp(corners, axis=0)))
    for normal, offset in zip(normals, offsets):
        side = corners @ normal - offset  # <= 0: the lens's side of this face's plane
        vertices = [corners[side <= 0]]
        for a, b in BOX_EDGES:
            if side[a] * side[b] < 0:
                vertices.append((corners[a] + side[a] / (side[a] - side[b]) * (corners[b] - corners[a]))[None])
        vertices = np.concatenate(vertices)
        if (vertices @ normals.T - offsets <= tolerance).all():
            return normal, float(offset)
    raise UnsupportedFeatureError(backend, f"clip lens {lens.name!r} with lens_method 'clipping-planes'",
                                  f"it cuts volume {instance.name!r}'s box with more than one face, so the box minus "
                                  "the lens is not one half-space of the box, and VTK's clipping planes keep only an "
                                  "intersection of half-spaces; use lens_method='cropping' (a box along the volume's "
                                  "axes) or 'label-map'")


def lens_mask(lens, instance):
    """The lens voxelised at the volume's resolution (:meth:`core.lens.Lens.voxel_mask`): ``uint8``
    ``(nz, ny, nx)``, :data:`LENS_LABEL` where the voxel centre lies in the lens, 0 elsewhere."""
    return lens.voxel_mask(instance.volume, instance.transform).astype(np.uint8) * LENS_LABEL
