"""Seeded noise for the phantoms: band-limited fBm, white Gaussian and Rician (MR) noise.

Every random draw comes from a ``numpy.random.Generator``. A phantom forks one child generator
per component (:func:`fork`), so the number of draws one component makes (which can depend on
``size``) never shifts another: the anatomy drawn for a seed is the same at every size and only
the voxel-level noise differs.

The fBm is value noise on a lattice fixed in normalised coordinates (it always covers the unit
cube ``[-0.5, 0.5]³``, whatever the volume's aspect), reconstructed with the cubic B-spline. The
B-spline is separable, so the lattice is mapped onto the voxel grid with three small dense
matrix products instead of a per-voxel interpolation. Its spectrum falls as sinc⁴, so octaves
whose lattice is finer than :data:`MIN_LATTICE_VOXELS` are left out: the field is band-limited at
every size.
"""

import numpy as np

MIN_LATTICE_VOXELS = 1.5
"""Finest lattice spacing kept, in voxels: the B-spline leaves < 1 % amplitude at Nyquist."""

PERIOD_PER_LATTICE = 5.4
"""Mean zero-crossing period of B-spline value noise, in lattice spacings (measured along lines).

:func:`fbm` takes this period as its ``wavelength``: the distance between two sign changes of
the same direction, i.e. the width of a bump plus a dip.
"""


def fork(rng):
    """An independent child generator; the parent advances by exactly one draw."""
    return np.random.default_rng(int(rng.integers(0, 2**63 - 1)))


def _bspline_matrix(coords, spacing, count):
    """Dense ``(len(coords), count)`` cubic B-spline weights of a lattice with ``spacing``.

    Lattice point ``j`` sits at ``-0.5 + (j - 2)·spacing``; two extra points on each side keep
    every support inside the lattice.
    """
    t = (coords.astype(np.float64) + 0.5) / spacing + 2.0
    base = np.floor(t).astype(np.int64)
    f = t - base
    weights = np.stack([(1 - f) ** 3 / 6, (3 * f**3 - 6 * f**2 + 4) / 6,
                        (-3 * f**3 + 3 * f**2 + 3 * f + 1) / 6, f**3 / 6], axis=1)
    matrix = np.zeros((coords.size, count), dtype=np.float32)
    rows = np.arange(coords.size)
    for k in range(4):
        matrix[rows, base - 1 + k] = weights[:, k]
    return matrix


def value_noise(grid, rng, spacing):
    """One octave of smooth value noise on a lattice of the given ``spacing`` (normalised units)."""
    count = int(np.ceil(1.0 / spacing)) + 5
    lattice = rng.standard_normal((count, count, count), dtype=np.float32)
    wx, wy, wz = (_bspline_matrix(axis, spacing, count) for axis in grid.axes)
    nz, ny, nx = grid.shape
    # Contract x, then y, then z, each as one 2-D matrix product (BLAS), smallest arrays first.
    field = (lattice.reshape(count * count, count) @ np.ascontiguousarray(wx.T)).reshape(count, count, nx)
    field = np.ascontiguousarray(np.tensordot(wy, field, axes=(1, 1)).transpose(1, 0, 2))   # (cz, ny, nx)
    return (wz @ field.reshape(count, ny * nx)).reshape(nz, ny, nx)


def fbm(grid, rng, *, wavelength, octaves=4, gain=0.5, lacunarity=2.0):
    """Fractional Brownian motion, standardised to zero mean and unit standard deviation.

    Parameters
    ----------
    grid : shapes.Grid
    rng : numpy.random.Generator
    wavelength : float
        Mean period of the first (coarsest) octave, normalised units (see
        :data:`PERIOD_PER_LATTICE`).
    octaves : int
        Octaves to sum; each has ``lacunarity`` times the frequency and ``gain`` times the
        amplitude of the previous one. Octaves finer than :data:`MIN_LATTICE_VOXELS` are dropped.
    """
    total = np.zeros(grid.shape, dtype=np.float32)
    amplitude = 1.0
    for octave in range(octaves):
        spacing = wavelength / PERIOD_PER_LATTICE / lacunarity**octave
        if spacing * grid.size < MIN_LATTICE_VOXELS:
            break
        total += np.float32(amplitude) * value_noise(grid, fork(rng), spacing)
        amplitude *= gain
    std = float(total.std())
    total -= np.float32(total.mean())
    if std > 0:
        total /= np.float32(std)
    return total


def add_gaussian(data, rng, sigma):
    """Add white Gaussian noise of standard deviation ``sigma`` to ``data`` in place."""
    data += np.float32(sigma) * rng.standard_normal(data.shape, dtype=np.float32)
    return data


def rician(data, rng, sigma):
    """MR magnitude noise: ``|v + σ·n₁ + i·σ·n₂|`` (Rayleigh where the signal is 0), in place."""
    real = data + np.float32(sigma) * rng.standard_normal(data.shape, dtype=np.float32)
    imag = np.float32(sigma) * rng.standard_normal(data.shape, dtype=np.float32)
    np.sqrt(real * real + imag * imag, out=data)
    return data
