"""Numba pieces the CPU backends share, so that they classify by one rule.

Imported only by backends that use Numba (the reference and shear-warp), never by
:mod:`renderers.base` itself, so the registry and the GPU backends do not need Numba.
"""

import math

from numba import njit

JIT = dict(cache=True, fastmath=False, nogil=True, error_model="numpy")
"""Options of every shared kernel: cached, IEEE arithmetic (bit-reproducible), no GIL."""


@njit(**JIT)
def table_position(x, size):
    """Lower entry and weight of ``x`` in [0, 1] on a table of ``size`` entries (clamped at the ends).

    Entry ``i`` sits at ``x = i/(size − 1)``, the rule of
    :meth:`core.transfer.TransferFunction.lookup`.
    """
    if x <= 0.0:
        return 0, 0.0
    if x >= 1.0:
        return size - 2, 1.0
    f = x * (size - 1)
    i0 = min(int(math.floor(f)), size - 2)
    return i0, f - i0

