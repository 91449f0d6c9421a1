"""Fuzzy volumes: Kainz et al.'s smoke clouds (note 002, C8) and a "golden lady" in a haze
(note 001: the data set whose large fuzzy area defeats both skipping techniques).
"""

import numpy as np

from datasets import noise
from datasets.shapes import Blend, Canvas, Capsule, Ellipsoid, Field, Grid, SmoothUnion, Sphere, rotation
from core.volume import Volume
from core.validation import check_scalar


def _radius(grid, center, radii, rot):
    """Ellipsoidal radius ``|R^T (p − c) / radii|`` over the whole grid."""
    x, y, z = grid.coords()
    d = [x - np.float32(center[0]), y - np.float32(center[1]), z - np.float32(center[2])]
    r = np.zeros(grid.shape, dtype=np.float32)
    for axis in range(3):
        local = sum(np.float32(rot[k, axis]) * d[k] for k in range(3))
        r += (local / np.float32(radii[axis])) ** 2
    return np.sqrt(r, out=r)


def smoke_cloud(size, seed):
    """A puff of smoke: fBm times a radial falloff; the seed varies the shape and the texture.

    The cloud's centre, semi-axes (0.3–0.46 of the box) and orientation are drawn from the seed,
    so fifty seeds give fifty different clouds for the many-volume scene (note 002, C8). Density
    0–255 is highest inside and frays into wisps where the noise cuts the falloff.
    """
    rng = np.random.default_rng(seed)
    shape_rng = noise.fork(rng)
    grid = Grid.for_aspect(size)
    center = shape_rng.uniform(-0.04, 0.04, 3)
    radii = shape_rng.uniform(0.3, 0.46, 3)
    axis = shape_rng.normal(size=3)
    rot = rotation(axis, shape_rng.uniform(0, 180))
    falloff = np.clip(1 - _radius(grid, center, radii, rot), 0, 1)
    field = noise.fbm(grid, noise.fork(rng), wavelength=0.45, octaves=5, gain=0.55)
    density = np.clip(falloff * (1.6 + 0.7 * field) - 0.15, 0, 1)
    return Volume(np.rint(255 * density).astype(np.uint8), name="smoke_cloud")


def _figure():
    """A standing woman in a long dress, arms at her sides, facing −y: solid shapes (normalised)."""
    dress_top, hem = -0.1, -0.46

    def skirt(x, y, z):
        t = np.clip((np.float32(dress_top) - z) / np.float32(dress_top - hem), 0, 1)   # 0 at the waist
        rx, ry = np.float32(0.075) + np.float32(0.13) * t, np.float32(0.06) + np.float32(0.09) * t
        side = (np.sqrt((x / rx) ** 2 + (y / ry) ** 2) - 1) * np.minimum(rx, ry)
        return np.maximum(side, np.maximum(np.float32(hem) - z, z - np.float32(dress_top)))

    body = SmoothUnion(Ellipsoid((0, 0, 0.12), (0.105, 0.065, 0.12)),                 # chest
                       Ellipsoid((0, 0, -0.04), (0.085, 0.06, 0.09)), 0.04)           # waist
    parts = [(Field(skirt, (-0.21, -0.16, hem), (0.21, 0.16, dress_top)), 0.05)]
    parts += [(Sphere((side * 0.04, -0.055, 0.14), 0.04), 0.02) for side in (-1, 1)]  # bust
    parts.append((Capsule((0, 0, 0.22), (0, -0.005, 0.31), 0.027), 0.03))              # neck
    parts.append((SmoothUnion(Ellipsoid((0, -0.005, 0.36), (0.048, 0.056, 0.066)),
                              Sphere((0, 0.04, 0.4), 0.035), 0.02), 0.02))             # head, hair in a bun
    for side in (-1, 1):
        shoulder, elbow = (side * 0.115, 0.0, 0.2), (side * 0.15, 0.01, 0.04)
        wrist = (side * 0.1, -0.07, -0.07)
        arm = SmoothUnion(Capsule(shoulder, elbow, 0.032, 0.026), Capsule(elbow, wrist, 0.025, 0.019), 0.015)
        hand = Ellipsoid((side * 0.085, -0.085, -0.1), (0.018, 0.028, 0.04))
        parts.append((SmoothUnion(arm, hand, 0.012), 0.03))
        parts.append((Ellipsoid((side * 0.05, -0.05, -0.475), (0.03, 0.06, 0.022)), 0.01))  # shoes
    figure = Blend(body, parts)
    return figure


def golden_lady(size, seed, haze=1.0):
    """A standing woman in a long dress (≈205) inside a broad low-density haze (≈30–55), note 001 §5.

    Parameters
    ----------
    haze : float
        Scales the haze's extent (the E11 fuzziness sweep): 0 removes it, 0.5 keeps it near the
        figure, 1 fills about two thirds of the box, 1.5 nearly all of it. The haze is densest
        (≈55) at the figure and falls to the iSBVR iso_t of 30 at its edge, so that the figure
        shows through it.
    """
    haze = check_scalar(haze, name="golden_lady haze", low=0, high=3)
    rng = np.random.default_rng(seed)
    grid = Grid.for_aspect(size)
    canvas = Canvas(grid)
    field = noise.fbm(grid, noise.fork(rng), wavelength=0.25, octaves=3)
    if haze > 0:
        envelope = np.exp(-((_radius(grid, (0, 0, -0.05), (0.45, 0.4, 0.6), np.eye(3)) / haze) ** 2))
        canvas.data[...] = np.clip((55 + 12 * field) * np.sqrt(envelope), 0, None)
    canvas.paint(_figure(), 205 + 6 * field)
    noise.add_gaussian(canvas.data, noise.fork(rng), 2.0)
    return Volume(canvas.to_uint8(), name="golden_lady")
