import numpy as np
import pytest
import trimesh

from core.errors import InputError
from core.mesh import HomogeneousMedium, Mesh, MeshInstance, SurfaceMaterial

BOX = trimesh.creation.box(extents=(2, 2, 2))


def test_a_closed_box_is_accepted_read_only_with_its_measures():
    mesh = Mesh(BOX.vertices, BOX.faces, name="box")
    assert mesh.triangle_count == 12 and mesh.faces.dtype == np.int64
    assert mesh.signed_volume() == pytest.approx(8.0)
    lo, hi = mesh.bounds()
    np.testing.assert_array_equal(lo, -1)
    np.testing.assert_array_equal(hi, 1)
    with pytest.raises(ValueError):
        mesh.vertices[0, 0] = 5
    assert mesh.content_hash() == Mesh(BOX.vertices.copy(), BOX.faces.copy()).content_hash()


@pytest.mark.parametrize("vertices, faces, match", [
    (np.zeros((4, 2)), BOX.faces[:4], r"vertices: expected a \(V, 3\) array"),
    (np.full((8, 3), np.nan), BOX.faces, "NaN"),
    (BOX.vertices, BOX.faces[:, :2], r"faces: expected an \(F, 3\)"),
    (BOX.vertices, BOX.faces.astype(float), "integer"),
    (BOX.vertices, BOX.faces + 1, r"indices must lie in \[0, 7\]"),
    (BOX.vertices, np.vstack([BOX.faces[:-1], [[0, 0, 1]]]), "repeat a vertex"),
    (BOX.vertices, BOX.faces[:-1], "not closed: 3 edges belong to one triangle only"),
    (BOX.vertices, np.vstack([BOX.faces[:-1], BOX.faces[-1, ::-1]]), "opposite orientation"),
    (BOX.vertices, np.vstack([BOX.faces, BOX.faces[:2]]), "more than once"),
])
def test_bad_meshes_name_the_problem(vertices, faces, match):
    with pytest.raises(InputError, match=match):
        Mesh(vertices, faces, name="bad")


def test_two_boxes_sharing_an_edge_are_not_two_manifold():
    other = BOX.vertices + (2, 2, 0)  # touches the first box along the edge x = y = 1
    vertices = np.vstack([BOX.vertices, other])
    faces = np.vstack([BOX.faces, BOX.faces + 8])
    _, inverse = np.unique(vertices.round(9), axis=0, return_inverse=True)
    with pytest.raises(InputError, match="more than once"):
        Mesh(vertices, inverse.ravel()[faces])


@pytest.mark.parametrize("make, match", [
    (lambda: SurfaceMaterial(colour=(1, 2, 0)), "colour: every channel"),
    (lambda: SurfaceMaterial(alpha=1.5), "alpha"),
    (lambda: SurfaceMaterial(shininess=0), "shininess"),
    (lambda: HomogeneousMedium(extinction=-1), "extinction"),
    (lambda: HomogeneousMedium(colour="red"), "medium colour"),
    (lambda: HomogeneousMedium.from_opacity(1.0, 2.0), "opacity"),
    (lambda: MeshInstance("box"), "mesh must be a Mesh"),
    (lambda: MeshInstance(Mesh(BOX.vertices, BOX.faces), transform=np.zeros((4, 4))), "transform"),
    (lambda: MeshInstance(Mesh(BOX.vertices, BOX.faces), surface=(1, 0, 0)), "SurfaceMaterial"),
])
def test_bad_materials_and_instances(make, match):
    with pytest.raises(InputError, match=match):
        make()


def test_instance_defaults_and_world_vertices():
    mesh = Mesh(BOX.vertices, BOX.faces, name="box")
    moved = np.eye(4)
    moved[:3, 3] = (1, 2, 3)
    instance = MeshInstance(mesh, transform=moved)
    assert instance.name == "box" and instance.surface is None and instance.medium is None
    np.testing.assert_allclose(instance.world_vertices(), BOX.vertices + (1, 2, 3))
    assert SurfaceMaterial(alpha=0.5).translucent and not SurfaceMaterial().translucent
    assert HomogeneousMedium(extinction=0.5).opacity(2.0) == pytest.approx(1 - np.exp(-1.0))
