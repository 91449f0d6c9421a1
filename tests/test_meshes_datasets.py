import pytest

from core.errors import InputError
from datasets import meshes


def _closed_two_manifold(mesh):
    import trimesh

    surface = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    return surface.is_watertight and surface.is_winding_consistent and mesh.signed_volume() > 0


@pytest.mark.parametrize("name, params, triangles", [
    ("rod", {"sides": 20}, 76),
    ("boxes_in_a_row", {"count": 20}, 240),
    ("helical_screw", {"turns": 4, "sides": 12, "rows_per_turn": 6}, 2 * 12 * 25),
])
def test_exact_triangle_counts_of_the_procedural_meshes(name, params, triangles):
    mesh = meshes.generate(name, **params)
    assert mesh.triangle_count == triangles and _closed_two_manifold(mesh)


@pytest.mark.parametrize("name, params", [
    ("noisy_sphere", {"triangles": 1500, "subdivisions": 4}),
    ("vessel_tree", {"depth": 3, "resolution": 40, "triangles": 1200}),
    ("helical_screw", {"turns": 6, "triangles": 1000}),
    ("phantom_isosurface", {"dataset": "sphere", "size": 24, "triangles": 600, "cache_dir": False}),
])
def test_decimated_meshes_are_closed_near_the_requested_count_and_deterministic(name, params):
    mesh = meshes.generate(name, **params)
    assert abs(mesh.triangle_count - params["triangles"]) <= meshes.TRIANGLE_TOLERANCE * params["triangles"]
    assert mesh.meta["triangles_before_decimation"] > params["triangles"]
    assert _closed_two_manifold(mesh)
    assert meshes.generate(name, **params).content_hash() == mesh.content_hash()


def test_seeds_change_the_random_meshes():
    a = meshes.noisy_sphere(subdivisions=2, seed=0)
    b = meshes.noisy_sphere(subdivisions=2, seed=1)
    assert a.content_hash() != b.content_hash()


def test_phantom_isosurface_sits_in_the_volume_object_space():
    mesh = meshes.phantom_isosurface(dataset="sphere", size=24, level=0.5, smoothing=0, cache_dir=False)
    lo, hi = mesh.bounds()
    assert (lo > 0).all() and (hi < 24).all()


def test_an_open_surface_is_refused_and_bad_requests_are_input_errors(tmp_path):
    import trimesh

    box = trimesh.creation.box()
    with pytest.raises(InputError, match="not a closed"):
        meshes.closed_mesh(box.vertices, box.faces[:-1], name="open")
    with pytest.raises(InputError, match="unknown mesh generator 'blob'"):
        meshes.generate("blob")
    with pytest.raises(InputError, match="rod.*takes.*sides"):
        meshes.generate("rod", corners=5)
    with pytest.raises(InputError, match="rod sides"):
        meshes.generate("rod", sides=2)
    with pytest.raises(InputError, match="does not exist"):
        meshes.load_mesh(tmp_path / "none.obj")
    box.export(tmp_path / "box.obj")
    assert meshes.load_mesh(tmp_path / "box.obj").triangle_count == 12


@pytest.mark.parametrize("name, params, match", [
    ("rod", {"sides": 10 ** 8}, r"^rod sides 100000000: 399999996 triangles needs 381 GiB .* use sides ≤ 4194305$"),
    ("boxes_in_a_row", {"count": 10 ** 9}, r"boxes_in_a_row count 1000000000: 12000000000 triangles .* use count ≤ 1398101"),
    ("helical_screw", {"turns": 10 ** 8}, r"helical_screw turns 100000000, rows_per_turn 12, sides 24: 57600000048 "
                                          r"triangles .* make 2·sides·\(turns·rows_per_turn \+ 1\) ≤ 16777216"),
    ("noisy_sphere", {"subdivisions": 10 ** 9}, r"noisy_sphere subdivisions 1000000000: 20·4\^1000000000 triangles .* "
                                                r"use subdivisions ≤ 9$"),
    ("vessel_tree", {"resolution": 10 ** 5}, r"vessel_tree resolution 100000 needs 142 PiB .* use resolution ≤ 475$"),
    ("phantom_isosurface", {"size": 4096}, r"phantom_isosurface size 4096: phantom 'sphere' needs 3 TiB"),
])
def test_a_mesh_this_machine_cannot_build_is_refused_before_building(monkeypatch, name, params, match):
    import core.resources
    import datasets

    monkeypatch.setattr(core.resources, "memory_limit", lambda: 16 * 2 ** 30)
    monkeypatch.setattr(datasets, "load", lambda *a, **k: pytest.fail("a phantom was generated before the check"))
    with pytest.raises(InputError, match=match):
        meshes.generate(name, **params)


def test_vessel_levels_thinner_than_half_a_cell_are_refused():
    with pytest.raises(InputError, match=r"vessel_tree depth 40: the last level's tubes are 7.3e-08 wide, thinner than "
                                         r"half a cell of the 64³ grid \(0.0078\), .* use depth ≤ 7 or a larger "
                                         "resolution or radius"):
        meshes.vessel_tree(depth=40)
    with pytest.raises(InputError, match="use depth ≤ 7"):
        meshes.vessel_tree(depth=8, resolution=64)


def test_a_triangle_target_that_is_not_a_count_is_named():
    with pytest.raises(InputError, match="mesh 'noisy_sphere' triangles: expected an integer >= 4, got 'many'"):
        meshes.noisy_sphere(subdivisions=1, triangles="many")
