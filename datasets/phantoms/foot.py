"""The CT foot phantom (notes 000 "Philips foot" and 004 "Foot").

The foot is modelled in its own frame (u: heel → toes, v: medial → lateral, z: up) and turned
40° about z so that it lies diagonally across the box, as in the scan. The 26 bones of the foot
(seven tarsals, five metatarsals, fourteen phalanges) and the tibia and fibula each have a bright
cortical shell two voxels thick around a darker, noisy cancellous interior, inside a soft-tissue
envelope (≈70) with five toes, over air.
"""

import numpy as np

from datasets import noise
from datasets.shapes import Blend, Canvas, Capsule, Ellipsoid, Grid, Offset, SmoothUnion, Sphere, frame, rotation
from core.volume import Volume

V = 1 / 256
_TURN = rotation("z", 40)


def _p(u, v, z):
    """A point of the foot frame in normalised volume coordinates."""
    return _TURN @ np.array([u, v, z], dtype=np.float64)


def _long_bone(a, b, r_shaft, r_base, r_head):
    """A tubular bone: a shaft with a wider base at ``a`` and a rounded head at ``b``."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = (b - a) / np.linalg.norm(b - a)
    base = Ellipsoid(a + axis * r_base * 0.6, (r_base, r_base, r_base * 1.2), frame(axis))
    head = Sphere(b - axis * r_head * 0.6, r_head)
    return SmoothUnion(SmoothUnion(Capsule(a, b, r_shaft), base, 0.6 * r_shaft), head, 0.6 * r_shaft)


def _bones():
    """The 26 bones of the foot with the tibia and fibula, in a fixed anatomical layout."""
    tibia = SmoothUnion(Capsule(_p(-0.22, 0.0, -0.2), _p(-0.30, 0.0, 0.75), 0.05, 0.045),
                        Ellipsoid(_p(-0.21, -0.04, -0.23), (0.035, 0.025, 0.045), _TURN), 0.02)   # medial malleolus
    fibula = SmoothUnion(Capsule(_p(-0.25, 0.12, -0.2), _p(-0.33, 0.12, 0.75), 0.02),
                         Ellipsoid(_p(-0.24, 0.125, -0.25), (0.025, 0.02, 0.045), _TURN), 0.015)  # lateral malleolus
    talus = SmoothUnion(Ellipsoid(_p(-0.2, 0.01, -0.28), (0.07, 0.06, 0.045), _TURN),
                        Ellipsoid(_p(-0.13, -0.01, -0.3), (0.04, 0.035, 0.03), _TURN), 0.02)     # body, head, neck
    calcaneus = SmoothUnion(Ellipsoid(_p(-0.29, 0.04, -0.36), (0.1, 0.055, 0.055), _TURN @ rotation("y", -12)),
                            Ellipsoid(_p(-0.38, 0.04, -0.37), (0.045, 0.045, 0.065), _TURN), 0.03)  # tuber
    bones = [tibia, fibula, talus, calcaneus,
             Ellipsoid(_p(-0.085, -0.04, -0.31), (0.03, 0.055, 0.036), _TURN),          # navicular
             Ellipsoid(_p(-0.12, 0.085, -0.35), (0.045, 0.04, 0.032), _TURN)]          # cuboid
    for v in (-0.085, -0.04, 0.0):                                                     # cuneiforms
        bones.append(Ellipsoid(_p(-0.025, v, -0.325), (0.032, 0.02, 0.035), _TURN))
    for i, v in enumerate(np.linspace(-0.095, 0.1, 5)):                               # metatarsals
        r = (6.5 if i == 0 else 4.5) * V
        length = 0.26 - 0.018 * i
        a, b = _p(0.02, v * 0.85, -0.345 + 0.005 * i), _p(0.02 + length, v * 1.2, -0.41)
        bones.append(_long_bone(a, b, r, 1.6 * r, 1.45 * r))
        direction = (b - a) / np.linalg.norm(b - a)
        direction = (direction + np.array([0, 0, 0.08])) / np.linalg.norm(direction + np.array([0, 0, 0.08]))
        start = b + direction * 3 * V
        pieces = (0.07, 0.05) if i == 0 else (0.05, 0.03, 0.022)                      # phalanges
        for k, piece in enumerate(pieces):
            radius = r * (0.85 - 0.15 * k)
            end = start + direction * piece
            bones.append(_long_bone(start, end, radius, 1.45 * radius, 1.3 * radius))
            start = end + direction * 2.5 * V
    return bones


def _toes():
    """Five soft-tissue toes in front of the forefoot (the phalanges' envelope)."""
    toes = []
    for i, v in enumerate(np.linspace(-0.095, 0.1, 5)):
        r = (0.032 if i == 0 else 0.022) - 0.001 * i
        a, b = _p(0.3 - 0.018 * i, v * 1.2, -0.41), _p(0.43 - 0.03 * i, v * 1.25, -0.415)
        toes.append(Capsule(a, b, r, r * 0.9))
    return toes


def foot(size, seed):
    """CT foot: the 26 bones of the foot and the ankle in soft tissue, lying diagonally (notes 000, 004).

    Soft tissue ≈70 (60–80) fills about a fifth of the box: a leg leaving through the top face,
    a heel, an arched mid- and forefoot and five toes, smoothly joined. Tarsals (talus with its
    head, calcaneus with its tuber, navicular, cuboid, three cuneiforms), five metatarsals and
    fourteen phalanges with wide bases and rounded heads, the tibia and fibula with their
    malleoli. Bones: cortex ≈235 (2 voxels) over cancellous ≈165 ± 20. Air ≈0, CT noise σ 3.
    """
    rng = np.random.default_rng(seed)
    grid = Grid.for_aspect(size)
    canvas = Canvas(grid)
    texture = noise.fbm(grid, noise.fork(rng), wavelength=0.3, octaves=3)
    trabecular = noise.fbm(grid, noise.fork(rng), wavelength=10 * V, octaves=1)
    leg = Capsule(_p(-0.22, 0.02, -0.22), _p(-0.3, 0.02, 0.8), 0.2, 0.34)
    heel = Ellipsoid(_p(-0.3, 0.03, -0.34), (0.17, 0.15, 0.13), _TURN)
    sole = Ellipsoid(_p(0.02, 0.01, -0.37), (0.38, 0.2, 0.11), _TURN @ rotation("y", 4))
    soft = Blend(leg, [(heel, 0.1), (sole, 0.1), *((toe, 0.025) for toe in _toes())])
    at, d = grid.distance(soft)
    canvas.paint(grid.region_of(d, at), 70 + 5 * texture)
    bones = _bones()
    canvas.paint(grid.union(bones), 235)
    canvas.paint(grid.union(Offset(b, -2 * V) for b in bones), 165 + 20 * trabecular)
    noise.add_gaussian(canvas.data, noise.fork(rng), 3.0)
    return Volume(canvas.to_uint8(), name="foot")
