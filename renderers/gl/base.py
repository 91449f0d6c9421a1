"""What the OpenGL backends share: the context, options, cached textures, targets, readback.

:class:`GLRenderer` is the base of ``gl-raycast``, ``gl-slicer`` and ``gl-peel`` (and of later GL
backends): it owns a :class:`renderers.gl.resources.ResourceCache` on the process's shared
context, declares the common ``timing`` option (:data:`TIMING`; each backend's table lists it
with its ``step_factor``), checks a scene against the GL limits before any work, binds the
per-frame uniforms and textures, and reads the result back as a volbench image (row 0 at the top).
"""

import time

import numpy as np

from core.errors import InputError, UnsupportedFeatureError
from renderers.base import Option, Renderer
from renderers.gl import context
from renderers.gl.resources import VOLUME_CACHE_SIZE, Preparation, ResourceCache
from renderers.gl.timing import TIMING_METHODS, PassTimer
from renderers.gl.view import cube_triangles

SCREEN_TRIANGLE = np.array([-1.0, -1.0, 3.0, -1.0, -1.0, 3.0], dtype=np.float32)
"""One triangle covering the viewport (full-screen passes)."""

TIMING = Option("timing", str, "auto", "How passes are timed (:mod:`renderers.gl.timing`): ``auto`` uses ``finish`` "
                "on a CPU rasterizer, whose timer queries do not cover its deferred work, and ``query`` otherwise.",
                choices=TIMING_METHODS)


def set_uniforms(program, values):
    """Set every uniform of ``values`` that ``program`` uses (the compiler drops unused ones).

    Matrices (2-D arrays) are written column-major, as GLSL reads them.
    """
    for name, value in values.items():
        uniform = program.get(name, None)
        if uniform is None:
            continue
        array = np.asarray(value)
        if array.ndim == 2:
            uniform.write(np.ascontiguousarray(array.T, dtype=np.float32).tobytes())
        elif array.ndim == 1:
            uniform.value = tuple(array.tolist())
        else:
            uniform.value = array.item()


class GLRenderer(Renderer):
    """Base class of the OpenGL backends (one volume per scene).

    A backend's ``option_table`` has ``step_factor`` (the world step) and :data:`TIMING`;
    ``options`` also records ``effective_step`` (the world step of the last frame) and
    ``effective_timing`` (the timing method of the frames so far).

    Notes
    -----
    The device is the process's, chosen by :mod:`renderers.gl.context` (the first EGL device that
    is not a software rasterizer, or ``$VOLBENCH_GL_DEVICE``), not by an option: see there why.
    """

    graphics_stack = "moderngl"

    cached_volumes = VOLUME_CACHE_SIZE
    """Volumes whose textures the renderer's cache keeps alive together (a multi-volume frame needs all)."""

    def __init__(self, **options):
        super().__init__(**options)
        self._ctx = None
        self._cache = None
        self._timer = None
        self._targets = {}
        self._buffers = {}
        self._vaos = {}
        self._last_step = None

    @classmethod
    def probe(cls):
        return context.probe()

    def environment(self):
        return context.environment()

    @property
    def options(self):
        """Options as given, plus the step and the timing method of the frames rendered so far."""
        return {**super().options, "effective_step": self._last_step, "effective_timing": self._effective_timing}

    @property
    def _effective_timing(self):
        """The timing method of the frames rendered so far (``None`` before the first)."""
        return None if self._timer is None else self._timer.method

    @property
    def timing_method(self):
        """The method actually used: ``"query"`` or ``"finish"`` (needs the context)."""
        if self.timing != "auto":
            return self.timing
        return "finish" if context.is_software(self._context()) else "query"

    def _context(self):
        """The shared context, current; objects made in an earlier, dead context are forgotten."""
        ctx = context.shared_context()
        if ctx is not self._ctx:
            self._forget()
            self._ctx = ctx
            self._cache = ResourceCache(ctx, volumes=self.cached_volumes)
        return ctx

    def _forget(self):
        """Drop every GL object reference (their context is gone, or they were released)."""
        self._cache, self._ctx, self._timer, self._targets, self._buffers = None, None, None, {}, {}
        self._vaos = {}

    def _release(self):
        """Release this renderer's GL objects (its context is current)."""
        self._cache.release()
        for target in self._targets.values():
            for item in target.values():
                item.release()
        for buffer in self._buffers.values():
            buffer.release()
        for vao in self._vaos.values():
            vao.release()

    def close(self):
        if self._ctx is not None and context.activate(self._ctx):
            self._release()
        self._forget()

    def check(self, scene):
        """Also refuse an image larger than this context's render targets (a device limit, so the
        pipeline records the pair as skipped; past it the framebuffer is "not complete")."""
        super().check(scene)
        ctx = self._context()
        most = min(int(ctx.info["GL_MAX_TEXTURE_SIZE"]), *map(int, ctx.info["GL_MAX_VIEWPORT_DIMS"]))
        if max(scene.width, scene.height) > most:
            raise UnsupportedFeatureError(self.name, f"a {scene.width}×{scene.height} image",
                                          f"{ctx.info['GL_RENDERER']} renders at most {most}×{most} pixels")

    # -----------------------------------------------------------------------------------------

    def _begin_frame(self, scene):
        """Context, limits check, pass timer and an empty :class:`Preparation` for ``scene``."""
        ctx = self._context()
        volume = scene.volumes[0].volume
        limit = context.max_3d_texture_size(ctx)
        if max(volume.shape_xyz) > limit:
            raise InputError(
                f"volume {volume.name!r}: dimensions {volume.shape_xyz} exceed GL_MAX_3D_TEXTURE_SIZE {limit} of "
                f"{ctx.info['GL_RENDERER']}; resample the volume to at most {limit} voxels per axis"
            )
        if self._timer is None:
            self._timer = PassTimer(ctx, self.timing_method)
        self._timer.start_frame()
        return ctx, Preparation(ctx)

    def _buffer(self, name, data):
        """A vertex buffer kept across frames, rewritten (grown if needed) with ``data``."""
        data = np.ascontiguousarray(data, dtype=np.float32)
        buffer = self._buffers.get(name)
        if buffer is None or buffer.size < data.nbytes:
            if buffer is not None:
                buffer.release()
            buffer = self._ctx.buffer(reserve=max(data.nbytes, 4), dynamic=True)
            self._buffers[name] = buffer
        buffer.write(data.tobytes())
        return buffer

    def _cube_vao(self, ctx, program):
        """``program``'s vertex array over the unit box's triangles (``in_tex``), made once."""
        return self._vao(program, lambda: ctx.vertex_array(
            program, [(self._buffer("cube", cube_triangles()), "3f", "in_tex")]))

    def _screen_vao(self, ctx, program):
        """``program``'s vertex array over one triangle covering the screen (``in_position``), made once."""
        return self._vao(program, lambda: ctx.vertex_array(
            program, [(self._buffer("screen", SCREEN_TRIANGLE), "2f", "in_position")]))

    def _vao(self, program, build):
        vao = self._vaos.get(program)
        if vao is None:
            vao = self._vaos[program] = build()
        return vao

    def _target(self, key, build):
        """Frame targets (textures, framebuffers) cached per key (usually the image size)."""
        target = self._targets.get(key)
        if target is None:
            for old in self._targets.values():
                for item in old.values():
                    item.release()
            self._targets = {}
            target = build()
            self._targets[key] = target
        return target

    def _float_texture(self, size, components=4):
        """A ``size`` RGBA32F (or fewer components) render target, nearest filtering."""
        import moderngl

        texture = self._ctx.texture(size, components, dtype="f4")
        texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return texture

    def _readback(self, texture, height, width):
        """``texture`` as a volbench image (row 0 at the top) and the seconds it took."""
        start = time.perf_counter()
        raw = np.frombuffer(texture.read(), dtype=np.float32).reshape(height, width, 4)
        image = np.ascontiguousarray(raw[::-1])
        return image, time.perf_counter() - start
