"""Tests of reports.imageio: EXR/PNG writing and reading, compositing, sRGB encoding."""

from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest

from core.errors import InputError
from reports.imageio import (
    check_output_path,
    composite_over,
    decode_srgb,
    encode_srgb,
    read_image,
    read_metadata,
    write_exr,
    write_image,
    write_images,
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


def _write_channels(path, names, dtype=oiio.FLOAT):
    spec = oiio.ImageSpec(4, 3, len(names), dtype)
    spec.channelnames = tuple(names)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec) and out.write_image(np.full((3, 4, len(names)), 0.5, np.float32))
    out.close()
    return path


@pytest.mark.parametrize("names", [("R", "G", "B", "Z"), ("X", "Y", "Z", "W"), ("Z",), ("R", "G")])
def test_files_whose_channels_are_not_colour_are_refused_naming_them(tmp_path, names):
    path = _write_channels(tmp_path / "aov.exr", names)
    with pytest.raises(InputError, match=rf"aov.exr: channels {', '.join(names)} are not colour channels; "
                                         r"expected R, G, B, A; R, G, B; Y, A; Y$"):
        read_image(path)


@pytest.mark.parametrize("names, alpha", [(("R", "G", "B", "A"), 0.5), (("R", "G", "B"), 1.0), (("Y",), 1.0),
                                          (("Y", "A"), 0.5)])
def test_colour_channel_sets_are_read(tmp_path, names, alpha):
    image = read_image(_write_channels(tmp_path / "c.exr", names))
    assert image.shape == (3, 4, 4) and image[0, 0, 3] == alpha and image[0, 0, 0] == 0.5


def test_output_paths_that_cannot_be_written_are_refused_naming_why(tmp_path):
    assert check_output_path(tmp_path / "ok.png") == tmp_path / "ok.png"
    assert list(tmp_path.iterdir()) == []  # the probe file is gone
    (tmp_path / "folder.png").mkdir()
    (tmp_path / "file").write_text("")
    for path, match in [(tmp_path / "folder.png", "is a folder; give a file name inside it"),
                        (tmp_path / "missing" / "x.png", r"folder .*missing does not exist"),
                        (tmp_path / "file" / "x.png", r"folder .*file is not a folder"),
                        (Path("/proc/x.exr"), r"cannot create a file in folder /proc \(No such file or directory\)"),
                        (tmp_path / "x.jpg", "unknown image suffix '.jpg'")]:
        with pytest.raises(InputError, match=match):
            check_output_path(path, name=f"--out {path}")


def test_several_outputs_are_written_all_or_none(tmp_path, monkeypatch):
    import reports.imageio

    image = np.full((2, 3, 4), 0.25, np.float32)
    png, exr = tmp_path / "a.png", tmp_path / "a.exr"
    assert write_images(image, [png, exr, None]) == [png, exr]
    np.testing.assert_array_equal(read_image(exr), image)
    before = png.read_bytes()

    def broken(path, image, **kwargs):
        raise OSError(f"{path}: disk full")

    monkeypatch.setattr(reports.imageio, "write_exr", broken)
    with pytest.raises(OSError, match="disk full"):
        write_images(np.zeros((2, 3, 4), np.float32), [png, exr])
    # The PNG written before the failure was not put in place, the old files stand, nothing is left over.
    assert png.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["a.exr", "a.png"]
