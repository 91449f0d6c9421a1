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
"""

import os
from dataclasses import dataclass, field

from core.errors import BackendUnavailableError

REQUIRED_VERSION = 430
"""OpenGL 4.3 core: ``layout(early_fragment_tests)`` (4.2) and shader storage buffers with atomics (4.3)."""

SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "lavapipe", "swiftshader")
"""Substrings of ``GL_RENDERER`` that name a CPU rasterizer (timer queries, early-z differ there)."""

LIMITS = ("GL_MAX_3D_TEXTURE_SIZE", "GL_MAX_TEXTURE_SIZE", "GL_MAX_VIEWPORT_DIMS", "GL_MAX_DRAW_BUFFERS",
          "GL_MAX_COLOR_ATTACHMENTS", "GL_MAX_TEXTURE_IMAGE_UNITS", "GL_MAX_FRAGMENT_UNIFORM_COMPONENTS")
"""Implementation limits reported by :func:`environment`."""


@dataclass
class _Shared:
    """The process's context (or why there is none) and the programs compiled for it."""

    pid: int | None = None
    context: object = None
    error: str | None = None
    programs: dict = field(default_factory=dict)


_SHARED = _Shared()


def _create():
    """A new standalone core-profile context through headless EGL (raises on failure)."""
    import moderngl

    return moderngl.create_standalone_context(backend="egl", require=REQUIRED_VERSION)


def _check(ctx):
    """Raise :class:`BackendUnavailableError` if ``ctx`` lacks what the backends need."""
    ctx.info  # read (and cached by moderngl) while this context is surely current
    if ctx.version_code < REQUIRED_VERSION:
        raise BackendUnavailableError(
            f"OpenGL {REQUIRED_VERSION // 100}.{REQUIRED_VERSION % 100 // 10} is required, the EGL context offers "
            f"{ctx.info.get('GL_VERSION', ctx.version_code)}"
        )


def activate(ctx):
    """Make ``ctx`` current and return whether it still works (see the module notes)."""
    try:
        ctx.__enter__()  # current from now on; never left, so no previous context is restored
        ctx.buffer(reserve=4).release()
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
        ctx = _create()
        _check(ctx)
    except BackendUnavailableError as exc:
        _SHARED.error = str(exc)
    except ImportError as exc:
        _SHARED.error = f"moderngl cannot be imported: {exc}"
    except Exception as exc:  # EGL and driver failures come as several exception types
        _SHARED.error = (f"no OpenGL {REQUIRED_VERSION // 100}.{REQUIRED_VERSION % 100 // 10} context through "
                         f"headless EGL: {type(exc).__name__}: {exc}")
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
    renderer = ctx.info.get("GL_RENDERER", "").lower()
    return any(name in renderer for name in SOFTWARE_RENDERERS)


def environment():
    """Facts about the shared context for result records: vendor, renderer, version, limits."""
    import moderngl

    ctx = shared_context()
    info = ctx.info
    facts = {
        "gl_vendor": info.get("GL_VENDOR"),
        "gl_renderer": info.get("GL_RENDERER"),
        "gl_version": info.get("GL_VERSION"),
        "gl_context": "standalone, headless EGL, core profile",
        "gl_software_rasterizer": is_software(ctx),
        "moderngl": moderngl.__version__,
    }
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
        _SHARED.programs[key] = compiled
    return compiled
