"""The lens scenes of ``ropinski2005`` (note 004 §5): valid scenes, each lens where the note puts it, the controls."""

import json

import numpy as np
import pytest

import datasets
from core.camera import Camera
from core.errors import InputError
from pipeline.experiments.kit.planning import headline_view
from pipeline.experiments.ropinski2005 import scenes as S
from pipeline.scene_io import build_scene

SIZE = 24


def built(spec, tmp_path):
    return build_scene(spec, cache_dir=str(tmp_path / "cache"))


def scene_of(name, tmp_path, **lens):
    """The built lens scene ``name`` at :data:`SIZE` voxels (skipped where a real scan is absent)."""
    try:
        return built(S.lens_scene(name, 16, size=SIZE, **lens), tmp_path)
    except datasets.DataUnavailableError as exc:
        pytest.skip(str(exc))


def box_of(scene):
    """The world box of a scene's one volume: centred on the origin (untransformed)."""
    half = 0.5 * np.asarray(scene.volumes[0].volume.extent)
    return -half, half


def inside(lens, point):
    """Whether world ``point`` is inside ``lens`` (sphere or box)."""
    if lens.shape == "sphere":
        return np.linalg.norm(np.asarray(point) - lens.center) <= lens.radius
    local = np.linalg.solve(lens.object_to_world(), np.append(point, 1.0))[:3]
    return bool(np.all(np.abs(local) <= np.asarray(lens.size) / 2 + 1e-9))


def eye_direction(dataset):
    view = headline_view(dataset)
    return Camera(azimuth=view["azimuth"], elevation=view["elevation"], up=view["up"])._offset_direction()


@pytest.mark.parametrize("dataset", sorted(S.PHANTOM_ASPECT))
def test_the_box_proportions_are_the_generators(dataset):
    volume = datasets.get(dataset).generator(SIZE, 0)
    assert tuple(float(n * s) for n, s in zip(volume.shape_xyz, volume.spacing)) == S.extent(dataset, SIZE)


def test_a_real_scans_box_is_its_manifests(tmp_path):
    (tmp_path / "volumes.json").write_text(json.dumps({"cthead": {"file": "x.raw", "dims": [256, 256, 99],
                                                                  "dtype": "uint8", "spacing": [1, 1, 2]}}))
    assert S.extent("cthead", SIZE, real_data=str(tmp_path)) == (256.0, 256.0, 198.0)
    assert S.extent("cthead", SIZE, real_data=str(tmp_path / "absent")) == (float(SIZE),) * 3


def test_every_scene_is_valid_with_one_lens_and_the_volumes_preset(tmp_path):
    for name, setup in S.SETUPS.items():
        spec = S.lens_scene(name, 16, size=SIZE)
        assert spec["volumes"] == [{"dataset": setup.dataset, "preset": setup.preset,
                                    **({"size": SIZE} if datasets.get(setup.dataset).kind == "phantom" else {})}]
        assert spec["mode"] == "dvr" and len(spec["lenses"]) == 1
        scene = scene_of(name, tmp_path)
        assert len(scene.lenses) == 1 and scene.lenses[0].shape == setup.shape


def test_the_seismic_clip_lens_sticks_out_of_the_front_top_corner(tmp_path):
    scene = scene_of("seismic", tmp_path)
    lens = scene.lenses[0]
    low, high = box_of(scene)
    assert lens.appearance.mode == "clip" and lens.radius == pytest.approx(0.3 * SIZE)
    assert np.all((low < lens.center) & (lens.center < high))
    corners = [np.array([x, y, z]) for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])]
    nearest = max(corners, key=lambda c: c @ eye_direction("seismic"))  # the corner facing the headline camera
    assert nearest[2] == high[2] and inside(lens, nearest)  # on top, and the sphere reaches past it
    assert sum(inside(lens, c) for c in corners) == 1


def test_the_transparency_lenses_scale_the_volumes_own_table(tmp_path):
    for name in ("skull", "engine", "cthead"):
        scene = scene_of(name, tmp_path)
        appearance, volume = scene.lenses[0].appearance, scene.volumes[0]
        assert appearance.mode == "dvr" and appearance.opacity_scale == pytest.approx(0.2)
        table = appearance.classification(volume.transfer_function).table
        assert np.array_equal(table[:, :3], volume.transfer_function.table[:, :3])
        assert np.allclose(table[:, 3], 0.2 * volume.transfer_function.table[:, 3])


def test_the_skull_lens_covers_bone_in_front(tmp_path):
    scene = scene_of("skull", tmp_path)
    lens, volume = scene.lenses[0], scene.volumes[0].volume
    assert lens.center[1] < 0 < lens.center[2]  # in front (−y, the face) and above the centre
    data = volume.data.astype(float)
    z, y, x = np.nonzero(data >= 160)  # the bone preset's ramp starts at 160
    points = np.stack([x, y, z], axis=1) + 0.5 - 0.5 * np.asarray(volume.shape_xyz)
    assert np.linalg.norm(points - lens.center, axis=1).min() < lens.radius


def test_the_foot_iso_lens_sits_on_the_metatarsals(tmp_path):
    scene = scene_of("foot", tmp_path)
    lens, volume = scene.lenses[0], scene.volumes[0].volume
    assert lens.appearance.mode == "iso" and lens.appearance.isovalue == S.BONE_ISOVALUE
    assert lens.radius == pytest.approx(0.25 * SIZE)
    z, y, x = np.nonzero(volume.data >= 255 * S.BONE_ISOVALUE)
    points = np.stack([x, y, z], axis=1) + 0.5 - 0.5 * np.asarray(volume.shape_xyz)
    in_lens = np.linalg.norm(points - lens.center, axis=1) <= lens.radius
    assert in_lens.sum() > 0.05 * len(points)  # a good part of the foot's bone: the forefoot's
    assert points[in_lens, 2].mean() < 0 and points[~in_lens, 2].mean() > points[in_lens, 2].mean()  # below the leg


def test_the_engine_lens_is_a_rotated_cuboid_of_the_stated_proportions(tmp_path):
    scene = scene_of("engine", tmp_path)
    lens = scene.lenses[0]
    extent = np.asarray(scene.volumes[0].volume.extent)
    assert extent.tolist() == [SIZE, SIZE, SIZE / 2]
    assert lens.shape == "box" and np.allclose(lens.size, [0.4, 0.4, 0.6] * extent)
    assert np.allclose(lens.center, 0.0)
    c, s = np.cos(np.radians(20)), np.sin(np.radians(20))
    assert np.allclose(lens.transform[:3, :3], [[c, 0, s], [0, 1, 0], [-s, 0, c]])


def test_keywords_move_resize_and_restyle_the_lens(tmp_path):
    spec = S.lens_scene("seismic", 16, size=40, radius=0.1, center=(0, 0, 0), appearance={"mode": "mip"})
    assert spec["lenses"][0] == {"shape": "sphere", "center": [0.0, 0.0, 0.0], "radius": 4.0,
                                 "appearance": {"mode": "mip"}}
    box = S.lens_scene("engine", 16, size=40, box_size=(0.5, 0.25, 1.0), rotate_y=0)["lenses"][0]
    assert box["size"] == [20.0, 10.0, 20.0] and "transform" not in box
    with pytest.raises(InputError, match="sphere lens takes radius"):
        S.lens_scene("seismic", 16, size=40, box_size=(1, 1, 1))
    with pytest.raises(InputError, match="box lens takes size"):
        S.lens_scene("engine", 16, size=40, radius=0.2)
    with pytest.raises(InputError, match="radius: expected"):
        S.lens_scene("seismic", 16, size=40, radius=0)
    with pytest.raises(InputError, match="unknown lens scene 'brain'; known: seismic"):
        S.lens_scene("brain", 16, size=40)
    assert S.SETUPS["seismic"].appearance == {"mode": "clip"}  # the override did not touch the setup


def test_the_controls(tmp_path):
    spec = S.lens_scene("skull", 16, size=SIZE)
    off = S.without_lens(spec)
    assert "lenses" not in off and "lenses" in spec and built(off, tmp_path).lenses == ()
    outside = S.outside_appearance(spec)
    assert outside["lenses"][0]["appearance"] == {"mode": "dvr", "preset": "bone"}
    assert spec["lenses"][0]["appearance"]["opacity_scale"] == 0.2  # the input is not changed
    scene = built(outside, tmp_path)
    instance = scene.volumes[0]
    assert np.array_equal(scene.lenses[0].appearance.classification(instance.transfer_function).table,
                          instance.transfer_function.table)
    with pytest.raises(InputError, match="has no lens"):
        S.outside_appearance(off)


def test_views():
    views = S.lens_views("foot", 2)
    assert [v["view"] for v in views] == ["headline", "orbit000", "orbit180"]
    assert views[0] == headline_view("foot") and all(v["up"] == [0.0, 0.0, 1.0] for v in views)
