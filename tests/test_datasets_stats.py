"""Statistics under a preset, checked on volumes whose answers can be worked out by hand."""

import json

import numpy as np
import pytest

import datasets
from datasets import presets as P
from datasets.stats import MAX_GRADIENT, opacity
from core.volume import Volume
from core.errors import InputError
from core.transfer import GradientOpacity, Preset, TransferFunction

IDENTITY = P.identity()


@pytest.mark.parametrize("block", [1, 2, 4, 8])
def test_checkerboard_runs_are_exact(block):
    volume = datasets.load("checkerboard", size=32, block=block, cache_dir=False)
    stats = datasets.statistics(volume, IDENTITY)
    assert stats["runs_per_scanline"] == 32 / (2 * block)
    assert stats["runs_per_occupied_scanline"] == 32 / (2 * block)
    assert stats["runs"] == 32 * 32 * 32 // (2 * block)
    assert stats["mean_run_length"] == block
    assert stats["nontransparent_fraction"] == 0.5
    # 8³ blocks: aligned 8-voxel squares are all on or all off; finer boards touch every block.
    assert stats["empty_block_fraction"] == (0.5 if block == 8 else 0.0)


@pytest.mark.parametrize("value, nontransparent, nonzero", [(0, 0.0, 0.0), (12, 0.0, 1.0), (13, 1.0, 1.0), (255, 1.0, 1.0)])
def test_constant_cube_is_all_or_nothing_around_the_threshold(value, nontransparent, nonzero):
    # identity preset: α = value / 255, so 12 → 0.047 (at or below 0.05) and 13 → 0.051.
    volume = datasets.load("constant_cube", size=16, value=value, cache_dir=False)
    stats = datasets.statistics(volume, IDENTITY)
    assert stats["nontransparent_fraction"] == nontransparent
    assert stats["nonzero_fraction"] == nonzero
    assert stats["runs_per_scanline"] == nontransparent
    assert stats["empty_block_fraction"] == 1 - nonzero
    assert stats["mean_opacity"] == pytest.approx(value / 255 if nontransparent else 0.0)


def test_empty_blocks_on_a_known_layout():
    data = np.zeros((20, 20, 20), np.uint8)        # 3 blocks per axis, the last ones partial
    data[0, 0, 0] = 255
    data[19, 19, 19] = 255
    data[10, 10, 10] = 8                           # α = 8/255 = 0.031: non-empty, yet below the threshold
    stats = datasets.statistics(Volume(data), IDENTITY)
    assert stats["empty_block_fraction"] == pytest.approx(24 / 27)
    assert stats["empty_block_fraction_threshold"] == pytest.approx(25 / 27)
    assert stats["nontransparent_voxels"] == 2
    assert datasets.statistics(Volume(data), IDENTITY, block=4)["empty_block_fraction"] == pytest.approx(1 - 3 / 125)


def test_runs_along_x():
    data = np.zeros((2, 3, 8), np.uint8)
    data[0, 0] = (0, 255, 255, 0, 255, 0, 0, 255)   # three runs
    data[1, 2] = 255                                 # one run spanning the line
    stats = datasets.statistics(Volume(data), IDENTITY)
    assert stats["runs"] == 4
    assert stats["runs_per_scanline"] == pytest.approx(4 / 6)
    assert stats["runs_per_occupied_scanline"] == pytest.approx(2.0)
    assert stats["mean_run_length"] == pytest.approx(12 / 4)


@pytest.mark.parametrize("dtype, value_range", [(np.uint8, None), (np.uint16, (0, 4095)), (np.float32, None)])
def test_classification_matches_the_transfer_function_lookup(dtype, value_range):
    rng = np.random.default_rng(1)
    top = {np.uint8: 255, np.uint16: 4095}.get(dtype)
    data = (rng.random((6, 7, 8)) * top).astype(dtype) if top else rng.random((6, 7, 8)).astype(dtype)
    volume = Volume(data, value_range=value_range)
    tf = TransferFunction.from_points([(0, 1, 0, 0, 0), (0.3, 0, 1, 0, 0.2), (0.31, 0, 0, 1, 0.9), (1, 1, 1, 1, 0.5)], size=64)
    expected = tf.lookup(volume.normalized(np.float64))[..., 3]
    np.testing.assert_allclose(opacity(volume, Preset(tf)), expected, atol=2e-6)


@pytest.mark.parametrize("spacing, axis", [((1, 1, 1), 2), ((1, 1, 2), 0), ((0.5, 1, 1), 2)])
def test_gradient_opacity_uses_object_space_central_differences(spacing, axis):
    """s grows by 0.02 per voxel along one axis; u = |∇s|·Δ0 / (√3/2), clamp-to-edge at the ends."""
    n = 12
    ramp = (0.02 * np.arange(n)).astype(np.float32)
    shape = [4, 4, 4]
    shape[axis] = n
    data = np.broadcast_to(ramp.reshape([-1 if a == axis else 1 for a in range(3)]), shape).copy()
    volume = Volume(data, spacing=spacing)
    preset = Preset(TransferFunction.constant(alpha=1.0), GradientOpacity.from_points([(0, 0), (1, 1)]))
    alpha = opacity(volume, preset)
    step = spacing[2 - axis]
    u = 0.02 / step * min(spacing) / MAX_GRADIENT
    inner = [slice(None)] * 3
    inner[axis] = slice(1, -1)
    np.testing.assert_allclose(alpha[tuple(inner)], u, rtol=1e-4)
    edge = [slice(None)] * 3
    edge[axis] = 0
    np.testing.assert_allclose(alpha[tuple(edge)], u / 2, rtol=1e-4)


def test_gradient_preset_hides_homogeneous_regions():
    data = np.zeros((16, 16, 16), np.uint8)
    data[:, :, 8:] = 200
    stats = datasets.statistics(Volume(data), P.volpack())
    # Only the columns x = 7 and 8 have a gradient, and x = 7 (density 0) is cut by the density ramp.
    assert stats["nontransparent_fraction"] == pytest.approx(1 / 16)
    assert stats["nonzero_fraction"] == pytest.approx(1 / 16)
    assert stats["runs_per_scanline"] == 1


def test_statistics_are_flat_json_numbers_and_check_their_options():
    volume = datasets.load("sphere", size=16, cache_dir=False)
    stats = datasets.statistics(volume, datasets.preset("sphere"))
    assert all(isinstance(v, (int, float)) for v in stats.values())
    json.dumps(stats)
    assert (stats["nx"], stats["ny"], stats["nz"], stats["voxels"]) == (16, 16, 16, 4096)
    assert stats["megabytes"] == pytest.approx(4096 / 2**20)
    assert stats["value_max"] == 200 and 0 < stats["scalar_mean"] < 1
    with pytest.raises(InputError, match="threshold"):
        datasets.statistics(volume, IDENTITY, threshold=1.5)
    with pytest.raises(InputError, match="block"):
        datasets.statistics(volume, IDENTITY, block=0)
    with pytest.raises(InputError, match="Preset"):
        datasets.statistics(volume, IDENTITY.transfer_function)
