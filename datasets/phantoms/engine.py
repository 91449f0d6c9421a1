"""The industrial-CT engine block (notes 000 "GE engine", 003 "engine", 004 "Engine").

A size × size × size/2 volume holding a thin-walled aluminium casting (material A ≈110) the way
the real two-cylinder engine scan does: about half the box wide, its walls 8–10 voxels thick
around a hollow water jacket and crankcase, internal webs, a deck, external cooling ribs and
mounting bosses, with cylinder bores. Steel parts (material B ≈230) are small: valves (seats,
heads and stems leaning out of the head), studs and a crankshaft. The many internal surfaces and the
low-opacity material A make it the data set where early ray termination does not help.
"""

import numpy as np

from datasets import noise
from datasets.shapes import Box, Canvas, Capsule, Cylinder, Grid, Offset
from core.volume import Volume
from core.errors import InputError

V = 1 / 256
ALUMINIUM, STEEL = 110, 230


def engine(size, seed, bores=2):
    """Engine block, two materials (notes 000, 003, 004).

    Parameters
    ----------
    bores : int
        Number of cylinder bores in a row along y (1–4; the real engine has two, note 003's
        stand-in four). Each has radius 25 voxels (at 256) when they fit, a cast wall and two
        valves.

    Notes
    -----
    The casting's bounding box covers about a quarter of the volume and the walls fill about
    a tenth of it (the real scan: 75 % of 8³ blocks empty). Material A carries a faint casting
    texture (± 4) and the volume CT noise σ 2.
    """
    if isinstance(bores, bool) or not isinstance(bores, (int, np.integer)) or not 1 <= bores <= 4:
        raise InputError(f"engine bores: expected an integer from 1 to 4, got {bores!r}")
    rng = np.random.default_rng(seed)
    grid = Grid.for_aspect(size, (1.0, 1.0, 0.5))
    canvas = Canvas(grid)
    texture = noise.fbm(grid, noise.fork(rng), wavelength=0.2, octaves=2)
    aluminium = ALUMINIUM + 4 * texture

    pitch = 0.62 / bores
    centers = [-0.31 + pitch * (i + 0.5) for i in range(bores)]
    bore_r = min(25 * V, 0.36 * pitch)
    casting = Box((0, 0, 0), (0.2, 0.38, 0.2), rounding=0.03)
    canvas.paint(casting, aluminium)
    canvas.paint(Offset(casting, -9 * V), 0)                                           # jacket, crankcase
    canvas.paint(Box((0, 0, 0.165), (0.2, 0.38, 0.035), rounding=0.01), aluminium)     # deck
    for y in [-0.38, *(0.5 * (a + b) for a, b in zip(centers[:-1], centers[1:])), 0.38]:
        canvas.paint(Box((0, y, -0.02), (0.2, 4 * V, 0.18)), aluminium)               # webs, end walls
    for y in centers:
        canvas.paint(Cylinder((0, y, -0.1), (0, y, 0.2), bore_r + 9 * V), aluminium)   # cylinder wall
        canvas.paint(Cylinder((0, y, -0.25), (0, y, 0.25), bore_r), 0)                 # bore
    for x in (-0.12, 0.12):                                                            # oil gallery, ports
        canvas.paint(Cylinder((x, -0.37, 0.08), (x, 0.37, 0.08), 4 * V), 0)
    for z in np.linspace(-0.14, 0.1, 7):                                              # cooling ribs
        for side in (-1, 1):
            canvas.paint(Box((side * 0.215, 0, z), (0.02, 0.33, 2 * V), rounding=V), aluminium)
    for sx in (-1, 1):                                                                 # mounting bosses
        for sy in (-1, 1):
            a, b = (sx * 0.2, sy * 0.33, -0.17), (sx * 0.27, sy * 0.33, -0.17)
            canvas.paint(Cylinder(a, b, 0.035), aluminium)
            canvas.paint(Cylinder(a, (sx * 0.28, sy * 0.33, -0.17), 0.015), 0)
            canvas.paint(Cylinder((sx * 0.16, sy * 0.33, -0.17), (sx * 0.3, sy * 0.33, -0.17), 0.012), STEEL)  # bolt
    canvas.paint(Cylinder((0, -0.43, -0.14), (0, 0.43, -0.14), 0.035), STEEL)          # crankshaft
    for y in centers:
        canvas.paint(Box((0, y, -0.14), (0.045, 0.01, 0.035), rounding=0.008), STEEL)  # crank webs
        for side in (-1, 1):                                  # valves: seat rings, heads, stems outwards
            seat = np.array((side * 0.5 * bore_r, y, 0.19))
            canvas.paint(Cylinder(seat, seat + (0, 0, 4 * V), 0.42 * bore_r), STEEL)
            canvas.paint(Capsule(seat, seat + (side * 0.17, 0, 0.06), 6 * V), STEEL)
    for y in np.linspace(-0.34, 0.34, bores + 1):                                      # head studs
        for x in (-0.16, 0.16):
            canvas.paint(Cylinder((x, y, 0.0), (x, y, 0.24), 5 * V), 0)
            canvas.paint(Cylinder((x, y, 0.02), (x, y, 0.24), 3.2 * V), STEEL)
    noise.add_gaussian(canvas.data, noise.fork(rng), 2.0)
    return Volume(canvas.to_uint8(), name="engine")
