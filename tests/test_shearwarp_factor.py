"""Shear-warp building blocks: the factorization, the 2-D warp, normals and the run-length encoding."""

import numpy as np
import pytest

from core.errors import InputError
from core.transfer import GradientOpacity, TransferFunction
from renderers.shearwarp import classify as cl
from renderers.shearwarp.factor import axes_ijk, factorize, permutation_matrix, view_direction
from renderers.shearwarp.warp import warp_image


def rotation(axis, degrees):
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m = np.eye(4)
    m[i, i] = m[j, j] = c
    m[i, j], m[j, i] = -s, s
    return m


def random_view(rng, *, affine=False):
    """A random view: rotation (optionally non-rigid), scale, y flip, translation (image conventions)."""
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    linear = q @ (rng.normal(size=(3, 3)) * 0.3 + np.eye(3) if affine else np.eye(3))
    m = np.eye(4)
    m[:3, :3] = np.diag([2.0, -2.0, -1.0]) @ linear
    m[:3, 3] = rng.uniform(-50, 50, 3)
    return m


def check_factorization(m, shape):
    f = factorize(m, shape)
    rng = np.random.default_rng(1)
    points = np.concatenate([rng.uniform(-1, np.array(shape) + 1, (50, 3)), np.ones((50, 1))], axis=1).T
    image = m @ points
    sheared = f.shear @ f.permutation @ points
    uv1 = np.stack([sheared[0], sheared[1], np.ones(points.shape[1])])
    warped = f.warp @ uv1
    np.testing.assert_allclose(warped[:2], image[:2], atol=1e-9 * max(1.0, np.abs(image).max()))
    # Sheared rays are parallel to k: the view direction has no (u, v) component after the shear.
    d = np.append(view_direction(m), 0.0)
    ray = f.shear @ f.permutation @ d
    np.testing.assert_allclose(ray[:2], 0.0, atol=1e-12 * np.abs(ray).max())
    assert np.sign(ray[2]) == f.slice_order
    # Every slice lands at non-negative offsets inside the intermediate image.
    n_i, n_j, n_k = f.shape_ijk
    u0, v0 = f.slice_offset(np.arange(n_k))
    assert u0.min() == 0.0 and v0.min() == 0.0
    assert np.floor(u0).max() + n_i + 1 <= f.intermediate_shape[1]
    assert np.floor(v0).max() + n_j + 1 <= f.intermediate_shape[0]
    return f


@pytest.mark.parametrize("seed", range(20))
def test_warp_shear_permutation_reproduce_random_views(seed):
    rng = np.random.default_rng(seed)
    check_factorization(random_view(rng, affine=seed % 2 == 1), (17, 11, 7))


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("sign_i", [-1, 1])
@pytest.mark.parametrize("sign_j", [-1, 1])
@pytest.mark.parametrize("backwards", [False, True])
def test_every_principal_axis_and_shear_sign(axis, sign_i, sign_j, backwards):
    # A view direction mostly along `axis` with small components of each sign on the other two.
    i_ax, j_ax, _ = axes_ijk(axis)
    direction = np.zeros(3)
    direction[axis] = -1.0 if backwards else 1.0
    direction[i_ax] = 0.3 * sign_i
    direction[j_ax] = 0.2 * sign_j
    back = -direction / np.linalg.norm(direction)
    helper = np.array([0.0, 0.0, 1.0]) if axis != 2 else np.array([0.0, 1.0, 0.0])
    right = np.cross(helper, back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    m = np.eye(4)
    m[:3, :3] = np.diag([3.0, -3.0, -1.0]) @ np.stack([right, up, back])
    f = check_factorization(m, (9, 10, 11))
    assert f.axis == axis
    assert f.slice_order == (-1 if backwards else 1)
    s_i, s_j = f.shear_ij
    # s = −v_i/v_k: its sign is opposite to the component's sign along the direction of travel.
    travel_sign = -1.0 if backwards else 1.0
    assert np.sign(s_i) == -sign_i * travel_sign and np.sign(s_j) == -sign_j * travel_sign
    np.testing.assert_allclose(f.permutation, permutation_matrix(axis))


def test_principal_axis_switches_at_45_degrees():
    base = np.diag([1.0, -1.0, -1.0, 1.0])
    assert factorize(base @ rotation(1, 44.9), (8, 8, 8)).axis == 2
    assert factorize(base @ rotation(1, 45.1), (8, 8, 8)).axis == 0
    assert factorize(base @ rotation(0, 44.9), (8, 8, 8)).axis == 2
    assert factorize(base @ rotation(0, 45.1), (8, 8, 8)).axis == 1
    # At 45° the spacing ratio peaks at √2 (one axis).
    f = factorize(base @ rotation(1, 44.999), (8, 8, 8))
    assert np.linalg.norm(f.step_xyz()) == pytest.approx(np.sqrt(2), rel=1e-4)


def test_factorize_refuses_bad_views():
    with pytest.raises(InputError, match="singular"):
        factorize(np.diag([1.0, 1.0, 0.0, 1.0]) @ np.diag([0.0, 1.0, 1.0, 1.0]), (4, 4, 4))
    projective = np.eye(4)
    projective[3, 2] = -1
    with pytest.raises(InputError, match="projective"):
        factorize(projective, (4, 4, 4))
    with pytest.raises(InputError, match="affine"):
        factorize(np.eye(4), (4, 4, 4), perspective=True)


# ---------------------------------------------------------------------------------------------
# Warp


def test_identity_warp_at_half_pixel_shift_is_exact():
    rng = np.random.default_rng(0)
    src = rng.uniform(0, 1, (6, 7, 4)).astype(np.float32)
    # Intermediate pixel (r, c) is at (u, v) = (c, r); image pixel centres are at +0.5.
    warp = np.array([[1.0, 0, 0.5], [0, 1.0, 0.5], [0, 0, 1]])
    np.testing.assert_array_equal(warp_image(src, warp, (6, 7)), src)


def test_affine_warp_matches_direct_bilinear_sampling():
    rng = np.random.default_rng(1)
    src = rng.uniform(0, 1, (9, 8, 4)).astype(np.float32)
    warp = np.array([[1.7, 0.4, 2.0], [-0.3, 1.2, 3.0], [0, 0, 1]])
    out = warp_image(src, warp, (20, 18))
    inverse = np.linalg.inv(warp)
    for row, col in [(5, 6), (10, 3), (12, 12), (0, 0), (19, 17)]:
        u, v, _ = inverse @ (col + 0.5, row + 0.5, 1.0)
        u0, v0 = int(np.floor(u)), int(np.floor(v))
        expected = np.zeros(4)
        for dv in (0, 1):
            for du in (0, 1):
                if 0 <= v0 + dv < 9 and 0 <= u0 + du < 8:
                    w = (v - v0 if dv else 1 - (v - v0)) * (u - u0 if du else 1 - (u - u0))
                    expected += w * src[v0 + dv, u0 + du]
        np.testing.assert_allclose(out[row, col], expected, atol=1e-6)


def test_projective_warp_divides_by_w():
    src = np.zeros((10, 10, 4), np.float32)
    src[4, 6] = 1.0
    # x = 2u / (0.1u + 1), y = v / (0.1u + 1): intermediate pixel (u, v) = (6, 4) lands exactly on the
    # centre (7.5, 2.5) of image pixel (row 2, column 7).
    warp = np.array([[2.0, 0, 0], [0, 1.0, 0], [0.1, 0, 1.0]])
    out = warp_image(src, warp, (10, 10))
    assert out[2, 7, 3] == pytest.approx(1.0, abs=1e-6)
    assert out[2, 6, 3] < 1.0 and out[3, 7, 3] < 1.0


def test_warp_rejects_bad_inputs():
    with pytest.raises(InputError, match="intermediate"):
        warp_image(np.zeros((4, 4, 3), np.float32), np.eye(3), (4, 4))
    with pytest.raises(InputError, match="singular"):
        warp_image(np.zeros((4, 4, 4), np.float32), np.zeros((3, 3)), (4, 4))


# ---------------------------------------------------------------------------------------------
# Normals, classification, RLE


def test_normal_codes_round_trip_within_the_grid_resolution():
    rng = np.random.default_rng(2)
    vectors = rng.normal(size=(5000, 3))
    codes = np.array([cl.encode_normal(*v) for v in vectors])
    assert codes.min() >= 0 and codes.max() < cl.NO_NORMAL
    decoded = cl.NORMAL_DIRECTIONS[codes]
    unit = vectors / np.linalg.norm(vectors, axis=1, keepdims=True)
    angles = np.degrees(np.arccos(np.clip((decoded * unit).sum(axis=1), -1, 1)))
    assert angles.max() < 3.5 and np.median(angles) < 1.5
    assert cl.encode_normal(0.0, 0.0, 0.0) == cl.NO_NORMAL
    assert np.all(cl.NORMAL_DIRECTIONS[cl.NO_NORMAL] == 0)


def classified_field(seed=0, shape=(9, 12, 300)):
    """A field with long transparent and non-transparent runs (over 255) and short ones."""
    rng = np.random.default_rng(seed)
    field = rng.uniform(0, 1, shape).astype(np.float32)
    field[:, :, :280] = np.where(rng.uniform(size=(shape[0], shape[1], 1)) < 0.5, 0.9, 0.0)
    field[3] = 0.0  # a fully transparent slice
    tf = TransferFunction.ramp(0.2, 0.8)
    return cl.classify(field, (1.0, 1.0, 1.0), tf, None, 1.0, 0.05, gradients=True), field


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_rle_round_trips_the_classified_volume(axis):
    classified, field = classified_field()
    encoding = cl.encode(classified, axis)
    dense = cl.standard_order(classified.records, axis)
    np.testing.assert_array_equal(cl.decode(encoding), dense)
    assert np.all(encoding.lengths <= 255)
    # Every scanline has an even number of alternating runs, transparent first.
    assert np.all(np.diff(encoding.run_offsets) % 2 == 0)
    assert encoding.voxels.size == np.count_nonzero(classified.records)
    assert np.all(encoding.voxels != 0)
    # Gradients travel with their voxels.
    grads = cl.standard_order(classified.gradients, axis)[dense != 0]
    np.testing.assert_array_equal(encoding.gradients, grads)
    brute = cl.dense_encoding(classified, axis)
    np.testing.assert_array_equal(cl.decode(brute), dense)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_run_index_and_extents_hold_where_a_walk_from_the_scanline_start_stands(axis):
    classified, _ = classified_field()
    for encoding in (cl.encode(classified, axis), cl.dense_encoding(classified, axis)):
        ni = encoding.shape_ijk[0]
        index = encoding.run_index
        assert index.shape == (encoding.run_offsets.size - 1, -(-ni // cl.INDEX_STEP), 3)
        assert index.dtype == np.uint16
        for sl in range(0, index.shape[0], 7):
            first, start, data = int(encoding.run_offsets[sl]), 0, 0
            run = first
            for c in range(index.shape[1]):
                position = c * cl.INDEX_STEP
                # The compositing cursor's walk: past every run that ends at or before the position.
                while start + int(encoding.lengths[run]) <= position:
                    data += int(encoding.lengths[run]) if (run - first) % 2 else 0
                    start += int(encoding.lengths[run])
                    run += 1
                assert tuple(index[sl, c]) == (run - first, start, data), (sl, c)
    # Each scanline's extent: its first non-transparent voxel and one past its last.
    for encoding in (cl.encode(classified, axis),):
        dense = cl.standard_order(classified.records, axis).reshape(-1, encoding.shape_ijk[0])
        for sl in range(dense.shape[0]):
            filled = np.flatnonzero(dense[sl])
            expected = (filled[0], filled[-1] + 1) if filled.size else (encoding.shape_ijk[0], 0)
            assert tuple(encoding.extents[sl]) == expected, sl
    assert np.all(cl.dense_encoding(classified, axis).extents == (0, encoding.shape_ijk[0]))
    # Scanlines too long for 16-bit entries get 32-bit ones.
    assert cl.run_index(np.array([255, 0] * 200 + [0], np.uint8)[:-1], np.array([0, 400]), np.array([0, 0]),
                        51000).dtype == np.int32


def test_classification_thresholds_and_quantises_like_the_tables():
    field = np.linspace(0, 1, 4 * 5 * 6, dtype=np.float32).reshape(4, 5, 6)
    tf = TransferFunction.ramp(0.2, 0.8, color=(0.5, 0.25, 1.0))
    classified = cl.classify(field, (1.0, 1.0, 1.0), tf, None, 1.0, 0.05)
    alpha = tf.lookup(field)[..., 3]
    records = classified.records
    transparent = alpha <= 0.05
    assert np.all(records[transparent] == 0)
    np.testing.assert_array_equal(records[~transparent] & 255, np.round(alpha[~transparent] * 255))
    np.testing.assert_array_equal((records[~transparent] >> 8) & 255, np.round(field[~transparent] * 255))
    assert classified.nontransparent == np.count_nonzero(~transparent)
    # A gradient-opacity table of zeros makes everything transparent.
    zero = GradientOpacity(np.zeros(8))
    assert cl.classify(field, (1.0, 1.0, 1.0), tf, zero, 1.0, 0.05).nontransparent == 0


def test_gradients_are_central_differences_with_clamped_edges():
    rng = np.random.default_rng(3)
    field = rng.uniform(0.5, 1, (5, 6, 7)).astype(np.float32)
    classified = cl.classify(field, (2.0, 1.0, 0.5), TransferFunction.constant(alpha=1.0), None, 1.0, 0.05,
                             gradients=True)
    padded = np.pad(field.astype(np.float64), 1, mode="edge")
    gx = (padded[1:-1, 1:-1, 2:] - padded[1:-1, 1:-1, :-2]) / (2 * 2.0)
    gz = (padded[2:, 1:-1, 1:-1] - padded[:-2, 1:-1, 1:-1]) / (2 * 0.5)
    np.testing.assert_allclose(classified.gradients[..., 0], gx, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(classified.gradients[..., 2], gz, rtol=1e-6, atol=1e-7)
