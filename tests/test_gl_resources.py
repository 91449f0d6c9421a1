"""renderers.gl.resources: what a frame derives from a volume on the CPU is kept for the process by the
volume's content, so that the next run's renderer, on a volume loaded afresh, does not derive it again."""

import numpy as np
import pytest

import renderers
from core.camera import Camera
from core.scene import Scene, Shading, VolumeInstance
from core.transfer import TransferFunction
from core.volume import Volume
from renderers.gl import context, resources

GL_OK, GL_REASON = context.probe()
needs_gl = pytest.mark.skipif(not GL_OK, reason=f"no OpenGL 4.3 context through EGL here: {GL_REASON}")


def volume(seed=0, spacing=(1.0, 1.0, 1.0)):
    data = np.random.default_rng(seed).integers(0, 255, size=(12, 10, 8), dtype=np.uint8)
    return Volume(data, spacing=spacing)


@pytest.fixture(autouse=True)
def empty_cache(monkeypatch):
    monkeypatch.setattr(resources, "_derived", type(resources._derived)())


def test_a_volume_of_the_same_content_finds_what_another_object_derived():
    built = []

    def build():
        built.append(1)
        return np.arange(6.0)

    first = resources.derived(volume(), "kind", (2,), build)
    again = resources.derived(volume(), "kind", (2,), build)
    assert again is first and len(built) == 1
    assert not first.flags.writeable


@pytest.mark.parametrize("other", [dict(seed=1), dict(spacing=(1.0, 1.0, 2.0))])
def test_other_data_or_spacing_derives_again(other):
    built = []
    resources.derived(volume(), "kind", (), lambda: built.append(1) or np.zeros(3))
    resources.derived(volume(**other), "kind", (), lambda: built.append(1) or np.zeros(3))
    assert len(built) == 2


def test_other_parameters_or_kinds_derive_again():
    built = []
    for kind, params in (("a", (1,)), ("a", (2,)), ("b", (1,))):
        resources.derived(volume(), kind, params, lambda: built.append(1) or np.zeros(3))
    assert len(built) == 3


def test_the_cache_drops_the_least_recently_used_beyond_its_bytes(monkeypatch):
    monkeypatch.setattr(resources, "DERIVED_CACHE_BYTES", 2 * 800)
    for seed in range(3):
        resources.derived(volume(seed), "kind", (), lambda: np.zeros(100))
    assert len(resources._derived) == 2
    too_large = resources.derived(volume(), "large", (), lambda: np.zeros(300))
    assert too_large.shape == (300,) and ("large", volume().content_hash(), ()) not in resources._derived


def test_a_machine_with_little_memory_keeps_less(monkeypatch):
    import core.resources

    monkeypatch.setattr(core.resources, "memory_limit", lambda: 50 * 800)  # 2 % of it: 800 bytes, one array
    for seed in range(3):
        resources.derived(volume(seed), "kind", (), lambda: np.zeros(100))
    assert len(resources._derived) == 1
    monkeypatch.setattr(core.resources, "memory_limit", lambda: 2 ** 50)
    assert resources.derived_capacity() == resources.DERIVED_CACHE_BYTES


@needs_gl
def test_the_next_renderer_on_a_reloaded_volume_builds_no_gradients_and_renders_the_same_image():
    def scene():
        data = np.zeros((16, 16, 16), dtype=np.uint8)
        data[4:12, 4:12, 4:12] = 200
        tf = TransferFunction.from_points([(0.0, 0, 0, 0, 0.0), (0.5, 1, 0.5, 0.2, 0.3), (1.0, 1, 1, 1, 0.8)])
        return Scene((VolumeInstance(Volume(data), tf),), camera=Camera(azimuth=30.0, elevation=20.0), width=24,
                     height=24, shading=Shading(model="phong"))

    first = renderers.get("gl-raycast").render(scene())
    second = renderers.get("gl-raycast").render(scene())
    assert {"gradients", "minmax"} <= set(first.timings)
    assert not {"gradients", "minmax"} & set(second.timings)
    np.testing.assert_array_equal(first.image, second.image)
