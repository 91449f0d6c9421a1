import dataclasses

import numpy as np
import pytest

from core.camera import Camera
from core.errors import InputError


def test_default_camera_looks_down_minus_z():
    camera = Camera(distance=10, view_height=2)
    np.testing.assert_allclose(camera.eye, (0, 0, 10))
    right, up, back = camera.basis()
    np.testing.assert_allclose(right, (1, 0, 0), atol=1e-12)
    np.testing.assert_allclose(up, (0, 1, 0), atol=1e-12)
    np.testing.assert_allclose(back, (0, 0, 1), atol=1e-12)


def test_azimuth_turns_eye_towards_plus_x():
    camera = Camera(azimuth=90, distance=5, view_height=1)
    np.testing.assert_allclose(camera.eye, (5, 0, 0), atol=1e-12)


def test_orthographic_rays_row_zero_is_top_and_pixel_centres():
    camera = Camera(distance=10, view_height=4)
    origins, directions = camera.rays(4, 2)
    assert origins.shape == (2, 4, 3)
    np.testing.assert_allclose(directions, np.broadcast_to((0, 0, -1), (2, 4, 3)))
    # Height 4 over 2 rows: centres at y = +1 (top row) and -1; width 8 over 4 columns.
    np.testing.assert_allclose(origins[:, 0, 1], (1, -1))
    np.testing.assert_allclose(origins[0, :, 0], (-3, -1, 1, 3))


def test_perspective_rays_pass_through_the_image_plane():
    camera = Camera(projection="perspective", fov_y=90, distance=3)
    origins, directions = camera.rays(2, 2)
    np.testing.assert_allclose(origins[0, 0], (0, 0, 3))
    np.testing.assert_allclose(np.linalg.norm(directions, axis=-1), 1)
    # Top-left pixel centre at (-0.5, 0.5) of a half-height tan(45°) = 1 plane at distance 1.
    expected = np.array([-0.5, 0.5, -1]) / np.linalg.norm([-0.5, 0.5, -1])
    np.testing.assert_allclose(directions[0, 0], expected)


def test_view_matrix_maps_eye_to_origin_and_target_to_minus_z():
    camera = Camera(azimuth=37, elevation=-20, distance=7, target=(1, 2, 3), view_height=1)
    view = camera.view_matrix()
    np.testing.assert_allclose(view @ np.append(camera.eye, 1), (0, 0, 0, 1), atol=1e-12)
    np.testing.assert_allclose(view @ np.array([1, 2, 3, 1]), (0, 0, -7, 1), atol=1e-12)


def test_projection_matrix_maps_view_volume_to_clip_cube():
    camera = Camera(distance=5, view_height=2)
    projection = camera.projection_matrix(2.0, 1.0, 9.0)
    corner = projection @ np.array([2, 1, -9, 1])
    np.testing.assert_allclose(corner[:3] / corner[3], (1, 1, 1))
    perspective = Camera(projection="perspective", fov_y=90, distance=5)
    point = perspective.projection_matrix(1.0, 1.0, 9.0) @ np.array([0, 1, -1, 1])
    np.testing.assert_allclose(point[:3] / point[3], (0, 1, -1), atol=1e-12)


@pytest.mark.parametrize("kwargs, match", [
    ({"elevation": 90}, "parallel"),
    ({"elevation": 120}, "elevation"),
    ({"projection": "fisheye"}, "projection"),
    ({"distance": -1}, "distance"),
    ({"fov_y": 0}, "fov_y"),
    ({"target": (0, float("nan"), 0)}, "target"),
])
def test_bad_camera_inputs_are_named(kwargs, match):
    with pytest.raises(InputError, match=match):
        Camera(**kwargs)


def test_framing_fills_only_missing_fields():
    camera = Camera(view_height=3).framed(np.zeros(3), 2.0)
    assert camera.view_height == 3 and camera.distance == pytest.approx(6.0)


def test_zero_up_is_refused():
    with pytest.raises(InputError, match="camera up: must be a non-zero vector"):
        Camera(up=(0, 0, 0))


@pytest.mark.parametrize("up", [(0, float("nan"), 0), (0, float("inf"), 0), "abc", (0, 1)])
def test_non_finite_or_malformed_up_is_refused(up):
    with pytest.raises(InputError, match="camera up"):
        Camera(up=up)


@pytest.mark.parametrize("elevation", [-90, -60, -30, -1e-3, 0, 15, 45, 89.5, 90])
@pytest.mark.parametrize("azimuth", [0, 37, -120])
@pytest.mark.parametrize("sign", [1, -1])
def test_up_parallel_to_the_view_direction_is_refused_at_every_elevation(elevation, azimuth, sign):
    az, el = np.radians(azimuth), np.radians(elevation)
    direction = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    with pytest.raises(InputError, match="parallel to the view direction"):
        Camera(azimuth=azimuth, elevation=elevation, up=tuple(sign * 3.0 * direction))


@pytest.mark.parametrize("elevation", [90, -90])
def test_looking_straight_up_or_down_needs_another_up(elevation):
    with pytest.raises(InputError, match="parallel"):
        Camera(elevation=elevation)
    camera = Camera(elevation=elevation, up=(0, 0, -1), distance=5, view_height=2)
    origins, directions = camera.rays(3, 2)
    assert np.isfinite(origins).all() and np.isfinite(directions).all()
    np.testing.assert_allclose(directions[0, 0], (0, -np.sign(elevation), 0), atol=1e-12)


def test_with_camera_revalidates_the_basis():
    from core.scene import Scene, VolumeInstance
    from core.transfer import TransferFunction
    from core.volume import Volume

    scene = Scene(VolumeInstance(Volume(np.zeros((4, 4, 4), np.uint8)), TransferFunction.constant(alpha=0.5)))
    with pytest.raises(InputError, match="parallel"):
        scene.with_camera(elevation=90)
    with pytest.raises(InputError, match="non-zero"):
        scene.with_camera(up=(0, 0, 0))


@pytest.mark.parametrize("kwargs", [{"azimuth": float("inf")}, {"elevation": float("nan")},
                                    {"distance": float("inf")}, {"view_height": float("nan")}])
def test_non_finite_camera_numbers_are_refused(kwargs):
    with pytest.raises(InputError, match=next(iter(kwargs))):
        Camera(**kwargs)


def test_basis_is_computed_once_and_cannot_be_changed_by_a_caller():
    camera = Camera(azimuth=30, elevation=20, distance=5.0, view_height=3.0)
    first = camera.basis()
    assert all(a is b for a, b in zip(first, camera.basis()))
    with pytest.raises(ValueError):
        first[0][0] = 0.0
    turned = dataclasses.replace(camera, azimuth=40)  # a new camera gets its own frame
    assert not np.allclose(turned.basis()[0], first[0])
