"""The industrial-CT engine block (notes 000 "GE engine", 003 "engine", 004 "Engine").

A size × size × size/2 volume. An aluminium casting (material A ≈110) with flanges and fillets,
cylinder bores with steel liners, a crankcase cavity holding a steel crankshaft, coolant channels
and bolt holes with steel studs (material B ≈230), over an empty background. The many internal
surfaces and the low-opacity material A make it the data set where early ray termination does
not help.
"""

import numpy as np

from datasets import noise
from datasets.shapes import Box, Canvas, Cylinder, Grid
from core.volume import Volume
from core.errors import InputError

V = 1 / 256
ALUMINIUM, STEEL = 110, 230


def engine(size, seed, bores=2):
    """Engine block, two materials (notes 000, 003, 004).

    Parameters
    ----------
    bores : int
        Number of cylinder bores in a row along x (1–4; the real engine has two, note 003's
        stand-in four). Each has radius 25 voxels (at 256) and a steel liner.

    Notes
    -----
    The casting fills about a third of the box (note 000: 30–40 %). Material A carries a faint
    casting texture (± 4) and the volume CT noise σ 2.
    """
    if isinstance(bores, bool) or not isinstance(bores, (int, np.integer)) or not 1 <= bores <= 4:
        raise InputError(f"engine bores: expected an integer from 1 to 4, got {bores!r}")
    rng = np.random.default_rng(seed)
    grid = Grid.for_aspect(size, (1.0, 1.0, 0.5))
    canvas = Canvas(grid)
    texture = noise.fbm(grid, noise.fork(rng), wavelength=0.2, octaves=2)
    aluminium = ALUMINIUM + 4 * texture

    block = Box((0, 0, -0.01), (0.4, 0.27, 0.21), rounding=0.03)
    flange = Box((0, 0, 0.19), (0.44, 0.31, 0.03), rounding=0.012)
    feet = [Box((sx * 0.36, sy * 0.29, -0.21), (0.06, 0.05, 0.03), rounding=0.01) for sx in (-1, 1) for sy in (-1, 1)]
    canvas.paint(grid.union((block, flange, *feet)), aluminium)

    pitch = 0.64 / bores
    centers = [(-0.32 + pitch * (i + 0.5)) for i in range(bores)]
    bore_r = min(25 * V, 0.42 * pitch)
    for x in centers:
        canvas.paint(Cylinder((x, 0, -0.09), (x, 0, 0.3), bore_r + 4 * V), STEEL)      # liner
        canvas.paint(Cylinder((x, 0, -0.12), (x, 0, 0.3), bore_r), 0)                  # bore
    canvas.paint(Box((0, 0, -0.15), (0.33, 0.18, 0.045), rounding=0.03), 0)              # crankcase
    canvas.paint(Cylinder((-0.43, 0, -0.15), (0.43, 0, -0.15), 0.03), STEEL)              # crankshaft
    for x in centers:                                                                    # crank webs
        canvas.paint(Box((x, 0, -0.15), (0.012, 0.05, 0.04), rounding=0.008), STEEL)
    for y in (-0.19, 0.19):                                                              # coolant
        canvas.paint(Cylinder((-0.39, y, 0.06), (0.39, y, 0.06), 3.5 * V), 0)
    for left, right in zip(centers[:-1], centers[1:]):                                  # cross-drilled
        x = 0.5 * (left + right)
        canvas.paint(Cylinder((x, -0.3, 0.0), (x, 0.3, 0.0), 3.0 * V), 0)
    for x in np.linspace(-0.36, 0.36, bores + 1):                                       # studs
        for y in (-0.25, 0.25):
            canvas.paint(Cylinder((x, y, 0.02), (x, y, 0.3), 5 * V), 0)
            canvas.paint(Cylinder((x, y, 0.03), (x, y, 0.24), 3.2 * V), STEEL)
    noise.add_gaussian(canvas.data, noise.fork(rng), 2.0)
    return Volume(canvas.to_uint8(), name="engine")
