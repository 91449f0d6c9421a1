import numpy as np
import yaml
import pytest

from core.errors import InputError
from core.volume import Volume
from pipeline.scene_io import build_scene, load_scene, phantom_requests, rotation_matrix


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


@pytest.mark.parametrize("volume, match", [
    ({"transfer_function": "bone"}, "transfer_function: expected a mapping"),
    ({"transfer_function": {"points": "abc"}}, r"transfer_function points: expected a list of \[x, r, g, b, a\]"),
    ({"transfer_function": {"points": [[0, 1, 1, "x", 0]]}}, "transfer_function points"),
    ({"gradient_opacity": {"points": "abc"}}, r"gradient_opacity points: expected a list of \[x, g\]"),
    ({"spacing": "fast"}, "spacing: expected 3 numbers"),
    ({"spacing": [1, 1, 0]}, "spacing: every entry must be finite and > 0"),
    ({"value_range": [0, "high"]}, "value_range: expected 2 numbers"),
    ({"value_range": [0, float("inf")]}, "value_range: both ends must be finite"),
    ({"value_range": [5, 1]}, "value_range: expected lo < hi"),
    ({"transform": {"translate": [1, 2]}}, "translate: expected 3 finite numbers"),
    ({"transform": {"translate": "left"}}, "translate"),
    ({"transform": {"scale": "big"}}, "scale: expected a number"),
    ({"transform": {"scale": [1, 2]}}, "scale"),
    ({"transform": {"rotate": {"axis": [0, 1, 0], "degrees": "ninety"}}}, "rotate degrees"),
    ({"transform": {"rotate": {"axis": "y"}}}, "rotate axis"),
    ({"transform": {"matrix": "identity"}}, "matrix: expected a 4x4 matrix"),
    ({"params": "x"}, "params: expected a mapping"),
])
def test_non_numeric_yaml_values_are_input_errors_before_work(volume, match, tmp_path, monkeypatch):
    import datasets

    def no_generation(*args, **kwargs):
        raise AssertionError("the volume must not be loaded before the entry is checked")

    if "params" not in volume and "transform" not in volume and "transfer_function" not in volume \
            and "gradient_opacity" not in volume:
        monkeypatch.setattr(datasets, "load", no_generation)
    with pytest.raises(InputError, match=match):
        build_scene(_spec(**volume), cache_dir=tmp_path)


def test_spacing_and_value_range_apply_to_data_sets_too(tmp_path):
    volume = build_scene(_spec(spacing=[1, 1, 2], value_range=[10, 200]), cache_dir=tmp_path).volumes[0].volume
    assert volume.spacing == (1, 1, 2) and volume.value_range == (10, 200)


def test_size_on_a_real_data_set_is_an_error():
    for key, value in (("size", 64), ("seed", 3), ("params", {"a": 1})):
        with pytest.raises(InputError, match=f"real scan with its own size; remove '{key}'"):
            build_scene({"volumes": [{"dataset": "cthead", key: value}]})


def test_float_file_outside_unit_range_needs_value_range_and_then_loads(tmp_path):
    data = np.linspace(-1, 3, 8, dtype=np.float32).reshape(2, 2, 2)
    data.astype("<f4").tofile(tmp_path / "d_2x2x2_float32.raw")
    entry = {"file": "d_2x2x2_float32.raw", "transfer_function": {"points": [[0, 1, 1, 1, 0], [1, 1, 1, 1, 1]]}}
    (tmp_path / "a.yaml").write_text(yaml.safe_dump({"volumes": [entry]}))
    with pytest.raises(InputError, match="outside the default range.*set value_range"):
        load_scene(tmp_path / "a.yaml")
    (tmp_path / "b.yaml").write_text(yaml.safe_dump({"volumes": [{**entry, "value_range": [-1, 3]}]}))
    volume = load_scene(tmp_path / "b.yaml").volumes[0].volume
    assert volume.value_range == (-1, 3)
    np.testing.assert_allclose(volume.normalized().ravel(), np.linspace(0, 1, 8), atol=1e-6)


def test_float_nrrd_outside_unit_range_takes_the_scene_value_range(tmp_path):
    data = np.linspace(0, 10, 8, dtype=np.float32).reshape(2, 2, 2)
    header = b"NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nendian: little\n\n"
    (tmp_path / "v.nrrd").write_bytes(header + data.astype("<f4").tobytes())
    entry = {"file": str(tmp_path / "v.nrrd"), "transfer_function": {"points": [[0, 1, 1, 1, 0], [1, 1, 1, 1, 1]]}}
    with pytest.raises(InputError, match="set value_range"):
        build_scene({"volumes": [entry]})
    assert build_scene({"volumes": [{**entry, "value_range": [0, 10]}]}).volumes[0].volume.value_range == (0, 10)


def test_degenerate_camera_in_a_scene_file(tmp_path):
    with pytest.raises(InputError, match="camera up: must be a non-zero vector"):
        build_scene({**_spec(), "camera": {"up": [0, 0, 0]}}, cache_dir=tmp_path)
    with pytest.raises(InputError, match="parallel"):
        build_scene({**_spec(), "camera": {"elevation": -90}}, cache_dir=tmp_path)


def _mesh_spec(**entry):
    return {"width": 8, "height": 8, "meshes": [{"name": "r", "generator": "rod", **entry}]}


def test_meshes_materials_instancing_and_csg_from_a_scene_file(tmp_path):
    import trimesh

    trimesh.creation.box(extents=(4, 4, 4)).export(tmp_path / "clip.obj")
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump({
        "volumes": [{"dataset": "sphere", "size": 16, "name": "ball"}],
        "meshes": [
            {"name": "rod", "generator": "rod", "params": {"sides": 8, "radius": 1, "length": 20},
             "surface": {"colour": [1, 0.5, 0], "alpha": 0.5, "specular": 0.1},
             "medium": {"colour": [0, 0, 1], "extinction": 0.2},
             "transform": {"rotate": {"axis": [1, 0, 0], "degrees": 90}}},
            {"name": "rod2", "instance_of": "rod", "transform": {"translate": [3, 0, 0]}},
            {"name": "clip", "file": "clip.obj"},
        ],
        "csg": [{"difference": ["ball", {"union": ["clip", "rod2"]}]}],
    }))
    scene = load_scene(tmp_path / "scene.yaml", cache_dir=tmp_path)
    rod, rod2, clip = scene.meshes
    assert rod2.mesh is rod.mesh and rod.mesh.triangle_count == 4 * 8 - 4
    assert rod.surface.alpha == 0.5 and rod.medium.extinction == 0.2 and rod2.surface is None
    np.testing.assert_allclose(rod.transform[:3, :3] @ (0, 0, 1), (0, -1, 0), atol=1e-12)
    np.testing.assert_allclose(rod2.transform[:3, 3], (3, 0, 0))
    assert clip.mesh.triangle_count == 12
    assert scene.csg[0].operation == "difference" and scene.csg[0].leaves() == ["ball", "clip", "rod2"]
    assert {"meshes", "csg", "translucent_geometry", "homogeneous_media"} <= set(scene.features())


def test_a_volume_boundary_from_a_generator(tmp_path):
    spec = _spec(boundary={"generator": "phantom_isosurface", "params": {"dataset": "sphere", "size": 16}})
    boundary = build_scene(spec, cache_dir=tmp_path).volumes[0].boundary
    assert boundary is not None and boundary.meta["generator"] == "phantom_isosurface"


@pytest.mark.parametrize("spec, match", [
    (_mesh_spec(params={"sides": 2}), "rod sides"),
    (_mesh_spec(params={"corners": 5}), "rod.*takes"),
    (_mesh_spec(generator="blob"), "unknown mesh generator 'blob'"),
    (_mesh_spec(file="x.obj"), r"meshes\[0\]: give exactly one of"),
    (_mesh_spec(colour=[1, 0, 0]), r"meshes\[0\]: unknown keys.*colour"),
    (_mesh_spec(surface={"color": [1, 0, 0]}), r"meshes\[0\] surface: unknown keys.*color"),
    (_mesh_spec(surface={"alpha": 2}), "surface material alpha"),
    (_mesh_spec(medium={"extinction": "thick"}), "medium extinction"),
    (_mesh_spec(transform={"translate": [1, 2]}), r"meshes\[0\] transform translate"),
    ({"meshes": [{"instance_of": "ghost"}]}, "instance_of: 'ghost' is not the name of an earlier mesh"),
    ({"meshes": [{"file": "missing.obj"}]}, "does not exist"),
    ({**_mesh_spec(), "csg": [{"xor": ["r", "r"]}]}, r"csg\[0\]: unknown operation 'xor'"),
    ({**_mesh_spec(), "csg": [{"union": "r"}]}, "expected a list"),
    ({**_mesh_spec(), "csg": ["r"]}, "not a bare name"),
    ({**_mesh_spec(), "csg": [{"union": ["r", "nope"]}]}, "leaf 'nope'"),
    ({**_mesh_spec(), "mode": "mip"}, "dvr"),
    ({"meshes": []}, "at least one volume or mesh"),
    (_spec(boundary={"generator": "rod", "file": "x.obj"}), r"boundary: give exactly one of 'generator' or 'file'"),
])
def test_bad_mesh_and_csg_keys_name_the_key(spec, match, tmp_path):
    with pytest.raises(InputError, match=match):
        build_scene(spec, cache_dir=tmp_path, base_dir=tmp_path)


# ---------------------------------------------------------------------------------------------
# Scene files as people write them, and sizes this machine cannot hold (refused before any work)


@pytest.fixture
def small_machine(monkeypatch):
    """A machine holding a 64³ phantom's generation (48 bytes a voxel) and nothing larger."""
    import core.resources

    monkeypatch.setattr(core.resources, "memory_limit", lambda: 48 * 64 ** 3)


@pytest.fixture
def nothing_is_loaded(monkeypatch):
    import datasets
    from datasets import meshes

    monkeypatch.setattr(datasets, "load", lambda *a, **k: pytest.fail("a volume was loaded before the check"))
    monkeypatch.setattr(meshes, "generate", lambda *a, **k: pytest.fail("a mesh was built before the check"))


@pytest.mark.parametrize("text, match", [
    ("width: 16\nheight: 16\nwidth: 32\nvolumes: [{dataset: sphere}]\n",
     r"scene file .*s.yaml, line 3: key 'width' is given twice in one mapping \(lines 1 and 3\)"),
    ("volumes:\n  - dataset: sphere\n    transform: {scale: 1.0e300}\n",
     r"line 3: 1.0e300 is read as text, not a number, by YAML 1.1 \(PyYAML\): write 1.0e\+300"),
    ("width: 016\nvolumes: [{dataset: sphere}]\n", "016 is read as the octal number 14"),
    ("", r"s.yaml: expected a mapping of scene keys \(width, volumes, ...\), got an empty file"),
    ("- dataset: sphere\n", "expected a mapping of scene keys.*got list"),
])
def test_scene_file_mistakes_are_errors_before_any_work(tmp_path, nothing_is_loaded, text, match):
    (tmp_path / "s.yaml").write_text(text)
    with pytest.raises(InputError, match=match):
        load_scene(tmp_path / "s.yaml")


def test_a_scene_file_that_is_not_utf8_or_not_a_file_is_named(tmp_path, nothing_is_loaded):
    (tmp_path / "s.yaml").write_bytes("name: t\xeate\nvolumes: [{dataset: sphere}]\n".encode("latin-1"))
    with pytest.raises(InputError, match=r"s.yaml, line 1: not UTF-8 text \(byte 0xea"):
        load_scene(tmp_path / "s.yaml")
    with pytest.raises(InputError, match=r"scene file .*: cannot be read \(Is a directory\)"):
        load_scene(tmp_path)


def test_a_phantom_too_large_is_refused_before_any_volume_is_generated(small_machine, nothing_is_loaded):
    spec = {"volumes": [{"dataset": "sphere", "size": 16}, {"dataset": "sphere", "size": 65}]}
    with pytest.raises(InputError, match=r"^volumes\[1\] size 65: phantom 'sphere' needs 12.6 MiB \(65³ voxels × 48 "
                                         r"bytes of working arrays while it is generated\), this machine has 12 MiB; "
                                         r"use size ≤ 64$"):
        build_scene(spec)
    # The pipeline plans its phantom jobs through the same arguments.
    with pytest.raises(InputError, match="size 65"):
        phantom_requests(spec["volumes"])
    # A size given by the profile (or --size) is checked the same way.
    with pytest.raises(InputError, match=r"volumes\[0\] size 100"):
        build_scene({"volumes": [{"dataset": "sphere"}]}, size=100)


def test_the_full_profiles_largest_phantom_fits_a_16_gib_machine(monkeypatch):
    import core.resources
    import datasets

    monkeypatch.setattr(core.resources, "memory_limit", lambda: 16 * 2 ** 30)
    datasets.get("ct_skull").check_memory(512, where="volume_size")
    with pytest.raises(InputError, match="use size ≤ 710"):
        datasets.get("ct_skull").check_memory(711, where="volume_size")


@pytest.mark.parametrize("spec, match", [
    ({"width": 100000, "height": 100000, "volumes": [{"dataset": "sphere", "size": 16}]},
     r"scene 'scene' image 100000×100000 needs 149 GiB .* use width × height ≤"),
    ({"volumes": [{"dataset": "sphere", "size": 16,
                   "transfer_function": {"points": [[0, 1, 1, 1, 0], [1, 1, 1, 1, 1]], "size": 10 ** 10}}]},
     r"transfer function 'tf' size 10000000000 needs 820 GiB"),
    ({"meshes": [{"generator": "rod", "params": {"sides": 10 ** 8}}]},
     r"rod sides 100000000: 399999996 triangles needs 381 GiB .* use sides ≤"),
])
def test_sizes_this_machine_cannot_hold_are_refused_before_allocating(monkeypatch, spec, match):
    import core.resources
    import datasets

    monkeypatch.setattr(core.resources, "memory_limit", lambda: 16 * 2 ** 30)
    monkeypatch.setattr(datasets, "load", lambda *a, **k: Volume(np.zeros((16, 16, 16), np.uint8), name="sphere"))
    with pytest.raises(InputError, match=match):
        build_scene(spec)


@pytest.mark.parametrize("spec, match", [
    ({"volumes": {"dataset": "sphere"}}, r"scene volumes: expected a list of entries \(each line starting with '- '\)"),
    ({"meshes": {"generator": "rod"}}, "scene meshes: expected a list of entries"),
    ({"name": 5, "volumes": [{"dataset": "sphere"}]}, "scene name: expected text, got 5"),
    ({"volumes": [{"dataset": ["sphere"]}]}, r"volumes\[0\] dataset: expected text \(a name or a path\), got \['sphere'\]"),
    ({"volumes": [{"file": 5}]}, r"volumes\[0\] file: expected text"),
    ({"volumes": [{"dataset": "sphere", "preset": ["bone"]}]}, r"volumes\[0\] preset: expected text"),
    ({"volumes": [{"dataset": "sphere", "name": 7}]}, r"volumes\[0\] name: expected text"),
    ({"volumes": [{"dataset": "sphere", "transfer_function": {"points": [[0, 1, 1, 1, 1]], "name": [1]}}]},
     r"volumes\[0\] transfer_function name: expected text"),
    ({"meshes": [{"generator": ["rod"]}]}, r"meshes\[0\] generator: expected text"),
    ({"meshes": [{"file": 3}]}, r"meshes\[0\] file: expected text"),
    ({"meshes": [{"generator": "rod", "name": ["r"]}]}, r"meshes\[0\] name: expected text"),
])
def test_wrong_types_in_a_scene_are_named_before_any_work(nothing_is_loaded, spec, match):
    with pytest.raises(InputError, match=match):
        build_scene(spec)


def test_a_folder_given_as_a_volume_or_mesh_file_is_called_a_folder(tmp_path):
    table = {"points": [[0, 1, 1, 1, 0], [1, 1, 1, 1, 1]]}
    with pytest.raises(InputError, match="is a folder, not a volume file"):
        build_scene({"volumes": [{"file": str(tmp_path), "transfer_function": table}]})
    with pytest.raises(InputError, match="is a folder, not a mesh file"):
        build_scene({"meshes": [{"file": str(tmp_path)}]})
