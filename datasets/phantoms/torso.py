"""The contrast-enhanced abdomen CT with a label volume (notes 003 "abdomen", 002 C1/C7).

An elliptic-cylinder body running through the top and bottom faces: subcutaneous fat over muscle
and viscera, the bases of the lungs, a spine of vertebrae (bodies, arches, spinous and transverse
processes) and discs, the lower rib cage (ribs 7–12, the upper ones joined in front by costal
cartilage), the iliac crests, kidneys with an enhanced cortex, a lobed liver holding a hypodense
tumour, the aorta and vena cava, and arterial trees (renal arteries, a hepatic tree, the superior
mesenteric artery) filled with dye. Every voxel
also gets a material id in ``Volume.labels`` (painter's order, where a structure covers at least
half the voxel), for per-material classification and shading.
"""

import numpy as np

from datasets import noise
from datasets.phantoms.vessels import grow_tree, paint_tree
from datasets.shapes import Box, Canvas, Capsule, Cylinder, Ellipsoid, Grid, Offset, Shell, Sphere, Torus, rotation
from core.volume import Volume

V = 1 / 256
TORSO_ASPECT = (1.0, 1.0, 159 / 257)
"""The thesis's abdomen is 257×257×159 (Table 5.1)."""

LABELS = {"air": 0, "fat": 1, "soft_tissue": 2, "bone": 3, "kidney": 4, "liver": 5, "vessel": 6,
          "tumour": 7, "vein": 8}
"""Material ids of the label volume."""

FAT, SOFT, CORTICAL, CANCELLOUS, KIDNEY, LIVER, DYE, TUMOUR, VEIN = 70, 95, 225, 175, 140, 112, 242, 78, 150


def _rib(side, z0, reach):
    """One rib from the spine around the body wall, sloping down: the bony part and, when it
    reaches the front (``reach`` > 0.55 of a half turn), its costal cartilage towards the midline."""
    angles = np.linspace(0.04 * np.pi, reach * np.pi, 14)
    pts = np.stack([side * 0.4 * np.sin(angles), 0.27 * np.cos(angles) - 0.01,
                    z0 - 0.2 * (angles / np.pi) ** 1.5], axis=1)
    bone = min(len(pts), 10)
    ribs = [Capsule(a, b, 3.4 * V, 2.8 * V) for a, b in zip(pts[:bone - 1], pts[1:bone])]
    cartilage = [Capsule(a, b, 2.8 * V) for a, b in zip(pts[bone - 1:-1], pts[bone:])]
    return ribs, cartilage


def torso(size, seed):
    """Abdomen CT phantom with dye in the arteries and an integer label volume (note 003).

    Values: fat ≈70, muscle/viscera ≈95, liver ≈112, kidney cortex ≈140, tumour ≈78, vena cava
    ≈150, bone cortex ≈225 over cancellous ≈175, dye ≈242; air 0 with CT noise σ 3. The box is
    size × size × round(size·159/257) (at ``size=257`` exactly the thesis's 257×257×159).
    """
    rng = np.random.default_rng(seed)
    grid = Grid.for_aspect(size, TORSO_ASPECT)
    canvas = Canvas(grid, labels=True)
    texture = noise.fbm(grid, noise.fork(rng), wavelength=0.3, octaves=3)
    topology = noise.fork(rng)

    body = Ellipsoid((0, 0, 0), (0.44, 0.3, 10.0))
    canvas.paint(body, FAT + 4 * texture, label=LABELS["fat"])
    canvas.paint(Offset(body, -9 * V), SOFT + 5 * texture, label=LABELS["soft_tissue"])

    for side in (-1, 1):                                                    # lung bases above the diaphragm
        canvas.paint(Ellipsoid((side * 0.2, 0.08, 0.4), (0.16, 0.16, 0.14)), 12, label=LABELS["air"])
    liver = grid.union((
        Ellipsoid((-0.16, -0.02, 0.12), (0.25, 0.2, 0.2), rotation("z", 15)),
        Ellipsoid((-0.02, -0.1, 0.18), (0.14, 0.1, 0.09))))
    canvas.paint(liver, LIVER + 4 * texture, label=LABELS["liver"])
    canvas.paint(Ellipsoid((0.25, 0.1, 0.15), (0.07, 0.11, 0.1), rotation("z", -30)), LIVER + 4 * texture,
                 label=LABELS["soft_tissue"])                                # spleen
    lumps = [Sphere((-0.2 + topology.normal(0, 0.012), -0.05 + topology.normal(0, 0.012),
                     0.12 + topology.normal(0, 0.012)), topology.uniform(0.022, 0.032)) for _ in range(4)]
    canvas.paint(grid.union(lumps), TUMOUR, label=LABELS["tumour"])

    for side in (-1, 1):
        kidney = Ellipsoid((side * 0.16, 0.12, -0.02), (0.045, 0.035, 0.09), rotation("y", side * 12))
        canvas.paint(kidney, KIDNEY, label=LABELS["kidney"])
        canvas.paint(Offset(kidney, -7 * V), KIDNEY - 25)

    # Spine: vertebral bodies (cortex around a cancellous core) separated by discs; each with its
    # arch, spinous and transverse processes.
    for z in np.arange(-0.34, 0.35, 0.075):
        vertebra = Cylinder((0, 0.17, z - 0.029), (0, 0.17, z + 0.029), 0.05)
        canvas.paint(vertebra, CORTICAL, label=LABELS["bone"])
        canvas.paint(Offset(vertebra, -2.5 * V), CANCELLOUS + 12 * texture)
        processes = [Torus((0, 0.245, z), 0.036, 3.5 * V), Capsule((0, 0.28, z), (0, 0.31, z - 0.03), 4 * V, 3 * V)]
        processes += [Capsule((side * 0.03, 0.23, z), (side * 0.085, 0.25, z + 0.01), 3.5 * V) for side in (-1, 1)]
        canvas.paint(grid.union(processes), CORTICAL, label=LABELS["bone"])
    # The lower rib cage: ribs 7–12 from the spine, the upper ones joined in front by cartilage.
    for side in (-1, 1):
        for z0, reach in ((0.38, 0.85), (0.3, 0.8), (0.22, 0.72), (0.14, 0.62), (0.06, 0.45), (-0.02, 0.35)):
            ribs, cartilage = _rib(side, z0, reach)
            canvas.paint(grid.union(ribs), 205, label=LABELS["bone"])
            canvas.paint(grid.union(cartilage), 125, label=LABELS["soft_tissue"])
    # Pelvis: the iliac crests rising from the bottom face.
    for side in (-1, 1):
        wing = Ellipsoid((side * 0.2, 0.12, -0.38), (0.13, 0.09, 0.14), rotation("y", side * 25))
        canvas.paint(grid.region(Shell(wing, 5 * V)).intersect(grid.region(
            Box((side * 0.2, 0.12, -0.36), (0.16, 0.12, 0.08)))), CORTICAL, label=LABELS["bone"])

    canvas.paint(Cylinder((-0.05, 0.07, -0.5), (-0.05, 0.07, 0.5), 7 * V), VEIN, label=LABELS["vein"])
    canvas.paint(Cylinder((0.03, 0.08, -0.5), (0.03, 0.08, 0.5), 6.5 * V), DYE, label=LABELS["vessel"])
    trees = []
    for side in (-1, 1):                                                     # renal arteries
        trees += grow_tree(topology, (0.03, 0.08, 0.0), (side * 1.0, 0.35, -0.05), radius=3 * V,
                           length=0.1, generations=2, segments=4, limit=0.45)
    trees += grow_tree(topology, (0.03, 0.06, 0.08), (-1.0, -0.4, 0.3), radius=4 * V, length=0.12,
                       generations=4, segments=4, limit=0.4)                 # hepatic
    trees += grow_tree(topology, (0.03, 0.05, -0.04), (0.1, -0.6, -1.0), radius=4 * V, length=0.12,
                       generations=3, segments=4, limit=0.4)                 # mesenteric
    paint_tree(canvas, trees, [DYE] * len(trees), label=LABELS["vessel"])

    noise.add_gaussian(canvas.data, noise.fork(rng), 3.0)
    return Volume(canvas.to_uint8(), name="torso", labels=canvas.labels,
                  meta={"labels": dict(LABELS)})
