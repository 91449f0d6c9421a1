"""The 2-D warp of the intermediate image into the final image (Lacroute 1995, §4.1.5).

One-pass backward mapping (gather) with a bilinear filter, as in the thesis: every final-image
pixel centre ``(x, y) = (column + ½, row + ½)`` is carried to intermediate-image coordinates
``(u, v, w) = M_warp⁻¹·(x, y, 1)``, divided by ``w`` (1 for an affine warp, any positive value
for a projective one), and the intermediate image is sampled bilinearly with its pixel
``(row, column)`` centred at ``(u, v) = (column, row)`` (the convention of
:mod:`renderers.shearwarp.factor`). Pixels outside the intermediate image are transparent (zero),
so the footprint fades over half a pixel at its border. Premultiplied RGBA is interpolated as is.
Rows are independent, so the ``prange`` over rows gives the same bits on any number of threads.
"""

import math

import numpy as np
from numba import njit, prange

from core.errors import InputError

_JIT = dict(cache=True, fastmath=False, nogil=True, error_model="numpy")


@njit(parallel=True, **_JIT)
def _warp_kernel(src, inverse, out):
    height, width = src.shape[0], src.shape[1]
    out_h, out_w = out.shape[0], out.shape[1]
    a00, a01, a02 = inverse[0, 0], inverse[0, 1], inverse[0, 2]
    a10, a11, a12 = inverse[1, 0], inverse[1, 1], inverse[1, 2]
    a20, a21, a22 = inverse[2, 0], inverse[2, 1], inverse[2, 2]
    for row in prange(out_h):
        y = row + 0.5
        for col in range(out_w):
            x = col + 0.5
            w = a20 * x + a21 * y + a22
            r = g = b = a = 0.0
            if w > 0.0:
                u = (a00 * x + a01 * y + a02) / w
                v = (a10 * x + a11 * y + a12) / w
                if u > -1.0 and v > -1.0 and u < width and v < height:
                    u0 = int(math.floor(u))
                    v0 = int(math.floor(v))
                    fu = u - u0
                    fv = v - v0
                    for dv in range(2):
                        vv = v0 + dv
                        if vv < 0 or vv >= height:
                            continue
                        wv = fv if dv == 1 else 1.0 - fv
                        for du in range(2):
                            uu = u0 + du
                            if uu < 0 or uu >= width:
                                continue
                            weight = wv * (fu if du == 1 else 1.0 - fu)
                            r += weight * src[vv, uu, 0]
                            g += weight * src[vv, uu, 1]
                            b += weight * src[vv, uu, 2]
                            a += weight * src[vv, uu, 3]
            out[row, col, 0] = r
            out[row, col, 1] = g
            out[row, col, 2] = b
            out[row, col, 3] = a


def warp_image(intermediate, warp, out_shape, *, out=None):
    """Warp a premultiplied RGBA intermediate image into the final image.

    Parameters
    ----------
    intermediate : numpy.ndarray, shape (h, w, 4), float32
        Premultiplied RGBA; pixel ``(row, column)`` centred at ``(u, v) = (column, row)``.
    warp : array_like, shape (3, 3)
        ``M_warp`` from ``(u, v, 1)`` to ``(x, y, 1)`` (affine, or projective with a positive
        ``w`` over the picture).
    out_shape : tuple of int
        ``(H, W)`` of the final image.
    out : numpy.ndarray, optional
        ``(H, W, 4)`` float32 array to write into.

    Returns
    -------
    numpy.ndarray
        ``(H, W, 4)`` float32, premultiplied, row 0 at the top; transparent where no
        intermediate pixel maps.
    """
    src = np.asarray(intermediate)
    if src.ndim != 3 or src.shape[2] != 4 or src.dtype != np.float32:
        raise InputError(f"warp_image intermediate: expected an (h, w, 4) float32 array, got {src.dtype} {src.shape}")
    matrix = np.asarray(warp, dtype=np.float64)
    if matrix.shape != (3, 3) or not np.isfinite(matrix).all():
        raise InputError(f"warp_image warp: expected a finite 3×3 matrix, got shape {matrix.shape}")
    try:
        inverse = np.linalg.inv(matrix)
    except np.linalg.LinAlgError:
        raise InputError("warp_image warp: the matrix is singular") from None
    height, width = (int(n) for n in out_shape)
    if out is None:
        out = np.empty((height, width, 4), dtype=np.float32)
    elif out.shape != (height, width, 4) or out.dtype != np.float32:
        raise InputError(f"warp_image out: expected ({height}, {width}, 4) float32, got {out.dtype} {out.shape}")
    if np.array_equal(matrix[2], (0.0, 0.0, 1.0)):
        inverse[2] = (0.0, 0.0, 1.0)  # affine: w is exactly 1 (no rounding in the last row)
    elif inverse[2] @ (0.5 * width, 0.5 * height, 1.0) < 0:
        inverse = -inverse  # projective: the same map, oriented so that w > 0 at the picture centre
    _warp_kernel(np.ascontiguousarray(src), np.ascontiguousarray(inverse), out)
    return out
