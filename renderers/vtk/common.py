"""What the two VTK backends share: the scene as VTK objects, an offscreen window, readback, probe.

VTK is imported lazily (:func:`vtk_modules`), so the registry can list these backends and say why
they cannot run where the wheel is missing.

Offscreen window
----------------
VTK ≥ 9.4's PyPI wheel picks its OpenGL window class at run time; without an X display its
default factory tries X first, warns (``bad X server connection``) and falls back to EGL. The
backends create a ``vtkEGLRenderWindow`` themselves: a headless context through EGL (Mesa's
llvmpipe on a machine without a GPU, the vendor's EGL driver on one with a GPU), no X involved.
:func:`offscreen_support` asks that window whether it gets an OpenGL 3.2 context
(``SupportsOpenGL``, which fails cleanly; rendering into a window without a context crashes the
process) and says why not when it cannot.

Device
------
The window follows the OpenGL backends' device variable (:data:`GL_DEVICE_VARIABLE`) as far as
VTK can: an EGL device index is given to the window (``SetDeviceIndex``; checked against VTK's
device count first, since VTK indexes its device list with it unchecked), and a renderer name
is checked against the renderer VTK's default device gives, the backends being unavailable
when it does not match (VTK takes indices only, and its record names the device it used).
Without the variable VTK keeps its own default, device 0 (or ``VTK_DEFAULT_EGL_DEVICE_INDEX``),
and does not search the devices for a GPU as :mod:`renderers.gl.context` does: that search
opens a window on each device in turn, and a VTK window's teardown terminates its device's EGL
display, which a GL backend's context in the same process may be using, on machines with GPUs
that this project cannot test on. On a machine with an NVIDIA GPU, libglvnd lists NVIDIA's
devices before Mesa's, so device 0 is the GPU; where Mesa drives the GPU, its software device
comes first and :data:`GL_DEVICE_VARIABLE` chooses the GPU for both kinds of backend.

Readback
--------
VTK's window framebuffers are 8-bit RGBA (``vtkOpenGLRenderWindow::CreateFramebuffers``), and
8-bit quantisation alone would cap the agreement with the reference near 59 dB. The renderer
therefore runs VTK's standard render steps (``vtkRenderStepsPass``) inside a
``vtkFramebufferPass`` whose colour texture is ``GL_RGBA32F``, and reads that texture back. Its
depth texture must be ``Fixed32``: the GPU mapper copies the depth buffer with a blit into its
own ``GL_DEPTH_COMPONENT32`` texture, a blit needs matching depth formats, and with the pass's
default ``Float32`` depth the copy fails and every ray is discarded (an empty image). Both
mappers blend premultiplied colour (``GL_ONE, GL_ONE_MINUS_SRC_ALPHA``) over the cleared,
transparent-black texture, so the texture holds premultiplied RGBA, our convention (checked in
``tests/test_vtk.py``: colour never exceeds alpha, and the images agree with the reference). GL's
row 0 is the bottom of the picture, so rows are flipped.

Camera
------
Position, focal point and view-up are our camera's eye, target and up (the orthonormal one from
:meth:`core.camera.Camera.basis`); orthographic views set the parallel scale to half the view
height, perspective views the vertical view angle. Pixel centres are at half-integers in both.
The clipping range is set from the scene's boxes, not VTK's ``ResetCameraClippingRange``: the
near plane just in front of the nearest box corner (or a small fraction of the far distance when
the eye is inside a box, where VTK's rays start at the near plane and ours at the eye).
"""

import functools
import os
import time
from types import SimpleNamespace

import numpy as np

from core.errors import BackendUnavailableError
from core.transfer import MAX_GRADIENT, correct_opacity
from renderers.base import Renderer

VTK_FLOAT = 10
"""``VTK_FLOAT`` (``vtkType.h``), the scalar type asked of texture downloads."""

VTK_STRING = 13
"""``VTK_STRING`` (``vtkType.h``), the call-data type of error events."""

MIN_VTK = (9, 4)
"""First VTK whose wheel has ``vtkEGLRenderWindow`` next to the X window (run-time selection)."""

INSTALL_HINT = "pip install 'vtk>=9.4,<10'"
EGL_HINT = ("install Mesa's EGL (apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri) or a GPU driver "
            "with EGL")

GL_DEVICE_VARIABLE = "VOLBENCH_GL_DEVICE"
"""The OpenGL backends' device variable (``renderers.gl.context.DEVICE_VARIABLE``), which VTK follows
(see the module notes); named here, not imported, since a backend package imports no other."""

NEAR_FRACTION = 1e-4
"""Near plane as a fraction of the far distance when the eye is inside a box."""

CLIP_MARGIN = 1e-3
"""Margin of the clipping range beyond the boxes, as a fraction of the scene's diameter."""


@functools.cache
def vtk_modules():
    """The VTK classes the backends use, imported once (``ImportError`` if VTK is missing)."""
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonCore import vtkMultiThreader, vtkVersion
    from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPiecewiseFunction, vtkPlane, vtkPlaneCollection
    from vtkmodules.vtkCommonMath import vtkMatrix4x4
    from vtkmodules.vtkFiltersCore import vtkCellDataToPointData
    from vtkmodules.vtkRenderingCore import (vtkColorTransferFunction, vtkLight, vtkRenderer, vtkVolume,
                                             vtkVolumeProperty)
    from vtkmodules.vtkRenderingOpenGL2 import (vtkEGLRenderWindow, vtkFramebufferPass, vtkRenderStepsPass,
                                                vtkTextureObject)
    from vtkmodules.vtkRenderingVolume import vtkFixedPointVolumeRayCastMapper, vtkMultiVolume
    from vtkmodules.vtkRenderingVolumeOpenGL2 import vtkOpenGLGPUVolumeRayCastMapper

    return SimpleNamespace(
        numpy_to_vtk=numpy_to_vtk, vtkMultiThreader=vtkMultiThreader, vtkVersion=vtkVersion,
        vtkImageData=vtkImageData, vtkPiecewiseFunction=vtkPiecewiseFunction, vtkPlane=vtkPlane,
        vtkPlaneCollection=vtkPlaneCollection, vtkMatrix4x4=vtkMatrix4x4,
        vtkColorTransferFunction=vtkColorTransferFunction, vtkLight=vtkLight, vtkRenderer=vtkRenderer,
        vtkVolume=vtkVolume, vtkVolumeProperty=vtkVolumeProperty, vtkEGLRenderWindow=vtkEGLRenderWindow,
        vtkFramebufferPass=vtkFramebufferPass, vtkRenderStepsPass=vtkRenderStepsPass,
        vtkTextureObject=vtkTextureObject, vtkFixedPointVolumeRayCastMapper=vtkFixedPointVolumeRayCastMapper,
        vtkMultiVolume=vtkMultiVolume, vtkOpenGLGPUVolumeRayCastMapper=vtkOpenGLGPUVolumeRayCastMapper,
        vtkCellDataToPointData=vtkCellDataToPointData)


def vtk_version():
    """VTK's version string, e.g. ``"9.7.2"``."""
    return vtk_modules().vtkVersion.GetVTKVersion()


def device_selector():
    """:data:`GL_DEVICE_VARIABLE`'s value: an EGL device index, a part of a renderer's name, or ``""``."""
    return os.environ.get(GL_DEVICE_VARIABLE, "").strip()


def make_window():
    """A new offscreen ``vtkEGLRenderWindow`` without multisampling, on the device index chosen if any."""
    window = vtk_modules().vtkEGLRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetMultiSamples(0)
    if device_selector().isdigit():
        window.SetDeviceIndex(int(device_selector()))
    return window


def gl_strings(window):
    """``{vendor, renderer, version}`` of an initialised window's OpenGL context."""
    facts = {}
    for line in window.ReportCapabilities().splitlines():
        for key in ("vendor", "renderer", "version"):
            prefix = f"OpenGL {key} string:"
            if line.startswith(prefix):
                facts[key] = line[len(prefix):].strip()
    return facts


@functools.cache
def offscreen_support():
    """``(True, "")`` if VTK renders offscreen here, else ``(False, why)``; checked once per process."""
    try:
        from vtkmodules.vtkCommonCore import vtkVersion
    except ImportError as exc:
        return False, f"VTK cannot be imported ({exc}); {INSTALL_HINT}"
    version = vtkVersion.GetVTKVersion()
    if tuple(int(part) for part in version.split(".")[:2]) < MIN_VTK:
        return False, f"VTK {version} is too old: the backends need its EGL window (VTK >= 9.4); {INSTALL_HINT}"
    try:
        vtk_modules()
    except ImportError as exc:
        return False, f"VTK {version} lacks a module the backends use ({exc}); {INSTALL_HINT}"
    selector = device_selector()
    if selector.isdigit():
        count = vtk_modules().vtkEGLRenderWindow().GetNumberOfDevices()
        if int(selector) >= count:
            return False, (f"{GL_DEVICE_VARIABLE}={selector}: VTK lists {count} EGL device(s), indices 0 to "
                           f"{count - 1}; name one of them")
    window = make_window()
    try:
        if not window.SupportsOpenGL():
            message = " ".join(window.GetOpenGLSupportMessage().split())
            return False, (f"VTK {version} gets no OpenGL 3.2 context offscreen through EGL "
                           f"(vtkEGLRenderWindow: {message!r}); {EGL_HINT}")
        if selector and not selector.isdigit():
            window.SetSize(1, 1)
            window.Initialize()
            renderer = gl_strings(window).get("renderer", "")
            if selector.lower() not in renderer.lower():
                return False, (f"{GL_DEVICE_VARIABLE}={selector!r} names a renderer, but VTK's EGL window takes a "
                               f"device index and its default device renders with {renderer!r}; set "
                               f"{GL_DEVICE_VARIABLE} to the index of the device meant (the OpenGL backends' "
                               f"records name it: gl_device_index)")
    finally:
        window.Finalize()
    return True, ""


# -- the scene as VTK data -----------------------------------------------------------------------


def vtk_matrix(array):
    """A ``vtkMatrix4x4`` holding a 4×4 array."""
    matrix = vtk_modules().vtkMatrix4x4()
    for row in range(4):
        for col in range(4):
            matrix.SetElement(row, col, float(array[row, col]))
    return matrix


def image_data(volume, *, cells):
    """The volume's normalised float32 scalars as ``vtkImageData`` in the volume's object space.

    ``cells=True``: an ``(n + 1)``-point grid from the origin with the scalars as cell data, so
    VTK's box is our ``[0, n·s]`` and its cell-data texture clamps to the edge as ours does.
    ``cells=False``: the scalars as point data on an ``n``-point grid whose points are our voxel
    centres (origin ``s/2``); VTK's box is then ``[s/2, (n − ½)·s]``, half a voxel smaller on
    every side. Returns ``(image, scalars)``; the numpy array backs the VTK array, keep it alive.
    """
    modules = vtk_modules()
    scalars = np.ascontiguousarray(volume.normalized(np.float32)).ravel()  # x fastest, as VTK's
    array = modules.numpy_to_vtk(scalars, deep=False)
    array.SetName("scalars")
    image = modules.vtkImageData()
    image.SetSpacing(*volume.spacing)
    if cells:
        image.SetDimensions(*(n + 1 for n in volume.shape_xyz))
        image.SetOrigin(0.0, 0.0, 0.0)
        image.GetCellData().SetScalars(array)
    else:
        image.SetDimensions(*volume.shape_xyz)
        image.SetOrigin(*(0.5 * s for s in volume.spacing))
        image.GetPointData().SetScalars(array)
    return image, scalars


def scalar_range(scalars):
    """``(lo, hi)`` of the normalised scalars: the range VTK maps its lookup tables over."""
    return float(scalars.min()), float(scalars.max())


def node_functions(transfer_function):
    """``(colour, opacity)`` VTK functions with one node per table entry, at ``s = i/(N − 1)``.

    VTK interpolates linearly between nodes in RGB, which is our table's lookup exactly; a
    mapper that samples the functions finely over the data range (the fixed-point mapper's
    32768-entry tables) then reproduces our classification.
    """
    return _functions(0.0, 1.0, transfer_function.table.astype(np.float64))


def dense_functions(transfer_function, lo, hi, width, *, step=None, reference_step=None):
    """``(colour, opacity)`` VTK functions that fill a ``width``-texel lookup texture with our table.

    The GPU mapper samples its functions at ``x_i = lo + i·(hi − lo)/(width − 1)`` into a
    ``width``-texel texture and looks it up, linearly filtered, at the scalar normalised over the
    data range ``[lo, hi]``, where texel ``i`` stands for ``lo + (i + ½)·(hi − lo)/width``. Giving
    the functions nodes at ``x_i`` holding our classification at the texel centres makes the
    texture hold our table at the texel centres, instead of shifting it by up to half a texel.
    ``width`` must be what VTK picks: the next power of two of the node count, at least 1024.
    ``step`` and ``reference_step`` (``Δ``, ``Δ0``) correct the opacity here, for a table VTK
    does not correct itself (the GPU mapper's label-map tables).
    """
    s = lo + (np.arange(width) + 0.5) / width * (hi - lo)
    rgba = transfer_function.lookup(s)
    if step is not None:
        rgba[:, 3] = correct_opacity(rgba[:, 3], step, reference_step)
    return _functions(lo, hi, rgba)


def _functions(lo, hi, rgba):
    modules = vtk_modules()
    colour = modules.vtkColorTransferFunction()
    colour.SetColorSpaceToRGB()
    colour.BuildFunctionFromTable(lo, hi, len(rgba), np.ascontiguousarray(rgba[:, :3]).ravel())
    opacity = modules.vtkPiecewiseFunction()
    opacity.BuildFunctionFromTable(lo, hi, len(rgba), np.ascontiguousarray(rgba[:, 3]))
    return colour, opacity


def gradient_function(gradient_opacity, reference_step, spacing):
    """Our ``g(u)`` as VTK's gradient-opacity function of its gradient measure ``G``.

    Both VTK mappers look the function up at ``G = |∇s|·h̄``, the gradient in scalar units per
    mean voxel edge ``h̄`` (central differences one voxel apart, divided by the spacing relative
    to ``h̄``), over ``[0, ¼·(data range)]`` and clamped beyond. Ours is ``g(u)`` with
    ``u = |∇s|·Δ0/(√3/2)``, so node ``u_i`` goes to ``G_i = u_i·(√3/2)·h̄/Δ0``.
    """
    table = gradient_opacity.table.astype(np.float64)
    u = np.linspace(0.0, 1.0, table.size)
    function = vtk_modules().vtkPiecewiseFunction()
    scale = MAX_GRADIENT * float(np.mean(spacing)) / reference_step
    for x, y in zip(u * scale, table):
        function.AddPoint(float(x), float(y))
    return function


def constant_function(value):
    """A ``vtkPiecewiseFunction`` that is ``value`` everywhere (VTK clamps beyond its one node)."""
    function = vtk_modules().vtkPiecewiseFunction()
    function.AddPoint(0.0, value)
    return function


def volume_property(*, colour, opacity, unit_distance, shading=None, gradient=None):
    """A linearly interpolated ``vtkVolumeProperty``; ``shading`` (a :class:`core.scene.Shading`) turns shading on."""
    prop = vtk_modules().vtkVolumeProperty()
    prop.SetColor(colour)
    prop.SetScalarOpacity(opacity)
    prop.SetScalarOpacityUnitDistance(unit_distance)
    prop.SetInterpolationTypeToLinear()
    if gradient is not None:
        prop.SetGradientOpacity(gradient)
    if shading is not None and shading.model == "phong":
        prop.ShadeOn()
        prop.SetAmbient(shading.ambient)
        prop.SetDiffuse(shading.diffuse)
        prop.SetSpecular(shading.specular)
        prop.SetSpecularPower(shading.shininess)
    else:
        prop.ShadeOff()
    return prop


def is_headlight(shading):
    """Whether the scene's light is the default headlight, ``(0, 0, 1)`` in view space."""
    return bool(np.allclose(shading.light_direction, (0.0, 0.0, 1.0), rtol=0.0, atol=1e-12))


# -- the offscreen view --------------------------------------------------------------------------

class OffscreenView:
    """An offscreen EGL window with one renderer that draws into a float32 framebuffer pass.

    The background is transparent black, automatic light creation is off (the backends set
    their own light) and two-sided lighting is VTK's default (on).
    """

    def __init__(self):
        modules = vtk_modules()
        self.window = make_window()
        self.renderer = modules.vtkRenderer()
        self.renderer.SetBackground(0.0, 0.0, 0.0)
        self.renderer.SetBackgroundAlpha(0.0)
        self.renderer.AutomaticLightCreationOff()
        self.framebuffer = modules.vtkFramebufferPass()
        self.framebuffer.SetColorFormat(modules.vtkTextureObject.Float32)
        self.framebuffer.SetDepthFormat(modules.vtkTextureObject.Fixed32)  # see the module notes
        self.framebuffer.SetDelegatePass(modules.vtkRenderStepsPass())
        self.renderer.SetPass(self.framebuffer)
        self.window.AddRenderer(self.renderer)
        self.window.SetSize(1, 1)
        self.window.Initialize()
        self.light = modules.vtkLight()
        self.renderer.AddLight(self.light)
        self._light_key = None
        self._gl = None

    def gl_facts(self):
        """``{vendor, renderer, version}`` of the window's OpenGL context."""
        if self._gl is None:
            self._gl = gl_strings(self.window)
        return self._gl

    def set_size(self, width, height):
        if tuple(self.window.GetSize()) != (width, height):
            self.window.SetSize(width, height)

    def set_camera(self, scene, *, eye_factor=1.0):
        """Our camera on VTK's; ``eye_factor`` moves the eye away from the target (orthographic only)."""
        camera = scene.camera
        vtk_camera = self.renderer.GetActiveCamera()
        right, up, back = camera.basis()
        target = np.asarray(camera.target, dtype=np.float64)
        eye = target + eye_factor * (camera.eye - target)
        vtk_camera.SetFocalPoint(*target)
        vtk_camera.SetPosition(*eye)
        vtk_camera.SetViewUp(*up)
        if camera.projection == "orthographic":
            vtk_camera.ParallelProjectionOn()
            vtk_camera.SetParallelScale(camera.view_height / 2)
        else:
            vtk_camera.ParallelProjectionOff()
            vtk_camera.UseHorizontalViewAngleOff()
            vtk_camera.SetViewAngle(camera.fov_y)
        corners = np.concatenate([instance.world_corners() for instance in scene.volumes])
        depth = (corners - eye) @ -back
        margin = CLIP_MARGIN * float(np.ptp(corners, axis=0).max())
        far = float(depth.max()) + margin
        near = float(depth.min()) - margin
        vtk_camera.SetClippingRange(max(near, NEAR_FRACTION * far), far)

    def set_light(self, shading, *, headlight):
        """One white light: VTK's headlight (``headlight=True``) or a directional camera light.

        The camera light sits at our view-space light direction and shines at the origin of
        VTK's camera-light frame (the camera at ``+z``), i.e. it comes from that direction.
        """
        key = (headlight, shading.light_direction)
        if key == self._light_key:
            return
        light = self.light
        if headlight:
            light.SetLightTypeToHeadlight()
        else:
            light.SetLightTypeToCameraLight()
            light.SetPositional(False)
            light.SetPosition(*shading.light_direction)
            light.SetFocalPoint(0.0, 0.0, 0.0)
        light.SetIntensity(1.0)
        light.SetAmbientColor(1.0, 1.0, 1.0)
        light.SetDiffuseColor(1.0, 1.0, 1.0)
        light.SetSpecularColor(1.0, 1.0, 1.0)
        self._light_key = key

    def render(self):
        """``Render()`` forced to finish (``glFinish``); returns the wall-clock seconds."""
        start = time.perf_counter()
        self.window.Render()
        self.window.WaitForCompletion()
        return time.perf_counter() - start

    def read(self):
        """The float colour texture as our ``(H, W, 4)`` float32 premultiplied RGBA, row 0 on top."""
        width, height = self.window.GetSize()
        image = np.empty((height, width, 4), dtype=np.float32)
        buffer = self.framebuffer.GetColorTexture().Download()
        if not buffer.Download2D(VTK_FLOAT, image, [width, height], 4, [0, 0]):
            raise RuntimeError("VTK could not download its float colour texture")
        return np.ascontiguousarray(image[::-1])

    def environment(self):
        gl = self.gl_facts()
        index = self.window.GetDeviceIndex()
        return {"vtk_version": vtk_version(), "vtk_render_window": self.window.GetClassName(),
                "vtk_gl_renderer": gl.get("renderer"), "vtk_gl_version": gl.get("version"),
                "vtk_gl_vendor": gl.get("vendor"),
                # None: VTK's default device (see the module notes).
                "vtk_egl_device_index": index if index >= 0 else None}

    def close(self):
        self.renderer.RemoveAllViewProps()
        self.window.Finalize()


# -- the frame both backends render ---------------------------------------------------------------

class Pipeline:
    """The VTK objects of one configuration (``key``): the prop in the renderer and what it needs.

    ``images`` maps each Volume to its ``(vtkImageData, scalars, range)`` and ``keep`` holds
    what else must live as long as the mapper (the volumes and their properties); ``setup`` is
    the seconds it took to build them and render them once. The mapper's errors (a shader that
    does not compile or link, which VTK only logs, leaving the image empty) are collected in
    ``errors`` so that a frame can raise instead of returning an empty picture.
    """

    def __init__(self, key, prop3d, mapper, step, images, keep=()):
        self.key = key
        self.prop3d = prop3d
        self.mapper = mapper
        self.step = step
        self.images = images
        self.keep = keep
        self.setup = 0.0
        self.errors = []
        mapper.AddObserver("ErrorEvent", self._record_error)

    def _record_error(self, caller, event, message):
        self.errors.append(" ".join(message.split()))

    _record_error.CallDataType = VTK_STRING  # VTK passes the message to observers that declare it


class VtkRenderer(Renderer):
    """What both VTK backends do each frame; a subclass builds its :class:`Pipeline` from a scene.

    Subclasses set :attr:`cells` and their ``option_table``, call :meth:`_open`, and implement
    ``_key(scene)`` (what needs new VTK objects when it changes: not the camera's pose) and
    ``_build(scene, key)``, taking the volumes' image data from :meth:`_image`.
    """

    technique_stages = ("render",)
    """The stages that are the technique itself: vtkRenderWindow.Render(); not the pipeline setup or the image readback."""

    graphics_stack = "vtk"

    cells = True
    """Whether the mapper gets the scalars as cell data (see :func:`image_data`)."""

    @classmethod
    def probe(cls):
        return offscreen_support()

    def _open(self):
        ok, reason = self.probe()
        if not ok:
            raise BackendUnavailableError(f"backend {self.name!r} is not available here: {reason}")
        self._view = OffscreenView()
        self._pipeline = None
        self._images = {}
        self._last_step = None

    @property
    def options(self):
        """Options as given, plus ``effective_step``: the ``SampleDistance`` of the last render."""
        return {**super().options, "effective_step": self._last_step}

    def environment(self):
        return self._view.environment()

    def close(self):
        self._pipeline = None
        self._images = {}
        self._view.close()

    def _image(self, volume, images):
        """``(vtkImageData, scalars, (lo, hi))`` of a volume, reused from the last pipeline.

        ``images`` collects the entries the new pipeline uses; it replaces the cache once built.
        """
        entry = self._images.get(volume)
        if entry is None:
            image, scalars = image_data(volume, cells=self.cells)
            entry = (image, scalars, scalar_range(scalars))
        images[volume] = entry
        return entry

    def _read(self):
        """The frame's image (the window's float framebuffer; a subclass may read its mapper's own)."""
        return self._view.read()

    def _frame(self, scene, *, headlight, eye_factor=1.0):
        """Render ``scene`` once: ``(pipeline, image, timings)``, building the pipeline if needed.

        A new pipeline is rendered once untimed-as-frame: that ``Render()`` uploads data and
        compiles shaders, and is counted in the pipeline's ``setup`` instead of the frame.
        """
        start = time.perf_counter()
        view = self._view
        key = self._key(scene)
        view.set_size(scene.width, scene.height)
        view.set_camera(scene, eye_factor=eye_factor)
        view.set_light(scene.shading, headlight=headlight)
        setup = 0.0
        if self._pipeline is None or self._pipeline.key != key:
            setup_start = time.perf_counter()
            if self._pipeline is not None:
                view.renderer.RemoveVolume(self._pipeline.prop3d)
            self._pipeline = None  # a failed build leaves no half-built pipeline behind
            pipeline = self._build(scene, key)
            self._images = pipeline.images
            view.renderer.AddVolume(pipeline.prop3d)
            view.render()
            setup = pipeline.setup = time.perf_counter() - setup_start
            self._pipeline = pipeline
        render = view.render()
        if self._pipeline.errors:
            failed, self._pipeline = self._pipeline, None
            view.renderer.RemoveVolume(failed.prop3d)
            errors = "; ".join(dict.fromkeys(failed.errors))
            raise RuntimeError(f"backend {self.name!r}: VTK failed to render the scene: {errors}")
        rendered = time.perf_counter()
        image = self._read()
        done = time.perf_counter()
        self._last_step = self._pipeline.step
        timings = {"setup": self._pipeline.setup, "render": render, "readback": done - rendered,
                   "total": done - start - setup}
        return self._pipeline, image, timings
