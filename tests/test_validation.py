"""core.validation: every helper turns malformed input into an InputError naming it."""

import math

import numpy as np
import pytest

from core.errors import InputError
from core.validation import (LIMITED_PRECISION_MIN_STEP_FACTOR, check_finite_vector, check_matrix4,
                             check_positive_vector, check_scalar, check_step_factor, check_value_range)
from core.volume import Volume


@pytest.mark.parametrize("value", ["fast", "1,2,3", [1, "two", 3], [1, 2], [1, 2, 3, 4], 5, None, [True, 1, 1]])
def test_vectors_refuse_non_numbers_with_the_name(value):
    with pytest.raises(InputError, match="spacing"):
        check_positive_vector(value, length=3, name="spacing")
    with pytest.raises(InputError, match="translate"):
        check_finite_vector(value, length=3, name="translate")


def test_vectors_accept_numbers_and_numeric_arrays():
    assert check_positive_vector(np.array([1, 2.5, 3]), length=3, name="s") == (1.0, 2.5, 3.0)
    assert check_finite_vector((0, -1, 2), length=3, name="t") == (0.0, -1.0, 2.0)


@pytest.mark.parametrize("value, match", [
    ([0, math.inf], "finite"), ([-math.inf, 1], "finite"), ([0, math.nan], "finite"),
    ([0, "high"], "numbers"), ("0 1", "numbers"), ([1], "numbers"), ([2, 1], "lo < hi"), ([1, 1], "lo < hi"),
])
def test_value_range(value, match):
    with pytest.raises(InputError, match=f"value_range.*{match}"):
        check_value_range(value, name="value_range")
    assert check_value_range([0, 4095], name="value_range") == (0.0, 4095.0)


def test_matrix_of_non_numbers():
    with pytest.raises(InputError, match="m: expected a 4x4 matrix of numbers"):
        check_matrix4("x", name="m")
    with pytest.raises(InputError, match="m: expected a 4x4 matrix"):
        check_matrix4([[1, 2], [3, 4]], name="m")


def test_scalar_refuses_text_and_non_finite():
    with pytest.raises(InputError, match="degrees: expected a number"):
        check_scalar("x", name="degrees")
    with pytest.raises(InputError, match="degrees"):
        check_scalar(math.inf, name="degrees")


def test_volume_value_range_must_be_finite():
    data = np.arange(8, dtype=np.uint8).reshape(2, 2, 2)
    with pytest.raises(InputError, match="value_range: both ends must be finite"):
        Volume(data, value_range=(0, math.inf))
    with pytest.raises(InputError, match="value_range"):
        Volume(data, value_range=(0, "high"))


def test_float_volume_outside_unit_range_asks_for_a_value_range():
    data = np.linspace(-2, 5, 8, dtype=np.float32).reshape(2, 2, 2)
    with pytest.raises(InputError, match=r"float32 values span \[-2, 5\].*set value_range"):
        Volume(data, name="density")
    volume = Volume(data, value_range=(-2, 5))
    np.testing.assert_allclose(volume.normalized().ravel(), np.linspace(0, 1, 8), atol=1e-6)
    Volume(np.linspace(0, 1, 8, dtype=np.float32).reshape(2, 2, 2))  # inside [0, 1]: fine


def test_normalisation_clips_to_the_unit_interval():
    data = np.array([0, 25, 50, 75, 100, 150, 200, 255], np.uint8).reshape(2, 2, 2)
    normalized = Volume(data, value_range=(50, 150)).normalized()
    np.testing.assert_allclose(normalized.ravel(), [0, 0, 0, 0.25, 0.5, 1, 1, 1], atol=1e-7)
    assert normalized.dtype == np.float32
    assert normalized.min() == 0 and normalized.max() == 1


def test_a_step_finer_than_float32_compositing_resolves_is_refused_naming_the_reference():
    assert check_step_factor(LIMITED_PRECISION_MIN_STEP_FACTOR, name="b option step_factor") == 2 ** -10
    assert check_step_factor(0.25, name="b option step_factor") == 0.25
    with pytest.raises(InputError, match=r"^b option step_factor: 1e-05 is finer than .* use step_factor ≥ 0.000977, "
                                         r"or the reference backend \(float64\) for finer steps$"):
        check_step_factor(1e-5, name="b option step_factor")
    for bad in (0, -1, math.nan, "fine"):
        with pytest.raises(InputError, match="b option step_factor"):
            check_step_factor(bad, name="b option step_factor")
