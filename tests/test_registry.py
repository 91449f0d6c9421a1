import pytest

import renderers
from core.errors import BackendUnavailableError, InputError
from renderers.base import Capabilities, Renderer


def test_registry_lists_reference_without_importing_backends():
    import subprocess
    import sys

    assert "reference" in renderers.names()
    assert renderers.backend_module("reference") == "renderers.reference"
    # A fresh interpreter: importing the registry and listing names imports no backend (nor numba).
    probe = "import sys, renderers; renderers.names(); print(any(m.startswith(('renderers.reference', 'numba')) for m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_unknown_backend_is_a_clear_error():
    with pytest.raises(InputError, match="unknown backend 'nope'.*reference"):
        renderers.get("nope")


def test_unavailable_backend_is_reported_not_raised(monkeypatch):
    monkeypatch.setitem(renderers.BACKENDS, "ghost", "renderers.does_not_exist:Ghost")
    rows = {row.name: row for row in renderers.available()}
    assert rows["ghost"].available is False and "cannot be imported" in rows["ghost"].reason
    assert rows["reference"].available is True
    with pytest.raises(BackendUnavailableError, match="ghost"):
        renderers.get("ghost")


class _Probeless(Renderer):
    name = "probeless"
    capabilities = Capabilities(reasons={"modes": "only dvr here"})

    @classmethod
    def probe(cls):
        return False, "no device in this test"

    def _render(self, scene):
        raise AssertionError("never called")


def test_probe_failure_blocks_get(monkeypatch):
    monkeypatch.setitem(renderers.BACKENDS, "probeless", f"{__name__}:_Probeless")
    with pytest.raises(BackendUnavailableError, match="no device in this test"):
        renderers.get("probeless")


def test_capabilities_name_what_is_missing():
    import numpy as np

    from core.volume import Volume
    from core.camera import Camera
    from core.scene import Scene, Shading, VolumeInstance
    from core.transfer import TransferFunction

    instance = VolumeInstance(Volume(np.zeros((4, 4, 4), np.uint8)), TransferFunction.ramp(0.1, 0.2))
    scene = Scene(volumes=[instance, instance], mode="mip", shading=Shading(model="phong"),
                  camera=Camera(projection="perspective"))
    missing = dict(_Probeless.capabilities.missing(scene))
    assert missing["modes 'mip'"] == "only dvr here"
    assert "2 volumes" in missing and "projections 'perspective'" in missing and "shading 'phong'" in missing


def test_camera_inside_a_volume_is_refused_where_a_backend_cannot_handle_it():
    import numpy as np

    from core.volume import Volume
    from core.camera import Camera
    from core.errors import UnsupportedFeatureError
    from core.scene import Scene, VolumeInstance
    from core.transfer import TransferFunction

    instance = VolumeInstance(Volume(np.zeros((20, 20, 20), np.uint8)), TransferFunction.ramp(0.1, 0.2), name="head")
    inside = Scene(volumes=[instance], camera=Camera(projection="perspective", distance=3))
    outside = Scene(volumes=[instance], camera=Camera(projection="perspective", distance=60))
    caps = Capabilities(projections=frozenset({"perspective"}), reasons={"camera_inside_volume": "rays start at the box"})
    assert caps.missing(outside) == []
    assert caps.missing(inside) == [("camera inside volume head", "rays start at the box")]
    renderer = _Probeless.__new__(_Probeless)
    renderer.capabilities = caps
    with pytest.raises(UnsupportedFeatureError, match="camera inside volume head"):
        renderer.render(inside)
