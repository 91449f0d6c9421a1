"""The layered seismic cube of Ropinski et al. (note 004 §5, "Seismic")."""

import numpy as np

from datasets import noise
from datasets.shapes import Grid
from core.volume import Volume

V = 1 / 256


def _smooth_step(d, width):
    t = np.clip(0.5 + d / np.float32(2 * width), 0, 1)
    return t * t * (3 - 2 * t)


def seismic(size, seed):
    """A dense layered volume with folds and two faults, filling the whole box.

    Horizons are the level sets of a stratigraphic coordinate ``t = z − fold(x, y) − throw``: a
    sum of three sinusoidal folds (amplitude 0.02–0.05) and two steep planar faults that offset
    the layers by 5–15 voxels (band-limited over a voxel and a half). Along ``t`` the
    reflectivity is a sequence of layers 5–15 voxels thick with values 0.2–0.9 plus a fine
    band-limited texture, smooth in x and y. No empty space: empty-space skipping gains nothing
    and rays saturate near the entry faces.
    """
    rng = np.random.default_rng(seed)
    layout = noise.fork(rng)
    grid = Grid.for_aspect(size)
    x, y, z = grid.coords()
    t = np.broadcast_to(z, grid.shape).astype(np.float32)
    for _ in range(3):
        amplitude = layout.uniform(0.02, 0.05)
        kx, ky = layout.uniform(2, 7, 2)
        px, py = layout.uniform(0, 2 * np.pi, 2)
        t = t - np.float32(amplitude) * np.sin(np.float32(kx) * x + np.float32(px)) * np.cos(np.float32(ky) * y + np.float32(py))
    for _ in range(2):
        normal = np.array([*layout.normal(size=2), layout.uniform(-0.3, 0.3)])
        normal /= np.linalg.norm(normal)
        point = layout.uniform(-0.25, 0.25, 3)
        throw = layout.uniform(5, 15) * V * layout.choice((-1, 1))
        side = (x - np.float32(point[0])) * np.float32(normal[0]) + (y - np.float32(point[1])) * np.float32(normal[1]) \
            + (z - np.float32(point[2])) * np.float32(normal[2])
        t = t - np.float32(throw) * _smooth_step(side, 1.5 * grid.h)
    # Reflectivity along t, tabulated at a quarter voxel over the range t can take.
    step = grid.h / 4
    axis = np.arange(-1.0, 1.0, step)
    edges = np.cumsum(layout.uniform(5, 15, 400) * V) - 1.0
    levels = layout.uniform(0.2, 0.9, edges.size + 1)
    profile = levels[np.searchsorted(edges, axis)]
    kernel = np.exp(-0.5 * (np.arange(-8, 9) / 4.0) ** 2)                # σ one voxel
    profile = np.convolve(np.pad(profile, 8, mode="edge"), kernel / kernel.sum(), mode="valid")
    texture = np.convolve(layout.normal(0, 0.08, axis.size + 16), kernel / kernel.sum(), mode="valid")
    profile = np.clip(profile + texture, 0, 1)
    data = np.interp(t.ravel(), axis, profile).reshape(grid.shape).astype(np.float32) * 255
    noise.add_gaussian(data, noise.fork(rng), 2.0)
    return Volume(np.clip(np.rint(data), 0, 255).astype(np.uint8), name="seismic")
