"""Empty-space skipping data (Krüger & Westermann 2003, Sec. 2.3): a min–max block grid and the
CT(min, max) visibility table, built on the CPU in NumPy.

* :func:`block_minmax`: one level of a min–max octree, disjoint blocks of ``block_size³`` voxels
  (the paper: 8³). Each block's range covers its voxels **plus a one-voxel apron**: a trilinear
  sample in a block's cells (voxel coordinates ``u ∈ [bB − ½, (b + 1)B − ½)`` per axis, the cells
  of voxels ``bB … (b + 1)B − 1``) blends voxels ``⌊u⌋`` and ``⌊u⌋ + 1``, i.e. voxels
  ``bB − 1 … (b + 1)B``, so the apron makes the range hold every value a sample in the block can
  take (and half a voxel to spare against rounding). Ranges are quantised outwards to
  :data:`LEVELS` levels of the normalised scalar (minimum down, maximum up) with a slack of
  :data:`_ROUNDING` levels, so they also hold the scalars the GPU computes from them: an 8-bit
  value ``v`` gets the range ``[v − 1, v + 1]``, because the float32 scalar and its table
  address may round to just below ``v`` and touch entry ``v − 1`` with a vanishing weight.
* :func:`visibility_table`: ``CT[max, min]`` (row = maximum level) is 1 where some transfer-
  function entry that a scalar in ``[min, max]`` can blend with a non-zero weight has opacity
  above ``min_opacity``. It is rebuilt whenever the transfer function
  changes, from a prefix sum over the table (the paper's "recomputed on the CPU").

With ``min_opacity = 0`` (the paper's "at least one colour component is non-zero") a block the
table calls empty contributes exactly nothing to any ray, so skipping it changes no pixel.
"""

import numpy as np

LEVELS = 256
"""Quantisation of block ranges and size of the CT table's axes (8-bit scalars are exact)."""

_ROUNDING = 1e-4
"""Slack, in levels, added before quantising block ranges outwards (float32 rounding is ~1e-5 levels)."""


def _block_reduce(field, block_size, reduce):
    """``reduce`` over each ``block_size³`` block's voxels and its one-voxel apron (edge blocks partial).

    A box is the product of its three ranges, so the reduction goes an axis at a time, each pass
    shrinking that axis to its block count: per axis, a block's voxels ``bB … (b + 1)B − 1`` and the
    voxels either side of them, clamped to the volume.
    """
    out = field
    for axis in range(3):  # the outermost first: reducing over it combines whole contiguous slabs
        n = out.shape[axis]
        count = -(-n // block_size)
        if count * block_size != n:
            out = np.pad(out, [(0, count * block_size - n) if a == axis else (0, 0) for a in range(3)], mode="edge")
        shape = out.shape
        inner = reduce.reduce(out.reshape(shape[:axis] + (count, block_size) + shape[axis + 1:]), axis=axis + 1)
        starts = np.arange(count) * block_size
        before = np.take(out, np.maximum(starts - 1, 0), axis=axis)
        after = np.take(out, np.minimum(starts + block_size, n - 1), axis=axis)
        out = reduce(reduce(inner, before), after)
    return out


def block_minmax(normalised, block_size):
    """Quantised min and max per block, each voxel's one-voxel apron included.

    Parameters
    ----------
    normalised : numpy.ndarray
        ``(nz, ny, nx)`` normalised scalars in [0, 1].
    block_size : int
        Voxels per block edge.

    Returns
    -------
    numpy.ndarray
        ``(bz, by, bx, 2)`` uint8: quantised minimum (rounded down) and maximum (rounded up),
        ``b = ceil(n / block_size)`` per axis.
    """
    low = _block_reduce(normalised, block_size, np.minimum)
    high = _block_reduce(normalised, block_size, np.maximum)
    top = LEVELS - 1
    qmin = np.clip(np.floor(low.astype(np.float64) * top - _ROUNDING), 0, top)
    qmax = np.clip(np.ceil(high.astype(np.float64) * top + _ROUNDING), 0, top)
    return np.ascontiguousarray(np.stack([qmin, qmax], axis=-1).astype(np.uint8))


def visibility_table(table_alpha, min_opacity):
    """The CT table: ``ct[max_level, min_level]`` is 1 where the range can be visible.

    Parameters
    ----------
    table_alpha : numpy.ndarray
        ``(N,)`` transfer-function opacities, entry ``i`` at ``s = i/(N − 1)``.
    min_opacity : float
        Entries with opacity at or below it count as empty.

    Returns
    -------
    numpy.ndarray
        ``(LEVELS, LEVELS)`` uint8; entries with ``min > max`` (never looked up) are 1.
    """
    alpha = np.asarray(table_alpha, dtype=np.float64)
    n = alpha.size
    prefix = np.concatenate([[0], np.cumsum(alpha > min_opacity)])
    levels = np.arange(LEVELS) / (LEVELS - 1) * (n - 1)
    # A scalar in [lo, hi] blends entries floor(lo·(N−1)) … ceil(hi·(N−1)) with non-zero weights
    # (the block ranges carry the slack for rounding; 1e-9 only absorbs this product's own).
    first = np.clip(np.floor(levels + 1e-9).astype(np.int64), 0, n - 1)
    last = np.clip(np.ceil(levels - 1e-9).astype(np.int64), 0, n - 1)
    visible = prefix[last[:, None] + 1] - prefix[first[None, :]] > 0
    visible |= np.arange(LEVELS)[None, :] > np.arange(LEVELS)[:, None]
    return np.ascontiguousarray(visible.astype(np.uint8))
