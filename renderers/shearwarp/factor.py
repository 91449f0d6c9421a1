"""The shear-warp factorization of a viewing transformation (Lacroute 1995, §3.2 and appendix A).

Pure NumPy. :func:`factorize` takes ``M_view``, the 4×4 map from voxel-index object coordinates
(voxel ``(i, j, k)`` centre at ``(i, j, k)``) to image coordinates (``x`` right in pixels, pixel
centres at half-integers; ``y`` *down* in pixels, row 0 at the top; ``z`` depth increasing away
from the eye), and factors it as ``M_view = M_warp · M_shear · P`` on the image ``(x, y)``
coordinates:

* ``P`` permutes the object axes so that the *principal viewing axis* (the object axis with the
  largest component of the view direction, eq. A.2) becomes the slice axis ``k``
  (principal x: ``(i, j, k) = (y, z, x)``; y: ``(z, x, y)``; z: ``(x, y, z)``);
* ``M_shear`` shears the standard object space so that every viewing ray is parallel to ``k``
  (eqs. A.4–A.6) and translates it so the whole sheared volume lies at non-negative
  intermediate-image coordinates (the translation of Fig. A.3);
* ``M_warp`` is the 2-D affine map (A.7) from intermediate-image coordinates ``(u, v, 1)`` to
  final-image coordinates ``(x, y, 1)``.

Intermediate-image convention: pixel ``(row, column)`` is centred at ``(u, v) = (column, row)``,
so a voxel ``(i, j)`` of a slice with an integer offset lands exactly on a pixel centre. Slice
``k``'s voxel ``(i, j)`` sits at ``(i + s_i·k + t_i, j + s_j·k + t_j)``; with the translation chosen
here these offsets are ``>= 0`` and are evaluated as ``s_i·(k − k_ref)`` with ``k_ref`` the slice
whose offset is 0, so they are never negative through rounding. The intermediate image is
``(floor(max v offset) + n_j + 1, floor(max u offset) + n_i + 1)`` pixels: each slice covers the
``n_i + 1`` columns from ``floor(u offset)`` (the bilinear footprint of ``n_i`` voxels at a
fractional offset).

The view direction is found with the cofactor formula (A.1), i.e. the cross product of the first
two rows of the linear part, with its sign chosen so that it points away from the eye (increasing
image depth); the slice order is front to back along it (``slice_order = +1``: slice 0 first).

Perspective (eqs. A.8–A.17) is not implemented: ``perspective=True`` raises
:class:`NotImplementedError` (the backend declares orthographic projection only).
"""

from dataclasses import dataclass

import numpy as np

from core.errors import InputError

# (i, j, k) = P·(x, y, z): the rows of P pick the object axis that becomes i, j and k.
_AXES_IJK = {0: (1, 2, 0), 1: (2, 0, 1), 2: (0, 1, 2)}


def permutation_matrix(axis):
    """The 4×4 permutation ``P`` with ``(i, j, k, 1) = P·(x, y, z, 1)`` for principal ``axis``."""
    matrix = np.zeros((4, 4))
    for row, source in enumerate(_AXES_IJK[axis]):
        matrix[row, source] = 1.0
    matrix[3, 3] = 1.0
    return matrix


def axes_ijk(axis):
    """Object axes (0 = x, 1 = y, 2 = z) that become ``(i, j, k)`` for principal ``axis``."""
    return _AXES_IJK[axis]


def view_direction(view_matrix):
    """Object-space direction of the viewing rays, pointing away from the eye (eq. A.1).

    The cofactor formula ``(m12·m23 − m22·m13, m21·m13 − m11·m23, m11·m22 − m21·m12)`` is the
    direction ``d`` with ``M·d`` having no ``x``/``y`` component; it is turned to increase the
    image depth (the sign of ``det`` of the 3×3 linear part).
    """
    m = np.asarray(view_matrix, dtype=np.float64)
    direction = np.array([
        m[0, 1] * m[1, 2] - m[1, 1] * m[0, 2],
        m[1, 0] * m[0, 2] - m[0, 0] * m[1, 2],
        m[0, 0] * m[1, 1] - m[1, 0] * m[0, 1],
    ])
    depth = m[2, :3] @ direction
    if not np.isfinite(depth) or depth == 0.0:
        raise InputError("shear-warp factorization: the view matrix is singular (no view direction)")
    return direction if depth > 0 else -direction


@dataclass(frozen=True)
class Factorization:
    """``M_view = M_warp · M_shear · P`` (on image x, y) for a parallel projection.

    Attributes
    ----------
    axis : int
        Principal object axis (0 = x, 1 = y, 2 = z).
    permutation : numpy.ndarray
        4×4 ``P``, ``(i, j, k, 1) = P·(x, y, z, 1)``.
    shear : numpy.ndarray
        4×4 ``M_shear``: ``u = i + s_i·k + t_i``, ``v = j + s_j·k + t_j``, ``w = k``.
    warp : numpy.ndarray
        3×3 affine ``M_warp`` from ``(u, v, 1)`` to ``(x, y, 1)``.
    intermediate_shape : tuple of int
        ``(height, width)`` of the intermediate image.
    slice_order : int
        ``+1``: slice ``k = 0`` is in front (composite increasing ``k``); ``−1``: the last is.
    shape_ijk : tuple of int
        ``(n_i, n_j, n_k)``: the volume's dimensions in standard object order.
    shear_ij : tuple of float
        ``(s_i, s_j)``.
    reference_slice : tuple of int
        ``(k_u, k_v)``: the slices whose ``u`` and ``v`` offsets are 0.
    """

    axis: int
    permutation: np.ndarray
    shear: np.ndarray
    warp: np.ndarray
    intermediate_shape: tuple
    slice_order: int
    shape_ijk: tuple
    shear_ij: tuple
    reference_slice: tuple

    def slice_offset(self, k):
        """``(u0, v0)``: where voxel ``(0, 0)`` of slice ``k`` lands in the intermediate image (>= 0).

        ``k`` may be an array; the offsets are ``s·(k − k_ref)``, exact zeros at the reference
        slice and never negative.
        """
        k = np.asarray(k, dtype=np.float64)
        s_i, s_j = self.shear_ij
        return s_i * (k - self.reference_slice[0]), s_j * (k - self.reference_slice[1])

    def slice_scale(self, k):
        """Scale of slice ``k`` in the intermediate image: 1 for a parallel projection."""
        return np.ones_like(np.asarray(k, dtype=np.float64))

    def slices_front_to_back(self):
        """Slice indices in compositing order."""
        n_k = self.shape_ijk[2]
        return np.arange(n_k) if self.slice_order > 0 else np.arange(n_k - 1, -1, -1)

    def step_ijk(self):
        """Standard-object-space step along a ray from one slice to the next: ``(−s_i, −s_j, 1)``."""
        s_i, s_j = self.shear_ij
        return np.array([-s_i, -s_j, 1.0])

    def step_xyz(self):
        """The same step in object (voxel-index) coordinates ``(x, y, z)``."""
        step = np.empty(3)
        step[list(axes_ijk(self.axis))] = self.step_ijk()
        return step


def factorize(view_matrix, shape_xyz, *, perspective=False):
    """Factor an affine view matrix for shear-warp rendering of a volume of ``shape_xyz`` voxels.

    Parameters
    ----------
    view_matrix : array_like, shape (4, 4)
        Voxel-index object coordinates → image coordinates (see the module notes).
    shape_xyz : tuple of int
        ``(nx, ny, nz)``.
    perspective : bool
        Perspective factorization (A.8–A.17): not implemented, raises ``NotImplementedError``.

    Returns
    -------
    Factorization
    """
    if perspective:
        raise NotImplementedError("shear-warp perspective factorization (thesis eqs. A.8–A.17) is not implemented")
    m = np.asarray(view_matrix, dtype=np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise InputError(f"shear-warp factorization: expected a finite 4×4 view matrix, got shape {m.shape}")
    if not np.allclose(m[3], (0.0, 0.0, 0.0, 1.0)):
        raise InputError("shear-warp factorization: the view matrix is projective; only affine (parallel) views are supported")
    shape = tuple(int(n) for n in shape_xyz)
    if len(shape) != 3 or min(shape) < 1:
        raise InputError(f"shear-warp factorization: expected three positive dimensions, got {shape_xyz}")

    direction = view_direction(m)
    axis = int(np.argmax(np.abs(direction)))  # ties go to x, then y (A.2)
    perm = permutation_matrix(axis)
    # M'_view = M_view · P⁻¹ (A.3); P is orthogonal, so P⁻¹ = Pᵀ.
    mp = m @ perm.T
    v_so = perm[:3, :3] @ direction
    # Shear coefficients (A.4, A.5): the ray direction (−s_i, −s_j, 1)·v_k keeps x and y fixed.
    denominator = mp[0, 0] * mp[1, 1] - mp[1, 0] * mp[0, 1]
    s_i = (mp[1, 1] * mp[0, 2] - mp[0, 1] * mp[1, 2]) / denominator
    s_j = (mp[0, 0] * mp[1, 2] - mp[1, 0] * mp[0, 2]) / denominator
    n_i, n_j, n_k = (shape[a] for a in axes_ijk(axis))
    k_last = n_k - 1
    # Translation to the intermediate-image origin (Fig. A.3): the slice with the smallest offset
    # along each axis lands at 0.
    k_u = 0 if s_i >= 0 else k_last
    k_v = 0 if s_j >= 0 else k_last
    t_i, t_j = -s_i * k_u, -s_j * k_v
    shear = np.array([[1.0, 0.0, s_i, t_i], [0.0, 1.0, s_j, t_j], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    # Warp (A.7): rows 1–2 of M'_view with the k column dropped, composed with the inverse translation.
    warp = np.array([
        [mp[0, 0], mp[0, 1], mp[0, 3] - t_i * mp[0, 0] - t_j * mp[0, 1]],
        [mp[1, 0], mp[1, 1], mp[1, 3] - t_i * mp[1, 0] - t_j * mp[1, 1]],
        [0.0, 0.0, 1.0],
    ])
    width = int(np.floor(abs(s_i) * k_last)) + n_i + 1
    height = int(np.floor(abs(s_j) * k_last)) + n_j + 1
    return Factorization(
        axis=axis, permutation=perm, shear=shear, warp=warp, intermediate_shape=(height, width),
        slice_order=1 if v_so[2] > 0 else -1, shape_ijk=(n_i, n_j, n_k), shear_ij=(float(s_i), float(s_j)),
        reference_slice=(k_u, k_v),
    )
