import numpy as np
import pytest

from core.volume import Volume
from core.camera import Camera
from core.errors import InputError
from core.scene import CsgNode, Scene, Shading, VolumeInstance
from core.transfer import GradientOpacity, TransferFunction

TF = TransferFunction.ramp(0.2, 0.8)


def make_volume(shape=(4, 5, 6), dtype=np.uint8, **kwargs):
    return Volume(np.zeros(shape, dtype), **kwargs)


def test_volume_layout_extent_and_normalisation():
    volume = Volume(np.full((2, 3, 4), 255, np.uint8), spacing=(1, 2, 0.5))
    assert volume.shape_xyz == (4, 3, 2)
    assert volume.extent == (4, 6, 1)
    assert volume.min_spacing == 0.5
    assert volume.normalized().max() == 1.0
    wide = Volume(np.full((2, 2, 2), 4095, np.uint16), value_range=(0, 4095))
    assert wide.normalized().min() == 1.0


@pytest.mark.parametrize("data, match", [
    (np.zeros((4, 4), np.uint8), "3-D"),
    (np.zeros((4, 4, 4), np.int64), "dtype"),
    (np.zeros((0, 4, 4), np.uint8), "empty"),
    (np.full((2, 2, 2), np.nan, np.float32), "NaN"),
    ([[[1]]], "numpy array"),
])
def test_bad_volume_arrays_name_the_problem(data, match):
    with pytest.raises(InputError, match=match):
        Volume(data, name="bad")


def test_bad_spacing_and_range():
    with pytest.raises(InputError, match="spacing"):
        make_volume(spacing=(1, 0, 1))
    with pytest.raises(InputError, match="value_range"):
        make_volume(value_range=(5, 5))
    with pytest.raises(InputError, match="labels"):
        make_volume(labels=np.zeros((1, 1, 1), np.uint8))


def test_default_transform_centres_the_box():
    instance = VolumeInstance(make_volume(spacing=(1, 1, 2)), TF)
    corners = instance.world_corners()
    np.testing.assert_allclose(corners.min(axis=0), -corners.max(axis=0))
    np.testing.assert_allclose(corners.max(axis=0), (3, 2.5, 4))


def test_scene_frames_camera_and_lists_features():
    scene = Scene(volumes=[VolumeInstance(make_volume(), TF)], camera=Camera(azimuth=10))
    assert scene.camera.distance > scene.bounding_sphere()[1]
    assert scene.camera.view_height >= 2 * scene.bounding_sphere()[1]
    assert scene.features() == {"projections": "orthographic", "modes": "dvr", "shading": "none", "max_volumes": 1}
    gradient = GradientOpacity(np.ones(4))
    moved = np.eye(4)
    moved[0, 3] = 5
    scene2 = Scene(volumes=[VolumeInstance(make_volume(spacing=(1, 1, 2)), TF, transform=moved, gradient_opacity=gradient)],
                   mode="mip", shading=Shading(model="phong"))
    features = scene2.features()
    assert features["modes"] == "mip" and features["shading"] == "phong"
    assert features["gradient_opacity"] and features["transforms"] and features["anisotropic_spacing"]


def test_with_camera_keeps_framing_fields():
    scene = Scene(volumes=[VolumeInstance(make_volume(), TF)])
    turned = scene.with_camera(azimuth=45)
    assert turned.camera.azimuth == 45 and turned.camera.distance == scene.camera.distance


def test_camera_inside_volume_is_detected():
    big = make_volume(shape=(20, 20, 20))
    scene = Scene(volumes=[VolumeInstance(big, TF, name="big")],
                  camera=Camera(projection="perspective", distance=2))
    assert scene.camera_inside_volume() == ["big"]


@pytest.mark.parametrize("kwargs, match", [
    ({"volumes": []}, "at least one"),
    ({"mode": "xray"}, "mode"),
    ({"width": 0}, "width"),
    ({"height": 2.5}, "height"),
])
def test_bad_scene_inputs(kwargs, match):
    args = {"volumes": [VolumeInstance(make_volume(), TF)], **kwargs}
    with pytest.raises(InputError, match=match):
        Scene(**args)


def test_bad_instance_inputs():
    with pytest.raises(InputError, match="singular"):
        VolumeInstance(make_volume(), TF, transform=np.zeros((4, 4)) + np.diag([0, 0, 0, 1]))
    with pytest.raises(InputError, match="isovalue"):
        VolumeInstance(make_volume(), TF, isovalue=1.5)
    with pytest.raises(InputError, match="transfer_function"):
        VolumeInstance(make_volume(), "bone")
    with pytest.raises(InputError, match="shading model"):
        Shading(model="toon")


def test_min_world_voxel_size_takes_spacing_and_transforms_into_account():
    tf = TransferFunction.constant(alpha=0.1)
    scaled = np.diag([3.0, 0.5, 1.0, 1.0])
    a = VolumeInstance(Volume(np.zeros((4, 4, 4), np.uint8), spacing=(2.0, 1.0, 1.5)), tf, name="a")
    b = VolumeInstance(Volume(np.zeros((4, 4, 4), np.uint8), spacing=(1.0, 1.0, 1.0)), tf, transform=scaled, name="b")
    assert Scene([a]).min_world_voxel_size() == 1.0
    assert Scene([a, b]).min_world_voxel_size() == 0.5  # b's y edge: 1.0 · 0.5


def _cube():
    import trimesh

    from core.mesh import Mesh

    box = trimesh.creation.box(extents=(2, 2, 2))
    return Mesh(box.vertices, box.faces, name="cube")


def test_geometry_features_and_bounds_include_meshes():
    from core.mesh import HomogeneousMedium, MeshInstance, SurfaceMaterial

    far = np.eye(4)
    far[:3, 3] = (50, 0, 0)
    cube = _cube()
    volume = VolumeInstance(make_volume(), TF, name="v")
    plain = Scene(volumes=[volume])
    assert not plain.has_geometry() and plain.meshes == () and plain.csg == ()
    scene = Scene(volumes=[volume], meshes=[MeshInstance(cube, transform=far, surface=SurfaceMaterial(alpha=0.5),
                                                         medium=HomogeneousMedium(), name="c")],
                  csg=[CsgNode("difference", ["v", "c"])])
    features = scene.features()
    assert features["meshes"] and features["csg"] and features["translucent_geometry"] and features["homogeneous_media"]
    assert scene.bounds()[1][0] == 51 and scene.camera.view_height > 54
    opaque = Scene(meshes=[MeshInstance(cube, surface=SurfaceMaterial())])
    assert "translucent_geometry" not in opaque.features() and opaque.features()["meshes"]
    bounded = Scene(volumes=[VolumeInstance(make_volume(), TF, boundary=cube)])
    assert bounded.has_geometry() and bounded.features()["meshes"]
    with pytest.raises(InputError, match="no volume"):
        opaque.min_world_voxel_size()


@pytest.mark.parametrize("make, match", [
    (lambda v, m: Scene(), "at least one volume or mesh"),
    (lambda v, m: Scene(volumes=[v], meshes=["cube"]), "MeshInstance"),
    (lambda v, m: Scene(volumes=[v], meshes=[m], csg=[CsgNode("union", ["v", "nope"])]), "leaf 'nope'.*no instance"),
    (lambda v, m: Scene(volumes=[v, v], meshes=[m], csg=[CsgNode("union", ["v", "c"])]), "leaf 'v'.*2 instances"),
    (lambda v, m: Scene(volumes=[v], meshes=[m], csg=[CsgNode("union", ["v", "c"]), CsgNode("union", ["c", "v"])]),
     "more than once"),
    (lambda v, m: Scene(volumes=[v], meshes=[m], csg=["v"]), "CsgNode"),
    (lambda v, m: CsgNode("xor", ["v", "c"]), "csg operation"),
    (lambda v, m: CsgNode("union", ["v"]), "at least two"),
    (lambda v, m: CsgNode("union", "vc"), "children must be a list"),
    (lambda v, m: Scene(volumes=[v], meshes=[m], mode="mip"), "modes 'dvr' and 'iso'.*got mode 'mip'"),
    (lambda v, m: VolumeInstance(make_volume(), TF, boundary="box"), "boundary must be a Mesh"),
])
def test_bad_geometry_inputs(make, match):
    from core.mesh import MeshInstance

    with pytest.raises(InputError, match=match):
        make(VolumeInstance(make_volume(), TF, name="v"), MeshInstance(_cube(), name="c"))



def test_an_image_this_machine_cannot_hold_is_refused_with_the_largest_that_fits(monkeypatch):
    import core.resources

    monkeypatch.setattr(core.resources, "memory_limit", lambda: 16 * 10 ** 6)  # one million float32 RGBA pixels
    instance = VolumeInstance(make_volume(), TF)
    with pytest.raises(InputError, match=r"^scene 'big' image 2000×1000 needs 30.5 MiB \(16 bytes a pixel, float32 RGBA\), "
                                         r"this machine has 15.3 MiB; use width × height ≤ 1000000 pixels \(e.g. 1000×1000\)$"):
        Scene(volumes=instance, width=2000, height=1000, name="big")
    assert Scene(volumes=instance, width=1000, height=1000).width == 1000


def test_a_scene_whose_bounds_overflow_is_refused_naming_them():
    huge = VolumeInstance(make_volume(spacing=(1e300, 1, 1)), TF)
    with pytest.raises(InputError, match="bounds overflow float64.*smaller spacings"):
        Scene(volumes=huge)
