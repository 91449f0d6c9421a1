"""Ctrl-C: ``volbench`` stops promptly and quietly, and the reference renderer's kernels, which
cannot be interrupted, are told to stop (:func:`renderers.reference.renderer.run_stoppable`)."""

import dataclasses
import os
import select
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numba
import numpy as np
import pytest
import trimesh

import renderers
from core.camera import Camera
from core.mesh import Mesh, MeshInstance, SurfaceMaterial
from core.scene import Scene, VolumeInstance
from core.transfer import TransferFunction
from core.volume import Volume
from renderers.reference import renderer as reference

ROOT = Path(__file__).resolve().parent.parent

# Two Numba threads on any machine, and a quarter of a million rays of ~2,500 samples each: a frame
# of several seconds however many cores the machine has, so that only a renderer that stops
# mid-frame can exit in time.
SLOW_RENDER = ["render", "constant_cube", "--size", "64", "--image", "256", "--option", "step_factor=0.02",
               "--warmup", "0", "--repeat", "1"]


def _read_until(stream, marker, timeout):
    """What ``stream`` yields until ``marker`` appears (or it closes, or ``timeout`` passes)."""
    seen = b""
    deadline = time.monotonic() + timeout
    while marker not in seen and time.monotonic() < deadline:
        if select.select([stream], [], [], deadline - time.monotonic())[0]:
            chunk = os.read(stream.fileno(), 4096)
            if not chunk:
                break
            seen += chunk
    return seen


def test_ctrl_c_during_a_reference_render_stops_within_two_seconds_without_a_traceback(tmp_path):
    renderers.get("reference")  # compiles the kernels into Numba's cache, so the command starts at once
    env = {**os.environ, "NUMBA_NUM_THREADS": "2", "VOLBENCH_CACHE": str(tmp_path / "cache")}
    output = tmp_path / "cube.png"
    # cwd: `-m` imports this checkout's code
    process = subprocess.Popen([sys.executable, "-m", "pipeline.cli", *SLOW_RENDER, "--output", str(output)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, cwd=ROOT)
    try:
        # The progress bar appears just before the first frame starts.
        stderr = _read_until(process.stderr, b"reference frames", timeout=60)
        assert b"reference frames" in stderr, stderr.decode()
        time.sleep(0.5)  # well inside the kernel
        process.send_signal(signal.SIGINT)
        interrupted = time.monotonic()
        stdout, rest = process.communicate(timeout=2)
        elapsed = time.monotonic() - interrupted
    finally:
        process.kill()
        process.wait()
    stderr = (stderr + rest).decode()
    assert process.returncode == 130, stderr
    assert elapsed < 2.0
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr
    assert stderr.splitlines()[-1] == "volbench: interrupted"
    assert stdout == b"" and not output.exists()


def _slow_scenes():
    """A volume scene (the volume kernel) and one with a mesh (the geometry kernel), tens of seconds a frame
    on one thread."""
    volume = Volume(np.full((48, 48, 48), 60, np.uint8))
    instance = VolumeInstance(volume, TransferFunction.from_points([(0, 1, 1, 1, 0), (1, 1, 1, 1, 0.2)]))
    camera = Camera(azimuth=30, elevation=20)
    box = trimesh.creation.box(extents=(20, 20, 20))
    mesh = MeshInstance(Mesh(box.vertices, box.faces, name="box"), surface=SurfaceMaterial(alpha=0.3))
    yield Scene((instance,), camera=camera, width=160, height=160)
    yield Scene((instance,), meshes=[mesh], camera=camera, width=160, height=160)


def interrupted_frame(index):
    """Seconds from the start of slow scene ``index``'s frame until Ctrl-C stopped it (in this process)."""
    scene = list(_slow_scenes())[index]
    backend = reference.ReferenceRenderer(step_factor=0.002)
    # Compiled first: from a cold Numba cache the first frame compiles for seconds, and the signal would
    # arrive during compilation, not in the kernel this test interrupts.
    backend.render(dataclasses.replace(scene, width=2, height=2))
    numba.set_num_threads(1)  # a frame of many seconds on any machine (the kernel thread takes this count)
    sigint = threading.Timer(0.3, signal.pthread_kill, (threading.main_thread().ident, signal.SIGINT))
    started = time.monotonic()
    sigint.start()
    try:
        backend.render(scene)
    except KeyboardInterrupt:
        stopped = time.monotonic() - started
    else:
        raise AssertionError("the frame ended without KeyboardInterrupt")
    # The kernel has returned: the kernel thread is free at once.
    reference._kernel_thread().submit(lambda: None).result(timeout=0.5)
    return stopped


@pytest.mark.parametrize("index", [0, 1], ids=["volume", "mesh"])
def test_ctrl_c_stops_the_kernel_mid_frame(index):
    # In a fresh interpreter: in a long-lived pytest-xdist worker the signal was now and then not turned
    # into KeyboardInterrupt (a fresh clone's CI; not reproduced alone), and Ctrl-C is a whole process's.
    script = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
              f"import test_cli_interrupt as t; print(t.interrupted_frame({index}))")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          cwd=Path(__file__).parent.parent)
    assert done.returncode == 0, done.stderr
    assert float(done.stdout.split()[-1]) < 1.5


def test_pre_classification_stops_when_told():
    """The pre-classification kernel (a pass over the voxels) checks the same flag, before each slice."""
    kernel = reference.ReferenceRenderer()._raycast.preclassify
    data = np.full(6 * 5 * 4, 0.5, np.float32)
    tf = np.ascontiguousarray(TransferFunction.ramp(0.0, 1.0).table[None])
    up = np.array([0.0, 0.0, 1.0])
    arguments = (data, np.zeros(1, np.int64), np.array([[6, 5, 4]]), np.ones((1, 3)), tf, np.array([tf.shape[1]]),
                 np.zeros((1, 2)), np.zeros(1, np.int64), np.ones(1), np.eye(3)[None], 0, np.ones(4), up, up, True)
    out = np.full((4, data.size), -1.0, np.float32)
    kernel(*arguments, np.ones(1, np.int64), out)
    assert np.all(out == -1.0)  # stopped before its first slice
    kernel(*arguments, np.zeros(1, np.int64), out)
    np.testing.assert_allclose(out[3], 0.5, rtol=1e-6)
