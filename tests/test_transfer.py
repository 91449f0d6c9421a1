import numpy as np
import pytest

from core.errors import InputError
from core.transfer import GradientOpacity, TransferFunction, correct_opacity, volpack_density_ramp


def test_entries_sit_at_i_over_n_minus_one():
    tf = TransferFunction.from_points([(0, 0, 0, 0, 0), (1, 1, 1, 1, 1)], size=256)
    np.testing.assert_allclose(tf.table[:, 3], np.arange(256) / 255, atol=1e-6)
    np.testing.assert_allclose(tf.lookup(100 / 255)[3], 100 / 255, atol=1e-6)


def test_lookup_interpolates_linearly_and_clamps():
    table = np.zeros((3, 4), np.float32)
    table[:, 3] = (0.0, 1.0, 0.0)
    tf = TransferFunction(table)
    np.testing.assert_allclose(tf.lookup([0.25, 0.5, 0.75, -1, 2])[:, 3], (0.5, 1, 0.5, 0, 0))


def test_ramp_and_step():
    ramp = TransferFunction.ramp(0.2, 0.6, alpha=0.8)
    assert ramp.lookup(0.1)[3] == 0
    assert ramp.lookup(0.4)[3] == pytest.approx(0.4, abs=0.01)
    assert ramp.lookup(0.9)[3] == pytest.approx(0.8)
    step = TransferFunction.step(0.5)
    assert step.table[127, 3] == 0 and step.table[128, 3] == 1
    assert step.nonzero_threshold() == pytest.approx(128 / 255)


def test_opacity_correction_composes_over_steps():
    alpha = 0.3
    half = correct_opacity(alpha, 0.5, 1.0)
    # Two half steps absorb exactly as much as one full step.
    assert 1 - (1 - half) ** 2 == pytest.approx(alpha)
    assert correct_opacity(alpha, 1.0, 1.0) == pytest.approx(alpha)


def test_volpack_preset_has_gradient_ramp():
    preset = volpack_density_ramp()
    assert preset.gradient_opacity.lookup(0.0) == 0
    assert preset.gradient_opacity.lookup(20 / 221) == pytest.approx(1.0, abs=0.01)
    assert preset.transfer_function.lookup(24 / 255)[3] == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("table, match", [
    (np.full((4, 4), 1.5), r"\[0, 1\]"),
    (np.full((4, 3), 0.5), "shape"),
    (np.full((4, 4), np.nan), "NaN"),
])
def test_bad_tables_are_rejected(table, match):
    with pytest.raises(InputError, match=match):
        TransferFunction(table, name="bad")


def test_bad_control_points_are_rejected():
    with pytest.raises(InputError, match="non-decreasing"):
        TransferFunction.from_points([(0.5, 0, 0, 0, 0), (0.2, 1, 1, 1, 1)])
    with pytest.raises(InputError, match=r"\[0, 1\]"):
        GradientOpacity.from_points([(0, 0), (1.5, 1)])


def test_lookup_at_and_past_one_is_the_last_entry_exactly():
    """s >= 1 classifies as entry N − 1 (not N − 2), s <= 0 as entry 0; the last two entries differ."""
    table = np.zeros((6, 4), np.float32)
    table[:, 0] = np.linspace(0.1, 0.5, 6)
    table[:, 3] = np.linspace(0.0, 0.4, 6)
    table[-1] = (0.9, 0.8, 0.7, 1.0)
    tf = TransferFunction(table)
    last = table[-1].astype(np.float64)
    for s in (1.0, 1.0 + 1e-12, 1.5, 40.0):
        np.testing.assert_array_equal(tf.lookup(s), last)
    np.testing.assert_array_equal(tf.lookup([1.0, 2.0]), [last, last])
    np.testing.assert_array_equal(tf.lookup([0.0, -3.0]), np.float64(table[[0, 0]]))
    # Just below 1 the lookup still blends towards the last entry.
    assert tf.lookup(1 - 1e-3)[3] > table[-2, 3]
