"""The VTK backends ``vtk-gpu`` and ``vtk-cpu`` against the reference renderer.

Skipped as a whole (except the probe's refusals) where VTK cannot render offscreen here: the
reason says what is missing (the ``vtk`` wheel, or an EGL driver). Bounds are measured values
(in the comments, VTK 9.7.2 on Mesa llvmpipe) less a margin.
"""

import dataclasses
import math
import os
import subprocess
import sys
import time

import numpy as np
import pytest

import datasets
import renderers
from core.camera import Camera
from core.errors import BackendUnavailableError, InputError, UnsupportedFeatureError
from core.scene import Scene, Shading, VolumeInstance
from core.transfer import TransferFunction
from core.volume import Volume
from renderers.vtk import common
from renderers.vtk.gpu import MAX_VOLUMES, VtkGpuRenderer

AVAILABLE, WHY = common.offscreen_support()
needs_vtk = pytest.mark.skipif(not AVAILABLE, reason=f"VTK cannot render offscreen here: {WHY}")

LINEAR = TransferFunction.from_points([(0, 1, 1, 1, 0), (1, 1, 1, 1, 1)], name="linear")


def psnr(reference, test):
    mse = float(np.mean((reference.astype(np.float64) - test) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(1 / mse)


def scene_of(name, preset, *, size=32, image=48, mode="dvr", shading="none", gradient=True, **camera):
    volume = datasets.load(name, size=size, cache_dir=False)
    chosen = datasets.get(name).preset(preset)
    instance = VolumeInstance(volume, chosen.transfer_function,
                              gradient_opacity=chosen.gradient_opacity if gradient else None,
                              isovalue=chosen.effective_isovalue)
    return Scene([instance], Camera(**camera), width=image, height=image, mode=mode, shading=Shading(model=shading))


def cube_scene(alpha_8bit, *, n=24, image=65, **camera):
    """A homogeneous cube under the linear ramp: opacity ``v/255`` per voxel everywhere."""
    return Scene([VolumeInstance(Volume(np.full((n, n, n), alpha_8bit, np.uint8)), LINEAR)], Camera(**camera),
                 width=image, height=image)


@pytest.fixture(scope="module")
def reference():
    return renderers.get("reference")


@pytest.fixture(scope="module")
def gpu():
    """VTK's GPU mapper without early termination: the accuracy configuration."""
    with renderers.get("vtk-gpu", early_termination=False) as backend:
        yield backend


@pytest.fixture(scope="module")
def cpu():
    with renderers.get("vtk-cpu", threads=1) as backend:
        yield backend


# -- probe and registry ------------------------------------------------------------------------

def test_registered_after_volpack():
    names = renderers.names()
    assert names.index("vtk-gpu") > names.index("volpack") and names.index("vtk-cpu") > names.index("volpack")
    assert renderers.backend_module("vtk-gpu") == "renderers.vtk.gpu"
    assert renderers.backend_module("vtk-cpu") == "renderers.vtk.cpu"


@pytest.mark.parametrize("name", ["vtk-gpu", "vtk-cpu"])
def test_probe_refusal_blocks_get(monkeypatch, name):
    monkeypatch.setattr(common, "offscreen_support", lambda: (False, "no EGL in this test"))
    assert renderers.backend_class(name).probe() == (False, "no EGL in this test")
    with pytest.raises(BackendUnavailableError, match="no EGL in this test"):
        renderers.get(name)
    row = {r.name: r for r in renderers.available()}[name]
    assert row.available is False and row.reason == "no EGL in this test"


def test_probe_says_why_without_an_opengl_context(monkeypatch):
    class NoContext:
        def SupportsOpenGL(self):
            return 0

        def GetOpenGLSupportMessage(self):
            return "Failed to initialize OpenGL for this window, OpenGL not supported."

        def Finalize(self):
            pass

    monkeypatch.setattr(common, "make_window", NoContext)
    ok, reason = common.offscreen_support.__wrapped__()  # past the per-process cache
    assert ok is False
    assert "no OpenGL 3.2 context offscreen through EGL" in reason and "libegl-mesa0" in reason


def test_probe_says_why_without_vtk(monkeypatch):
    monkeypatch.setitem(sys.modules, "vtkmodules.vtkCommonCore", None)  # importing it raises ImportError
    ok, reason = common.offscreen_support.__wrapped__()
    assert ok is False and "pip install 'vtk>=9.4,<10'" in reason


@needs_vtk
def test_probe_without_an_egl_driver_in_a_fresh_process():
    """glvnd without any EGL vendor: the real failure, reported instead of a crash."""
    env = {**os.environ, "__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent/egl_vendor.json"}
    code = "from renderers.vtk.gpu import VtkGpuRenderer; print(VtkGpuRenderer.probe())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60,
                         cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    assert out.returncode == 0, out.stderr
    if out.stdout.startswith("(True"):
        pytest.skip("this libEGL is not glvnd's: it ignores __EGL_VENDOR_LIBRARY_FILENAMES")
    assert "(False" in out.stdout and "no OpenGL 3.2 context offscreen through EGL" in out.stdout


# -- options -----------------------------------------------------------------------------------

@pytest.mark.parametrize("name, options, match", [
    ("vtk-gpu", {"step_factor": 0}, "step_factor"),
    ("vtk-gpu", {"step_factor": -0.5}, "step_factor"),
    ("vtk-gpu", {"step_factor": "fine"}, "step_factor"),
    ("vtk-gpu", {"early_termination": "no"}, "early_termination"),
    ("vtk-gpu", {"early_termination": 0}, "early_termination"),
    ("vtk-cpu", {"step_factor": 0}, "step_factor"),
    ("vtk-cpu", {"threads": 0}, "threads"),
    ("vtk-cpu", {"threads": 1.5}, "threads"),
    ("vtk-cpu", {"threads": True}, "threads"),
    ("vtk-cpu", {"readback": "screen"}, "readback"),
])
def test_bad_options_are_named_before_any_work(name, options, match):
    with pytest.raises(InputError, match=f"{name} option {match}"):
        renderers.backend_class(name)(**options)


@needs_vtk
def test_unknown_option_lists_the_valid_ones():
    with pytest.raises(InputError, match="valid options: step_factor, early_termination"):
        renderers.get("vtk-gpu", threads=2)
    with pytest.raises(InputError, match="valid options: step_factor, threads"):
        renderers.get("vtk-cpu", early_termination=False)


@needs_vtk
def test_options_and_environment_are_recorded(gpu, cpu):
    assert gpu.options == {"step_factor": 0.25, "early_termination": False, "depth_pass": False,
                           "lens_method": "label-map", "effective_step": gpu._last_step}
    assert cpu.options["threads"] == 1 and cpu.options["effective_threads"] == 1
    for backend, mapper in ((gpu, "vtkOpenGLGPUVolumeRayCastMapper"), (cpu, "vtkFixedPointVolumeRayCastMapper")):
        env = backend.environment()
        assert env["vtk_version"] == common.vtk_version() and env["vtk_mapper"] == mapper
        assert env["vtk_render_window"] == "vtkEGLRenderWindow"
        assert env["vtk_gl_renderer"] and env["vtk_gl_version"]
    with renderers.get("vtk-cpu") as default:
        assert default.options["threads"] is None and default.options["effective_threads"] >= 1


# -- refusals ----------------------------------------------------------------------------------

def _small():
    data = np.zeros((8, 8, 8), np.uint8)
    data[2:6, 2:6, 2:6] = 200
    return Volume(data, name="small")


def _instances(count):
    volume = _small()
    return [VolumeInstance(volume, LINEAR, transform=_shifted(2.0 * k)) for k in range(count)]


def _shifted(dx):
    matrix = np.eye(4)
    matrix[:3, 3] = (dx - 4.0, -4.0, -4.0)
    return matrix


@needs_vtk
@pytest.mark.parametrize("name, make, feature", [
    ("vtk-cpu", lambda: Scene([VolumeInstance(_small(), LINEAR, isovalue=0.5)], mode="iso", width=8, height=8),
     "modes 'iso'"),
    ("vtk-cpu", lambda: Scene(_instances(2), width=8, height=8), "2 volumes"),
    ("vtk-gpu", lambda: Scene(_instances(MAX_VOLUMES + 1), width=8, height=8), f"{MAX_VOLUMES + 1} volumes"),
    ("vtk-gpu", lambda: Scene(_instances(2), mode="mip", width=8, height=8), "2 volumes in mode 'mip'"),
    ("vtk-gpu", lambda: Scene(_instances(2), width=8, height=8,
                              shading=Shading(model="phong", light_direction=(1, 0, 1))), "2 volumes lit from"),
])
def test_unsupported_features_are_refused_with_a_reason(name, make, feature):
    backend_class = renderers.backend_class(name)
    with renderers.get(name) as backend:
        with pytest.raises(UnsupportedFeatureError) as info:
            backend.render(make())
    assert feature in str(info.value) and info.value.reason
    for missing in ("max_volumes", "meshes", "lenses") + (("modes",) if name == "vtk-cpu" else ()):
        assert backend_class.capabilities.reasons[missing]


@needs_vtk
def test_iso_without_an_isovalue_is_an_input_error(gpu):
    scene = Scene([VolumeInstance(_small(), LINEAR)], mode="iso", width=8, height=8)
    with pytest.raises(InputError, match="isovalue"):
        gpu.render(scene)


@needs_vtk
def test_a_shader_vtk_cannot_link_raises_instead_of_an_empty_picture(monkeypatch):
    """One volume more than fits the texture units: VTK only logs its link error."""
    wide = dataclasses.replace(VtkGpuRenderer.capabilities, max_volumes=64)
    monkeypatch.setattr(VtkGpuRenderer, "capabilities", wide)
    gradient = datasets.get("ct_skull").preset("volpack").gradient_opacity
    volume = _small()
    scene = Scene([VolumeInstance(volume, LINEAR, transform=_shifted(k), gradient_opacity=gradient) for k in range(8)],
                  width=8, height=8, shading=Shading(model="phong"))
    with renderers.get("vtk-gpu") as backend:
        with pytest.raises(RuntimeError, match="VTK failed to render the scene: .*Shader failed to compile"):
            backend.render(scene)


# -- the image: convention, framing, determinism ------------------------------------------------

@needs_vtk
@pytest.mark.parametrize("name", ["vtk-gpu", "vtk-cpu"])
def test_image_is_premultiplied_float_rgba_with_row_0_on_top(reference, name):
    data = np.zeros((16, 16, 16), np.uint8)
    data[6:10, 10:14, 2:6] = 255  # [z, y, x]; high y: the top of the picture, low x: its left
    tf = TransferFunction.from_points([(0, 1, 0.5, 0.2, 0), (1, 1, 0.5, 0.2, 0.8)])
    scene = Scene([VolumeInstance(Volume(data), tf)], width=32, height=32)
    with renderers.get(name) as backend:
        result = backend.render(scene)
    image = result.image
    assert image.shape == (32, 32, 4) and image.dtype == np.float32
    # premultiplied: colour never exceeds alpha (but for the fixed-point mapper's 15-bit rounding)
    assert np.all(image[..., :3] <= image[..., 3:] + (5e-4 if name == "vtk-cpu" else 1e-6))
    assert image[..., 3].max() > 0.5 and image[..., 3].min() == 0  # transparent black background
    rows, cols = np.nonzero(image[..., 3] > 0.1)
    assert rows.mean() < 16 and cols.mean() < 16  # row 0 is the top, column 0 the left
    truth = reference.render(scene).image
    assert abs(rows.mean() - np.nonzero(truth[..., 3] > 0.1)[0].mean()) < 1.0


@needs_vtk
def test_frames_are_reproducible_and_the_pipeline_is_cached(gpu):
    scene = scene_of("engine", "semi", azimuth=30, elevation=20)
    started = time.perf_counter()
    first = gpu.render(scene)
    elapsed = time.perf_counter() - started
    pipeline = gpu._pipeline
    second = gpu.render(scene)
    assert np.array_equal(first.image, second.image)
    assert {"setup", "render", "readback", "total"} == set(second.timings)
    assert second.timings["setup"] == first.timings["setup"] > 0  # measured once, reported with every frame
    assert elapsed >= first.timings["setup"] + first.timings["total"]  # setup is not part of total
    assert second.timings["total"] >= second.timings["render"] + second.timings["readback"]
    gpu.render(scene.with_camera(azimuth=60))
    assert gpu._pipeline is pipeline  # a new view needs no new VTK objects
    gpu.render(scene_of("engine", "smooth", azimuth=30))
    assert gpu._pipeline is not pipeline  # a new classification does
    assert gpu.options["effective_step"] == 0.25


# -- vtk-gpu against the reference ----------------------------------------------------------------

GPU_AGREEMENT = [
    # data set, preset, mode, shading, projection, PSNR bound (measured, early termination off)
    ("sphere", "opaque", "dvr", "none", "orthographic", 77.0),     # 80.5 dB
    ("engine", "semi", "dvr", "none", "orthographic", 58.0),       # 59.5 dB (thin-walled casting)
    ("sphere", "opaque", "dvr", "none", "perspective", 85.0),      # 89.3 dB
    ("engine", "semi", "dvr", "none", "perspective", 57.8),        # 59.3 dB
    ("ct_skull", "bone", "dvr", "none", "orthographic", 53.5),     # 56.6 dB (sharp threshold: sample positions)
    ("ct_skull", "volpack", "dvr", "none", "orthographic", 39.5),  # 41.1 dB (density × gradient opacity)
    ("ct_skull", "bone", "mip", "none", "orthographic", 40.5),     # 43.4 dB (sampled, not exact, maximum)
    ("sphere", "opaque", "iso", "none", "orthographic", 60.0),     # inf (the same pixels hit, one colour)
    ("ct_skull", "bone", "dvr", "phong", "orthographic", 44.3),    # 45.8 dB (Phong against Blinn specular)
    ("ct_skull", "bone", "dvr", "phong", "perspective", 43.5),     # 45.0 dB (+ point headlight)
    ("sphere", "opaque", "iso", "phong", "orthographic", 36.0),    # 38.9 dB (+ shaded after the crossing)
]


@needs_vtk
@pytest.mark.parametrize("name, preset, mode, shading, projection, bound", GPU_AGREEMENT)
def test_gpu_agrees_with_the_reference(reference, gpu, name, preset, mode, shading, projection, bound):
    scene = scene_of(name, preset, mode=mode, shading=shading, projection=projection, azimuth=30, elevation=20)
    truth = reference.render(scene).image
    image = gpu.render(scene).image
    assert psnr(truth, image) >= bound
    # tight enough to catch a framing mistake: one pixel off, or upside down
    assert psnr(truth, np.roll(image, 1, axis=1)) < bound
    if name != "sphere":
        assert psnr(truth, image[::-1]) < bound


@needs_vtk
def test_gpu_ambient_and_diffuse_match_with_the_headlight(reference, gpu):
    """Without the specular term, only sampling differs: the far eye makes VTK's headlight directional."""
    volume = datasets.load("sphere", size=32, cache_dir=False)
    tf = datasets.get("sphere").preset("opaque").transfer_function
    scene = Scene([VolumeInstance(volume, tf)], Camera(azimuth=30, elevation=20), width=48, height=48,
                  shading=Shading(model="phong", specular=0.0))
    assert psnr(reference.render(scene).image, gpu.render(scene).image) >= 67.0  # 70.8 dB


@needs_vtk
@pytest.mark.parametrize("backend", ["gpu", "cpu"])
def test_light_from_the_side_is_not_mirrored(request, reference, backend):
    """Another light direction: VTK's camera light, from the same side as ours."""
    backend = request.getfixturevalue(backend)
    volume = datasets.load("sphere", size=32, cache_dir=False)
    tf = datasets.get("sphere").preset("opaque").transfer_function
    base = Scene([VolumeInstance(volume, tf)], Camera(azimuth=30, elevation=20), width=48, height=48)
    lit = dataclasses.replace(base, shading=Shading(model="phong", light_direction=(0.8, 0.3, 0.5)))
    mirrored = dataclasses.replace(base, shading=Shading(model="phong", light_direction=(-0.8, -0.3, 0.5)))
    truth = reference.render(lit).image
    assert psnr(truth, backend.render(lit).image) > psnr(truth, backend.render(mirrored).image) + 10


def optical_path(alpha, alpha_voxel):
    """Path length in voxels that composites to ``alpha`` through voxels of opacity ``alpha_voxel``."""
    return math.log(1 - alpha) / math.log(1 - alpha_voxel)


@needs_vtk
def test_gpu_homogeneous_cube_drops_the_last_partial_step(reference):
    """24 voxels at 0.35 voxel: VTK takes floor(24/0.35) = 68 samples from entry + Δ (23.8 voxels).

    A step that divides the box would put VTK's last sample on the exit face, where rounding
    decides whether it counts; 0.35 keeps the count unambiguous.
    """
    alpha = 20 / 255
    scene = cube_scene(20)
    with renderers.get("vtk-gpu", step_factor=0.35, early_termination=False) as backend:
        image = backend.render(scene).image
    truth = reference.render(scene).image
    assert optical_path(image[32, 32, 3], alpha) == pytest.approx(68 * 0.35, abs=1e-3)
    assert optical_path(truth[32, 32, 3], alpha) == pytest.approx(24, abs=1e-4)  # float32 image
    assert psnr(truth, image) >= 55.0  # 58.1 dB: the cell-data box is ours, only sampling differs


@needs_vtk
def test_gpu_early_termination_is_vtks_unless_disabled(reference):
    """VTK stops at opacity 1 − 1/255 by default; the shader replacement lets the ray run on."""
    alpha = 120 / 255
    scene = cube_scene(120, n=16, image=33)
    with renderers.get("vtk-gpu", step_factor=0.35) as default:
        early = default.render(scene)
    with renderers.get("vtk-gpu", step_factor=0.35, early_termination=False) as exact:
        full = exact.render(scene)
    stop = 1 - 1 / 255
    assert early.info["early_termination"] == pytest.approx(stop) and full.info["early_termination"] is None
    step_alpha = 1 - (1 - alpha) ** 0.35
    # stopped at the first sample past the threshold; floor(16/0.35) = 45 samples otherwise
    assert stop < early.image[16, 16, 3] <= stop + (1 - stop) * step_alpha + 1e-6
    assert full.image[16, 16, 3] == pytest.approx(1 - (1 - alpha) ** (45 * 0.35), abs=1e-6)
    sphere = scene_of("sphere", "opaque", azimuth=30, elevation=20)
    with renderers.get("vtk-gpu") as default:
        assert psnr(reference.render(sphere).image, default.render(sphere).image) >= 71.0  # 74.1 dB (80.5 without)


@needs_vtk
@pytest.mark.parametrize("transform", ["rotated", "scaled", "anisotropic"])
def test_gpu_transforms_and_spacing(reference, gpu, transform):
    volume = datasets.load("engine", size=32, cache_dir=False)
    tf = datasets.get("engine").preset("semi").transfer_function
    centre = np.eye(4)
    centre[:3, 3] = -16
    if transform == "rotated":
        c, s = np.cos(np.radians(25)), np.sin(np.radians(25))
        matrix = np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]]) @ centre
        instance = VolumeInstance(volume, tf, transform=matrix)
    elif transform == "scaled":
        instance = VolumeInstance(volume, tf, transform=np.diag([1.5, 1.0, 0.7, 1.0]) @ centre)
    else:
        instance = VolumeInstance(Volume(volume.data, spacing=(1.0, 0.8, 1.5)), tf)
    scene = Scene([instance], Camera(azimuth=30, elevation=20), width=48, height=48)
    assert psnr(reference.render(scene).image, gpu.render(scene).image) >= 57.4  # 58.9 dB rotated, 61.2 scaled


@needs_vtk
def test_gpu_several_volumes(reference, gpu):
    """vtkMultiVolume: VTK composites overlapping volumes one after the other, we sum them."""
    engine = datasets.load("engine", size=32, cache_dir=False)
    sphere = datasets.load("sphere", size=32, cache_dir=False)
    faint = TransferFunction(datasets.get("sphere").preset("opaque").transfer_function.table
                             * np.array([1, 1, 1, 0.1], np.float32), name="faint")
    left, right = np.eye(4), np.eye(4)
    left[:3, 3] = (-26, -16, -16)
    right[:3, 3] = (-6, -16, -16)
    scene = Scene([VolumeInstance(engine, datasets.get("engine").preset("semi").transfer_function, transform=left),
                   VolumeInstance(sphere, faint, transform=right)], Camera(azimuth=30, elevation=20),
                  width=48, height=48)
    result = gpu.render(scene)
    assert result.counters["volumes"] == 2 and result.info["step_space"].startswith("world")
    assert psnr(reference.render(scene).image, result.image) >= 62.0  # 63.5 dB


@needs_vtk
def test_gpu_camera_inside_the_volume(reference, gpu):
    scene = scene_of("engine", "semi", projection="perspective", distance=8, fov_y=60, azimuth=30, elevation=20)
    assert scene.camera_inside_volume()
    assert psnr(reference.render(scene).image, gpu.render(scene).image) >= 46.0  # 49.2 dB


# -- vtk-cpu against the reference ----------------------------------------------------------------

@needs_vtk
def test_cpu_box_is_half_a_voxel_smaller_per_side(reference, cpu):
    """Point data: VTK's box is [½, n − ½] voxels, so rays are one voxel shorter and the picture narrower."""
    alpha = 20 / 255
    scene = cube_scene(20, view_height=32.0, image=64)  # two pixels per voxel
    image = cpu.render(scene).image
    truth = reference.render(scene).image
    assert optical_path(truth[32, 32, 3], alpha) == pytest.approx(24, abs=1e-4)
    assert 22.5 < optical_path(image[32, 32, 3], alpha) < 23.5  # 22.72 (91 samples of ¼ voxel, 15-bit)
    covered = (image[..., 3] > 0).sum(axis=1)[32], (image[..., 3] > 0).sum(axis=0)[32]
    assert (truth[..., 3] > 0).sum(axis=1)[32] == 48
    assert covered in ((46, 46), (45, 46))  # 23 voxels; VTK's row bounds drop a column on the left
    assert psnr(truth, image) < 16.0  # 13.7 dB: two-pixel rims missing all round


CPU_AGREEMENT = [
    # data set, preset, mode, shading, projection, PSNR bound (measured, the mapper's own image)
    ("sphere", "opaque", "dvr", "none", "orthographic", 63.0),     # 66.0 dB (nothing near the box faces)
    ("engine", "semi", "dvr", "none", "perspective", 50.0),        # 53.2 dB
    ("ct_skull", "bone", "dvr", "phong", "orthographic", 36.0),    # 39.0 dB
    ("ct_skull", "volpack", "dvr", "none", "orthographic", 32.3),  # 33.8 dB (density × gradient opacity)
    ("ct_skull", "bone", "mip", "none", "orthographic", 38.0),     # 40.7 dB
]


@needs_vtk
@pytest.mark.parametrize("name, preset, mode, shading, projection, bound", CPU_AGREEMENT)
def test_cpu_agrees_with_the_reference(reference, cpu, name, preset, mode, shading, projection, bound):
    scene = scene_of(name, preset, mode=mode, shading=shading, projection=projection, azimuth=30, elevation=20)
    truth = reference.render(scene).image
    image = cpu.render(scene).image
    assert psnr(truth, image) >= bound
    assert psnr(truth, np.roll(image, 1, axis=1)) < bound
    if name != "sphere":
        assert psnr(truth, image[::-1]) < bound


def stretched(raycast, origin, size):
    """What VTK's display helper draws: texture coordinates from the first to the last texel centre.

    Over ``size`` pixels from ``origin`` (per axis, GL's bottom-up rows) pixel ``p`` samples the
    ray-cast image bilinearly at texel coordinate ``(p − origin + ½)·(size − 1)/size``.
    """
    out = raycast.astype(np.float64)
    for axis, (o, n) in enumerate(zip(origin, size)):
        out = np.moveaxis(out, axis, 0)
        part = out[o:o + n]
        t = (np.arange(n) + 0.5) * (n - 1) / n
        i0 = np.minimum(np.floor(t).astype(int), n - 2)
        w = (t - i0)[:, None, None]
        resampled = out.copy()
        resampled[o:o + n] = part[i0] * (1 - w) + part[i0 + 1] * w
        out = np.moveaxis(resampled, 0, axis)
    return out


@needs_vtk
def test_cpu_window_readback_is_vtks_stretched_drawing(cpu):
    """readback='window' is the ray-cast image as VTK draws it: stretched by a texel, bilinear."""
    scene = scene_of("engine", "semi", azimuth=30, elevation=20)
    raycast = cpu.render(scene).image
    rc = cpu._pipeline.mapper.GetRayCastImage()
    (x0, y0), (width, height) = rc.GetImageOrigin(), rc.GetImageInUseSize()
    with renderers.get("vtk-cpu", threads=1, readback="window") as backend:
        window = backend.render(scene)
    assert window.info["readback"].startswith("float32 framebuffer")
    expected = stretched(raycast[::-1], (y0, x0), (height, width))[::-1]  # GL rows
    assert psnr(expected, window.image) > 70.0  # 16-bit texture
    assert psnr(raycast, window.image) < 45.0


@needs_vtk
def test_cpu_view_missing_the_volume_reads_empty(cpu):
    """The ray-cast image is the mapper's buffer: a frame must never show the previous one."""
    scene = scene_of("engine", "semi", azimuth=30, elevation=20)
    assert cpu.render(scene).image[..., 3].max() > 0.1
    assert cpu.render(scene.with_camera(target=(200.0, 0.0, 0.0))).image.max() == 0
    assert cpu.render(scene).image[..., 3].max() > 0.1


@needs_vtk
def test_cpu_threads_and_camera_inside(reference, cpu):
    scene = scene_of("engine", "semi", azimuth=30, elevation=20)
    one = cpu.render(scene).image
    with renderers.get("vtk-cpu", threads=2) as two:
        result = two.render(scene)
    assert result.counters["threads"] == 2
    assert psnr(one, result.image) > 60  # VTK warns results may differ slightly across threads
    inside = scene_of("engine", "semi", projection="perspective", distance=8, fov_y=60, azimuth=30, elevation=20)
    assert psnr(reference.render(inside).image, cpu.render(inside).image) >= 48.4  # 49.9 dB


@needs_vtk
def test_cpu_steps_in_object_space():
    """VTK's SampleDistance is in data coordinates: a volume scaled by 2 still takes one sample per voxel.

    From entry + Δ with the last (partial) step dropped, one-voxel steps through 24 voxels give
    23 samples; world steps of one unit (half a voxel) would give 47, an optical path of 23.5.
    """
    volume = Volume(np.full((24, 24, 24), 5, np.uint8))
    scaled = np.diag([2.0, 2.0, 2.0, 1.0])
    scaled[:3, 3] = -24
    scene = Scene([VolumeInstance(volume, LINEAR, transform=scaled)], width=33, height=33)
    with renderers.get("vtk-cpu", step_factor=1.0) as backend:
        result = backend.render(scene)
    assert result.info["step"] == 1.0 and result.info["step_space"] == "object"
    assert optical_path(result.image[16, 16, 3], 5 / 255) == pytest.approx(23.0, abs=0.1)  # 22.996


@pytest.mark.parametrize("backend", ["vtk-cpu", "vtk-gpu"])
def test_a_step_finer_than_the_mappers_arithmetic_resolves_is_refused(backend):
    # At 1e-5 voxel both mappers' faint samples round to nothing and their images came out blank.
    with pytest.raises(InputError, match=rf"{backend} option step_factor: 1e-05 is finer than .* use step_factor ≥"):
        renderers.backend_class(backend)(step_factor=1e-5)


@needs_vtk
def test_more_threads_than_vtk_runs_are_refused_not_recorded():
    import re

    with pytest.raises(InputError, match=r"vtk-cpu option threads: 100000 is more than VTK runs \(VTK_MAX_THREADS \d+\)"
                       ) as refused:
        renderers.get("vtk-cpu", threads=100000)
    most = int(re.search(r"VTK_MAX_THREADS (\d+)", str(refused.value))[1])
    assert renderers.get("vtk-cpu", threads=most).options["threads"] == most


@needs_vtk
def test_gpu_depth_pass_starts_rays_at_the_contour_and_loses_a_little(reference):
    """VTK's depth pass (iSBVR's nearest peer): rays start at a contour at the transfer function's Φ_t. It must
    render the volume where it is placed (the pass ignores a user matrix; the placement goes into the data),
    and it changes the image (lossy where the contour lies behind visible samples, and the samples move)."""
    centre = np.eye(4)
    centre[:3, 3] = -16
    volume = datasets.load("ct_skull", size=32, cache_dir=False)
    tf = datasets.get("ct_skull").preset("isbvr").transfer_function
    for transform in (np.eye(4), np.diag([1.5, 1.0, 0.7, 1.0]) @ centre):
        scene = Scene([VolumeInstance(volume, tf, transform=transform)], Camera(azimuth=30, elevation=20),
                      width=48, height=48)
        with renderers.get("vtk-gpu") as plain, renderers.get("vtk-gpu", depth_pass=True) as passed:
            without, with_pass = plain.render(scene).image, passed.render(scene).image
        # The same coverage (a misplaced contour cut half of it away); rays starting at the contour take their
        # samples at other points along the ray, so pixels differ.
        assert with_pass[..., 3].sum() == pytest.approx(without[..., 3].sum(), rel=0.02)
        assert np.abs(with_pass - without).max() > 1 / 255
    rotated = Scene([VolumeInstance(volume, tf, transform=np.array(
        [[0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1.0]]) @ centre)], Camera(), width=16, height=16)
    with renderers.get("vtk-gpu", depth_pass=True) as passed:
        with pytest.raises(UnsupportedFeatureError, match="without the volume's user matrix"):
            passed.render(rotated)
        with pytest.raises(UnsupportedFeatureError, match="contours one volume"):
            passed.render(scene_of("ct_skull", "bone", mode="mip"))
