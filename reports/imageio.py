"""Reading and writing volbench images (EXR to keep the values, PNG to look at them).

A volbench image is an ``(H, W, 4)`` float32 array of linear, premultiplied RGBA with row 0 at the
top (CONVENTIONS, Cameras and images). EXR files store exactly that (32-bit float, lossless ZIP
compression, premultiplied as OpenEXR defines alpha). PNG files are for people: the image is
composited over an opaque background, clamped to [0, 1] and encoded with the sRGB transfer function
(IEC 61966-2-1) to 8 bits, which is what a browser or image viewer expects. Reading a PNG undoes the
encoding, so the result is linear again, with alpha 1 where the image was composited.

OpenImageIO does the file work; every error names the file. Several outputs of one result are
written all or none (:func:`write_images`), and :func:`check_output_path` tells before any work
whether a file can be written at all.
"""

import os
import secrets
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from core.errors import InputError

__all__ = [
    "check_image",
    "check_output_path",
    "composite_over",
    "decode_srgb",
    "encode_srgb",
    "read_image",
    "read_metadata",
    "stored_as_float",
    "write_exr",
    "write_image",
    "write_images",
    "write_png",
]

_METADATA_PREFIX = "volbench:"

COLOUR_CHANNELS = (("R", "G", "B", "A"), ("R", "G", "B"), ("Y", "A"), ("Y",))
"""Channel sets :func:`read_image` reads as colour: RGBA, RGB, grey with alpha, grey."""

_WRITERS_BY_SUFFIX = (".exr", ".png")


def check_image(image, *, name="image"):
    """Check that ``image`` is a volbench image.

    Parameters
    ----------
    image : numpy.ndarray
        Candidate image: ``(H, W, 4)`` float32, finite, at least one pixel.
    name : str, optional
        How the input is named in error messages.

    Returns
    -------
    numpy.ndarray
        The same image.

    Raises
    ------
    core.errors.InputError
        If the type, shape or dtype is wrong, the image is empty or it holds NaN or infinity.
    """
    if not isinstance(image, np.ndarray):
        raise InputError(f"{name}: expected a numpy array, got {type(image).__name__}")
    if image.ndim != 3 or image.shape[2] != 4:
        raise InputError(f"{name}: expected shape (H, W, 4) (RGBA), got {image.shape}")
    if image.dtype != np.float32:
        raise InputError(
            f"{name}: expected dtype float32, got {image.dtype}; convert with .astype(np.float32)"
        )
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise InputError(f"{name}: empty image with shape {image.shape}")
    if not np.isfinite(image).all():
        raise InputError(f"{name}: contains NaN or infinite values")
    return image


def encode_srgb(linear):
    """Encode linear values with the sRGB transfer function (IEC 61966-2-1).

    Parameters
    ----------
    linear : array_like
        Linear values in [0, 1]; values outside are clamped first.

    Returns
    -------
    numpy.ndarray
        Encoded (display) values in [0, 1], float32.
    """
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return encoded.astype(np.float32)


def decode_srgb(encoded):
    """Decode sRGB-encoded values to linear values, the inverse of :func:`encode_srgb`.

    Parameters
    ----------
    encoded : array_like
        Encoded values in [0, 1]; values outside are clamped first.

    Returns
    -------
    numpy.ndarray
        Linear values in [0, 1], float32.
    """
    x = np.clip(np.asarray(encoded, dtype=np.float64), 0.0, 1.0)
    linear = np.where(x <= 0.04045, x / 12.92, np.power((x + 0.055) / 1.055, 2.4))
    return linear.astype(np.float32)


def _background_rgb(background):
    """Return ``background`` as three linear floats (see :func:`composite_over`)."""
    if isinstance(background, str):
        try:
            from matplotlib.colors import to_rgb  # here: matplotlib costs every render job 0.3 s to import

            return tuple(float(v) for v in decode_srgb(to_rgb(background)))
        except ValueError:
            raise InputError(f"background: unknown colour name {background!r}") from None
    try:
        rgb = tuple(float(v) for v in background)
    except TypeError:
        raise InputError(
            f"background: expected 3 numbers or a colour name, got {background!r}"
        ) from None
    if len(rgb) != 3 or not all(0.0 <= v <= 1.0 for v in rgb):
        raise InputError(f"background: expected 3 linear values in [0, 1], got {background!r}")
    return rgb


def composite_over(image, background=(0.0, 0.0, 0.0)):
    """Composite a premultiplied RGBA image over an opaque background.

    Computes ``rgb + (1 - alpha) * background`` per pixel.

    Parameters
    ----------
    image : numpy.ndarray
        Volbench image, ``(H, W, 4)`` float32, linear premultiplied RGBA.
    background : tuple of 3 float or str, optional
        Background colour. A tuple holds linear values in [0, 1], like every volbench colour; a
        string is a matplotlib/CSS colour name or hex code (``"white"``, ``"#202020"``), which are
        display (sRGB-encoded) colours and are decoded to linear first. Default black.

    Returns
    -------
    numpy.ndarray
        Opaque linear RGB image, ``(H, W, 3)`` float32, not clamped.
    """
    check_image(image)
    bg = np.asarray(_background_rgb(background), dtype=np.float32)
    return image[..., :3] + (1.0 - image[..., 3:]) * bg


def write_exr(path, image, *, metadata=None):
    """Write an image to OpenEXR, exactly.

    Channels ``R, G, B, A`` are stored as 32-bit float with lossless ZIP compression, so
    :func:`read_image` returns the same bits. OpenEXR defines colour as premultiplied by alpha,
    which is the volbench convention.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; parent directories are created.
    image : numpy.ndarray
        Volbench image, ``(H, W, 4)`` float32.
    metadata : dict, optional
        Extra header attributes; keys and values are stored as strings under the ``volbench:``
        prefix and returned by :func:`read_metadata`.

    Returns
    -------
    pathlib.Path
        The written file.
    """
    check_image(image)
    spec = oiio.ImageSpec(image.shape[1], image.shape[0], 4, oiio.FLOAT)
    spec.channelnames = ("R", "G", "B", "A")
    spec.alpha_channel = 3
    spec.attribute("compression", "zip")
    for key, value in (metadata or {}).items():
        spec.attribute(_METADATA_PREFIX + str(key), str(value))
    return _write(path, spec, np.ascontiguousarray(image), ".exr")


def write_png(path, image, *, background=(0.0, 0.0, 0.0)):
    """Write an image to an 8-bit sRGB PNG for viewing.

    The image is composited over ``background`` (:func:`composite_over`), clamped to [0, 1],
    encoded with the sRGB transfer function and rounded to 8 bits. The PNG has no alpha channel.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; parent directories are created.
    image : numpy.ndarray
        Volbench image, ``(H, W, 4)`` float32, linear premultiplied RGBA.
    background : tuple of 3 float or str, optional
        Background colour, as in :func:`composite_over`. Default black.

    Returns
    -------
    pathlib.Path
        The written file.
    """
    rgb = composite_over(image, background)
    pixels = np.round(encode_srgb(rgb) * 255.0).astype(np.uint8)
    spec = oiio.ImageSpec(image.shape[1], image.shape[0], 3, oiio.UINT8)
    return _write(path, spec, pixels, ".png")


def check_output_path(path, *, name=None):
    """Refuse an image output path that cannot be written, before any work is done.

    The suffix must be ``.exr`` or ``.png``, the path must not be a folder, and its folder must
    exist and accept a new file: one is created there and removed again, which also catches what
    permission bits do not tell (a read-only file system, ``/proc``).

    Parameters
    ----------
    path : str or os.PathLike
    name : str, optional
        How the path is named in messages (e.g. ``"--exr out.exr"``); default the path.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    core.errors.InputError
        Naming the path and what is wrong with it.
    """
    path = Path(path)
    name = name or str(path)
    if path.suffix.lower() not in _WRITERS_BY_SUFFIX:
        raise InputError(f"{name}: unknown image suffix {path.suffix.lower()!r}; use .exr or .png")
    if path.is_dir():
        raise InputError(f"{name}: is a folder; give a file name inside it")
    folder = path.parent
    if not folder.is_dir():
        problem = "is not a folder" if folder.exists() else "does not exist"
        raise InputError(f"{name}: folder {folder} {problem}")
    probe = folder / f".{path.name}.{secrets.token_hex(4)}.probe"
    try:
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
    except OSError as exc:
        raise InputError(f"{name}: cannot create a file in folder {folder} ({exc.strerror}); "
                         "choose a folder you can write to") from None
    probe.unlink()
    return path


def write_images(image, paths):
    """Write one image to several files (format by suffix), all of them or none.

    Each file is written to a temporary file beside it first; only when every one is written are
    they renamed over their targets, so a failure leaves no output behind (and no PNG without its
    EXR), and an existing file is replaced whole.

    Parameters
    ----------
    image : numpy.ndarray
        Volbench image, ``(H, W, 4)`` float32.
    paths : iterable of str or os.PathLike
        ``.exr`` and ``.png`` files; ``None`` entries are skipped.

    Returns
    -------
    list of pathlib.Path
        The written files.
    """
    check_image(image)
    targets = [Path(path) for path in paths if path is not None]
    written = {}
    try:
        for target in targets:
            # The temporary keeps the suffix, which chooses OpenImageIO's writer.
            temporary = target.with_name(f".{target.stem}.{secrets.token_hex(4)}.partial{target.suffix}")
            written[target] = temporary
            write_image(temporary, image)
        for target, temporary in written.items():
            os.replace(temporary, target)
    finally:
        for temporary in written.values():
            temporary.unlink(missing_ok=True)
    return targets


def write_image(path, image, **kwargs):
    """Write an image, choosing the format by suffix (``.exr`` or ``.png``).

    Parameters
    ----------
    path : str or os.PathLike
        Output file.
    image : numpy.ndarray
        Volbench image, ``(H, W, 4)`` float32.
    **kwargs
        Passed to :func:`write_exr` (``metadata``) or :func:`write_png` (``background``).

    Returns
    -------
    pathlib.Path
        The written file.
    """
    writers = {".exr": write_exr, ".png": write_png}
    suffix = Path(path).suffix.lower()
    if suffix not in writers:
        raise InputError(f"{path}: unknown image suffix {suffix!r}; use .exr or .png")
    return writers[suffix](path, image, **kwargs)


def _write(path, spec, pixels, suffix):
    """Write ``pixels`` described by ``spec`` to ``path``, which must end in ``suffix``."""
    path = Path(path)
    if path.suffix.lower() != suffix:
        raise InputError(f"{path}: expected a {suffix} file name")
    path.parent.mkdir(parents=True, exist_ok=True)
    out = oiio.ImageOutput.create(str(path))
    if out is None:
        raise OSError(f"{path}: no image writer: {oiio.geterror()}")
    try:
        if not (out.open(str(path), spec) and out.write_image(pixels)):
            raise OSError(f"{path}: cannot write image: {out.geterror()}")
    finally:
        out.close()
    return path


def _open(path):
    """Open ``path`` for reading with OpenImageIO, raising InputError naming it on failure."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: {'is not a file' if path.exists() else 'no such image file'}")
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)  # PNG alpha as stored; read_image premultiplies
    inp = oiio.ImageInput.open(str(path), config)
    if inp is None:
        raise InputError(f"{path}: cannot read image: {oiio.geterror()}")
    return inp


def read_image(path):
    """Read an image file into a volbench image.

    Parameters
    ----------
    path : str or os.PathLike
        An EXR written by :func:`write_exr`, a PNG, or any other format OpenImageIO reads.

    Returns
    -------
    numpy.ndarray
        ``(H, W, 4)`` float32, linear premultiplied RGBA. Floating-point files (EXR) are returned
        as stored: 4 channels are taken as premultiplied RGBA, 3 channels get alpha 1. Integer
        files (PNG) are taken as sRGB-encoded with straight alpha, as PNG defines them: they are
        decoded to linear and premultiplied; files without alpha get alpha 1, and grey files
        are expanded to RGB.

    Raises
    ------
    core.errors.InputError
        If the file is missing or unreadable, or its channels are not one of
        :data:`COLOUR_CHANNELS` (e.g. ``R, G, B, Z`` or ``X, Y, Z, W``; the message lists them).
    """
    inp = _open(path)
    try:
        spec = inp.spec()
        channels = tuple(spec.channelnames)
        if tuple(name.upper() for name in channels) not in COLOUR_CHANNELS:
            # Four float channels are not RGBA because there are four: R,G,B,Z (depth) or X,Y,Z,W
            # (positions) would be compared as colour and opacity.
            raise InputError(f"{path}: channels {', '.join(channels) or 'none'} are not colour channels; expected "
                             f"{'; '.join(', '.join(names) for names in COLOUR_CHANNELS)}")
        pixels = inp.read_image(spec.format)  # native type: integer for PNG, float for EXR
        if pixels is None:
            raise InputError(f"{path}: cannot read image: {inp.geterror()}")
    finally:
        inp.close()
    pixels = pixels.reshape(spec.height, spec.width, spec.nchannels)
    if spec.nchannels in (1, 2):  # grey or grey + alpha
        pixels = np.concatenate([pixels[..., :1]] * 3 + [pixels[..., 1:]], axis=-1)
    if np.issubdtype(pixels.dtype, np.integer):
        values = pixels.astype(np.float64) / np.iinfo(pixels.dtype).max
        values[..., :3] = decode_srgb(values[..., :3])
        if values.shape[2] == 4:
            values[..., :3] *= values[..., 3:]
    else:
        values = pixels.astype(np.float32)
    if values.shape[2] == 3:
        values = np.concatenate([values, np.ones(values.shape[:2] + (1,))], axis=-1)
    return np.ascontiguousarray(values, dtype=np.float32)


def stored_as_float(path):
    """Whether ``path`` stores floating-point pixels (linear values, as EXR does) rather than
    display-encoded integers (8- or 16-bit sRGB, as PNG does)."""
    inp = _open(path)
    try:
        return inp.spec().format.basetype in (oiio.FLOAT, oiio.HALF, oiio.DOUBLE)
    finally:
        inp.close()


def read_metadata(path):
    """Read the metadata stored by :func:`write_exr`.

    Parameters
    ----------
    path : str or os.PathLike
        An image file.

    Returns
    -------
    dict of str to str
        The ``metadata`` given to :func:`write_exr`, without the ``volbench:`` prefix; empty for
        files without it.
    """
    inp = _open(path)
    try:
        attribs = inp.spec().extra_attribs
    finally:
        inp.close()
    return {
        a.name[len(_METADATA_PREFIX):]: str(a.value)
        for a in attribs
        if a.name.startswith(_METADATA_PREFIX)
    }
