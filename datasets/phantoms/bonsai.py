"""A bonsai in its pot (note 001 §5, "Bonsai"), shaped after the real CT bonsai: a board, a deep
oval pot full of soil, a flaring, curving trunk, branches and foliage pads of leaf clusters, in
air. Grey levels follow the real scan's: leaves ≈50 (thin, so partial-volume dark), wood ≈150,
soil ≈120, ceramic ≈210, the board ≈55."""

import numpy as np

from datasets import noise
from datasets.phantoms.vessels import grow_tree, paint_tree
from datasets.shapes import Box, Canvas, Capsule, Ellipsoid, Field, Grid
from core.volume import Volume

V = 1 / 256
DISH, SOIL, WOOD, LEAF, BOARD = 210, 120, 150, 50, 55


def _dish(center, radii, height):
    """Solid oval pot: an elliptic cylinder whose sides lean out by 10 % towards the rim."""
    cx, cy, bottom = center
    rx, ry = radii

    def sdf(x, y, z):
        flare = 1 + np.float32(0.1) * np.clip((z - np.float32(bottom)) / np.float32(height), 0, 1)
        k = np.sqrt(((x - np.float32(cx)) / np.float32(rx)) ** 2 + ((y - np.float32(cy)) / np.float32(ry)) ** 2)
        side = (k / flare - 1) * np.float32(min(rx, ry))
        cap = np.maximum(np.float32(bottom) - z, z - np.float32(bottom + height))
        return np.maximum(side, cap)

    return Field(sdf, (cx - 1.1 * rx, cy - 1.1 * ry, bottom), (cx + 1.1 * rx, cy + 1.1 * ry, bottom + height))


def bonsai_like(size, seed):
    """A board (≈55) under an oval pot (ceramic ≈210, wall 6 voxels) 0.66 × 0.6 of the box wide
    and 0.22 deep, full of soil (≈120 ± 15); a trunk (≈150) flaring at the roots from radius 16
    to 6 voxels along a seeded S-curve, three generations of branches (radius 6 → 2) and eight
    ten foliage pads (≈50): flattened ellipsoids holding leaf clusters where a band-limited
    noise of 12-voxel period is high, with gaps between the clusters as in the real crown.
    (Lengths at 256.)
    """
    rng = np.random.default_rng(seed)
    layout = noise.fork(rng)
    grid = Grid.for_aspect(size)
    canvas = Canvas(grid)
    grain = noise.fbm(grid, noise.fork(rng), wavelength=8 * V, octaves=2)
    leaves = noise.fbm(grid, noise.fork(rng), wavelength=12 * V, octaves=2, gain=0.4)

    canvas.paint(Box((0, 0, -0.485), (0.42, 0.45, 0.012), rounding=0.005), BOARD)
    bottom, depth = -0.47, 0.22
    canvas.paint(_dish((0, 0, bottom), (0.3, 0.27), depth), DISH)
    canvas.paint(_dish((0, 0, bottom + 6 * V), (0.3 - 6 * V, 0.27 - 6 * V), depth), SOIL + 15 * grain)
    canvas.paint(Ellipsoid((0, 0, bottom + depth), (0.32, 0.29, 0.03)), SOIL + 15 * grain)   # soil mound

    bend = layout.uniform(-0.08, 0.08, 2)
    s = np.linspace(0, 1, 10)
    trunk_pts = np.stack([bend[0] * np.sin(np.pi * s), bend[1] * np.sin(2 * np.pi * s),
                          bottom + depth - 0.02 + 0.36 * s], axis=1)
    radii = 6 * V + 10 * V * (1 - s) ** 2
    trunk = [Capsule(a, b, ra, rb) for a, b, ra, rb in zip(trunk_pts[:-1], trunk_pts[1:], radii[:-1], radii[1:])]
    trunk += [Capsule(trunk_pts[0], trunk_pts[0] + (0.09 * np.cos(t), 0.07 * np.sin(t), -0.015), 6 * V, 2 * V)
              for t in layout.uniform(0, 2 * np.pi, 5)]                                      # surface roots
    canvas.paint(grid.union(trunk), WOOD)
    branches = []
    for k, angle in enumerate(np.linspace(0, 2 * np.pi, 4, endpoint=False) + layout.uniform(0, 1)):
        start = trunk_pts[4 + k]
        direction = np.array([np.cos(angle), np.sin(angle), 0.35])
        branches += grow_tree(layout, start, direction, radius=6 * V, length=0.16, generations=2,
                              segments=4, spread=(25, 45), taper=0.8, limit=0.47)
    paint_tree(canvas, branches, [WOOD - 10] * len(branches))

    tips = [b.points[-1] for b in branches if b.generation == 2]
    pads = [Ellipsoid(np.clip(tips[i], -0.32, 0.32), (layout.uniform(0.15, 0.2), layout.uniform(0.15, 0.2),
                                                       layout.uniform(0.09, 0.12)))
            for i in layout.choice(len(tips), size=min(10, len(tips)), replace=False)]
    crown = grid.union(pads)
    x, y, z = grid.coords_of(crown.start, crown.cov)
    window = crown.slices
    # Leaf clusters where the noise is high, as a distance: the noise changes by about 2π per period,
    # doubled here so that the small leaves keep a sharp (one-voxel) edge.
    clusters = grid.region_of((np.float32(0.5) - leaves[window]) * np.float32(12 * V / np.pi), crown.start)
    canvas.paint(clusters.intersect(crown), LEAF)
    noise.add_gaussian(canvas.data, noise.fork(rng), 2.0)
    return Volume(canvas.to_uint8(), name="bonsai_like")
