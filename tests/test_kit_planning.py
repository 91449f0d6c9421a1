"""The kit's planning helpers (pipeline.experiments.kit.planning): frames of timed runs, views of data sets."""

import numpy as np
import pytest

from core.camera import Camera
from pipeline.experiments import Profile
from pipeline.experiments.kit import planning as C
from pipeline.experiments.kit.planning import UPRIGHT, volume_and_image_size
from pipeline.scene_io import rotation_matrix


def test_profile_frames_raise_the_floor_only():
    profile = Profile(name="t", warmup=2, repeat=7)
    assert C.timed_frames(profile) == {"warmup": 2, "repeat": 7, "min_time": 0.0, "replicates": 1}
    # Five timed frames at least: fewer leave a timing claim inconclusive (intervals.MIN_FRAMES).
    assert C.timed_frames(Profile(name="t", warmup=0, repeat=1)) == {"warmup": 1, "repeat": 5, "min_time": 0.0,
                                                                      "replicates": 1}


def test_replicates_share_the_frames_budget_with_three_frames_each_at_least():
    """Each process takes its share of the arm's frames and min_time, and at least PROCESS_FRAMES frames."""
    two = C.timed_frames(Profile(name="t", warmup=1, repeat=3, min_time=0.2, replicates=2))
    assert two == {"warmup": 1, "repeat": 3, "min_time": 0.1, "replicates": 2}
    assert C.timed_frames(Profile(name="t", repeat=12, replicates=3))["repeat"] == 4
    assert C.timed_frames(Profile(name="t", repeat=1, replicates=5))["repeat"] == 3


# --------------------------------------------------------------------------------------- views
def _upright_camera(azimuth, elevation):
    return Camera(azimuth=azimuth, elevation=elevation, distance=1.0)


@pytest.mark.parametrize("azimuth,elevation", [(0, 0), (30, 20), (90, 0), (135, -40), (200, 10), (300, 60)])
def test_upright_view_matches_the_gallery_rotation(azimuth, elevation):
    """Seeing the untransformed volume with this camera equals the gallery's view of the rotated one."""
    inverse = np.linalg.inv(rotation_matrix(UPRIGHT["rotate"]["axis"], UPRIGHT["rotate"]["degrees"]))[:3, :3]
    gallery = _upright_camera(azimuth, elevation).basis()  # world frame of the upright volume
    view = C.upright_view("v", azimuth, elevation)
    ours = Camera(**{k: v for k, v in view.items() if k != "view"}, distance=1.0).basis()
    for upright_axis, our_axis in zip(gallery, ours):
        np.testing.assert_allclose(inverse @ upright_axis, our_axis, atol=1e-6)


def test_views_of_symmetric_controls_are_plain():
    assert C.dataset_view("sphere", "a", 30) == {"view": "a", "azimuth": 30.0, "elevation": 0.0}
    assert C.headline_view("ct_skull")["up"] == [0.0, 0.0, 1.0]
    assert C.upright_view("front", 0, 0)["elevation"] == -90.0


def test_volume_and_image_size_take_the_experiments_settings_else_the_profiles():
    from pipeline.experiments.kit.model import Experiment, Profile

    class Sized(Experiment):
        name = "test-sized"
        settings = frozenset({"volume_size", "image_size"})
        scales = {"full": {"image_size": 512}}

    assert volume_and_image_size(Profile(name="a", scale="full", volume_size=96), Sized()) == (96, 512)
    assert volume_and_image_size(Profile(name="b", scale="smoke", volume_size=32, image_size=64), Sized()) == (32, 64)
