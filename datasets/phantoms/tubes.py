"""Thin tubes with a known iso-surface: the stability atlas's thin-feature control.

Each tube is a straight segment along z through voxel centres with a linear radial ramp about it, so that the
trilinear field of its voxels crosses 0.5 at the tube's radius ``R`` along the lattice directions for any
``R > 0``, however far below a voxel: a sampled iso-surface hit steps over a tube thinner than its step,
an exact one (the reference's cell walk) does not.
"""

import numpy as np

from core.errors import InputError
from core.volume import Volume

TUBE_SPACING = 10
"""Voxels between neighbouring tube axes: each tube owns a slab this wide, wholly inside the box; its axis ends
half of it before the first and the last z slice."""

MAX_RADIUS = TUBE_SPACING / 2 - 1
"""The widest tube whose ramp (zero from ``R + 1`` voxels out) stays inside its slab, apart from its neighbours."""

MIN_RADIUS = 0.05
"""The thinnest tube: rounding to 8 bits moves the surface by up to 0.004 voxel, a tenth of this radius."""


def tube_axes(size):
    """The x index of each tube axis at ``size``: the centre voxel and every ``TUBE_SPACING`` either side whose
    slab fits in the box."""
    centre = size // 2
    reach = min(centre + 0.5, size - 0.5 - centre) - TUBE_SPACING / 2  # room beyond the centre tube's slab
    others = max(0, int(reach // TUBE_SPACING))
    return [centre + k * TUBE_SPACING for k in range(-others, others + 1)]


def tube(size, seed, radius=1.0):
    """Parallel tubes along z of ``radius`` voxels, in a row along x through the centre of a ``size``³ box.

    Every voxel holds ``clip(0.5 + (R − r)/2, 0, 1)`` on 0–255, ``r`` the distance in voxels from its centre to
    the nearest tube axis: the field falls linearly by 0.5 per voxel from 1 inside to 0 beyond ``R + 1``, so
    linear interpolation between voxels crosses 0.5 at ``r = R`` (within the 8-bit rounding, 0.004 voxel)
    along the lattice directions, and the trilinear iso-surface at 0.5 is a tube of radius ≈ ``R`` even for
    ``R`` far below a voxel. The axes pass through voxel centres (y = ``size // 2``, x = :func:`tube_axes`),
    ``TUBE_SPACING`` voxels apart, and end ``TUBE_SPACING / 2`` voxels before the first and the last z slice in
    rounded caps (``r`` there is the distance to the axis's end): each iso-surface is closed, and a ray enters
    the box outside every tube. No noise, so ``seed`` does not change it.

    Parameters
    ----------
    size : int
        Voxels along each edge.
    seed : int
        Unused (the tubes are deterministic).
    radius : float
        The iso-surface's radius in voxels, from ``MIN_RADIUS`` to ``MAX_RADIUS``.
    """
    if (isinstance(radius, bool) or not isinstance(radius, (int, float, np.integer, np.floating))
            or not MIN_RADIUS <= radius <= MAX_RADIUS):
        raise InputError(f"tube radius: expected voxels from {MIN_RADIUS:g} (thinner, the 8-bit rounding moves its "
                         f"surface by a tenth of it) to {MAX_RADIUS:g} (wider, tubes {TUBE_SPACING} voxels apart "
                         f"meet), got {radius!r}")
    index = np.arange(size, dtype=np.float64)
    centre = size // 2
    across = np.min(np.abs(index - np.array(tube_axes(size), dtype=np.float64)[:, None]), axis=0)  # along x
    first, last = min(TUBE_SPACING // 2, centre), max(size - 1 - TUBE_SPACING // 2, centre)
    beyond = np.maximum(0.0, np.maximum(first - index, index - last))  # along z, past an axis's ends
    r = np.sqrt(beyond[:, None, None] ** 2 + (index[None, :, None] - centre) ** 2 + across[None, None, :] ** 2)
    field = np.clip(0.5 + (float(radius) - r) / 2, 0.0, 1.0)
    return Volume(np.rint(255 * field).astype(np.uint8), name="tube")
