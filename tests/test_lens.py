"""The lens-volume contract (core.lens, Scene.lenses, scene files): shapes, appearances, refusals."""

import numpy as np
import pytest

import datasets
import renderers
from core.errors import InputError
from core.lens import Lens, LensAppearance
from core.mesh import Mesh, MeshInstance
from core.scene import Scene, VolumeInstance
from core.transfer import GradientOpacity, TransferFunction
from core.volume import Volume
from datasets import meshes
from pipeline.scene_io import build_scene, rotation_matrix

TF = TransferFunction.ramp(0.2, 0.8, alpha=0.5)
CLIP = LensAppearance("clip")


def octahedron(scale=1.0):
    """``|x| + |y| + |z| <= scale``, faces wound counter-clockwise from outside."""
    vertices = scale * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return Mesh(vertices, np.array(faces), name="octahedron")


def volume_scene(**changes):
    volume = Volume(np.zeros((8, 8, 8), np.uint8))
    return Scene([VolumeInstance(volume, TF)], width=8, height=8, **changes)


# ---------------------------------------------------------------------------------------------
# Shapes


def test_a_sphere_lens_is_a_translated_quadric_without_half_spaces():
    lens = Lens("sphere", center=(1, 2, 3), radius=4, appearance=CLIP)
    assert lens.radius == 4.0 and lens.center == (1.0, 2.0, 3.0)
    np.testing.assert_array_equal(lens.object_to_world()[:3, 3], (1, 2, 3))
    assert lens.half_spaces()[0].shape == (0, 3)


def test_a_box_lens_is_its_six_slab_planes_moved_by_its_transform_then_its_centre():
    rotate = rotation_matrix((0, 0, 1), 30)
    lens = Lens("box", center=(5, 0, 0), size=(2, 4, 6), transform=rotate, appearance=CLIP)
    normals, offsets = lens.half_spaces()
    np.testing.assert_array_equal(normals, np.concatenate([np.eye(3), -np.eye(3)]))
    np.testing.assert_array_equal(offsets, [1, 2, 3, 1, 2, 3])
    np.testing.assert_allclose(lens.object_to_world(), np.array([[1, 0, 0, 5], [0, 1, 0, 0], [0, 0, 1, 0],
                                                                 [0, 0, 0, 1.0]]) @ rotate)


@pytest.mark.parametrize("flip", [False, True])
def test_a_convex_mesh_lens_has_its_face_planes_pointing_out(flip):
    mesh = octahedron(2.0)
    if flip:  # clockwise winding: the planes still point outwards
        mesh = Mesh(mesh.vertices, mesh.faces[:, ::-1], name="clockwise")
    normals, offsets = Lens("mesh", center=(0, 0, 0), mesh=mesh, appearance=CLIP).half_spaces()
    expected = {tuple(np.round(n, 12)) for n in np.array([[a, b, c] for a in (1, -1) for b in (1, -1) for c in (1, -1)])
                / np.sqrt(3)}
    assert {tuple(np.round(n, 12)) for n in normals} == expected
    np.testing.assert_allclose(offsets, 2 / np.sqrt(3), rtol=1e-14)


def test_a_non_convex_mesh_is_refused_with_the_fix():
    with pytest.raises(InputError, match="not convex.*convex hull"):
        Lens("mesh", center=(0, 0, 0), mesh=meshes.boxes_in_a_row(count=2), appearance=CLIP)


@pytest.mark.parametrize("shape, fields, match", [
    ("cone", {"radius": 1}, "shape"),
    ("sphere", {}, "needs radius"),
    ("sphere", {"radius": 0}, "radius"),
    ("sphere", {"radius": 1, "size": (1, 1, 1)}, "size does not apply to a sphere"),
    ("sphere", {"radius": 1, "transform": np.eye(4)}, "transform does not apply"),
    ("box", {}, "needs size"),
    ("box", {"size": (1, 0, 1)}, "size"),
    ("box", {"size": (1, 1, 1), "radius": 2}, "radius does not apply"),
    ("box", {"size": (1, 1, 1), "transform": np.zeros((4, 4))}, "transform"),
    ("mesh", {}, "needs mesh"),
    ("mesh", {"mesh": "octahedron.obj"}, "must be a Mesh"),
])
def test_bad_lens_shapes_are_refused_naming_the_field(shape, fields, match):
    with pytest.raises(InputError, match=match):
        Lens(shape, center=(0, 0, 0), appearance=CLIP, **fields)


def test_centre_and_appearance_are_checked():
    with pytest.raises(InputError, match="center"):
        Lens("sphere", center=(0, 0), radius=1, appearance=CLIP)
    with pytest.raises(InputError, match="LensAppearance"):
        Lens("sphere", center=(0, 0, 0), radius=1, appearance={"mode": "clip"})
    with pytest.raises(TypeError):  # options are keyword-only
        Lens("sphere", (0, 0, 0), CLIP)


# ---------------------------------------------------------------------------------------------
# Appearances


@pytest.mark.parametrize("mode, fields, match", [
    ("blur", {}, "mode"),
    ("clip", {"transfer_function": TF}, "transfer_function does not apply"),
    ("dvr", {}, "needs a transfer_function"),
    ("dvr", {"transfer_function": TF, "opacity_scale": -1}, "opacity_scale"),
    ("dvr", {"transfer_function": TF, "isovalue": 0.5}, "isovalue does not apply"),
    ("iso", {}, "needs an isovalue"),
    ("iso", {"isovalue": 1.5}, "isovalue"),
    ("iso", {"isovalue": 0.5, "gradient_opacity": GradientOpacity(np.ones(4))}, "gradient_opacity does not apply"),
    ("mip", {"opacity_scale": 0.5}, "opacity_scale does not apply"),
    ("mip", {"transfer_function": "bone"}, "must be a TransferFunction"),
])
def test_bad_appearances_are_refused_naming_the_field(mode, fields, match):
    with pytest.raises(InputError, match=match):
        LensAppearance(mode, **fields)


def test_opacity_scale_multiplies_the_table_and_clips_at_one():
    tf = TransferFunction.from_points([(0, 1, 0, 0, 0.2), (1, 1, 0, 0, 0.8)], size=4)
    assert LensAppearance("dvr", transfer_function=tf).classification(TF) is tf
    scaled = LensAppearance("dvr", transfer_function=tf, opacity_scale=2.0).classification(TF)
    np.testing.assert_allclose(scaled.table[:, 3], np.minimum(2 * tf.table[:, 3].astype(float), 1.0), rtol=1e-7)
    np.testing.assert_array_equal(scaled.table[:, :3], tf.table[:, :3])
    assert LensAppearance("mip").classification(TF) is TF
    assert LensAppearance("iso", isovalue=0.3).classification(TF) is TF
    assert CLIP.classification(TF) is None


# ---------------------------------------------------------------------------------------------
# Scenes


def test_a_lens_scene_needs_the_lenses_capability_and_every_other_backend_says_why_not():
    scene = volume_scene(lenses=[Lens("sphere", center=(0, 0, 0), radius=2, appearance=CLIP)])
    assert scene.features()["lenses"] is True
    assert "lenses" not in volume_scene().features()
    for name in renderers.names():
        capabilities = renderers.backend_class(name).capabilities
        missing = dict(capabilities.missing(scene))
        if capabilities.lenses:
            assert "lenses" not in missing
        else:
            assert "lens" in missing["lenses"] or "shear-warp" in missing["lenses"] or "VolPack" in missing["lenses"]
    assert renderers.backend_class("reference").capabilities.lenses


def test_a_single_lens_is_held_as_a_tuple_and_does_not_move_the_camera():
    lens = Lens("sphere", center=(100, 0, 0), radius=50, appearance=CLIP)
    scene = volume_scene(lenses=lens)
    assert scene.lenses == (lens,)
    assert scene.camera == volume_scene().camera


@pytest.mark.parametrize("changes, match", [
    ({"lenses": ["sphere"]}, "Lens objects"),
    ({"lenses": [Lens("sphere", center=(0, 0, 0), radius=1, appearance=CLIP)] * 2}, "at most one"),
    ({"mode": "mip"}, "outside the lens.*mode: dvr"),
])
def test_lens_scenes_outside_the_contract_are_refused_with_the_reason(changes, match):
    changes.setdefault("lenses", [Lens("sphere", center=(0, 0, 0), radius=1, appearance=CLIP)])
    with pytest.raises(InputError, match=match):
        volume_scene(**changes)


def test_a_lens_needs_exactly_one_volume_and_no_geometry():
    lens = Lens("sphere", center=(0, 0, 0), radius=1, appearance=CLIP)
    volume = VolumeInstance(Volume(np.zeros((4, 4, 4), np.uint8)), TF)
    with pytest.raises(InputError, match="exactly one volume"):
        Scene([volume, volume], lenses=[lens])
    with pytest.raises(InputError, match="meshes"):
        Scene([volume], meshes=[MeshInstance(octahedron())], lenses=[lens])


# ---------------------------------------------------------------------------------------------
# Scene files


def _spec(*lenses, volume=None):
    return {"width": 8, "height": 8, "volumes": [volume or {"dataset": "sphere", "size": 16}], "lenses": list(lenses)}


def test_the_issue_yaml_builds_a_sphere_clip_lens(tmp_path):
    scene = build_scene(_spec({"shape": "sphere", "center": [0, 10, 0], "radius": 30, "appearance": {"mode": "clip"}}),
                        cache_dir=tmp_path)
    (lens,) = scene.lenses
    assert (lens.shape, lens.center, lens.radius, lens.appearance.mode) == ("sphere", (0.0, 10.0, 0.0), 30.0, "clip")


def test_a_dvr_lens_preset_is_the_volume_data_sets_preset(tmp_path):
    scene = build_scene(_spec({"shape": "box", "center": [1, 2, 3], "size": [2, 4, 6],
                               "transform": {"rotate": {"axis": [0, 0, 1], "degrees": 30}},
                               "appearance": {"mode": "dvr", "preset": "binary", "opacity_scale": 0.5}}),
                        cache_dir=tmp_path)
    (lens,) = scene.lenses
    preset = datasets.preset("sphere", "binary")
    assert lens.appearance.transfer_function is preset.transfer_function
    assert lens.appearance.opacity_scale == 0.5
    np.testing.assert_allclose(lens.object_to_world()[:3, :3], rotation_matrix((0, 0, 1), 30)[:3, :3])
    np.testing.assert_allclose(lens.object_to_world()[:3, 3], (1, 2, 3))


def test_iso_and_mip_lenses_and_a_mesh_lens_from_a_file(tmp_path):
    mesh = octahedron()
    path = tmp_path / "octahedron.obj"
    path.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in mesh.vertices)
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in mesh.faces))
    iso = build_scene(_spec({"shape": "mesh", "center": [0, 0, 0], "mesh": {"file": str(path)},
                             "appearance": {"mode": "iso", "preset": "opaque"}}), cache_dir=tmp_path).lenses[0]
    assert iso.appearance.isovalue == pytest.approx(datasets.preset("sphere", "opaque").effective_isovalue)
    assert len(iso.half_spaces()[0]) == 8
    mip = build_scene(_spec({"shape": "sphere", "center": [0, 0, 0], "radius": 3,
                             "appearance": {"mode": "mip", "transfer_function": {"points": [[0, 1, 1, 1, 0],
                                                                                            [1, 1, 1, 1, 1]]}}}),
                      cache_dir=tmp_path).lenses[0]
    assert mip.appearance.mode == "mip" and mip.appearance.transfer_function.table[-1, 3] == 1


SPHERE = {"shape": "sphere", "center": [0, 0, 0], "radius": 3}


@pytest.mark.parametrize("lens, match", [
    ({**SPHERE, "colour": 1, "appearance": {"mode": "clip"}}, r"lenses\[0\]: unknown keys \['colour'\]"),
    ({"shape": "sphere", "radius": 3, "appearance": {"mode": "clip"}}, r"lenses\[0\]: needs 'center'"),
    ({**SPHERE}, r"lenses\[0\]: needs 'appearance'"),
    ({**SPHERE, "appearance": {}}, "appearance: needs a mode"),
    ({**SPHERE, "appearance": {"mode": "clip", "preset": "opaque"}}, r"clip lens.*\['preset'\]"),
    ({**SPHERE, "appearance": {"mode": "dvr", "preset": "opaque", "transfer_function": {"points": [[0, 1, 1, 1, 1]]}}},
     "one of 'preset' or 'transfer_function'"),
    ({**SPHERE, "appearance": {"mode": "dvr", "preset": "nope"}}, "no preset 'nope'"),
    ({**SPHERE, "appearance": {"mode": "dvr", "transfer_function": {"points": "ramp"}}}, "transfer_function points"),
    ({**SPHERE, "appearance": {"mode": 3}}, "appearance mode: expected text"),
    ({**SPHERE, "transform": {"scale": 2}, "appearance": {"mode": "clip"}}, "transform does not apply to a sphere"),
    ({**SPHERE, "radius": "big", "appearance": {"mode": "clip"}}, "radius"),
])
def test_bad_lens_entries_name_the_key(lens, match, tmp_path):
    with pytest.raises(InputError, match=match):
        build_scene(_spec(lens), cache_dir=tmp_path)


def test_a_preset_needs_a_data_set_volume(tmp_path):
    volume = {"file": "x_4x4x4_uint8.raw", "transfer_function": {"points": [[0, 1, 1, 1, 1]]}}
    with pytest.raises(InputError, match="preset.*data set"):
        build_scene(_spec({**SPHERE, "appearance": {"mode": "dvr", "preset": "opaque"}}, volume=volume))


def test_lens_entries_are_refused_before_any_volume_is_generated(tmp_path, monkeypatch):
    def no_loading(*args, **kwargs):
        raise AssertionError("a volume was loaded before the lens was checked")

    monkeypatch.setattr(datasets, "load", no_loading)
    with pytest.raises(InputError, match="shape"):
        build_scene(_spec({"shape": "cone", "center": [0, 0, 0], "appearance": {"mode": "clip"}}), cache_dir=tmp_path)
    with pytest.raises(InputError, match="scene lenses: expected a list"):
        build_scene({**_spec(), "lenses": {"shape": "sphere"}}, cache_dir=tmp_path)


def test_contains_and_the_voxel_mask_agree_with_the_lens_frame():
    rotation = np.eye(4)
    c, s = np.cos(0.6), np.sin(0.6)
    rotation[:2, :2] = [[c, -s], [s, c]]
    box = Lens("box", center=(5.0, 4.0, 3.0), size=(6.0, 4.0, 2.0), transform=rotation,
               appearance=LensAppearance("clip"))
    points = np.random.default_rng(0).uniform(-2, 12, size=(4000, 3))
    local = (points - box.center) @ rotation[:3, :3]  # world -> the box's own frame
    expected = np.all(np.abs(local) <= np.array(box.size) / 2, axis=1)
    np.testing.assert_array_equal(box.contains(points), expected)
    sphere = Lens("sphere", center=(8.0, 8.0, 8.0), radius=5.0, appearance=LensAppearance("clip"))
    np.testing.assert_array_equal(sphere.contains(points), np.linalg.norm(points - 8.0, axis=1) <= 5.0)
    volume = Volume(np.zeros((16, 16, 16), np.uint8), spacing=(1.0, 1.0, 1.0))
    shift = np.eye(4)
    shift[:3, 3] = [1.0, 0.0, 0.0]  # voxel (i, j, k)'s centre at (i + 1.5, j + 0.5, k + 0.5)
    mask = sphere.voxel_mask(volume, shift)
    k, j, i = np.nonzero(mask)
    assert np.all((i + 1.5 - 8) ** 2 + (j + 0.5 - 8) ** 2 + (k + 0.5 - 8) ** 2 <= 25)
    assert abs(mask.sum() - 4 / 3 * np.pi * 125) < 0.1 * 4 / 3 * np.pi * 125  # 552 lattice points
