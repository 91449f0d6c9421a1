"""The CT foot phantom (notes 000 "Philips foot" and 004 "Foot").

The foot is modelled in its own frame (u: heel → toes, v: medial → lateral, z: up) and turned
40° about z so that it lies diagonally across the box, as in the scan. About twenty bones (tibia,
fibula, talus, calcaneus, navicular, cuboid, three cuneiforms, five metatarsals, fourteen
phalanges) each have a bright cortical shell two voxels thick around a darker, noisy cancellous
interior, inside a soft-tissue envelope (≈70) over air.
"""

import numpy as np

from datasets import noise
from datasets.shapes import Canvas, Capsule, Ellipsoid, Grid, Offset, SmoothUnion, rotation
from core.volume import Volume

V = 1 / 256
_TURN = rotation("z", 40)


def _p(u, v, z):
    """A point of the foot frame in normalised volume coordinates."""
    return _TURN @ np.array([u, v, z], dtype=np.float64)


def _bones():
    """The bone shapes (outer surfaces) in a fixed anatomical layout."""
    bones = [
        Capsule(_p(-0.21, 0.0, -0.22), _p(-0.30, 0.0, 0.75), 0.055, 0.048),      # tibia
        Capsule(_p(-0.25, 0.14, -0.23), _p(-0.33, 0.13, 0.75), 0.024),           # fibula
        Ellipsoid(_p(-0.2, 0.0, -0.28), (0.075, 0.065, 0.05), _TURN),            # talus
        Ellipsoid(_p(-0.31, 0.03, -0.36), (0.11, 0.065, 0.06), _TURN @ rotation("y", -15)),  # calcaneus
        Ellipsoid(_p(-0.09, -0.04, -0.31), (0.035, 0.06, 0.038), _TURN),         # navicular
        Ellipsoid(_p(-0.1, 0.09, -0.35), (0.05, 0.042, 0.035), _TURN),           # cuboid
    ]
    for v in (-0.1, -0.05, 0.0):                                                 # cuneiforms
        bones.append(Ellipsoid(_p(-0.01, v, -0.32), (0.035, 0.022, 0.035), _TURN))
    for i, v in enumerate(np.linspace(-0.11, 0.11, 5)):                          # metatarsals
        r = (7.0 if i == 0 else 5.5) * V
        length = 0.27 - 0.02 * i
        a, b = _p(0.04, v * 0.8, -0.34), _p(0.04 + length, v * 1.15, -0.4)
        bones.append(Capsule(a, b, r, r * 0.85))
        direction = (b - a) / np.linalg.norm(b - a)
        start = b + direction * (r + 2.5 * V)
        pieces = (0.075, 0.05) if i == 0 else (0.05, 0.032, 0.025)               # phalanges
        for k, piece in enumerate(pieces):
            radius = r * (0.8 - 0.12 * k)
            end = start + direction * piece
            bones.append(Capsule(start, end, radius, radius * 0.9))
            start = end + direction * (2 * radius + 2 * V)
    return bones


def foot(size, seed):
    """CT foot: bones in soft tissue lying diagonally (notes 000, 004).

    Soft tissue ≈70 (60–80) fills about a fifth of the box: a leg leaving through the top face,
    a heel, a flattened mid- and forefoot and the toes, smoothly joined. Bones: cortex ≈235,
    cancellous ≈165 ± 20. Air ≈0 with CT noise σ 3.
    """
    rng = np.random.default_rng(seed)
    grid = Grid.for_aspect(size)
    canvas = Canvas(grid)
    texture = noise.fbm(grid, noise.fork(rng), wavelength=0.3, octaves=3)
    trabecular = noise.fbm(grid, noise.fork(rng), wavelength=10 * V, octaves=1)
    leg = Capsule(_p(-0.2, 0.02, -0.22), _p(-0.3, 0.02, 0.8), 0.22, 0.25)
    heel = Ellipsoid(_p(-0.31, 0.02, -0.33), (0.17, 0.17, 0.14), _TURN)
    sole = Ellipsoid(_p(0.08, 0.0, -0.36), (0.48, 0.22, 0.13), _TURN @ rotation("y", 4))
    toes = Ellipsoid(_p(0.44, 0.0, -0.41), (0.13, 0.21, 0.07), _TURN)
    soft = SmoothUnion(SmoothUnion(SmoothUnion(leg, heel, 0.1), sole, 0.12), toes, 0.08)
    canvas.paint(soft, 70 + 5 * texture)
    bones = _bones()
    canvas.paint(grid.union(bones), 235)
    canvas.paint(grid.union(Offset(b, -2 * V) for b in bones), 165 + 20 * trabecular)
    noise.add_gaussian(canvas.data, noise.fork(rng), 3.0)
    return Volume(canvas.to_uint8(), name="foot")
