"""A bonsai-like tree in a pot (note 001 §5, "Bonsai"): opaque pot and trunk, fine foliage, air."""

import numpy as np

from datasets import noise
from datasets.phantoms.vessels import grow_tree, paint_tree
from datasets.shapes import Canvas, Capsule, Field, Grid, Sphere
from core.volume import Volume

V = 1 / 256
POT, SOIL, WOOD, LEAF = 220, 130, 200, 95


def _pot(bottom, top, r_bottom, r_top):
    """Solid truncated cone between heights ``bottom`` and ``top`` (radius linear in z)."""
    slope = (r_top - r_bottom) / (top - bottom)
    scale = np.float32(1 / np.sqrt(1 + slope**2))  # distance to a slanted side

    def sdf(x, y, z):
        radius = np.float32(r_bottom) + np.float32(slope) * (z - np.float32(bottom))
        side = (np.sqrt(x * x + y * y) - radius) * scale
        cap = np.maximum(np.float32(bottom) - z, z - np.float32(top))
        return np.maximum(side, cap)

    r = max(r_bottom, r_top)
    return Field(sdf, (-r, -r, bottom), (r, r, top))


def bonsai_like(size, seed):
    """Pot (wall ≈220, 5 voxels) of soil (≈130), a curved trunk (≈200, radius 12 → 8 voxels),
    three generations of branches (radius 5 → 2) and five canopy clusters of small leaf blobs
    (≈95, radius 1–3 voxels, 250 per cluster) with gaps, in air.
    """
    rng = np.random.default_rng(seed)
    layout = noise.fork(rng)
    grid = Grid.for_aspect(size)
    canvas = Canvas(grid)
    canvas.paint(_pot(-0.48, -0.29, 0.23, 0.27), POT)
    canvas.paint(_pot(-0.48 + 5 * V, -0.31, 0.23 - 5 * V, 0.27 - 5 * V), SOIL)
    bend = layout.uniform(-0.06, 0.06, 2)
    trunk_pts = np.array([[bend[0] * s * s, bend[1] * s * s, -0.32 + 0.4 * s] for s in np.linspace(0, 1, 8)])
    radii = np.linspace(12 * V, 8 * V, len(trunk_pts))
    trunk = [Capsule(a, b, ra, rb) for a, b, ra, rb in zip(trunk_pts[:-1], trunk_pts[1:], radii[:-1], radii[1:])]
    canvas.paint(grid.union(trunk), WOOD)
    branches = []
    for k in range(3):
        start = trunk_pts[4 + k]
        direction = np.array([*layout.normal(size=2), 0.6])
        branches += grow_tree(layout, start, direction, radius=5 * V, length=0.16, generations=2,
                              segments=4, spread=(30, 55), radius_ratio=0.7, limit=0.47)
    paint_tree(canvas, branches, [WOOD - 10] * len(branches))
    tips = [b.points[-1] for b in branches if b.generation == 2]
    for index in layout.choice(len(tips), size=min(5, len(tips)), replace=False):
        center = tips[index]
        radius = layout.uniform(0.09, 0.13)
        offsets = layout.normal(size=(250, 3))
        offsets *= (radius * layout.uniform(0, 1, (250, 1)) ** (1 / 3)) / np.linalg.norm(offsets, axis=1, keepdims=True)
        blobs = [Sphere(np.clip(center + o, -0.48, 0.48), layout.uniform(1, 3) * V) for o in offsets]
        canvas.paint(grid.union(blobs), LEAF)
    noise.add_gaussian(canvas.data, noise.fork(rng), 2.0)
    return Volume(canvas.to_uint8(), name="bonsai_like")
