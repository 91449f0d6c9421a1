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
