"""The lens scenes of note 004 §5: the Table 1 data sets and the engine, each with its lens.

A scene is a scene mapping (:mod:`pipeline.scene_io`) with one ``lenses:`` entry. The lens is placed
in fractions of the volume's box, so one setup serves every volume size and the real scan's own
grid: ``center`` is the lens centre's offset from the box centre in fractions of each edge
(``(0.5, -0.5, 0.5)`` is a corner), a sphere's ``radius`` a fraction of the longest edge and a box
lens's ``size`` fractions of each edge. The box is untransformed (centred on the world origin,
object axes along world axes), so a fraction ``f`` of edge ``e`` is at world ``f·e``.

The headline view (30° yaw, 20° pitch of the upright volume, :func:`~pipeline.experiments.kit.planning.headline_view`)
looks from the corner ``(+x, −y, +z)`` of these z-up volumes: "front" below means ``−y`` and ``+x``,
"top" ``+z``.
"""

import copy
from dataclasses import dataclass, field

import datasets
from core.errors import InputError
from datasets.real import DataUnavailableError, read_manifest
from pipeline.experiments.kit.planning import dataset_view, headline_view, phantom, scene


@dataclass(frozen=True)
class LensSetup:
    """One lens scene: the data set and its preset (the outside appearance: context DVR), and its lens, a
    ``"sphere"`` or a ``"box"`` placed in fractions of the box (``center``, ``radius``, ``size``: the module's
    conventions) with its ``appearance`` entry (scene-file format); a box lens turns ``rotate_y`` degrees about
    the world's y axis, about its centre. ``paper_row``: the row of the paper's Table 1 this scene stands for
    (``None``: not in Table 1); ``what``: the paper's figure or row, in words.
    """

    dataset: str
    preset: str
    shape: str
    center: tuple
    appearance: dict = field(default_factory=dict)
    radius: float | None = None
    size: tuple | None = None
    rotate_y: float = 0.0
    paper_row: str | None = None
    what: str = ""


BONE_ISOVALUE = 0.55
"""The foot's bone isovalue (140 of 255): between soft tissue (≈70) and cancellous bone (≈165). The
note's 0.75 (the ``iso`` preset's 191) lies above the foot's thin cortex once a volume below 256³
blurs it, so the lens showed specks instead of bones at 128³ (rendered here)."""

SETUPS = {
    "seismic": LensSetup("seismic", "layers", "sphere", (0.35, -0.35, 0.35), {"mode": "clip"}, radius=0.3,
                         paper_row="seismic",
                         what="Fig. 1 middle and Table 1: a spherical clipping lens near the front top corner, "
                              "sticking out of the box"),
    "skull": LensSetup("ct_skull", "bone", "sphere", (0.1, -0.2, 0.25),
                       {"mode": "dvr", "preset": "bone", "opacity_scale": 0.2}, radius=0.22, paper_row="skull",
                       what="Table 1's skull, in no figure: a spherical transparency lens over the forehead"),
    "foot": LensSetup("foot", "skin_bone", "sphere", (0.11, 0.09, -0.38), {"mode": "iso", "isovalue": BONE_ISOVALUE},
                      radius=0.25, paper_row="foot",
                      what="Fig. 1 right and Table 1: a spherical bone-isosurface lens over the metatarsals"),
    "engine": LensSetup("engine", "semi", "box", (0.0, 0.0, 0.0),
                        {"mode": "dvr", "preset": "semi", "opacity_scale": 0.2}, size=(0.4, 0.4, 0.6), rotate_y=20.0,
                        what="Fig. 1 left, not timed in the paper: a cuboid transparency lens, 0.4 × 0.4 × 0.6 of "
                             "the box, rotated 20° about y"),
    "cthead": LensSetup("cthead", "bone", "sphere", (0.1, -0.2, 0.2),
                        {"mode": "dvr", "preset": "bone", "opacity_scale": 0.2}, radius=0.22, paper_row="skull",
                        what="the real CT head in the skull's row: a spherical transparency lens over the forehead"),
}
"""The lens scenes, keyed by scene name (note 004 §5; the real CT head beside the skull stand-in)."""

CUTAWAYS = {
    "seismic-cutaway": LensSetup("seismic", "layers", "box", (0.0, -0.5, 0.0), {"mode": "clip"}, size=(1.2, 1.0, 1.2),
                                 what="a box clip lens along the axes removing the front half of the cube (y < 0): "
                                      "one face cuts the box, so cropping regions and one clipping plane render "
                                      "it too (the peers' common ground)"),
}
"""Lens scenes beyond the paper's, for the peers (not in :data:`SETUPS`: the paper's experiments skip them)."""

PHANTOM_ASPECT = {"seismic": (1.0, 1.0, 1.0), "ct_skull": (1.0, 1.0, 1.0), "foot": (1.0, 1.0, 1.0),
                  "engine": (1.0, 1.0, 0.5)}
"""Each phantom's box proportions (its generator's ``Grid.for_aspect``): the longest edge has ``size`` voxels."""


def extent(dataset, size, *, real_data=None):
    """The world extent ``(ex, ey, ez)`` of ``dataset``'s box at phantom ``size`` (a real scan: its own).

    A real scan's extent is its manifest's dims times spacing; where the scan is absent the box of
    ``size`` voxels stands in (the run is then recorded as skipped for the missing data, so where its
    lens would lie does not matter).
    """
    spec = datasets.get(dataset)
    if spec.kind == "real":
        try:
            entry = read_manifest(real_data)[spec.source]
        except (DataUnavailableError, KeyError):
            return (float(size),) * 3
        spacing = entry.get("spacing", (1.0, 1.0, 1.0))
        return tuple(float(n) * float(s) for n, s in zip(entry["dims"], spacing))
    if dataset not in PHANTOM_ASPECT:
        raise InputError(f"lens scene: no box proportions for phantom {dataset!r}; add them to PHANTOM_ASPECT")
    return tuple(float(max(1, round(size * a))) for a in PHANTOM_ASPECT[dataset])


def _vector(values, name, length=3):
    values = tuple(float(v) for v in values)
    if len(values) != length:
        raise InputError(f"lens {name}: expected {length} numbers, got {values}")
    return values


def lens_entry(setup, box, *, radius=None, center=None, size=None, rotate_y=None, appearance=None):
    """The ``lenses`` entry of ``setup`` in a box of world extent ``box`` (:func:`extent`); the keywords replace
    :class:`LensSetup`'s fields (fractions of the box), ``None`` keeps the setup's."""
    center = _vector(setup.center if center is None else center, "center")
    entry = {"shape": setup.shape, "center": [round(c * e, 6) for c, e in zip(center, box)],
             "appearance": copy.deepcopy(setup.appearance if appearance is None else appearance)}
    if setup.shape == "sphere":
        if size is not None or rotate_y is not None:
            raise InputError(f"lens of {setup.dataset}: a sphere lens takes radius, not size or rotate_y")
        fraction = float(setup.radius if radius is None else radius)
        if not fraction > 0:
            raise InputError(f"lens radius: expected a fraction of the longest edge > 0, got {fraction}")
        entry["radius"] = round(fraction * max(box), 6)
    else:
        if radius is not None:
            raise InputError(f"lens of {setup.dataset}: a box lens takes size and rotate_y, not radius")
        fractions = _vector(setup.size if size is None else size, "size")
        if min(fractions) <= 0:
            raise InputError(f"lens size: expected fractions of the edges > 0, got {fractions}")
        entry["size"] = [round(f * e, 6) for f, e in zip(fractions, box)]
        degrees = float(setup.rotate_y if rotate_y is None else rotate_y)
        if degrees:
            entry["transform"] = {"rotate": {"axis": [0.0, 1.0, 0.0], "degrees": degrees}}
    return entry


def setup_of(name):
    setups = {**SETUPS, **CUTAWAYS}
    if name not in setups:
        raise InputError(f"unknown lens scene {name!r}; known: {', '.join(setups)}")
    return setups[name]


def scene_tags(name, **more):
    setup = setup_of(name)
    return {"scene": name, "dataset": setup.dataset, "preset": setup.preset, **more}


def lens_scene(name, image, *, size, real_data=None, **lens):
    """The scene mapping of lens scene ``name`` (:func:`setup_of`): ``image`` pixels high and wide, phantoms of
    ``size`` voxels along the longest edge (a real scan keeps its own grid) and the real scans from ``real_data``
    (the profile's; ``None``: the default). ``lens`` are :func:`lens_entry`'s keywords, a box lens's ``size`` as
    ``box_size``."""
    setup = setup_of(name)
    if "box_size" in lens:
        lens["size"] = lens.pop("box_size")
    volume = phantom(setup.dataset, size, preset=setup.preset)
    spec = scene(name, image, volumes=[volume])
    spec["lenses"] = [lens_entry(setup, extent(setup.dataset, size, real_data=real_data), **lens)]
    return spec


def without_lens(scene_spec):
    return {key: copy.deepcopy(value) for key, value in scene_spec.items() if key != "lenses"}


def outside_appearance(scene_spec):
    """``scene_spec`` with the lens showing the outside appearance, ``dvr`` with the volume's own preset: its image
    must be the lens-off image, the lens changing only which region each sample is composited in, never a colour."""
    if not scene_spec.get("lenses"):
        raise InputError(f"scene {scene_spec.get('name')!r} has no lens to give the outside appearance")
    out = copy.deepcopy(scene_spec)
    out["lenses"][0]["appearance"] = {"mode": "dvr", "preset": out["volumes"][0]["preset"]}
    return out


def lens_views(name, orbit=0):
    """The headline view of scene ``name``'s data set, then ``orbit`` views around it (20° pitch)."""
    dataset = setup_of(name).dataset
    return (headline_view(dataset),) + tuple(
        dataset_view(dataset, f"orbit{round(360.0 * i / orbit):03d}", 360.0 * i / orbit, 20.0) for i in range(orbit))
