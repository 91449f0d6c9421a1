"""Scene pieces several of this paper's experiments render: overlapping smoke clouds, translucent meshes, the screw.

Each returns a volume or mesh entry of the scene format (:mod:`pipeline.scene_io`); an experiment puts
them in a scene with :func:`pipeline.experiments.kit.planning.scene`.
"""

import numpy as np

from pipeline.experiments.kainz2009.methods import IMAGE_SIZES
from pipeline.experiments.kit.model import scaled
from pipeline.experiments.kit.planning import phantom

CLOUD_SPREAD = 0.25
"""Cloud centres lie within ± this fraction of a cloud's edge of the first one: heavy overlap (C8)."""

SURFACE = {"colour": [0.9, 0.75, 0.55], "alpha": 0.35, "specular": 0.3}
"""A translucent Phong surface (Table 2's scenes, the meshes of C6–C8)."""

CLOUD_SIZES = scaled(base=IMAGE_SIZES, smoke={"small_size": 16, "large_size": 32},
                     default={"small_size": 32, "large_size": 96}, full={"small_size": 64, "large_size": 256})
"""The small volumes' (the clouds') and the large volume's sizes (voxels) at each scale, with the images'
(:data:`~pipeline.experiments.kainz2009.methods.IMAGE_SIZES`): Table 1's scenes and those built like them."""

AXIS_VIEW = {"view": "axis", "azimuth": 0.0, "elevation": 0.0}
"""Along the z axis: the screw's, the coil's and the row of boxes' axis."""


def volume(dataset, size, preset, name, **extra):
    """A volume entry of phantom ``dataset`` at ``size`` with ``preset``, called ``name`` in the scene."""
    return phantom(dataset, int(size), preset=preset, name=name, **extra)


def clouds(count, size, *, scale=1.0):
    """``count`` smoke clouds of ``size``³ (seeds 0…), heavily overlapping and randomly turned.

    Cloud ``i`` is the same in every count: the draws do not depend on ``count``. The first sits
    at the origin, the others within ±:data:`CLOUD_SPREAD` of an edge of it.
    """
    rng = np.random.default_rng(2009)
    entries = []
    for i in range(count):
        offset = rng.uniform(-CLOUD_SPREAD, CLOUD_SPREAD, 3) * size * scale
        axis, degrees = rng.normal(size=3), rng.uniform(0.0, 360.0)
        entries.append(volume("smoke_cloud", size, "smoke", f"cloud{i:02d}", seed=i,
                              transform={"translate": [0.0] * 3 if i == 0 else [round(float(v), 4) for v in offset],
                                         "rotate": {"axis": [round(float(v), 4) for v in axis],
                                                    "degrees": round(float(degrees), 3)},
                                         "scale": float(scale)}))
    return entries


def mesh(name, generator, params, *, transform=None, surface=SURFACE):
    """A generated mesh entry with a (by default translucent) surface."""
    return {"name": name, "generator": generator, "params": params, "surface": dict(surface),
            **({"transform": transform} if transform else {})}


def blob(size, triangles):
    """The ``triangles`` mesh of C8: a noisy sphere among the clouds (radius a third of a cloud edge)."""
    return mesh("mesh30k", "noisy_sphere",
                {"radius": round(size / 3, 4), "subdivisions": 6, "triangles": int(triangles)})


def screw(turns):
    """The thumbscrew stand-in: a threaded rod along the view axis (z), centred on the origin."""
    pitch = 0.1
    return mesh("screw", "helical_screw", {"turns": int(turns), "pitch": pitch},
                transform={"translate": [0.0, 0.0, -0.5 * pitch * int(turns)]})
