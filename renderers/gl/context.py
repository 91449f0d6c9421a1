"""The one OpenGL context of a process: headless EGL through moderngl, created on first use.

Every OpenGL backend renders through :func:`shared_context`. Creating a context costs 0.1–1 s
(driver start, shader-compiler warm-up), so the context is made lazily, once per process, and
kept until the process ends; programs compiled for it are cached with it (:func:`program`).
A process forked after the context was made (the pipeline renders in child processes) cannot
use its parent's context, so the process id is part of the cache and a fork makes a new one.

Other libraries in the same process use EGL too: VTK makes its own context current and its
window teardown terminates the shared EGL display, after which this context cannot create
anything. :func:`shared_context` therefore makes the context current on every call and checks
that it still works (:func:`activate`); a context found dead is replaced by a new one, and
renderers drop the objects they made in the old one (they compare the context they get).

A failure to create or check the context is remembered for the process and reported by
:func:`probe` as ``(False, reason)`` instead of raised, so a machine without EGL or OpenGL
4.3 lists the backends as unavailable with the reason.

Which device
------------
Headless EGL lists the machine's devices (``EGL_EXT_device_enumeration``): on a machine with an
NVIDIA GPU beside Mesa, the GPU and Mesa's software rasterizer (llvmpipe) are both there.
glcontext's default, device 0, is whichever is listed first: libglvnd lists each vendor
library's devices in turn, and Mesa lists its software device before its GPUs, so device 0 is
llvmpipe on a machine whose GPU Mesa drives. So the devices are tried in index order, each by
creating a context on it (glcontext's ``device_index``), until one that is not a software
rasterizer (:data:`SOFTWARE_RENDERERS` in its ``GL_RENDERER``) gives OpenGL 4.3; failing that,
the first software device that does is used (:func:`choose_device`). The search stops at the
first hardware device, so a machine with several GPUs pays for one context per device up to
it, not for all. The environment variable :data:`DEVICE_VARIABLE` chooses instead: an EGL device index
(``1``) or a case-insensitive substring of the renderer (``nvidia``, ``llvmpipe``); the device
it names is used or the backends are unavailable with why, never another device. glcontext's
own ``GLCONTEXT_DEVICE_INDEX``, which overrides every index asked for, counts as an index
given in :data:`DEVICE_VARIABLE`.

The OpenGL backends take no ``device`` option: the context is one per process and every
texture, program and cache belongs to it, so a per-backend device would need a context per
device, each renderer switching the current context and keeping its objects apart, for a need
(two GPUs compared in one process) that no experiment has. The pipeline renders each run in a
process of its own, so the variable chooses the device of every OpenGL run. The choice (which
index) outlives a fork: a forked child makes its context on the same device without searching.
"""

import ctypes
import ctypes.util
import os
from dataclasses import dataclass, field

from core.errors import BackendUnavailableError, InputError
from renderers.base import compilation

DEVICE_VARIABLE = "VOLBENCH_GL_DEVICE"
"""Environment variable choosing the EGL device: an index or a substring of the renderer's name."""

GLCONTEXT_VARIABLE = "GLCONTEXT_DEVICE_INDEX"
"""glcontext's own device index, which overrides the ``device_index`` it is given."""

REQUIRED_VERSION = 430
"""OpenGL 4.3 core: ``layout(early_fragment_tests)`` (4.2) and shader storage buffers with atomics (4.3)."""
REQUIRED = f"OpenGL {REQUIRED_VERSION // 100}.{REQUIRED_VERSION % 100 // 10}"

SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "lavapipe", "swiftshader")
"""Substrings of ``GL_RENDERER`` that name a CPU rasterizer (timer queries, early-z differ there)."""

LIMITS = ("GL_MAX_3D_TEXTURE_SIZE", "GL_MAX_TEXTURE_SIZE", "GL_MAX_VIEWPORT_DIMS", "GL_MAX_DRAW_BUFFERS",
          "GL_MAX_COLOR_ATTACHMENTS", "GL_MAX_TEXTURE_IMAGE_UNITS", "GL_MAX_FRAGMENT_UNIFORM_COMPONENTS")
"""Implementation limits reported by :func:`environment`."""


@dataclass(frozen=True)
class EglDevice:
    """What a context made on one EGL device showed: its renderer, or why it is not usable."""

    index: int
    renderer: str = ""
    error: str = ""
    """Empty when the device gives a context of :data:`REQUIRED_VERSION`; else why not."""

    @property
    def usable(self):
        return not self.error

    @property
    def software(self):
        return is_software_renderer(self.renderer)

    def describe(self):
        """``"1: NVIDIA H100/PCIe/SSE2"``, or the index with why it is not usable."""
        if self.usable:
            return f"{self.index}: {self.renderer}"
        return f"{self.index}: {self.renderer + ', ' if self.renderer else ''}{self.error}"


@dataclass
class _Shared:
    """The process's context (or why there is none), its device and the programs compiled for it."""

    pid: int | None = None
    context: object = None
    error: str | None = None
    programs: dict = field(default_factory=dict)
    device: EglDevice | None = None
    """The device chosen; kept across a fork (indices do not change), unlike the context."""
    devices: tuple = ()
    """Every device tried before the choice, in index order."""
    device_count: int | None = None


_SHARED = _Shared()


def _create(device_index):
    """A new standalone core-profile context on EGL device ``device_index`` (raises on failure)."""
    import moderngl

    return moderngl.create_standalone_context(backend="egl", require=REQUIRED_VERSION, device_index=device_index)


def egl_device_count():
    """How many devices headless EGL lists (``eglQueryDevicesEXT``, as glcontext asks it).

    Raises
    ------
    OSError
        No libEGL, or one without device enumeration.
    """
    name = ctypes.util.find_library("EGL")
    if name is None:
        raise OSError("libEGL not found")
    egl = ctypes.CDLL(name)
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    address = egl.eglGetProcAddress(b"eglQueryDevicesEXT")
    if not address:
        raise OSError(f"{name} lacks eglQueryDevicesEXT (EGL_EXT_device_enumeration)")
    query = ctypes.CFUNCTYPE(ctypes.c_uint, ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(ctypes.c_int))(address)
    count = ctypes.c_int(0)
    if not query(0, None, ctypes.byref(count)):
        raise OSError(f"eglQueryDevicesEXT failed in {name}")
    return count.value


def device_selector():
    """``(selector, variable)`` in force: :data:`DEVICE_VARIABLE`'s, else glcontext's index, else ``""``."""
    for variable in (DEVICE_VARIABLE, GLCONTEXT_VARIABLE):
        if os.environ.get(variable, "").strip():
            return os.environ[variable].strip(), variable
    return "", DEVICE_VARIABLE


def is_software_renderer(renderer):
    """Whether a ``GL_RENDERER`` string names a CPU rasterizer (:data:`SOFTWARE_RENDERERS`)."""
    return any(name in renderer.lower() for name in SOFTWARE_RENDERERS)


def _wanted(device, selector):
    """Whether ``device`` is one the search may stop at: usable, hardware, and named by a name selector."""
    return device.usable and not device.software and selector.lower() in device.renderer.lower()


def choose_device(devices, selector, *, count, variable=DEVICE_VARIABLE):
    """The :class:`EglDevice` the backends use among ``devices`` (tried, in index order).

    ``selector`` is ``""`` (a usable hardware device first, else a usable software one), an
    index (that device) or a case-insensitive substring of the renderer (the devices it
    matches, hardware first). ``count`` is how many devices EGL lists; ``variable`` is where the
    selector was read, for the messages.

    Raises
    ------
    InputError
        The selector names no device; the message lists the devices seen.
    BackendUnavailableError
        The device named, or every device, gives no OpenGL 4.3 context; the message says why.
    """
    seen = "; ".join(device.describe() for device in devices) or "none"
    if selector.isdigit():
        named = [device for device in devices if device.index == int(selector)]
        if not named:
            raise InputError(f"OpenGL device {selector!r} ({variable}): no EGL device {selector}; this "
                             f"machine lists {count} (indices 0 to {count - 1})")
        if not named[0].usable:
            raise BackendUnavailableError(f"OpenGL device {selector!r} ({variable}): {named[0].describe()}; "
                                          f"name another device or unset {variable}")
        return named[0]
    named = [device for device in devices if selector.lower() in device.renderer.lower()]
    if selector and not named:
        raise InputError(f"OpenGL device {selector!r} ({variable}): matches no renderer; EGL devices: "
                         f"{seen}; give a part of a renderer's name or an index")
    usable = sorted((device for device in named if device.usable), key=lambda device: device.software)
    if usable:
        return usable[0]
    if selector:
        raise BackendUnavailableError(f"OpenGL device {selector!r} ({variable}): no device it names gives "
                                      f"{REQUIRED}: {seen}")
    raise BackendUnavailableError(f"no {REQUIRED} context through headless EGL on any of its {count} device(s): "
                                  f"{seen}")


def _try(index):
    """``(EglDevice, context or None)``: a context on device ``index``, checked."""
    try:
        ctx = _create(index)
    except ImportError:
        raise
    except Exception as exc:  # EGL and driver failures come as several exception types
        return EglDevice(index, error=f"{type(exc).__name__}: {exc}"), None
    try:
        _check(ctx)
    except BackendUnavailableError as exc:
        renderer = ctx.info.get("GL_RENDERER", "")
        ctx.release()
        return EglDevice(index, renderer=renderer, error=str(exc)), None
    return EglDevice(index, renderer=ctx.info.get("GL_RENDERER", "")), ctx


def _search(selector, variable):
    """Choose the device (see the module notes); return its context, the device, those tried and the count."""
    count = egl_device_count()
    if selector.isdigit():
        indices = [int(selector)] if int(selector) < count else []
    else:
        indices = range(count)
    devices, contexts = [], {}
    try:
        for index in indices:
            device, ctx = _try(index)
            devices.append(device)
            if ctx is not None:
                contexts[index] = ctx
            if _wanted(device, selector):
                break
        chosen = choose_device(devices, selector, count=count, variable=variable)
        return contexts.pop(chosen.index), chosen, tuple(devices), count
    finally:
        for ctx in contexts.values():  # the devices tried and not chosen
            ctx.release()


def _check(ctx):
    """Raise :class:`BackendUnavailableError` if ``ctx`` lacks what the backends need."""
    ctx.info  # read (and cached by moderngl) while this context is surely current
    if ctx.version_code < REQUIRED_VERSION:
        raise BackendUnavailableError(
            f"{REQUIRED} is required, the EGL context offers "
            f"{ctx.info.get('GL_VERSION', ctx.version_code)}"
        )


def activate(ctx):
    """Make ``ctx`` current and return whether it still works (see the module notes)."""
    try:
        ctx.__enter__()  # current from now on; never left, so no previous context is restored
        ctx.buffer(reserve=4).release()
        # Reading the error flag clears it: an error left by earlier work in this process (another
        # run, another backend) would otherwise surface in the next PyOpenGL call (segments-stencil).
        ctx.error
    except Exception:  # moderngl.Error, or an InvalidObject after a release: the context is unusable
        return False
    return True


def shared_context():
    """The process's moderngl context, current, created and checked on first use.

    Raises
    ------
    BackendUnavailableError
        No context could be made (no EGL, no GL 4.3, moderngl missing); the message says why.
        The failure is remembered, so later calls in the process fail at once.
    """
    pid = os.getpid()
    if _SHARED.pid != pid:
        # A forked child: the parent's context and programs belong to another process.
        _SHARED.pid, _SHARED.context, _SHARED.error, _SHARED.programs = pid, None, None, {}
    if _SHARED.context is not None:
        if activate(_SHARED.context):
            return _SHARED.context
        _SHARED.context, _SHARED.programs = None, {}
    if _SHARED.error is not None:
        raise BackendUnavailableError(_SHARED.error)
    ctx = None
    try:
        if _SHARED.device is None:
            ctx, _SHARED.device, _SHARED.devices, _SHARED.device_count = _search(*device_selector())
        else:  # the device is known (a fork, or a context that stopped working): no new search
            ctx = _create(_SHARED.device.index)
            _check(ctx)
    except (BackendUnavailableError, InputError) as exc:
        _SHARED.error = str(exc)
    except ImportError as exc:
        _SHARED.error = f"moderngl cannot be imported: {exc}"
    except Exception as exc:  # EGL and driver failures come as several exception types
        _SHARED.error = f"no {REQUIRED} context through headless EGL: {type(exc).__name__}: {exc}"
    if _SHARED.error is not None:
        if ctx is not None:
            ctx.release()
        raise BackendUnavailableError(_SHARED.error)
    _SHARED.context = ctx
    return ctx


def probe():
    """``(True, "")`` if a context can be made here, else ``(False, reason)``; never raises."""
    try:
        shared_context()
    except BackendUnavailableError as exc:
        return False, str(exc)
    return True, ""


def is_software(ctx):
    """Whether ``ctx`` renders on a CPU rasterizer (llvmpipe and the like)."""
    return is_software_renderer(ctx.info.get("GL_RENDERER", ""))


def device_facts():
    """The shared context's device for records: vendor, renderer, version, EGL index, devices tried."""
    import moderngl

    ctx = shared_context()
    info = ctx.info
    return {
        "gl_vendor": info.get("GL_VENDOR"),
        "gl_renderer": info.get("GL_RENDERER"),
        "gl_version": info.get("GL_VERSION"),
        "gl_context": "standalone, headless EGL, core profile",
        "gl_software_rasterizer": is_software(ctx),
        "gl_device_index": _SHARED.device.index,
        "gl_devices": "; ".join(device.describe() for device in _SHARED.devices),
        "gl_egl_device_count": _SHARED.device_count,
        "moderngl": moderngl.__version__,
    }


def environment():
    """Facts about the shared context for result records: :func:`device_facts` and the limits."""
    ctx = shared_context()
    facts = device_facts()
    info = ctx.info
    for name in LIMITS:
        value = info.get(name)
        facts[name.lower()] = list(value) if isinstance(value, tuple) else value
    return facts


def max_3d_texture_size(ctx):
    """``GL_MAX_3D_TEXTURE_SIZE`` of ``ctx``: the largest volume edge a 3-D texture holds."""
    return int(ctx.info["GL_MAX_3D_TEXTURE_SIZE"])


def program(ctx, vertex_shader, fragment_shader):
    """A linked program for ``ctx``, compiled once per process and source text."""
    key = (id(ctx), vertex_shader, fragment_shader)
    compiled = _SHARED.programs.get(key)
    if compiled is None:
        compiled = ctx.program(vertex_shader=vertex_shader, fragment_shader=fragment_shader)
        compilation.record()
        _SHARED.programs[key] = compiled
    return compiled
