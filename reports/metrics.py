"""Image-accuracy metrics between a reference image and a test image.

Both images are volbench images: ``(H, W, 4)`` float32, linear, premultiplied RGBA
(CONVENTIONS, Cameras and images), of the same shape.

- Pixel metrics (:func:`rmse`, :func:`psnr`, :func:`max_error`, :func:`fraction_over`) use all four
  premultiplied RGBA channels, so a wrong opacity counts as much as a wrong colour.
- Perceptual metrics (:func:`ssim`, :func:`flip`) use what a viewer sees: the RGB image composited
  over black, i.e. the PNG volbench writes.

:func:`compare` gathers them under stable keys (:data:`METRIC_KEYS`) that become CSV columns.
"""

import math

import flip_evaluator
import numpy as np
from skimage.metrics import structural_similarity

from core.errors import InputError
from reports.imageio import check_image, composite_over, decode_srgb, read_image, write_image

__all__ = [
    "DEFAULT_DIFF_SCALE",
    "METRIC_KEYS",
    "compare",
    "compare_files",
    "difference_image",
    "flip",
    "flip_map",
    "fraction_over",
    "max_error",
    "psnr",
    "rmse",
    "ssim",
]

#: Keys of the dictionary returned by :func:`compare`, in order.
METRIC_KEYS = ("rmse", "psnr", "ssim", "flip", "max_error", "frac_over_threshold", "alpha_rmse")


def _check_pair(reference, test):
    """Validate two images of the same shape; return them as float64 arrays."""
    check_image(reference, name="reference")
    check_image(test, name="test")
    if reference.shape != test.shape:
        raise InputError(
            f"reference and test must have the same shape, got {reference.shape} and {test.shape}"
        )
    return reference.astype(np.float64), test.astype(np.float64)


def _check_positive(value, name):
    """Return ``value`` as a finite float > 0."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number, got {value!r}") from None
    if not (math.isfinite(number) and number > 0):
        raise InputError(f"{name}: expected a finite number > 0, got {value!r}")
    return number


def _rgb_over_black(image):
    """Displayed linear colour of ``image``: composited over black, clamped to [0, 1]."""
    return np.clip(composite_over(image), 0.0, 1.0)


def rmse(reference, test):
    """Root-mean-square error over all pixels and premultiplied RGBA channels.

    Parameters
    ----------
    reference, test : numpy.ndarray
        Volbench images of the same shape.

    Returns
    -------
    float
    """
    ref, tst = _check_pair(reference, test)
    return float(np.sqrt(np.mean((ref - tst) ** 2)))


def psnr(reference, test, *, data_range=1.0):
    """Peak signal-to-noise ratio in dB over premultiplied RGBA.

    ``10 · log10(data_range² / MSE)``, the formula of
    :func:`skimage.metrics.peak_signal_noise_ratio`, computed in float64 (written out here because
    importing that module imports ``scipy.stats``: 0.6 s in every evaluate job; the tests check
    that both agree).

    Parameters
    ----------
    reference, test : numpy.ndarray
        Volbench images of the same shape.
    data_range : float, optional
        Peak value of the signal (1.0 for images in [0, 1]). Always explicit, never guessed from
        the data.

    Returns
    -------
    float
        PSNR in dB; ``math.inf`` for identical images (pandas writes it to CSV as ``inf`` and reads
        it back as infinity).
    """
    ref, tst = _check_pair(reference, test)
    data_range = _check_positive(data_range, "data_range")
    if np.array_equal(ref, tst):
        return math.inf
    mse = np.mean(np.square(ref.astype(np.float64) - tst.astype(np.float64)))
    return float(10.0 * np.log10(data_range ** 2 / mse))


def ssim(reference, test, *, data_range=1.0, win_size=7):
    """Mean structural similarity of the RGB images composited over black.

    The composite is not clamped, so ``data_range`` applies to it as given. Computed by
    :func:`skimage.metrics.structural_similarity` with its defaults: a uniform
    ``win_size × win_size`` window, sample covariance, K1 = 0.01, K2 = 0.03, averaged over the
    three colour channels.

    Parameters
    ----------
    reference, test : numpy.ndarray
        Volbench images of the same shape.
    data_range : float, optional
        Peak value of the signal.
    win_size : int, optional
        Odd side length of the window, at least 3. Images smaller than the window use the
        largest odd window that fits.

    Returns
    -------
    float
        SSIM in [-1, 1]; 1 for identical images.

    Raises
    ------
    core.errors.InputError
        If the image is smaller than 3 × 3 pixels or ``win_size`` is not an odd integer ≥ 3.
    """
    _check_pair(reference, test)
    data_range = _check_positive(data_range, "data_range")
    if not isinstance(win_size, (int, np.integer)) or win_size < 3 or win_size % 2 == 0:
        raise InputError(f"win_size: expected an odd integer >= 3, got {win_size!r}")
    smallest = min(reference.shape[:2])
    if smallest < 3:
        raise InputError(f"reference: SSIM needs at least 3 x 3 pixels, got {reference.shape}")
    win_size = min(int(win_size), smallest if smallest % 2 else smallest - 1)
    return float(
        structural_similarity(
            composite_over(reference).astype(np.float64),
            composite_over(test).astype(np.float64),
            win_size=win_size,
            data_range=data_range,
            channel_axis=-1,
        )
    )


def _flip_evaluate(reference, test, *, apply_magma):
    """Run LDR-FLIP on the displayed images (see :func:`flip`); return (map, mean)."""
    _check_pair(reference, test)
    error_map, mean, _ = flip_evaluator.evaluate(
        _rgb_over_black(reference),
        _rgb_over_black(test),
        "LDR",
        inputsRGB=False,
        applyMagma=apply_magma,
    )
    return error_map, float(mean)


def flip(reference, test):
    """Mean LDR-FLIP error of the images as displayed (RGB over black, clamped to [0, 1]).

    FLIP (Andersson et al. 2020, NVIDIA ``flip-evaluator``) models the difference a viewer notices
    when flipping between the two images. LDR-FLIP works on display values in [0, 1] and by
    default decodes sRGB input to linear first. Volbench images are already linear, so the
    clamped composite is passed with ``inputsRGB=False``, which skips that decoding: the result
    equals LDR-FLIP on the sRGB-encoded PNGs (:func:`reports.imageio.write_png`) without their
    8-bit rounding. Viewing conditions are FLIP's default, 67 pixels per degree.

    Parameters
    ----------
    reference, test : numpy.ndarray
        Volbench images of the same shape.

    Returns
    -------
    float
        Mean FLIP error in [0, 1]; 0 for identical images.
    """
    return _flip_evaluate(reference, test, apply_magma=False)[1]


def flip_map(reference, test):
    """Per-pixel FLIP error map coloured with the magma colour map, as in the FLIP tool.

    Parameters
    ----------
    reference, test : numpy.ndarray
        Volbench images of the same shape (evaluated as in :func:`flip`).

    Returns
    -------
    numpy.ndarray
        ``(H, W, 4)`` float32 linear RGBA with alpha 1; :func:`reports.imageio.write_png` shows the
        exact magma colours (black-purple for no error, pale yellow for error 1).
    """
    coloured, _ = _flip_evaluate(reference, test, apply_magma=True)
    return _opaque(decode_srgb(coloured))  # magma colours are sRGB display values


def max_error(reference, test):
    """Largest absolute difference over all pixels and premultiplied RGBA channels.

    Parameters
    ----------
    reference, test : numpy.ndarray
        Volbench images of the same shape.

    Returns
    -------
    float
    """
    ref, tst = _check_pair(reference, test)
    return float(np.max(np.abs(ref - tst)))


def fraction_over(reference, test, *, threshold=0.05):
    """Fraction of pixels where any RGBA channel differs by more than ``threshold``.

    Parameters
    ----------
    reference, test : numpy.ndarray
        Volbench images of the same shape.
    threshold : float, optional
        Absolute difference, in the units of the image (0.05 is "off by more than 5 %" for
        values in [0, 1]).

    Returns
    -------
    float
        Fraction in [0, 1].
    """
    ref, tst = _check_pair(reference, test)
    threshold = _check_positive(threshold, "threshold")
    return float(np.mean(np.any(np.abs(ref - tst) > threshold, axis=-1)))


def compare(reference, test, *, data_range=1.0, threshold=0.05):
    """Compute every metric between a reference and a test image.

    Parameters
    ----------
    reference, test : numpy.ndarray
        Volbench images of the same shape.
    data_range : float, optional
        Peak signal value for PSNR and SSIM.
    threshold : float, optional
        Per-channel absolute difference counted by ``frac_over_threshold``.

    Returns
    -------
    dict of str to float
        Keys :data:`METRIC_KEYS`, in that order:

        ``rmse``, ``max_error``
            Over premultiplied RGBA (:func:`rmse`, :func:`max_error`).
        ``psnr``
            dB over premultiplied RGBA, ``inf`` for identical images (:func:`psnr`).
        ``ssim``, ``flip``
            On the RGB image over black (:func:`ssim`, :func:`flip`).
        ``frac_over_threshold``
            :func:`fraction_over` with ``threshold``.
        ``alpha_rmse``
            RMSE of the alpha channel alone.

    Raises
    ------
    core.errors.InputError
        If an image is malformed or the shapes differ.
    """
    ref, tst = _check_pair(reference, test)
    return {
        "rmse": rmse(reference, test),
        "psnr": psnr(reference, test, data_range=data_range),
        "ssim": ssim(reference, test, data_range=data_range),
        "flip": flip(reference, test),
        "max_error": max_error(reference, test),
        "frac_over_threshold": fraction_over(reference, test, threshold=threshold),
        "alpha_rmse": float(np.sqrt(np.mean((ref[..., 3] - tst[..., 3]) ** 2))),
    }


def _opaque(rgb):
    """Append alpha 1 to an ``(H, W, 3)`` array; return float32 RGBA."""
    alpha = np.ones(rgb.shape[:2] + (1,), dtype=np.float32)
    return np.concatenate([rgb.astype(np.float32), alpha], axis=-1)


#: Absolute error shown at the top of the colour map by :func:`difference_image` when no scale
#: is given: a quarter of the full [0, 1] intensity range. Fixed, so that images from different
#: runs can be compared by eye; a report states the scale it uses beside a colour bar.
DEFAULT_DIFF_SCALE = 0.25


def difference_image(reference, test, *, scale=None, gain=None):
    """Visualise where and how much two images differ, on a fixed scale.

    The per-pixel error is the largest absolute difference over the premultiplied RGBA channels
    (the quantity behind :func:`max_error` and :func:`fraction_over`). It is divided by ``scale``,
    clamped to [0, 1] and mapped through matplotlib's perceptually uniform ``magma`` colour map:
    black for no difference, pale yellow for an error of ``scale`` or more. The scale never
    depends on the images, so an error of 3e-7 stays black where one of 3e-2 shows
    (:func:`reports.plots.difference_colorbar` draws the matching colour bar).

    Parameters
    ----------
    reference, test : numpy.ndarray
        Volbench images of the same shape.
    scale : float, optional
        Absolute error mapped to the top of the colour map; default :data:`DEFAULT_DIFF_SCALE`.
    gain : float, optional
        The older way to give the scale: ``gain = 1 / scale`` (give one of the two).

    Returns
    -------
    numpy.ndarray
        ``(H, W, 4)`` float32 linear RGBA with alpha 1, ready for
        :func:`reports.imageio.write_png`, which shows the exact magma colours.
    """
    ref, tst = _check_pair(reference, test)
    if scale is not None and gain is not None:
        raise InputError("difference_image: give scale or gain, not both")
    if gain is not None:
        scale = 1.0 / _check_positive(gain, "gain")
    scale = _check_positive(DEFAULT_DIFF_SCALE if scale is None else scale, "scale")
    error = np.max(np.abs(ref - tst), axis=-1)
    from matplotlib import colormaps  # here, not at import: the tabulate jobs read METRIC_KEYS only

    colours = colormaps["magma"](np.clip(error / scale, 0.0, 1.0))[..., :3]
    return _opaque(decode_srgb(colours))  # matplotlib colours are sRGB display values


def compare_files(reference_path, test_path, *, diff_path=None, **kwargs):
    """Read two image files, compare them and optionally write their difference image.

    Parameters
    ----------
    reference_path, test_path : str or os.PathLike
        Image files (EXR for exact values; see :func:`reports.imageio.read_image`).
    diff_path : str or os.PathLike, optional
        Where to write :func:`difference_image` (fixed default scale), ``.png`` or ``.exr``.
    **kwargs
        ``data_range`` and ``threshold``, passed to :func:`compare`.

    Returns
    -------
    dict of str to float
        As :func:`compare`.

    Raises
    ------
    core.errors.InputError
        If a file cannot be read, holds other channels than colour (e.g. ``R, G, B, Z``), or the
        images differ in shape (both paths are named).

    Warns
    -----
    UserWarning
        When one file stores linear float values (EXR) and the other display-encoded integers
        (PNG, composited over black): the numbers then measure the encoding as well.
    """
    import warnings

    from reports.imageio import stored_as_float

    reference = read_image(reference_path)
    test = read_image(test_path)
    floats = {path: stored_as_float(path) for path in (reference_path, test_path)}
    if len(set(floats.values())) > 1:
        exact, encoded = sorted(floats, key=floats.get, reverse=True)
        warnings.warn(f"{exact} holds linear float values (as EXR) but {encoded} holds display-encoded integers (as "
                      "PNG: composited over black, clamped, sRGB-encoded and quantised, alpha 1): the metrics measure "
                      "that encoding too, not only the renderers' difference; compare two EXRs (or two PNGs) instead",
                      UserWarning, stacklevel=2)
    if reference.shape != test.shape:
        raise InputError(
            f"{reference_path} has shape {reference.shape} but {test_path} has shape {test.shape}; "
            "compare images of the same size"
        )
    metrics = compare(reference, test, **kwargs)
    if diff_path is not None:
        write_image(diff_path, difference_image(reference, test))
    return metrics
