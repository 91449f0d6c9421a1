import numpy as np
import pytest

from core.errors import InputError
from pipeline.scene_io import build_scene, load_scene, rotation_matrix


def _spec(**volume):
    return {"width": 16, "height": 12, "volumes": [{"dataset": "sphere", "size": 16, **volume}]}


def test_builds_a_phantom_scene_with_its_default_preset(tmp_path):
    scene = build_scene(_spec(), cache_dir=tmp_path)
    instance = scene.volumes[0]
    assert (scene.width, scene.height, scene.mode) == (16, 12, "dvr")
    assert instance.volume.data.shape == (16, 16, 16)
    import datasets

    default = datasets.preset("sphere")
    np.testing.assert_array_equal(instance.transfer_function.table, default.transfer_function.table)
    assert instance.isovalue == pytest.approx(default.effective_isovalue)


def test_explicit_transfer_function_gradient_table_and_transform(tmp_path):
    spec = _spec(transfer_function={"points": [[0, 1, 0, 0, 0], [1, 1, 0, 0, 0.5]]},
                 gradient_opacity={"points": [[0, 0], [1, 1]]},
                 transform={"translate": [5, 0, 0], "rotate": {"axis": [0, 0, 1], "degrees": 90}})
    instance = build_scene(spec, cache_dir=tmp_path).volumes[0]
    assert instance.transfer_function.table[-1, 3] == pytest.approx(0.5)
    assert instance.gradient_opacity is not None
    # The box is centred, rotated about z, then moved: its centre lands on (5, 0, 0).
    centre = instance.transform @ np.array([8, 8, 8, 1.0])
    np.testing.assert_allclose(centre[:3], (5, 0, 0), atol=1e-12)
    np.testing.assert_allclose(rotation_matrix((0, 0, 1), 90)[:3, :3] @ (1, 0, 0), (0, 1, 0), atol=1e-12)


def test_raw_file_volume_from_yaml(tmp_path):
    data = (np.arange(4 * 5 * 6) % 256).astype(np.uint8).reshape(6, 5, 4)
    data.tofile(tmp_path / "blob_4x5x6_uint8.raw")
    (tmp_path / "scene.yaml").write_text(
        "mode: mip\nvolumes:\n  - file: blob_4x5x6_uint8.raw\n    spacing: [1, 1, 2]\n"
        "    transfer_function: {points: [[0, 1, 1, 1, 0], [1, 1, 1, 1, 1]]}\n")
    scene = load_scene(tmp_path / "scene.yaml")
    volume = scene.volumes[0].volume
    np.testing.assert_array_equal(volume.data, data)
    assert volume.spacing == (1, 1, 2) and scene.mode == "mip"


@pytest.mark.parametrize("spec, match", [
    ({"volumes": []}, "at least one"),
    ({"volumes": [{"dataset": "sphere"}], "colour": "red"}, "unknown keys.*colour"),
    ({"volumes": [{"dataset": "sphere", "size": 16, "presett": "x"}]}, "unknown keys.*presett"),
    ({"volumes": [{"dataset": "sphere", "size": 16, "preset": "nope"}]}, "nope"),
    ({"volumes": [{"dataset": "no_such_set"}]}, "unknown data set"),
    ({"volumes": [{"dataset": "sphere", "file": "x.raw"}]}, "exactly one"),
    ({"volumes": [{"dataset": "sphere", "size": 16}], "camera": {"zoom": 2}}, "camera.*zoom"),
    ({"volumes": [{"dataset": "sphere", "size": 16, "transform": {"matrix": np.eye(4).tolist(), "scale": 2}}]},
     "cannot be combined"),
    ({"volumes": [{"dataset": "sphere", "size": 16, "transform": {"rotate": {"axis": [0, 0, 0]}}}]}, "axis"),
])
def test_bad_scene_specs_name_the_key(spec, match, tmp_path):
    with pytest.raises(InputError, match=match):
        build_scene(spec, cache_dir=tmp_path)


def test_file_volume_needs_a_transfer_function(tmp_path):
    np.zeros((2, 2, 2), np.uint8).tofile(tmp_path / "z_2x2x2_uint8.raw")
    with pytest.raises(InputError, match="transfer_function"):
        build_scene({"volumes": [{"file": str(tmp_path / "z_2x2x2_uint8.raw")}]})


def test_unreadable_scene_file(tmp_path):
    with pytest.raises(InputError, match="cannot be read"):
        load_scene(tmp_path / "missing.yaml")
    (tmp_path / "bad.yaml").write_text("volumes: [unclosed\n")
    with pytest.raises(InputError, match="invalid YAML"):
        load_scene(tmp_path / "bad.yaml")
