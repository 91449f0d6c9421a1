"""Tests of reports.metrics against analytic values."""

import math

import numpy as np
import pandas as pd
import pytest
from scipy.ndimage import gaussian_filter

from core.errors import InputError
from reports import metrics
from reports.imageio import encode_srgb, read_image, write_exr


def textured(height=32, width=32, seed=0):
    """An opaque image with structure at several scales, values in [0.2, 0.8]."""
    rng = np.random.default_rng(seed)
    rgb = 0.2 + 0.6 * gaussian_filter(rng.random((height, width, 3)), sigma=(1, 1, 0))
    rgb = (rgb - rgb.min()) / (rgb.max() - rgb.min()) * 0.6 + 0.2
    return np.concatenate([rgb, np.ones((height, width, 1))], axis=-1).astype(np.float32)


def test_identical_images():
    image = textured()
    result = metrics.compare(image, image)
    assert list(result) == list(metrics.METRIC_KEYS)
    assert result["rmse"] == 0.0
    assert result["psnr"] == math.inf
    assert result["ssim"] == pytest.approx(1.0)
    assert result["flip"] == 0.0
    assert result["max_error"] == 0.0
    assert result["frac_over_threshold"] == 0.0
    assert result["alpha_rmse"] == 0.0
    assert all(isinstance(v, float) for v in result.values())


def test_psnr_inf_survives_csv(tmp_path):
    image = textured()
    pd.DataFrame([metrics.compare(image, image)]).to_csv(tmp_path / "m.csv", index=False)
    assert pd.read_csv(tmp_path / "m.csv")["psnr"].iloc[0] == math.inf


def test_constant_offset_gives_analytic_rmse_and_psnr():
    reference = textured()
    test = reference + np.float32(0.1)
    assert metrics.rmse(reference, test) == pytest.approx(0.1, rel=1e-5)
    assert metrics.psnr(reference, test) == pytest.approx(20.0, abs=1e-3)
    assert metrics.max_error(reference, test) == pytest.approx(0.1, rel=1e-5)
    assert metrics.fraction_over(reference, test, threshold=0.05) == 1.0
    assert metrics.fraction_over(reference, test, threshold=0.2) == 0.0
    result = metrics.compare(reference, test)
    assert result["alpha_rmse"] == pytest.approx(0.1, rel=1e-5)


@pytest.mark.parametrize("data_range", [1.0, 2.0])
def test_psnr_is_scikit_images(data_range):
    from skimage.metrics import peak_signal_noise_ratio

    rng = np.random.default_rng(4)
    reference = textured()
    test = np.clip(reference + rng.normal(0, 0.05, reference.shape), 0, 1).astype(np.float32)
    assert metrics.psnr(reference, test, data_range=data_range) == pytest.approx(
        peak_signal_noise_ratio(reference, test, data_range=data_range), rel=1e-8)  # it subtracts in float32


def test_data_range_is_respected():
    reference = textured()
    test = reference + np.float32(0.1)
    # data_range 2 doubles the peak: +20·log10(2) dB.
    assert metrics.psnr(reference, test, data_range=2.0) == pytest.approx(
        20.0 + 20 * math.log10(2), abs=1e-3)
    assert metrics.compare(reference, test, data_range=2.0)["psnr"] == pytest.approx(26.0206, 1e-4)
    assert metrics.ssim(reference, test, data_range=10.0) > metrics.ssim(reference, test)
    with pytest.raises(InputError, match="data_range"):
        metrics.psnr(reference, test, data_range=0)


def test_single_pixel_error():
    reference = textured()
    test = reference.copy()
    test[5, 7, 1] += 0.5
    n = reference.shape[0] * reference.shape[1]
    result = metrics.compare(reference, test)
    assert result["frac_over_threshold"] == pytest.approx(1 / n)
    assert result["max_error"] == pytest.approx(0.5)
    assert result["rmse"] == pytest.approx(math.sqrt(0.25 / (4 * n)), rel=1e-5)
    assert result["alpha_rmse"] == 0.0


def test_alpha_only_error_counts_in_pixel_metrics():
    reference = np.zeros((8, 8, 4), np.float32)
    test = reference.copy()
    test[..., 3] = 0.2  # same colour, wrong opacity
    result = metrics.compare(reference, test)
    assert result["alpha_rmse"] == pytest.approx(0.2)
    assert result["rmse"] == pytest.approx(0.1)  # sqrt(0.04 / 4)
    assert result["frac_over_threshold"] == 1.0
    assert result["ssim"] == pytest.approx(1.0)  # invisible over black


def test_ssim_decreases_with_noise():
    reference = textured()
    rng = np.random.default_rng(1)
    values = [
        metrics.ssim(reference, reference + np.float32(sigma) * rng.standard_normal(
            reference.shape).astype(np.float32))
        for sigma in (0.01, 0.05, 0.2)
    ]
    assert 1.0 > values[0] > values[1] > values[2]


def test_ssim_small_images_use_a_smaller_window():
    reference = textured(5, 5)
    assert metrics.ssim(reference, reference) == pytest.approx(1.0)
    assert metrics.ssim(reference, reference * np.float32(0.5)) < 1.0
    with pytest.raises(InputError, match="3 x 3"):
        metrics.ssim(reference[:2], reference[:2])
    with pytest.raises(InputError, match="win_size"):
        metrics.ssim(reference, reference, win_size=4)


def test_flip_increases_with_blur():
    reference = textured(48, 48)
    errors = []
    for sigma in (0.5, 1.0, 2.0):
        blurred = gaussian_filter(reference, sigma=(sigma, sigma, 0))
        errors.append(metrics.flip(reference, blurred))
    assert 0.0 < errors[0] < errors[1] < errors[2] < 1.0


def test_shape_mismatch_names_both_shapes():
    with pytest.raises(InputError, match=r"\(8, 8, 4\) and \(8, 9, 4\)"):
        metrics.compare(textured(8, 8), textured(8, 9))


def test_bad_images_are_rejected():
    good = textured(8, 8)
    with pytest.raises(InputError, match="test: .*float32"):
        metrics.rmse(good, good.astype(np.float64))
    bad = good.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(InputError, match="reference: .*NaN"):
        metrics.compare(bad, good)


def test_difference_image():
    reference = textured(8, 8)
    test = reference.copy()
    test[2, 3, 0] += 0.2
    test[4, 4, 3] -= 0.1  # alpha-only difference shows too
    diff = metrics.difference_image(reference, test)
    assert diff.shape == reference.shape and diff.dtype == np.float32
    np.testing.assert_array_equal(diff[..., 3], 1.0)
    brightness = diff[..., :3].sum(axis=-1)
    assert brightness[2, 3] > brightness[4, 4] > brightness[0, 0]
    assert brightness[0, 0] == brightness.min()
    # Gain 1 (scale 1) shows the same error dimmer than the default scale of 0.25.
    assert metrics.difference_image(reference, test, gain=1.0)[2, 3, :3].sum() < brightness[2, 3]
    same = metrics.difference_image(reference, reference)
    np.testing.assert_array_equal(same, np.broadcast_to(same[0, 0], same.shape))
    with pytest.raises(InputError, match="gain"):
        metrics.difference_image(reference, test, gain=-1)


@pytest.mark.parametrize("channel", range(4))
def test_difference_image_shows_a_one_channel_error_where_the_colour_bar_puts_it(channel):
    """The colour bar (``reports.plots.difference_colorbar``) maps 0 … scale to magma; a pixel's
    error is its largest channel error, so an error in one channel alone reads at its full size."""
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    scale = 0.2
    reference = np.full((2, 4, 4), 0.5, np.float32)
    reference[..., 3] = 1.0
    test = reference.copy()
    test[0, 0, channel] -= 0.13  # 0.65 of the bar (away from the edges of magma's 256 colours)
    test[0, 1, channel] -= 0.13
    test[0, 1, (channel + 1) % 4] -= 0.05  # a smaller error elsewhere changes nothing
    test[0, 2, channel] -= 0.3  # past the scale: the bar's top
    bar = ScalarMappable(norm=Normalize(0.0, scale), cmap=colormaps["magma"])
    expected = bar.to_rgba([[0.13, 0.13, scale, 0.0], [0.0] * 4])[..., :3]
    shown = encode_srgb(metrics.difference_image(reference, test, scale=scale)[..., :3])  # as write_png shows it
    np.testing.assert_allclose(shown, expected, atol=1e-5)


def test_flip_map_is_an_opaque_image():
    reference = textured(16, 16)
    coloured = metrics.flip_map(reference, gaussian_filter(reference, sigma=(1, 1, 0)))
    assert coloured.shape == reference.shape and coloured.dtype == np.float32
    np.testing.assert_array_equal(coloured[..., 3], 1.0)
    identical = metrics.flip_map(reference, reference)
    assert coloured[..., :3].sum() > identical[..., :3].sum()


def test_compare_files(tmp_path):
    reference = textured(8, 8)
    test = reference + np.float32(0.1)
    ref_path = write_exr(tmp_path / "ref.exr", reference)
    test_path = write_exr(tmp_path / "test.exr", test)
    result = metrics.compare_files(ref_path, test_path, diff_path=tmp_path / "diff.png",
                                   threshold=0.2)
    assert result == metrics.compare(reference, test, threshold=0.2)
    assert read_image(tmp_path / "diff.png").shape == reference.shape
    small = write_exr(tmp_path / "small.exr", textured(4, 4))
    with pytest.raises(InputError, match="small.exr"):
        metrics.compare_files(ref_path, small)


def _noisy_pair():
    reference = textured(24, 24, seed=3)
    rng = np.random.default_rng(7)
    test = np.clip(reference + np.float32(0.08) * rng.standard_normal(reference.shape).astype(np.float32), 0, 1)
    test[..., 3] = 1
    return reference, test.astype(np.float32)


def test_ssim_uses_a_7_by_7_window():
    # Pinned value for a fixed pair with skimage's uniform 7 x 7 window; windows 5 and 9 give
    # 0.677 and 0.732, so a changed default window (in ssim or in compare) fails here.
    reference, test = _noisy_pair()
    pinned = 0.7173655831350247
    assert metrics.ssim(reference, test) == pytest.approx(pinned, rel=1e-9)
    assert metrics.ssim(reference, test, win_size=7) == pytest.approx(pinned, rel=1e-9)
    assert metrics.compare(reference, test)["ssim"] == pytest.approx(pinned, rel=1e-9)
    assert metrics.ssim(reference, test, win_size=5) == pytest.approx(0.6774013154556061, rel=1e-9)


def test_default_threshold_is_five_percent():
    reference = np.zeros((4, 4, 4), np.float32)
    below, above = reference.copy(), reference.copy()
    # The float32 neighbours of 0.05: just under and just over the default threshold.
    below[0, 0, 0] = np.nextafter(np.float32(0.05), np.float32(0))
    above[0, 0, 0] = np.nextafter(np.float32(0.05), np.float32(1))
    assert float(below[0, 0, 0]) < 0.05 < float(above[0, 0, 0])
    assert metrics.compare(reference, below)["frac_over_threshold"] == 0.0
    assert metrics.compare(reference, above)["frac_over_threshold"] == pytest.approx(1 / 16)
    assert metrics.fraction_over(reference, above) == pytest.approx(1 / 16)
    assert metrics.fraction_over(reference, below) == 0.0


def test_a_difference_equal_to_the_threshold_is_not_over_it():
    reference = np.full((4, 4, 4), 0.5, np.float32)
    test = reference.copy()
    test[1, 2, 0] = 0.75  # exactly 0.25 more, in binary too
    test[3, 3, 2] = 0.8125  # 0.3125 more
    assert metrics.fraction_over(reference, test, threshold=0.25) == pytest.approx(1 / 16)
    assert metrics.compare(reference, test, threshold=0.25)["frac_over_threshold"] == pytest.approx(1 / 16)
    assert metrics.fraction_over(reference, test, threshold=0.3125) == 0.0
