"""The shared OpenGL context: creation, failure reporting (no GL needed), the EGL device choice on
fake device lists, facts, queries, programs; VTK's window following the device variable."""

import sys

import numpy as np
import pytest

import renderers
from core.errors import BackendUnavailableError, InputError
from renderers.gl import context
from renderers.gl.context import EglDevice
from renderers.gl.timing import PassTimer

GL_OK, GL_REASON = context.probe()
needs_gl = pytest.mark.skipif(not GL_OK, reason=f"no OpenGL 4.3 context through EGL here: {GL_REASON}")


class _FakeContext:
    """Just enough of a moderngl context for :mod:`renderers.gl.context`'s bookkeeping."""

    def __init__(self, version_code=450, renderer="fake"):
        self.version_code = version_code
        self.info = {"GL_VERSION": f"{version_code // 100}.{version_code % 100 // 10} fake", "GL_RENDERER": renderer}
        self.released = False
        self.dead = False
        self.error = "GL_NO_ERROR"

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
    """An empty per-process cache and no device variable, so the test decides what creating a context does.

    ``use(creator, devices=1)`` makes EGL list ``devices`` devices and ``creator(index)`` make the
    context on one; it returns the list of the device indices asked for.
    """
    monkeypatch.setattr(context, "_SHARED", context._Shared())
    for variable in (context.DEVICE_VARIABLE, context.GLCONTEXT_VARIABLE):
        monkeypatch.delenv(variable, raising=False)
    calls = []

    def use(creator, devices=1):
        def counted(index):
            calls.append(index)
            return creator(index)

        monkeypatch.setattr(context, "_create", counted)
        monkeypatch.setattr(context, "egl_device_count", lambda: devices)
        return calls

    return use


def test_probe_reports_a_failing_context_instead_of_raising(fresh):
    def fail():
        raise RuntimeError("eglGetDisplay failed: no EGL display")

    calls = fresh(lambda index: fail())
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
    fresh(lambda index: old)
    ok, reason = context.probe()
    assert not ok and "4.3 is required" in reason and "4.1 fake" in reason
    assert old.released


def test_a_missing_moderngl_is_a_reason(fresh):
    fresh(lambda index: __import__("moderngl_that_is_not_installed"))
    ok, reason = context.probe()
    assert not ok and reason.startswith("moderngl cannot be imported")


def test_one_context_per_process_and_a_new_one_after_fork(fresh):
    calls = fresh(lambda index: _FakeContext())
    first = context.shared_context()
    assert context.shared_context() is first and len(calls) == 1
    context._SHARED.pid = -1  # as in a forked child: the parent's context is not usable
    second = context.shared_context()
    assert second is not first and len(calls) == 2


def test_a_context_that_stopped_working_is_replaced(fresh):
    """Another library's EGL teardown (VTK's window Finalize) can leave the context unusable."""
    calls = fresh(lambda index: _FakeContext())
    first = context.shared_context()
    first.dead = True
    assert not context.activate(first)
    second = context.shared_context()
    assert second is not first and len(calls) == 2 and context.activate(second)


# ------------------------------------------------------------------------------ which EGL device

LLVMPIPE, H100 = "llvmpipe (LLVM 15.0.6, 256 bits)", "NVIDIA H100 80GB HBM3/PCIe/SSE2"


def egl_devices(*specs):
    """A creator over EGL devices, one spec each: a renderer (a GL 4.5 context), a GL version code
    (a context of that version) or an exception (creation fails); and the contexts it made."""
    made = {}

    def create(index):
        spec = specs[index]
        if isinstance(spec, Exception):
            raise spec
        made[index] = _FakeContext(spec) if isinstance(spec, int) else _FakeContext(renderer=spec)
        return made[index]

    return create, made


@pytest.mark.parametrize("order", [(LLVMPIPE, H100), (H100, LLVMPIPE)])
def test_a_hardware_device_is_chosen_over_a_software_one_in_either_order(order):
    devices = [EglDevice(index, renderer) for index, renderer in enumerate(order)]
    assert context.choose_device(devices, "", count=2).renderer == H100


def test_a_software_device_is_the_fallback_and_unusable_devices_are_passed_over():
    devices = [EglDevice(0, error="Exception: eglInitialize failed (0x3001)"),
               EglDevice(1, "Mesa Intel(R) UHD 620", error="OpenGL 4.3 is required, the EGL context offers 4.2"),
               EglDevice(2, LLVMPIPE)]
    assert context.choose_device(devices, "", count=3).index == 2
    with pytest.raises(BackendUnavailableError, match=r"no OpenGL 4.3 context through headless EGL on any of its 2 "
                                                      r"device\(s\): 0: Exception: eglInitialize failed \(0x3001\); "
                                                      r"1: Mesa Intel\(R\) UHD 620, OpenGL 4.3 is required"):
        context.choose_device(devices[:2], "", count=2)


def test_explicit_selectors_by_index_and_renderer_name():
    devices = [EglDevice(0, H100), EglDevice(1, LLVMPIPE), EglDevice(2, "NVIDIA RTX A6000/PCIe/SSE2")]
    assert context.choose_device(devices, "1", count=3).index == 1  # a software device, when named
    assert context.choose_device(devices, "LLVMpipe", count=3).index == 1
    assert context.choose_device(devices, "nvidia", count=3).index == 0
    assert context.choose_device(devices, "a6000", count=3).index == 2
    with pytest.raises(InputError, match=r"'amd' \(VOLBENCH_GL_DEVICE\): matches no renderer; EGL devices: 0: NVIDIA "
                                         r"H100 80GB HBM3/PCIe/SSE2; 1: llvmpipe"):
        context.choose_device(devices, "amd", count=3)
    with pytest.raises(InputError, match=r"'3' \(GLCONTEXT_DEVICE_INDEX\): no EGL device 3; this machine lists 3 "
                                         r"\(indices 0 to 2\)"):
        context.choose_device([], "3", count=3, variable=context.GLCONTEXT_VARIABLE)


def test_a_named_device_without_opengl_4_3_is_not_replaced():
    devices = [EglDevice(0, error="Exception: eglCreateContext failed (0x3009)"), EglDevice(1, LLVMPIPE)]
    with pytest.raises(BackendUnavailableError, match=r"'0' \(VOLBENCH_GL_DEVICE\): 0: Exception: eglCreateContext "
                                                      r"failed \(0x3009\); name another device or unset"):
        context.choose_device(devices[:1], "0", count=2)


def test_the_search_takes_the_first_gpu_releases_the_rest_and_records_them(fresh):
    create, made = egl_devices(LLVMPIPE, H100, "never asked")
    calls = fresh(create, devices=3)
    ctx = context.shared_context()
    assert ctx is made[1] and calls == [0, 1]  # stops at the first hardware device
    assert made[0].released and not made[1].released
    facts = context.device_facts()
    assert facts["gl_renderer"] == H100 and facts["gl_device_index"] == 1 and facts["gl_egl_device_count"] == 3
    assert facts["gl_devices"] == f"0: {LLVMPIPE}; 1: {H100}" and facts["gl_software_rasterizer"] is False
    # A fork, or a context that stopped working, makes a context on the chosen device without a search.
    context._SHARED.pid = -1
    assert context.shared_context() is made[1] is not ctx and calls == [0, 1, 1]


def test_without_a_gpu_the_software_device_is_used(fresh):
    create, made = egl_devices(RuntimeError("eglInitialize failed (0x3001)"), LLVMPIPE, 410)
    calls = fresh(create, devices=3)
    assert context.shared_context() is made[1] and calls == [0, 1, 2]
    assert made[2].released
    assert context.device_facts()["gl_devices"] == (
        f"0: RuntimeError: eglInitialize failed (0x3001); 1: {LLVMPIPE}; 2: fake, OpenGL 4.3 is required, the EGL "
        f"context offers 4.1 fake")


def test_the_device_variable_chooses_by_name_or_index(fresh, monkeypatch):
    create, made = egl_devices(H100, LLVMPIPE)
    calls = fresh(create, devices=2)
    monkeypatch.setenv(context.DEVICE_VARIABLE, "llvmpipe")
    assert context.shared_context() is made[1] and calls == [0, 1] and made[0].released
    monkeypatch.setattr(context, "_SHARED", context._Shared())
    monkeypatch.delenv(context.DEVICE_VARIABLE)
    monkeypatch.setenv(context.GLCONTEXT_VARIABLE, "1")  # glcontext's own index would override any other
    calls.clear()
    assert context.shared_context() is made[1] and calls == [1]
    monkeypatch.setattr(context, "_SHARED", context._Shared())
    monkeypatch.setenv(context.DEVICE_VARIABLE, "5")
    ok, reason = context.probe()
    assert not ok and reason == "OpenGL device '5' (VOLBENCH_GL_DEVICE): no EGL device 5; this machine lists 2 " \
                                "(indices 0 to 1)"


@needs_gl
def test_this_machine_lists_its_egl_devices_and_records_the_one_chosen():
    facts = context.device_facts()
    assert context.egl_device_count() == facts["gl_egl_device_count"] >= 1
    assert 0 <= facts["gl_device_index"] < facts["gl_egl_device_count"]
    assert f"{facts['gl_device_index']}: {facts['gl_renderer']}" in facts["gl_devices"]


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


# ------------------------------------------------------------------- VTK's window follows the variable


@pytest.fixture
def vtk_support(monkeypatch):
    """VTK's offscreen check, uncached, under a device variable the test sets; skips without VTK."""
    from renderers.vtk import common

    monkeypatch.delenv(common.GL_DEVICE_VARIABLE, raising=False)
    ok, reason = common.offscreen_support()
    if not ok:
        pytest.skip(f"VTK does not render offscreen here: {reason}")

    def check(selector):
        monkeypatch.setenv(common.GL_DEVICE_VARIABLE, selector)
        return common.offscreen_support.__wrapped__()

    return common, check


def test_vtk_follows_the_opengl_device_variable(vtk_support):
    common, check = vtk_support
    assert common.GL_DEVICE_VARIABLE == context.DEVICE_VARIABLE
    count = common.vtk_modules().vtkEGLRenderWindow().GetNumberOfDevices()
    assert check("0") == (True, "") and common.make_window().GetDeviceIndex() == 0
    # VTK indexes its device list unchecked: an index past it is refused before any window.
    assert check(str(count)) == (False, f"VOLBENCH_GL_DEVICE={count}: VTK lists {count} EGL device(s), indices 0 "
                                        f"to {count - 1}; name one of them")
    # A name is checked against the renderer of VTK's default device, never ignored.
    window = common.make_window()
    window.SetSize(1, 1)
    window.Initialize()
    renderer = common.gl_strings(window)["renderer"]
    window.Finalize()
    assert check(renderer.split()[0].upper()) == (True, "")
    ok, reason = check("no such renderer")
    assert not ok and reason.startswith("VOLBENCH_GL_DEVICE='no such renderer' names a renderer, but VTK's EGL "
                                        f"window takes a device index and its default device renders with "
                                        f"{renderer!r}; set VOLBENCH_GL_DEVICE to the index")
