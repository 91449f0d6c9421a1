"""The shared OpenGL context: creation, failure reporting (no GL needed), facts, queries, programs."""

import sys

import numpy as np
import pytest

import renderers
from core.errors import BackendUnavailableError
from renderers.gl import context
from renderers.gl.timing import PassTimer

GL_OK, GL_REASON = context.probe()
needs_gl = pytest.mark.skipif(not GL_OK, reason=f"no OpenGL 4.3 context through EGL here: {GL_REASON}")


class _FakeContext:
    """Just enough of a moderngl context for :mod:`renderers.gl.context`'s bookkeeping."""

    def __init__(self, version_code=450):
        self.version_code = version_code
        self.info = {"GL_VERSION": f"{version_code // 100}.{version_code % 100 // 10} fake", "GL_RENDERER": "fake"}
        self.released = False
        self.dead = False

    def __enter__(self):
        return self

    def buffer(self, reserve):
        if self.dead:
            raise RuntimeError("cannot create buffer")
        return _FakeContext()

    def release(self):
        self.released = True


@pytest.fixture
def fresh(monkeypatch):
    """An empty per-process cache, so the test decides what creating a context does."""
    monkeypatch.setattr(context, "_SHARED", context._Shared())
    calls = []

    def use(creator):
        def counted():
            calls.append(1)
            return creator()

        monkeypatch.setattr(context, "_create", counted)
        return calls

    return use


def test_probe_reports_a_failing_context_instead_of_raising(fresh):
    def fail():
        raise RuntimeError("eglGetDisplay failed: no EGL display")

    calls = fresh(fail)
    ok, reason = context.probe()
    assert not ok and "EGL" in reason and "RuntimeError" in reason and "no EGL display" in reason
    with pytest.raises(BackendUnavailableError, match="no EGL display"):
        context.shared_context()
    assert len(calls) == 1  # the failure is remembered for the process
    for name in ("gl-raycast", "gl-slicer"):
        row = {info.name: info for info in renderers.available()}[name]
        assert row.available is False and "no EGL display" in row.reason
        with pytest.raises(BackendUnavailableError, match="not available here.*no EGL display"):
            renderers.get(name)


def test_an_old_opengl_version_is_refused_and_released(fresh):
    old = _FakeContext(version_code=410)
    fresh(lambda: old)
    ok, reason = context.probe()
    assert not ok and "4.3 is required" in reason and "4.1 fake" in reason
    assert old.released


def test_a_missing_moderngl_is_a_reason(fresh):
    fresh(lambda: __import__("moderngl_that_is_not_installed"))
    ok, reason = context.probe()
    assert not ok and reason.startswith("moderngl cannot be imported")


def test_one_context_per_process_and_a_new_one_after_fork(fresh):
    calls = fresh(_FakeContext)
    first = context.shared_context()
    assert context.shared_context() is first and len(calls) == 1
    context._SHARED.pid = -1  # as in a forked child: the parent's context is not usable
    second = context.shared_context()
    assert second is not first and len(calls) == 2


def test_a_context_that_stopped_working_is_replaced(fresh):
    """Another library's EGL teardown (VTK's window Finalize) can leave the context unusable."""
    calls = fresh(_FakeContext)
    first = context.shared_context()
    first.dead = True
    assert not context.activate(first)
    second = context.shared_context()
    assert second is not first and len(calls) == 2 and context.activate(second)


@needs_gl
def test_environment_reports_the_renderer_and_limits():
    facts = context.environment()
    assert facts["gl_renderer"] and facts["gl_version"] and facts["gl_vendor"]
    assert facts["gl_max_3d_texture_size"] >= 256
    assert len(facts["gl_max_viewport_dims"]) == 2
    assert isinstance(facts["gl_software_rasterizer"], bool)
    ctx = context.shared_context()
    assert ctx.version_code >= context.REQUIRED_VERSION
    assert context.max_3d_texture_size(ctx) == facts["gl_max_3d_texture_size"]


@needs_gl
def test_programs_are_compiled_once_per_source():
    from renderers.gl import glsl

    ctx = context.shared_context()
    source = glsl.fragment_source("out vec4 o; void main() { o = vec4(u_step); }")
    assert context.program(ctx, glsl.SCREEN_VERTEX, source) is context.program(ctx, glsl.SCREEN_VERTEX, source)


@needs_gl
@pytest.mark.parametrize("method", ["query", "finish"])
def test_pass_timer_counts_fragments_and_times_passes(method):
    """Occlusion and timer queries work here; a depth test against 1 culls every fragment."""
    import moderngl

    from renderers.gl import glsl

    ctx = context.shared_context()
    program = context.program(ctx, glsl.SCREEN_VERTEX, glsl.VERSION + "out vec4 o; void main() { o = vec4(1.0); }")
    vbo = ctx.buffer(np.array([-1, -1, 3, -1, -1, 3], np.float32).tobytes())
    vao = ctx.vertex_array(program, [(vbo, "2f", "in_position")])
    colour, depth = ctx.texture((32, 16), 4, dtype="f4"), ctx.depth_texture((32, 16))
    fbo = ctx.framebuffer([colour], depth)
    timer = PassTimer(ctx, method)
    timer.start_frame()
    fbo.clear(depth=0.0)
    fbo.use()
    ctx.enable_only(moderngl.DEPTH_TEST)
    ctx.depth_func = ">"
    timer.run("open", vao.render, count=True)
    fbo.clear(depth=1.0)
    fbo.use()
    timer.run("culled", vao.render, count=True)
    timer.run("uncounted", vao.render)
    seconds, fragments = timer.results()
    assert fragments == {"open": [32 * 16], "culled": [0]}
    assert set(seconds) == {"open", "culled", "uncounted"} and all(v >= 0 for v in seconds.values())
    assert seconds["open"] > 0
    for item in (vao, vbo, fbo, colour, depth):
        item.release()


@needs_gl
def test_software_rasterizers_are_recognised():
    ctx = context.shared_context()
    renderer = ctx.info["GL_RENDERER"].lower()
    assert context.is_software(ctx) == any(name in renderer for name in context.SOFTWARE_RENDERERS)


def test_importing_the_package_needs_no_moderngl():
    import subprocess

    probe = ("import sys; import renderers.gl.raycast, renderers.gl.slicer; "
             "print('moderngl' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
