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

Perspective (eqs. A.8–A.17, ``perspective=True``)
------------------------------------------------
``M_view`` is then projective: image ``x = row0·p / row3·p``, ``y = row1·p / row3·p`` (row 3 is the
depth in front of the eye; row 2 only orders depth and is unused).

1. **Eye** (A.8–A.11): the homogeneous point ``e`` with ``row0·e = row1·e = row3·e = 0`` (every ray
   passes through it), by cofactors of those three rows (the generalised cross product, Cramer's
   rule with the common factor dropped); ``e_w ≠ 0`` for a perspective view and the eye is
   ``e[:3]/e_w``. (With ``row3 = (0, 0, 0, 1)`` the same cofactors give ``e_w = 0`` and the view
   direction of A.1.)
2. **Principal axis** (A.12): for each of the 8 corners ``c`` of the object box
   ``[−½, n − ½]³`` (cell-centred voxels) the axis of the largest ``|c − e|`` component and its
   sign. When the 8 corners agree, that axis (the thesis's rule). When they do not, the thesis
   splits the volume along 45° planes through the eye into up to six pyramidal sub-volumes,
   rendered separately (§4.2.5; *not implemented here*); this module instead keeps one axis, the
   one among the axes whose slab the eye lies outside of (``c_k − e_k`` of one sign over the box)
   with the smallest worst-case ray-to-slice-normal angle, and records that angle
   (``max_ray_angle``: above 45° some rays sample slices more than √2 voxels apart and quality
   degrades, as the thesis says). No axis qualifies exactly when the eye is inside the box: that
   is refused with an :class:`InputError` naming the fix (move the camera out of the volume).
3. **Slices** are projected from the eye onto the *front* slice plane ``k_f`` (the slice nearest
   the eye): slice ``k`` is scaled by ``f_k = (k_f − e_k)/(k − e_k)`` (1 at the front, ``< 1``
   behind it: slices are only ever decimated, A.15) about the eye's foot point, so slice ``k``'s
   voxel ``(i, j)`` lands at ``(u, v) = (f_k·i + (1 − f_k)·e_i + t_u, f_k·j + (1 − f_k)·e_j + t_v)``.
   This is A.14 with the scale renormalised to the front slice; no ``T_shift`` is needed because
   ``k_f − e_k ≠ 0`` always holds for an eye outside the box (A.13's ``T_shift`` only avoids
   ``e_k = 0`` in A.14's division, which this form never performs). ``M_shear`` is the 4×4
   projective matrix of this map (``u = U/H``, ``v = V/H``, ``H = (k − e_k)/(k_f − e_k)``).
4. **Translation** ``(t_u, t_v)``: the smallest integer pixel any slice's resampling footprint
   touches (box-filter support ``½ + ½/f_k`` voxels about each sample) is pixel 0.
5. **Warp** (A.17): intermediate ``(u, v)`` is the point ``(u − t_u, v − t_v, k_f)`` of the front
   slice, so ``M_warp = M'_view[(0, 1, 3)] · B`` with ``B`` that 4×3 embedding: a projective 3×3.
6. **Slice order**: front to back away from the eye (``+1`` when ``e_k`` is below the box).
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
        ``(s_i, s_j)``; perspective: ``(e_i, e_j)/(k_f − e_k)`` (A.14's shear of the eye's ray).
    reference_slice : tuple of int
        ``(k_u, k_v)``: the slices whose ``u`` and ``v`` offsets are 0 (perspective: the front slice).
    perspective : bool
        A perspective factorization: slices scaled by :meth:`slice_scale`, projective ``warp``.
    eye_ijk : tuple of float or None
        Perspective: the eye in standard object coordinates.
    front_slice : int
        Perspective: the slice nearest the eye (scale 1).
    translation : tuple of float
        Perspective: ``(t_u, t_v)``, integers.
    max_ray_angle : float
        Perspective: the largest angle (degrees) between a ray to a box corner and the principal
        axis (the thesis's rule keeps it at or below about 45°; module notes).
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
    perspective: bool = False
    eye_ijk: tuple = None
    front_slice: int = 0
    translation: tuple = (0.0, 0.0)
    max_ray_angle: float = 0.0

    def slice_offset(self, k):
        """``(u0, v0)``: where voxel ``(0, 0)`` of slice ``k`` lands in the intermediate image.

        ``k`` may be an array. Parallel: the offsets are ``s·(k − k_ref)``, exact zeros at the
        reference slice and never negative. Perspective: ``(1 − f_k)·(e_i, e_j) + (t_u, t_v)``
        (slice ``k`` scaled by ``f_k`` about the eye's foot point, then translated).
        """
        k = np.asarray(k, dtype=np.float64)
        if self.perspective:
            f = self.slice_scale(k)
            e_i, e_j, _ = self.eye_ijk
            t_u, t_v = self.translation
            return (1.0 - f) * e_i + t_u, (1.0 - f) * e_j + t_v
        s_i, s_j = self.shear_ij
        return s_i * (k - self.reference_slice[0]), s_j * (k - self.reference_slice[1])

    def slice_scale(self, k):
        """Scale of slice ``k`` in the intermediate image: 1 for a parallel projection.

        Perspective: ``f_k = (k_f − e_k)/(k − e_k)``, 1 at the front slice ``k_f`` and ``< 1``
        behind it (A.14–A.15).
        """
        k = np.asarray(k, dtype=np.float64)
        if self.perspective:
            e_k = self.eye_ijk[2]
            return (self.front_slice - e_k) / (k - e_k)
        return np.ones_like(k)

    def ray_step_ijk(self, u, v):
        """Perspective: standard-object-space step from one slice to the next along the ray of
        intermediate pixel ``(u, v)`` (arrays), shape ``(..., 3)``, with ``|k component| = 1``.

        The ray goes from the eye through the front-slice point ``(u − t_u, v − t_v, k_f)``.
        """
        if not self.perspective:
            raise ValueError("ray_step_ijk is for perspective factorizations; use step_ijk")
        u = np.asarray(u, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
        e_i, e_j, e_k = self.eye_ijk
        t_u, t_v = self.translation
        depth = self.front_slice - e_k
        return np.stack([(u - t_u - e_i) / depth, (v - t_v - e_j) / depth, np.full(np.broadcast(u, v).shape, 1.0)],
                        axis=-1) * np.sign(depth)

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
        Perspective factorization (A.8–A.17) of a projective ``view_matrix`` (module notes).

    Returns
    -------
    Factorization
    """
    m = np.asarray(view_matrix, dtype=np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise InputError(f"shear-warp factorization: expected a finite 4×4 view matrix, got shape {m.shape}")
    if perspective:
        return _factorize_perspective(m, shape_xyz)
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


def eye_homogeneous(view_matrix):
    """Homogeneous object-space eye ``e`` with ``row0·e = row1·e = row3·e = 0`` (A.8–A.11).

    Cofactor expansion: ``e_c = (−1)^c·det`` of rows 0, 1, 3 with column ``c`` deleted (the common
    factor ``|M_view|`` dropped). Parallel views give ``e_w = 0`` and ``e[:3]`` along the view axis.
    """
    m = np.asarray(view_matrix, dtype=np.float64)[[0, 1, 3]]
    return np.array([(-1.0) ** c * np.linalg.det(np.delete(m, c, axis=1)) for c in range(4)])


def _factorize_perspective(m, shape_xyz):
    shape = tuple(int(n) for n in shape_xyz)
    if len(shape) != 3 or min(shape) < 1:
        raise InputError(f"shear-warp factorization: expected three positive dimensions, got {shape_xyz}")
    if np.allclose(m[3, :3], 0.0):
        raise InputError("shear-warp perspective factorization: the view matrix is affine (its last row is "
                         f"{m[3].tolist()}); use perspective=False for a parallel projection")
    e_h = eye_homogeneous(m)
    scale = np.abs(e_h).max()
    if not np.isfinite(scale) or scale == 0.0 or abs(e_h[3]) <= 1e-12 * scale:
        raise InputError("shear-warp perspective factorization: the view matrix is singular or has no finite "
                         "eye (rows x, y and w must be independent with a finite centre of projection)")
    eye = e_h[:3] / e_h[3]
    lo = np.full(3, -0.5)
    hi = np.array(shape, dtype=np.float64) - 0.5
    if np.all(eye > lo) and np.all(eye < hi):
        raise InputError(f"shear-warp perspective: the eye {eye.round(3).tolist()} (voxel coordinates) is inside the "
                         f"volume box [-0.5, n - 0.5] of shape {shape}; shear-warp needs every ray to cross the "
                         "slices from one side: move the camera out of the volume (larger distance)")
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    rays = corners - eye
    lengths = np.linalg.norm(rays, axis=1)
    rays = rays[lengths > 0]
    lengths = lengths[lengths > 0]
    # A.12: the principal axis of each corner's ray; the thesis needs them to agree (axis and sign).
    corner_axes = np.argmax(np.abs(rays), axis=1)
    candidates = []
    for a in range(3):
        signs = np.sign(rays[:, a])
        if np.all(signs == signs[0]) and signs[0] != 0:
            worst = float(np.degrees(np.arccos(np.min(np.abs(rays[:, a]) / lengths))))
            candidates.append((worst, a))
    if not candidates:  # unreachable for an eye outside the box; kept as the explicit refusal
        raise InputError("shear-warp perspective: no principal axis has every viewing ray crossing the slices "
                         "from one side (the eye is within the volume's extent along every axis); move the "
                         "camera farther from the volume (the thesis splits the volume into pyramidal "
                         "sub-volumes, §4.2.5, not implemented)")
    if np.all(corner_axes == corner_axes[0]) and any(a == corner_axes[0] for _, a in candidates):
        axis = int(corner_axes[0])
        worst = next(w for w, a in candidates if a == axis)
    else:
        worst, axis = min(candidates)
    perm = permutation_matrix(axis)
    mp = m @ perm.T
    e_i, e_j, e_k = (float(eye[a]) for a in axes_ijk(axis))
    n_i, n_j, n_k = (shape[a] for a in axes_ijk(axis))
    k_last = n_k - 1
    order = 1 if e_k < 0 else -1  # e_k < -0.5 (below the box) or > n_k - 0.5 (above)
    k_front = 0 if order > 0 else k_last
    ks = np.arange(n_k, dtype=np.float64)
    f = (k_front - e_k) / (ks - e_k)
    # Footprint of each slice (box-filter support ½ + ½/f voxels about the voxel centres), before translation.
    a_u = (1.0 - f) * e_i
    a_v = (1.0 - f) * e_j
    low_u = np.min(a_u - 0.5 * f - 0.5)
    low_v = np.min(a_v - 0.5 * f - 0.5)
    high_u = np.max(a_u + f * (n_i - 0.5) + 0.5)
    high_v = np.max(a_v + f * (n_j - 0.5) + 0.5)
    # Pixel 0 is the first integer strictly above the lowest bound.
    t_u = -(np.floor(low_u) + 1.0)
    t_v = -(np.floor(low_v) + 1.0)
    width = int(np.ceil(high_u) - 1.0 - np.floor(low_u))
    height = int(np.ceil(high_v) - 1.0 - np.floor(low_v))
    depth = k_front - e_k
    # M_shear: (U, V, W, H) with u = U/H, v = V/H, H = (k − e_k)/(k_f − e_k) = 1/f_k.
    shear = np.array([
        [1.0, 0.0, (e_i + t_u) / depth, (-e_i * k_front - t_u * e_k) / depth],
        [0.0, 1.0, (e_j + t_v) / depth, (-e_j * k_front - t_v * e_k) / depth],
        [0.0, 0.0, 1.0 / depth, -e_k / depth],
        [0.0, 0.0, 1.0 / depth, -e_k / depth],
    ])
    shear[2] = (0.0, 0.0, 1.0, 0.0)  # w = k/H: depth order only
    embed = np.array([[1.0, 0.0, -t_u], [0.0, 1.0, -t_v], [0.0, 0.0, float(k_front)], [0.0, 0.0, 1.0]])
    warp = mp[[0, 1, 3]] @ embed
    return Factorization(
        axis=axis, permutation=perm, shear=shear, warp=warp, intermediate_shape=(height, width), slice_order=order,
        shape_ijk=(n_i, n_j, n_k), shear_ij=(float(e_i / depth), float(e_j / depth)), reference_slice=(k_front, k_front),
        perspective=True, eye_ijk=(e_i, e_j, e_k), front_slice=k_front, translation=(float(t_u), float(t_v)),
        max_ray_angle=worst,
    )
