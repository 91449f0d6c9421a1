"""Validation helpers: each checks one input and raises :class:`InputError` naming it."""

import math

import numpy as np

from core.errors import InputError

SUPPORTED_DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.float32))


def check_volume_array(data, *, name="volume"):
    """Check a volume array: 3-D, a supported dtype, not empty, finite.

    Parameters
    ----------
    data : array_like
        Candidate volume, indexed ``[z, y, x]``.
    name : str
        How the input is named in error messages.

    Returns
    -------
    numpy.ndarray
        The array, C-contiguous.
    """
    if not isinstance(data, np.ndarray):
        raise InputError(f"{name}: expected a numpy array, got {type(data).__name__}")
    if data.ndim != 3:
        raise InputError(f"{name}: expected a 3-D array indexed [z, y, x], got shape {data.shape}")
    if data.dtype not in SUPPORTED_DTYPES:
        raise InputError(
            f"{name}: dtype {data.dtype} is not supported; convert to uint8, uint16 or float32"
        )
    if 0 in data.shape:
        raise InputError(f"{name}: empty volume with shape {data.shape}")
    if data.dtype.kind == "f" and not np.isfinite(data).all():
        raise InputError(f"{name}: contains NaN or infinite values; clean or mask them first")
    return np.ascontiguousarray(data)


def _float_tuple(value, *, length, name):
    """``value`` as a tuple of floats, or an :class:`InputError` naming ``name``.

    Strings are refused even though they are iterable (``"fast"`` is not three numbers), and so
    are booleans (YAML's ``yes``/``no``).
    """
    if isinstance(value, (str, bytes)) or not np.iterable(value):
        raise InputError(f"{name}: expected {length} numbers, got {value!r}")
    values = []
    for v in value:
        if isinstance(v, (bool, np.bool_, str, bytes)):
            raise InputError(f"{name}: expected {length} numbers, got {value!r}")
        try:
            values.append(float(v))
        except (TypeError, ValueError):
            raise InputError(f"{name}: expected {length} numbers, got {value!r}") from None
    return tuple(values)


def check_positive_vector(value, *, length, name):
    """Return ``value`` as a float tuple of ``length`` finite, strictly positive entries."""
    values = _float_tuple(value, length=length, name=name)
    if len(values) != length:
        raise InputError(f"{name}: expected {length} numbers, got {len(values)} ({value!r})")
    if not all(math.isfinite(v) and v > 0 for v in values):
        raise InputError(f"{name}: every entry must be finite and > 0, got {values}")
    return values


def check_finite_vector(value, *, length, name):
    """Return ``value`` as a float tuple of ``length`` finite entries."""
    values = _float_tuple(value, length=length, name=name)
    if len(values) != length or not all(math.isfinite(v) for v in values):
        raise InputError(f"{name}: expected {length} finite numbers, got {value!r}")
    return values


def check_scalar(value, *, name, low=-math.inf, high=math.inf, low_open=False, high_open=False):
    """Return ``value`` as a float inside the given interval.

    ``low_open``/``high_open`` exclude the bound itself.
    """
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number, got {value!r}") from None
    too_low = number <= low if low_open else number < low
    too_high = number >= high if high_open else number > high
    if not math.isfinite(number) or too_low or too_high:
        lo = "(" if low_open else "["
        hi = ")" if high_open else "]"
        raise InputError(f"{name}: {value!r} is outside {lo}{low}, {high}{hi}")
    return number


def check_value_range(value, *, name):
    """Return ``value`` as ``(lo, hi)``: two finite numbers with ``lo < hi``.

    A normalisation range with an infinite end would map every value to 0 (or NaN), so it is
    refused here rather than rendered as an empty picture.
    """
    values = _float_tuple(value, length=2, name=name)
    if len(values) != 2:
        raise InputError(f"{name}: expected two numbers [lo, hi], got {value!r}")
    lo, hi = values
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise InputError(f"{name}: both ends must be finite numbers, got {value!r}")
    if not hi > lo:
        raise InputError(f"{name}: expected lo < hi, got {value!r}")
    return lo, hi


def check_positive_int(value, *, name, minimum=1):
    """Return ``value`` as an int >= ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


def check_choice(value, choices, *, name):
    """Return ``value`` if it is one of ``choices``."""
    if value not in choices:
        raise InputError(f"{name}: {value!r} is not one of {sorted(choices)}")
    return value


def check_matrix4(value, *, name):
    """Return ``value`` as an invertible, finite 4×4 float64 affine matrix."""
    try:
        matrix = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a 4x4 matrix of numbers, got {value!r}") from None
    if matrix.shape != (4, 4):
        raise InputError(f"{name}: expected a 4x4 matrix, got shape {matrix.shape}")
    if not np.isfinite(matrix).all():
        raise InputError(f"{name}: contains NaN or infinite entries")
    if not np.allclose(matrix[3], (0, 0, 0, 1)):
        raise InputError(f"{name}: last row must be (0, 0, 0, 1) for an affine transform")
    if abs(np.linalg.det(matrix[:3, :3])) < 1e-12:
        raise InputError(f"{name}: the matrix is singular and cannot be inverted")
    return matrix


LIMITED_PRECISION_MIN_STEP_FACTOR = 2 ** -10
"""The finest ``step_factor`` of a backend that composites in float32 (or VTK's fixed point).

A step's opacity ``1 − (1 − α)^(Δ/Δ0)`` shrinks with the step, and a faint entry of an 8-bit
table (α = 1/255) corrected for 1/1024 voxel is 3.8e-6, 64 float32 units below 1: finer steps
round such samples towards nothing and the picture fades (at ``step_factor=1e-5`` gl-peel,
vtk-cpu and vtk-gpu render a blank image; at 1e-3 all of them are within 0.5 % of their 0.5
image), and the many more steps cost time without a better picture. The reference computes in
float64 and has no such bound."""


def check_step_factor(value, *, name, minimum=LIMITED_PRECISION_MIN_STEP_FACTOR):
    """Return ``value`` as a finite ``step_factor`` no finer than ``minimum`` voxels.

    Parameters
    ----------
    value : float
        Candidate step, in units of the smallest world-space voxel edge.
    name : str
        How the option is named in messages (``"gl-peel option step_factor"``).
    minimum : float, optional
        The finest step the backend's arithmetic resolves (see
        :data:`LIMITED_PRECISION_MIN_STEP_FACTOR`).
    """
    value = check_scalar(value, name=name, low=0, low_open=True)
    if value < minimum:
        raise InputError(f"{name}: {value:g} is finer than this backend's float32 (or fixed-point) compositing "
                         f"resolves: a faint sample's opacity rounds to nothing below {minimum:.3g} voxel and the "
                         "picture fades; "
                         f"use step_factor ≥ {minimum:.3g}, or the reference backend (float64) for finer steps")
    return value
