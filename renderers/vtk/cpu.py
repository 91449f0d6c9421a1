"""The ``vtk-cpu`` backend: VTK's CPU ray caster, ``vtkFixedPointVolumeRayCastMapper``.

VTK casts the rays on the CPU (threaded by scan line) in 15-bit fixed point into an image of
its own, then draws that image into the window as a texture; Python builds the VTK objects from
the scene and reads the image back (:mod:`.common`).

How the scene maps onto VTK, and what differs
---------------------------------------------
Measured against the reference (``tests/test_vtk.py`` has the numbers) with VTK 9.7.2:

* **Point data only.** The fixed-point mapper reads point scalars, so each voxel becomes a
  grid point at our voxel centre (origin ``s/2``). VTK's box is then ``[s/2, (n − ½)·s]``:
  half a voxel smaller on every side than ours, without the clamp-to-edge border. Rays through
  a homogeneous box are one voxel shorter and its picture one voxel narrower (24³ voxels at two
  pixels per voxel: 13.7 dB); data that fades out before the faces does not notice. It cannot
  be removed without resampling the data.
* **Readback.** ``readback="raycast"`` (default) copies the mapper's own ray-cast image
  (``vtkFixedPointRayCastImage``: 15-bit premultiplied RGBA, :func:`raycast_image`).
  ``readback="window"`` reads what VTK draws instead: its display helper maps texture
  coordinates from the first to the last texel *centre* across the image rectangle, which
  stretches the image by one texel and filters it bilinearly, blurring it by up to half a
  pixel towards the edges of the rectangle (the opaque sphere: 27.9 dB instead of 66.0 dB).
  ``Render()`` draws the image either way, so timings do not depend on it.
* **Sampling and classification.** ``AutoAdjustSampleDistances`` and
  ``LockSampleDistanceToInputSpacing`` off, ``ImageSampleDistance`` 1, linear interpolation,
  ``SampleDistance`` = ``step_factor`` times the smallest voxel edge, in the volume's object
  space (where the mapper steps: a volume scaled by 2 takes half the samples). VTK
  interpolates the scalar, quantised to 15 bits over the data range, and classifies through
  32768-entry tables built from our transfer function (one node per table entry,
  :func:`.common.node_functions`). ``ScalarOpacityUnitDistance`` is Δ0; VTK corrects opacity per
  table entry and skips entries ≤ 1e-4, as the GPU mapper does. Composited in 15-bit fixed
  point.
* **Early ray termination.** Compiled in: a ray stops when its remaining transparency falls
  below ``255/32767`` (opacity above about 0.9922). There is no option to turn it off.
* **Modes.** ``dvr`` (composite) and ``mip`` (the largest sampled scalar, classified without
  opacity correction or shading, as the reference). The mapper has no isosurface mode.
* **Gradient opacity.** VTK's gradient measure and its ``[0, ¼·data range]`` table as for the
  GPU mapper (:func:`.common.gradient_function`), here precomputed per voxel by the mapper and
  quantised to 256 magnitudes.
* **Shading.** Table-driven (``vtkEncodedGradientShader``): per-voxel normals quantised to VTK's
  encoded directions, shaded per direction; lights are always directional. The light is a white
  camera light from our view-space light direction, so ambient (``ambient · colour``) and
  diffuse are ours; the specular term is Blinn–Phong as ours, but two-sidedness flips the
  normal towards the viewer where ours takes absolute values, and shaded colours are not
  clamped to 1 per sample (a highlight can leave a pixel's colour above its alpha).

Timing
------
As ``vtk-gpu``: ``setup`` (the VTK objects for a new volume, classification, mode, shading,
projection, image size or thread count, and the first ``Render()``, which converts the scalars
to 15 bits, builds the space-leaping min-max volume and, with shading or gradient opacity, the
gradients and normals), measured when the pipeline is built, reported with every frame that
uses it and not part of ``total``; per frame ``render`` (``Render()`` forced to finish: the ray
casting and drawing its image), ``readback`` and ``total``. Counters: ``pixels``, ``voxels``,
``threads``.
"""

import ctypes
import re

import numpy as np

from core.errors import InputError
from renderers.base import Capabilities, Option, RenderResult, step_factor_option
from renderers.vtk import common

TERMINATION_OPACITY = 1 - 255 / 32767
"""Opacity above which the fixed-point mapper stops a ray (remaining transparency < 0xff/0x7fff)."""

FIXED_POINT_ONE = 32767
"""1.0 in the mapper's 15-bit fixed point (``VTKKW_FP_SCALE``)."""

READBACKS = ("raycast", "window")
"""``raycast``: the mapper's own image; ``window``: that image as VTK draws it (see the module notes)."""

_POINTER = re.compile(r"^_([0-9a-fA-F]+)_p_void$")
"""How VTK's Python wrapping returns a ``void*`` it cannot size: ``_<hex address>_p_void``."""

BLEND_MODES = {"dvr": "SetBlendModeToComposite", "mip": "SetBlendModeToMaximumIntensity"}


class VtkCpuRenderer(common.VtkRenderer):
    """VTK's fixed-point CPU ray caster (``vtkFixedPointVolumeRayCastMapper``).

    ``options`` also records ``effective_step`` (the ``SampleDistance`` of the last render) and
    ``effective_threads`` (the threads the mapper casts rays with).

    Notes
    -----
    See the module notes for how the scene maps onto VTK, what differs from the reference
    (above all the half-voxel smaller box of point data), and the timing stages.
    """

    name = "vtk-cpu"
    description = ("VTK vtkFixedPointVolumeRayCastMapper (CPU, 15-bit fixed point): point data, "
                   "interpolate then classify, early termination at 0.992")
    capabilities = Capabilities(
        projections=frozenset({"orthographic", "perspective"}),
        modes=frozenset({"dvr", "mip"}),
        shading=frozenset({"none", "phong"}),
        gradient_opacity=True,
        transforms=True,
        camera_inside_volume=True,
        reasons={
            "modes": "vtkFixedPointVolumeRayCastMapper composites or takes the maximum; it has no "
                     "isosurface mode (its documentation: 'it does not do isosurface ray casting')",
            "max_volumes": "the fixed-point mapper renders one vtkImageData; VTK blends several volumes "
                           "per sample only on the GPU (vtkMultiVolume)",
            "meshes": "the backend renders volumes only (VTK's polygon mappers are not wired in)",
            "lenses": "the fixed-point mapper has cropping regions and clipping planes (vtk-gpu's clip-lens methods, "
                      "not wired in here) but no label-map mask, so no dvr lens; vtk-gpu carries VTK's lens peers",
        },
    )
    option_table = (
        step_factor_option(0.25, "``SampleDistance`` as a fraction of the smallest voxel edge in the volume's "
                                 "object space; the default is the reference's."),
        Option("threads", int, None, "Ray-casting threads (``SetNumberOfThreads``); ``None`` keeps VTK's default, "
               "one per core. VTK warns that results may differ slightly with more than one thread.", low=1),
        Option("readback", str, "raycast", "``raycast``: the mapper's own image; ``window``: the image as VTK draws "
               "it, resampled (see the module notes).", choices=READBACKS),
    )
    quality_sweep = tuple({"step_factor": factor} for factor in (1.0, 0.5, 0.25))
    """Sample distance from one voxel to the reference's quarter voxel."""
    cells = False  # the fixed-point mapper reads point data only

    def __init__(self, **options):
        super().__init__(**options)
        threader = common.vtk_modules().vtkMultiThreader
        if self.threads is not None:
            # VTK clamps the count to VTK_MAX_THREADS without a word; the record would claim the request.
            clamped = threader()
            clamped.SetNumberOfThreads(self.threads)
            if clamped.GetNumberOfThreads() != self.threads:
                raise InputError(f"vtk-cpu option threads: {self.threads} is more than VTK runs "
                                 f"(VTK_MAX_THREADS {clamped.GetNumberOfThreads()}); use at most that many")
        self._open()
        self._default_threads = threader.GetGlobalDefaultNumberOfThreads()

    @property
    def effective_threads(self):
        """The threads the mapper casts rays with (VTK's default, one per core, unless set)."""
        return self._default_threads if self.threads is None else self.threads

    @property
    def options(self):
        """Options as given, plus the step of the last render and the effective thread count."""
        return {**super().options, "effective_threads": self.effective_threads}

    def environment(self):
        return {**super().environment(), "vtk_mapper": "vtkFixedPointVolumeRayCastMapper",
                "vtk_threads": self.effective_threads}

    # ------------------------------------------------------------------------------------------
    def _key(self, scene):
        """Everything that needs new VTK objects (not the camera's pose); objects compare by identity."""
        instance = scene.volumes[0]
        return (instance.volume, instance.transfer_function, instance.gradient_opacity, instance.transform.tobytes(),
                scene.mode, scene.shading, scene.camera.projection, scene.width, scene.height,
                self.step_factor * instance.volume.min_spacing)

    def _build(self, scene, key):
        modules = common.vtk_modules()
        instance = scene.volumes[0]
        step = key[-1]
        images = {}
        image, _, _ = self._image(instance.volume, images)
        mapper = modules.vtkFixedPointVolumeRayCastMapper()
        mapper.SetInputData(image)
        mapper.SetAutoAdjustSampleDistances(0)
        mapper.SetLockSampleDistanceToInputSpacing(0)
        mapper.SetImageSampleDistance(1.0)
        mapper.SetSampleDistance(step)
        mapper.SetInteractiveSampleDistance(step)
        mapper.SetNumberOfThreads(self.effective_threads)
        getattr(mapper, BLEND_MODES[scene.mode])()
        colour, opacity = common.node_functions(instance.transfer_function)
        gradient = None
        if scene.mode == "dvr" and instance.gradient_opacity is not None:
            gradient = common.gradient_function(instance.gradient_opacity, instance.reference_step,
                                                instance.volume.spacing)
        prop = common.volume_property(colour=colour, opacity=opacity, unit_distance=instance.reference_step,
                                      shading=scene.shading if scene.mode == "dvr" else None, gradient=gradient)
        volume = modules.vtkVolume()
        volume.SetMapper(mapper)
        volume.SetProperty(prop)
        volume.SetUserMatrix(common.vtk_matrix(instance.transform))
        return common.Pipeline(key, volume, mapper, step, images)

    def _read(self):
        if self.readback == "window":
            return super()._read()
        return raycast_image(self._pipeline.mapper, *self._view.window.GetSize())

    def _render(self, scene):
        # Every light is directional in VTK's encoded-gradient shader; a camera light sets its direction.
        pipeline, image, timings = self._frame(scene, headlight=False)
        counters = {"pixels": scene.width * scene.height, "voxels": int(np.prod(scene.volumes[0].volume.shape_xyz)),
                    "threads": self.effective_threads}
        info = {
            "step": pipeline.step,
            "step_space": "object",
            "early_termination": TERMINATION_OPACITY,
            "data_layout": "point data at voxel centres: box half a voxel smaller per side than ours",
            "precision": "15-bit fixed point (scalars, opacities, colours)",
            "light": (None if scene.shading.model == "none" or scene.mode == "mip" else
                      "directional camera light (VTK's encoded-gradient shader)"),
            "readback": ("the mapper's 15-bit ray-cast image, premultiplied RGBA" if self.readback == "raycast" else
                         "float32 framebuffer-pass texture of VTK's drawing of the ray-cast image"),
            "timing": "wall clock around Render() + glFinish",
        }
        return RenderResult(image=image, timings=timings, counters=counters, info=info)


def raycast_image(mapper, width, height):
    """The fixed-point mapper's last ray-cast image as our ``(H, W, 4)`` float32 premultiplied RGBA.

    The mapper keeps its image in a ``vtkFixedPointRayCastImage``: 15-bit premultiplied RGBA,
    row 0 at the bottom, ``ImageInUseSize`` pixels at ``ImageOrigin`` of the viewport inside a
    buffer of ``ImageMemorySize``. VTK's Python wrapping hands the buffer out as an address only,
    which is copied here while the mapper (which owns it) is alive.
    """
    raycast = mapper.GetRayCastImage()
    if tuple(raycast.GetImageViewportSize()) != (width, height):
        raise RuntimeError(f"vtk-cpu: the ray-cast image covers {tuple(raycast.GetImageViewportSize())} pixels, "
                           f"not the window's {(width, height)}")
    match = _POINTER.match(str(raycast.GetImage()))
    if match is None:
        raise RuntimeError(f"vtk-cpu: cannot read the ray-cast image's address from {raycast.GetImage()!r}; "
                           "use the option readback='window'")
    memory_width, memory_height = raycast.GetImageMemorySize()
    address = int(match.group(1), 16)
    buffer = (ctypes.c_uint16 * (memory_width * memory_height * 4)).from_address(address)
    pixels = np.ctypeslib.as_array(buffer).reshape(memory_height, memory_width, 4)
    image = np.zeros((height, width, 4), dtype=np.float32)
    x0, y0 = raycast.GetImageOrigin()
    used_width, used_height = raycast.GetImageInUseSize()
    x1, y1 = min(x0 + used_width, width), min(y0 + used_height, height)
    if x1 > x0 and y1 > y0:
        image[y0:y1, x0:x1] = pixels[:y1 - y0, :x1 - x0] * np.float32(1.0 / FIXED_POINT_ONE)
    ctypes.memset(address, 0, ctypes.sizeof(buffer))
    return np.ascontiguousarray(image[::-1])
