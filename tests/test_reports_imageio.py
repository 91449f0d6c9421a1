"""Tests of reports.imageio: EXR/PNG writing and reading, compositing, sRGB encoding."""

import numpy as np
import OpenImageIO as oiio
import pytest

from core.errors import InputError
from reports.imageio import (
    composite_over,
    decode_srgb,
    encode_srgb,
    read_image,
    read_metadata,
    write_exr,
    write_image,
    write_png,
)


def premultiplied(height=6, width=5, seed=0):
    """A random premultiplied RGBA image (colour <= alpha), float32."""
    rng = np.random.default_rng(seed)
    alpha = rng.random((height, width, 1))
    rgb = rng.random((height, width, 3)) * alpha
    return np.concatenate([rgb, alpha], axis=-1).astype(np.float32)


def test_exr_round_trip_is_exact_with_metadata(tmp_path):
    image = premultiplied()
    image[0, 0] = [2.5, 1e-8, 0.0, 1.0]  # HDR and tiny values survive too
    path = write_exr(tmp_path / "sub" / "a.exr", image, metadata={"backend": "ref", "step": 0.5})
    back = read_image(path)
    assert back.dtype == np.float32 and back.shape == image.shape
    np.testing.assert_array_equal(back, image)
    assert read_metadata(path) == {"backend": "ref", "step": "0.5"}


def test_png_is_composited_srgb_and_reads_back_linear(tmp_path):
    image = np.zeros((2, 3, 4), np.float32)
    image[0, 0] = [0.2, 0.1, 0.0, 0.5]  # half-transparent
    image[1, 2] = [1.0, 1.0, 1.0, 1.0]
    path = write_png(tmp_path / "a.png", image, background=(0.0, 0.0, 1.0))
    back = read_image(path)
    expected = composite_over(image, (0.0, 0.0, 1.0))
    np.testing.assert_allclose(back[..., :3], expected, atol=0.01)  # 8-bit sRGB quantisation
    np.testing.assert_array_equal(back[..., 3], 1.0)
    np.testing.assert_allclose(back[0, 0, :3], [0.2, 0.1, 0.5], atol=0.005)


@pytest.mark.parametrize("channels", [1, 2, 4])
def test_foreign_png_is_decoded_and_premultiplied(tmp_path, channels):
    pixels = np.array([[[255, 128, 0, 128][:channels]]], np.uint8)  # one pixel, straight alpha
    path = str(tmp_path / "foreign.png")
    spec = oiio.ImageSpec(1, 1, channels, oiio.UINT8)
    spec.attribute("oiio:UnassociatedAlpha", 1)  # store the values as given
    out = oiio.ImageOutput.create(path)
    assert out.open(path, spec) and out.write_image(pixels)
    out.close()
    alpha = {1: 1.0, 2: 128 / 255, 4: 128 / 255}[channels]
    colour = {1: [1.0] * 3, 2: [1.0] * 3, 4: [1.0, decode_srgb(128 / 255), 0.0]}[channels]
    np.testing.assert_allclose(read_image(path)[0, 0], [*(np.array(colour) * alpha), alpha],
                               rtol=1e-6)


def test_png_is_deterministic(tmp_path):
    image = premultiplied()
    first = write_png(tmp_path / "a.png", image).read_bytes()
    assert write_png(tmp_path / "b.png", image).read_bytes() == first


def test_srgb_transfer_function():
    np.testing.assert_allclose(encode_srgb([0.0, 0.0031308, 0.2140, 1.0]),
                               [0.0, 0.04045, 0.5, 1.0], atol=1e-4)
    x = np.linspace(0, 1, 101)
    np.testing.assert_allclose(decode_srgb(encode_srgb(x)), x, atol=1e-6)


def test_composite_over_named_background():
    image = np.zeros((1, 1, 4), np.float32)  # fully transparent
    np.testing.assert_allclose(composite_over(image, "white"), 1.0)
    np.testing.assert_allclose(composite_over(image, "#808080"), decode_srgb(128 / 255), rtol=1e-6)
    with pytest.raises(InputError, match="background"):
        composite_over(image, "not-a-colour")
    with pytest.raises(InputError, match="background"):
        composite_over(image, (0.0, 2.0, 0.0))


def test_write_image_chooses_format_by_suffix(tmp_path):
    image = premultiplied()
    np.testing.assert_array_equal(read_image(write_image(tmp_path / "a.EXR", image)), image)
    assert write_image(tmp_path / "a.png", image).read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(InputError, match="a.tiff"):
        write_image(tmp_path / "a.tiff", image)


@pytest.mark.parametrize(
    ("image", "message"),
    [
        (np.zeros((4, 4, 3), np.float32), r"shape \(H, W, 4\)"),
        (np.zeros((4, 4), np.float32), r"shape \(H, W, 4\)"),
        (np.zeros((4, 4, 4), np.float64), "float32"),
        (np.full((4, 4, 4), np.nan, np.float32), "NaN"),
        (np.zeros((0, 4, 4), np.float32), "empty"),
        ([[0.0]], "numpy array"),
    ],
)
def test_writers_reject_bad_images(tmp_path, image, message):
    for name in ("a.exr", "a.png"):
        with pytest.raises(InputError, match=message):
            write_image(tmp_path / name, image)


def test_unreadable_files_name_the_path(tmp_path):
    with pytest.raises(InputError, match="missing.exr"):
        read_image(tmp_path / "missing.exr")
    garbage = tmp_path / "garbage.png"
    garbage.write_bytes(b"not an image")
    with pytest.raises(InputError, match="garbage.png"):
        read_image(garbage)
