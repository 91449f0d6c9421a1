"""The reference renderer on meshes, media and CSG against closed forms (Kainz et al. 2009)."""

import numpy as np
import pytest
import trimesh

import renderers
from core.camera import Camera
from core.errors import InputError, UnsupportedFeatureError
from core.mesh import HomogeneousMedium, Mesh, MeshInstance, SurfaceMaterial
from core.scene import CsgNode, Scene, Shading, VolumeInstance
from core.transfer import TransferFunction
from core.volume import Volume
from renderers.base import Capabilities
from renderers.reference.renderer import ReferenceRenderer

CUBE = Mesh(trimesh.creation.box(extents=(2, 2, 2)).vertices, trimesh.creation.box(extents=(2, 2, 2)).faces, name="cube")
# Azimuth 0 looks down −z; the eye plane is 10 units from the origin, a pixel is 0.25 wide and
# the 17 × 17 pixel centres include 0 and ±1, so rays run exactly along the cube's edges.
VIEW = Camera(view_height=17 * 0.25, distance=10.0)


def moved(offset):
    matrix = np.eye(4)
    matrix[:3, 3] = offset
    return matrix


def render(scene, **options):
    return ReferenceRenderer(depth=True, **options).render(scene)


def _pixel_positions(size=17, pixel=0.25):
    return (np.arange(size) - (size - 1) / 2) * pixel


def test_opaque_cube_silhouette_and_depth():
    scene = Scene(meshes=[MeshInstance(CUBE, surface=SurfaceMaterial(colour=(1, 0.5, 0)))], camera=VIEW,
                  width=17, height=17)
    result = render(scene)
    x = _pixel_positions()
    inside = (np.abs(x)[:, None] < 1) & (np.abs(x)[None, :] < 1)
    alpha = result.image[..., 3]
    np.testing.assert_array_equal(alpha[inside], 1.0)
    np.testing.assert_array_equal(alpha[(np.abs(x)[:, None] > 1) | (np.abs(x)[None, :] > 1)], 0.0)
    np.testing.assert_allclose(result.info["depth"][inside], 9.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(result.image[inside][:, :3], np.tile([1, 0.5, 0], (inside.sum(), 1)), atol=1e-7)
    assert result.counters["max_fragments"] == 2


def test_sphere_silhouette_lies_between_the_polygons_radii():
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    mesh = Mesh(sphere.vertices, sphere.faces, name="sphere")
    scene = Scene(meshes=[MeshInstance(mesh, surface=SurfaceMaterial())], camera=Camera(view_height=3.0, distance=10.0),
                  width=48, height=48)
    result = render(scene)
    x = (np.arange(48) - 23.5) * 3.0 / 48
    radius = np.hypot(x[:, None], x[None, :])
    # Every face plane is at least ``inner`` from the centre, every vertex at 1.
    normals = mesh.face_normals() / np.linalg.norm(mesh.face_normals(), axis=1, keepdims=True)
    inner = np.min(np.abs(np.einsum("ij,ij->i", normals, mesh.vertices[mesh.faces[:, 0]])))
    alpha = result.image[..., 3]
    assert (alpha[radius < inner] == 1).all() and (alpha[radius > 1.0] == 0).all()
    centre_depth = result.info["depth"][23:25, 23:25]
    assert ((centre_depth >= 9.0) & (centre_depth <= 10.0 - inner)).all()


def test_homogeneous_medium_is_composited_in_closed_form_with_no_crack_on_edges():
    sigma = 0.7
    medium = HomogeneousMedium(colour=(0.2, 0.4, 1.0), extinction=sigma)
    result = render(Scene(meshes=[MeshInstance(CUBE, medium=medium)], camera=VIEW, width=17, height=17))
    expected = 1 - np.exp(-sigma * 2.0)
    alpha = result.image[..., 3].astype(np.float64)
    x = _pixel_positions()
    inside = (np.abs(x)[:, None] < 1) & (np.abs(x)[None, :] < 1)
    np.testing.assert_allclose(alpha[inside], expected, rtol=1e-6)
    np.testing.assert_allclose(result.image[inside][:, :3], np.tile(expected * np.array([0.2, 0.4, 1.0]), (inside.sum(), 1)), rtol=1e-6)
    # Rays along the silhouette edges meet both faces or neither: never half a medium.
    on_edge = ~inside & ((np.abs(x)[:, None] <= 1) & (np.abs(x)[None, :] <= 1))
    assert np.all(np.isclose(alpha[on_edge], expected, rtol=1e-6) | (alpha[on_edge] == 0))
    assert HomogeneousMedium.from_opacity(0.5, 2.0).opacity(2.0) == pytest.approx(0.5)


def _two_media(node):
    red = MeshInstance(CUBE, medium=HomogeneousMedium(colour=(1, 0, 0), extinction=1.0), name="a")
    green = MeshInstance(CUBE, medium=HomogeneousMedium(colour=(0, 1, 0), extinction=1.0), name="b",
                         transform=moved((0, 0, 1)))
    return Scene(meshes=[red, green], csg=() if node is None else (node,), camera=VIEW, width=17, height=17)


def _expected(segments):
    """Front-to-back composite of ``[(length, σ_red, σ_green), ...]`` in closed form."""
    colour = np.zeros(3)
    alpha = 0.0
    for length, red, green in segments:
        sigma = red + green
        if sigma == 0 or length == 0:
            continue
        a = 1 - np.exp(-sigma * length)
        colour += (1 - alpha) * a * np.array([red, green, 0.0]) / sigma
        alpha += (1 - alpha) * a
    return np.append(colour, alpha)


# The camera looks down −z: b spans z ∈ [0, 2] and is met first, a spans [−1, 1].
@pytest.mark.parametrize("node, segments", [
    (None, [(1, 0, 1), (1, 1, 1), (1, 1, 0)]),
    (CsgNode("union", ["a", "b"]), [(1, 0, 1), (1, 1, 1), (1, 1, 0)]),
    (CsgNode("intersection", ["a", "b"]), [(1, 1, 1)]),
    (CsgNode("difference", ["a", "b"]), [(1, 1, 0)]),
    (CsgNode("difference", ["b", "a"]), [(1, 0, 1)]),
])
def test_csg_truth_table_on_two_overlapping_media(node, segments):
    pixel = render(_two_media(node)).image[8, 8]
    np.testing.assert_allclose(pixel, _expected(segments), rtol=1e-6, atol=1e-7)


def test_csg_surfaces_drawn_only_on_the_solid_boundary():
    # Translucent surfaces count the crossings drawn on the centre ray: the two cubes alone show
    # 4, their union, intersection and difference 2 each (only the solid's boundary).
    surface = SurfaceMaterial(colour=(1, 1, 1), alpha=0.5)
    a = MeshInstance(CUBE, surface=surface, name="a")
    b = MeshInstance(CUBE, surface=surface, name="b", transform=moved((0, 0, 1)))
    for node, crossings in ((None, 4), (CsgNode("union", ["a", "b"]), 2), (CsgNode("intersection", ["a", "b"]), 2),
                            (CsgNode("difference", ["a", "b"]), 2)):
        scene = Scene(meshes=[a, b], csg=() if node is None else (node,), camera=VIEW, width=17, height=17)
        alpha = render(scene).image[8, 8, 3]
        assert alpha == pytest.approx(1 - 0.5 ** crossings), node


def _constant_volume(alpha=0.05):
    volume = Volume(np.full((8, 8, 8), 255, np.uint8), name="v")
    return VolumeInstance(volume, TransferFunction.constant(alpha=alpha), name="v")


def test_volume_clipped_by_a_mesh_has_the_exact_optical_depth():
    # The volume box is [−4, 4]³; the clip box removes z > 0.3 from it.
    clip = MeshInstance(CUBE, name="clip", transform=moved((0, 0, 5.3)) @ np.diag([5.0, 5.0, 5.0, 1.0]))
    scene = Scene([_constant_volume()], meshes=[clip], csg=(CsgNode("difference", ["v", "clip"]),),
                  camera=Camera(view_height=8.0, distance=20.0), width=8, height=8)
    alpha = render(scene).image[..., 3]
    np.testing.assert_allclose(alpha, 1 - (1 - 0.05) ** 4.3, rtol=1e-6)
    inside = Scene([_constant_volume()], meshes=[clip], csg=(CsgNode("intersection", ["v", "clip"]),),
                   camera=Camera(view_height=8.0, distance=20.0), width=8, height=8)
    np.testing.assert_allclose(render(inside).image[..., 3], 1 - (1 - 0.05) ** 3.7, rtol=1e-6)


def test_volume_clipped_by_a_mesh_equals_the_volume_masked_by_it():
    # Clip away x > 0 of a volume with a structured field; columns more than a voxel from the cut
    # equal the render of the data with those voxels zeroed (which a ramp TF makes transparent).
    z, y, x = np.mgrid[0:8, 0:8, 0:8]
    data = (80 + 20 * np.sin(x + 2 * y) + 15 * z).astype(np.uint8)
    tf = TransferFunction.ramp(0.2, 1.0, alpha=0.3)
    camera = Camera(view_height=8.0, distance=20.0, azimuth=0, elevation=0)
    clip = MeshInstance(CUBE, name="clip", transform=moved((5.0, 0, 0)) @ np.diag([5.0, 5.0, 5.0, 1.0]))
    clipped = Scene([VolumeInstance(Volume(data, name="v"), tf, name="v")], meshes=[clip],
                    csg=(CsgNode("difference", ["v", "clip"]),), camera=camera, width=8, height=8)
    masked_data = data.copy()
    masked_data[:, :, 4:] = 0
    masked = Scene([VolumeInstance(Volume(masked_data, name="v"), tf, name="v")], camera=camera, width=8, height=8)
    a, b = render(clipped).image, render(masked).image
    np.testing.assert_array_equal(a[:, :3], b[:, :3])
    assert (a[:, 4:, 3] == 0).all()


def test_instances_of_one_mesh_equal_separately_built_meshes():
    surface = SurfaceMaterial(colour=(0.3, 0.6, 0.9), alpha=0.6)
    rotation = trimesh.transformations.rotation_matrix(0.4, (1, 1, 0))
    shifts = ((-1.5, 0, 0), (1.5, 0.5, -1))
    shared = [MeshInstance(CUBE, transform=moved(s) @ rotation, surface=surface, name=f"i{k}")
              for k, s in enumerate(shifts)]
    separate = []
    for k, s in enumerate(shifts):
        matrix = moved(s) @ rotation
        vertices = CUBE.vertices @ matrix[:3, :3].T + matrix[:3, 3]
        separate.append(MeshInstance(Mesh(vertices, CUBE.faces, name=f"m{k}"), surface=surface, name=f"i{k}"))
    camera = Camera(view_height=6.0, distance=10.0, azimuth=20, elevation=10)
    shading = Shading(model="phong")
    a = render(Scene(meshes=shared, camera=camera, width=24, height=24, shading=shading)).image
    b = render(Scene(meshes=separate, camera=camera, width=24, height=24, shading=shading)).image
    np.testing.assert_allclose(a, b, atol=1e-6)


def test_a_volume_no_geometry_touches_renders_bit_identically():
    z, y, x = np.mgrid[0:10, 0:9, 0:8]
    volume = Volume(((np.sin(x / 2.0) + np.cos(y / 3.0) + z / 10.0 + 2) * 60).astype(np.uint8), spacing=(1, 1.2, 0.8))
    tf = TransferFunction.from_points([[0, 1, 0, 0, 0], [0.5, 0, 1, 0, 0.2], [1, 1, 1, 1, 0.6]])
    instance = VolumeInstance(volume, tf, name="v")
    camera = Camera(azimuth=25, elevation=15, view_height=16.0, distance=30.0)
    far_away = MeshInstance(CUBE, surface=SurfaceMaterial(), transform=moved((100, 0, 0)), name="far")
    for shading in ("none", "phong"):
        plain = Scene([instance], camera=camera, width=20, height=18, shading=Shading(model=shading))
        with_mesh = Scene([instance], meshes=[far_away], camera=camera, width=20, height=18,
                          shading=Shading(model=shading))
        a, b = render(plain), render(with_mesh)
        np.testing.assert_array_equal(a.image, b.image)
        np.testing.assert_array_equal(a.info["depth"], b.info["depth"])
        assert a.counters["samples"] == b.counters["samples"]


def test_translucent_surface_in_front_of_a_volume_is_composited_first():
    volume = _constant_volume(alpha=0.1)
    wall = MeshInstance(CUBE, surface=SurfaceMaterial(colour=(1, 0, 0), alpha=0.5), name="wall",
                        transform=moved((0, 0, 8)))
    scene = Scene([volume], meshes=[wall], camera=Camera(view_height=4.0, distance=20.0), width=4, height=4)
    pixel = render(scene).image[1, 1].astype(np.float64)
    # The wall's two faces (red, alpha 0.5 each), then the white volume behind them.
    a_volume = 1 - 0.9 ** 8
    np.testing.assert_allclose(pixel, [0.75 + 0.25 * a_volume, 0.25 * a_volume, 0.25 * a_volume, 0.75 + 0.25 * a_volume],
                               rtol=1e-6)


def test_camera_inside_a_medium_starts_inside():
    medium = HomogeneousMedium(extinction=0.5)
    big = MeshInstance(CUBE, medium=medium, transform=np.diag([10.0, 10.0, 10.0, 1.0]), name="big")
    scene = Scene(meshes=[big], camera=Camera(projection="perspective", distance=5.0, fov_y=20.0), width=3, height=3)
    result = render(scene)
    # The eye sits 5 units from the centre; the ray to the far face (z = −10) is 15 long.
    assert result.image[1, 1, 3] == pytest.approx(1 - np.exp(-0.5 * 15.0), rel=1e-6)


def test_helical_screw_depth_complexity():
    from datasets.meshes import helical_screw

    screw = helical_screw(turns=5, pitch=0.2, sides=12, rows_per_turn=6)
    scene = Scene(meshes=[MeshInstance(screw, surface=SurfaceMaterial(alpha=0.1))],
                  camera=Camera(view_height=1.2, distance=5.0, target=(0, 0, 0.5)), width=12, height=12)
    result = render(scene)
    assert result.counters["max_fragments"] == 2 * 5 + 2
    assert result.counters["fragments"] % 2 == 0


def test_meshes_need_dvr_and_reference_options_stay_checked():
    with pytest.raises(InputError, match="dvr"):
        Scene(meshes=[MeshInstance(CUBE, surface=SurfaceMaterial())], mode="mip")
    scene = Scene(meshes=[MeshInstance(CUBE, surface=SurfaceMaterial())], width=4, height=4)
    assert ReferenceRenderer.capabilities.missing(scene) == []
    assert render(scene).info["step"] is None


def test_backends_without_meshes_refuse_every_geometry_feature_with_their_reason():
    caps = Capabilities(max_volumes=2, reasons={"meshes": "volumes only here"})
    csg_of_volumes = Scene([_constant_volume(), VolumeInstance(_constant_volume().volume,
                                                               TransferFunction.constant(alpha=0.1), name="w")],
                           csg=(CsgNode("intersection", ["v", "w"]),))
    assert caps.missing(csg_of_volumes) == [("csg", "volumes only here")]
    medium = Scene(meshes=[MeshInstance(CUBE, medium=HomogeneousMedium(), surface=SurfaceMaterial(alpha=0.5))])
    assert [label for label, _ in caps.missing(medium)] == ["meshes", "translucent_geometry", "homogeneous_media"]
    shearwarp = renderers.backend_class("shearwarp")
    with pytest.raises(UnsupportedFeatureError, match="meshes"):
        shearwarp().check(medium)
