"""The table of every data set volbench knows: generated phantoms and real scans.

Each entry is a :class:`DatasetSpec`: what the data set stands for, which papers use it, its
classification presets and, for phantoms, the generator and the statistics the reproduction
notes ask the stand-in to reach. Thresholds in the presets are raw voxel values (see
:mod:`datasets.presets`); where a note gives a transfer function the preset follows it.

Targets are the numbers the notes give for the original data sets, under the preset that
mirrors the paper's classification; :attr:`DatasetSpec.targets` are those of the default preset
(what the phantom gallery renders), :attr:`DatasetSpec.targets_by_preset` all of them.
"""

import inspect
from dataclasses import dataclass, field
from typing import Callable

from datasets import presets as P
from datasets.phantoms import bonsai, clouds, controls, engine, foot, geology, heads, torso, tubes, vessels
from core.errors import InputError
from core.papers import PAPERS
from core.resources import check_memory, largest_fitting
from core.transfer import VOLPACK_GRADIENT_RAMP, Preset

KINDS = ("phantom", "real")

PHANTOM_BYTES_PER_VOXEL = 48
"""Peak memory of generating a phantom, in bytes per voxel of its ``size³`` cube.

The generators hold several float32 and float64 fields of the whole grid at once (distance
fields, noise octaves, the canvas): tracemalloc measures 10 to 46 bytes a voxel at 64³–128³,
``ct_skull`` the most; the finished uint8 volume is one byte a voxel of that."""


@dataclass(frozen=True, eq=False)
class DatasetSpec:
    """One registered data set.

    Parameters
    ----------
    name : str
    kind : {"phantom", "real"}
    description : str
        What it is and what it stands in for.
    papers : tuple of str
        Keys of :data:`PAPERS` whose experiments use it.
    presets : dict of str to Preset
    default_preset : str
    generator : callable, optional
        Phantoms only: ``generator(size, seed, **params) -> Volume``.
    default_size : int, optional
        Phantoms only: voxels along the longest axis when ``load`` is given none.
    targets_by_preset : dict, optional
        ``{preset: {statistic: value}}``: what the notes report for the original data set, with
        statistic names as returned by :func:`datasets.statistics`.
    version : int
        Bump when a generator's output changes on purpose (part of the cache key, together with
        a digest of the generator source).
    modality : str
    source : str, optional
        Real data sets only: the real-data manifest entry (``"brainsmall"``: VolPack's ``.den``
        example) when it differs from ``name``.
    up_axis : {"z", "y"}
        The object axis that points up in the subject: ``"z"`` for scanner stacks (the body axis),
        ``"y"`` for data stored upright in y. Galleries turn it to the world's up.
    """

    name: str
    kind: str
    description: str
    papers: tuple
    presets: dict
    default_preset: str
    generator: Callable | None = None
    default_size: int | None = None
    targets_by_preset: dict = field(default_factory=dict)
    version: int = 1
    modality: str = ""
    source: str | None = None
    up_axis: str = "z"

    def __post_init__(self):
        where = f"data set {self.name!r}"
        if self.kind not in KINDS:
            raise InputError(f"{where}: kind must be one of {KINDS}, got {self.kind!r}")
        unknown = set(self.papers) - set(PAPERS)
        if unknown:
            raise InputError(f"{where}: unknown paper ids {sorted(unknown)}; known: {sorted(PAPERS)}")
        if self.default_preset not in self.presets:
            raise InputError(f"{where}: default preset {self.default_preset!r} is not one of {sorted(self.presets)}")
        if not all(isinstance(p, Preset) for p in self.presets.values()):
            raise InputError(f"{where}: every preset must be a core.transfer.Preset")
        if set(self.targets_by_preset) - set(self.presets):
            raise InputError(f"{where}: targets name presets it does not have: {sorted(set(self.targets_by_preset) - set(self.presets))}")
        if (self.kind == "phantom") != (self.generator is not None):
            raise InputError(f"{where}: a phantom needs a generator and a real data set must not have one")
        if self.kind == "phantom" and not (isinstance(self.default_size, int) and self.default_size >= 2):
            raise InputError(f"{where}: a phantom needs an integer default_size >= 2")
        if self.kind == "real" and self.source is None:
            object.__setattr__(self, "source", self.name)

    @property
    def targets(self):
        """Target statistics under the default preset (``{}`` when the notes give none)."""
        return dict(self.targets_by_preset.get(self.default_preset, {}))

    def preset(self, name=None):
        """The preset called ``name`` (the default preset when ``None``)."""
        name = self.default_preset if name is None else name
        if name not in self.presets:
            raise InputError(f"data set {self.name!r} has no preset {name!r}; presets: {', '.join(self.presets)}")
        return self.presets[name]

    def check_memory(self, size, *, where):
        """Refuse a phantom ``size`` whose generation this machine cannot hold, before generating.

        ``size`` is a validated integer; ``where`` names it in the message (``"volumes[0] size"``).

        Raises
        ------
        InputError
            The estimate (:data:`PHANTOM_BYTES_PER_VOXEL` per voxel of ``size³``) exceeds the
            machine's memory; the message names the largest size that fits.
        """
        check_memory(size ** 3 * PHANTOM_BYTES_PER_VOXEL, what=f"{where} {size}: phantom {self.name!r}",
                     detail=f"{size}³ voxels × {PHANTOM_BYTES_PER_VOXEL} bytes of working arrays while it is generated",
                     fix=lambda limit: f"use size ≤ {largest_fitting(limit, PHANTOM_BYTES_PER_VOXEL, power=3)}")

    @property
    def parameters(self):
        """The generator's extra keyword parameters and their defaults (phantoms only)."""
        if self.generator is None:
            return {}
        signature = inspect.signature(self.generator)
        return {name: p.default for name, p in list(signature.parameters.items())[2:]}


def _phantom(name, generator, description, papers, presets, default, *, size=256, targets=None):
    return DatasetSpec(name, "phantom", description, tuple(papers), presets, default, generator, size,
                       targets or {})


# Colours used by several presets.
GOLD = (0.95, 0.75, 0.35)
LEAF = (0.35, 0.7, 0.25)
WOOD = (0.55, 0.35, 0.18)
TERRACOTTA = (0.8, 0.4, 0.25)
BRAIN = (0.92, 0.82, 0.78)
LIVER = (0.6, 0.25, 0.2)
KIDNEY = (0.9, 0.6, 0.35)
COPPER = (0.85, 0.5, 0.3)


def _skin_and_bone(bone_low, bone_high, *, band=(25, 40, 65, 85), scale=255.0, alpha=0.35, name="skin"):
    """Two materials (Lacroute's Fig. 5.5): a semi-transparent skin band at the air/tissue
    boundary and opaque bone above ``bone_low``–``bone_high``."""
    a, b, c, d = band
    return P.points([(a, P.SKIN_COLOR, 0.0), (b, P.SKIN_COLOR, alpha), (c, P.SKIN_COLOR, alpha),
                     (d, P.SKIN_COLOR, 0.0), (bone_low, P.BONE_COLOR, 0.0), (bone_high, P.BONE_COLOR, 1.0)],
                    scale=scale, name=name,
                    description=f"semi-transparent skin (α {alpha:g}) over opaque bone")


def _bonsai_tree():
    """The bonsai's classification (phantom and real scan alike): faint leaves, wood, opaque pot."""
    return P.points([(25, LEAF, 0.0), (40, LEAF, 0.15), (70, LEAF, 0.15), (90, WOOD, 0.0), (110, WOOD, 0.6),
                     (170, WOOD, 0.8), (190, TERRACOTTA, 1.0)], name="tree",
                    description="leaves α 0.15, wood 0.6–0.8, pot opaque (the real bonsai's levels)")


def _engine_presets(a_low, a_high, b_low, b_high):
    """The engine's classifications, given where material A and material B start."""
    alu, steel = P.ALUMINIUM_COLOR, P.STEEL_COLOR
    return {
        "semi": P.points([(a_low, alu, 0.0), (a_high, alu, 0.04), (b_low, alu, 0.04), (b_high, steel, 0.6),
                          (255, steel, 0.8)], name="semi",
                         description="material A semi-transparent (α 0.04 per step), material B more opaque (note 000)"),
        "surfaces": P.points([(a_low, alu, 0.0), (a_high, alu, 0.25), (b_low, alu, 0.25), (b_high, steel, 1.0)],
                             gradient=VOLPACK_GRADIENT_RAMP, name="surfaces",
                             description="gradient-weighted: A's boundaries α 0.25, B's opaque (note 003)"),
        "binary": P.step(a_high, alu, name="binary"),
        "smooth": P.opaque(a_low - 30, b_high, alu, name="smooth",
                           description="wide opacity ramp: the low-passing classification of Fig. 5.10c"),
        "volpack": P.volpack(),
    }


def _phantoms():
    volpack = P.volpack()
    skull_bone = P.opaque(160, 200, P.BONE_COLOR, name="bone", description="opaque bone: α 0 → 1 over 160–200")
    return [
        _phantom("mri_head", heads.mri_head,
                 "T1 MRI head with face, nose, lips, ears, neck and shoulders: scalp, dark skull with marrow, "
                 "CSF, folded grey over white matter, over Rayleigh background noise. Stand-in for Krüger & "
                 "Westermann's 256³ MRI head (note 000 §6). Rays saturate at the scalp.",
                 ["kruger2003"],
                 {"skin": P.opaque(40, 80, P.SKIN_COLOR, alpha=0.8, name="skin",
                                   description="opaque skin: α 0 → 0.8 over 40–80, 0 below (note 000)"),
                  "semi_transparent": P.points([(40, P.SKIN_COLOR, 0.0), (80, P.SKIN_COLOR, 0.02),
                                                (140, BRAIN, 0.06)], name="semi_transparent",
                                               description="faint scalp and brighter white matter: no early termination"),
                  "volpack": volpack},
                 "skin", targets={"skin": {"nontransparent_fraction": 0.425}}),
        _phantom("ct_skull", heads.ct_skull,
                 "CT head: cranium of varying thickness over a folded brain, orbits, nasal cavity, sinuses, "
                 "zygomatic arches, maxilla and mandible with 32 teeth, cervical vertebrae; a face with nose, "
                 "lips and ears on the scanner's head rest. Stands in for Lacroute's CT head (note 003), the "
                 "iSBVR Head (note 001) and Ropinski's skull (note 004).",
                 ["lacroute1995", "xue2005", "ropinski2005", "kainz2009"],
                 {"bone": skull_bone,
                  "skin": _skin_and_bone(160, 200, band=(25, 45, 65, 85), alpha=0.12),
                  "bone_surfaces": P.surfaces(160, 200, P.BONE_COLOR, name="bone_surfaces"),
                  "isbvr": P.points([(50, P.SKIN_COLOR, 0.0), (170, P.BONE_COLOR, 1.0)], name="isbvr",
                                    description="α 0 below iso_t = 50, ramp to 1 at iso_p = 170 (note 001)"),
                  "volpack": volpack},
                 "bone", targets={"bone": {"nontransparent_fraction": 0.05},
                                  "bone_surfaces": {"nontransparent_fraction": 0.05, "runs_per_scanline": 5.8,
                                                    "mean_run_length": 2.4},
                                  "skin": {"nontransparent_fraction": 0.11}}),
        _phantom("folded_brain", heads.folded_brain,
                 "MR head whose scalp and skull are cut away over the upper left, showing a cortex folded "
                 "by gyri and sulci (256×256×167 at size 256): Lacroute's brain; with decimate=2 at size "
                 "128 his brainsmall (128×128×84), note 003 §5.",
                 ["lacroute1995"],
                 {"volpack": P.volpack(BRAIN),
                  "opaque": P.opaque(60, 100, BRAIN, name="opaque")},
                 "volpack", targets={"volpack": {"nontransparent_fraction": 0.11, "runs_per_scanline": 12.5}}),
        _phantom("aneurysm", vessels.aneurysm,
                 "3-D rotational angiography: three arterial trees whose radii taper by Murray's law and a "
                 "saccular aneurysm over a near-zero background; most 8³ blocks empty (notes 000, 001).",
                 ["kruger2003", "xue2005"],
                 {"vessels": P.opaque(60, 100, P.VESSEL_COLOR, alpha=0.9, name="vessels",
                                      description="α 0 below 60, 0.9 above 100 (note 000)"),
                  "isbvr": P.points([(50, P.VESSEL_COLOR, 0.0), (150, (1.0, 0.85, 0.8), 1.0)], name="isbvr",
                                    description="iso_t 50, iso_p 150 (note 001)")},
                 "vessels", targets={"vessels": {"nontransparent_fraction": 0.02}}),
        _phantom("foot", foot.foot,
                 "CT foot lying diagonally: the 26 bones of the foot (tarsals, metatarsals, phalanges) with "
                 "tibia and fibula, cortical shells over cancellous bone, in soft tissue with toes (notes 000, 004).",
                 ["kruger2003", "ropinski2005"],
                 {"bone": P.opaque(120, 170, P.BONE_COLOR, name="bone",
                                   description="soft tissue transparent, bone opaque (note 000)"),
                  "skin_bone": P.points([(30, P.SKIN_COLOR, 0.0), (50, P.SKIN_COLOR, 0.02), (90, P.SKIN_COLOR, 0.02),
                                         (120, P.BONE_COLOR, 0.0), (170, P.BONE_COLOR, 1.0)], name="skin_bone",
                                        description="faint soft tissue plus opaque bone (note 004's context)"),
                  "iso": P.points([(185, P.BONE_COLOR, 0.0), (195, P.BONE_COLOR, 1.0)], name="iso", isovalue=191,
                                  description="bone isosurface at 0.75 (note 004's lens appearance)"),
                  "soft_tissue": P.opaque(30, 60, P.SKIN_COLOR, name="soft_tissue",
                                          description="the soft-tissue envelope as an opaque surface")},
                 "bone", targets={"soft_tissue": {"nontransparent_fraction": 0.25}}),
        _phantom("engine", engine.engine,
                 "Engine block, size × size × size/2: thin-walled aluminium casting (A) with bores, water "
                 "jacket, webs, cooling ribs and bosses; steel valves, studs, bolts and crankshaft (B). "
                 "Notes 000, 003, 004; the "
                 "binary and smooth presets are the Fig. 5.10 aliasing test.",
                 ["kruger2003", "lacroute1995", "ropinski2005"],
                 _engine_presets(50, 90, 160, 200),
                 "semi", targets={"semi": {"nonzero_fraction": 0.35},
                                  "surfaces": {"nontransparent_fraction": 0.08, "runs_per_scanline": 10.7}}),
        _phantom("torso", torso.torso,
                 "Contrast-enhanced abdomen CT (257×257×159 at size 257) with an integer label volume: "
                 "lung bases, spine with processes, lower rib cage with costal cartilage, iliac crests, "
                 "kidneys, liver with tumour, spleen, aorta, vena cava and arterial trees (notes 003, 002).",
                 ["lacroute1995", "kainz2009"],
                 {"abdomen": P.points([(15, P.SKIN_COLOR, 0.0), (30, P.SKIN_COLOR, 0.2), (50, P.SKIN_COLOR, 0.2),
                                       (60, P.SKIN_COLOR, 0.0), (103, LIVER, 0.0), (108, LIVER, 0.06),
                                       (118, LIVER, 0.06), (124, LIVER, 0.0), (130, KIDNEY, 0.0), (136, KIDNEY, 0.3),
                                       (150, KIDNEY, 0.3), (160, KIDNEY, 0.0), (175, P.BONE_COLOR, 0.0),
                                       (195, P.BONE_COLOR, 0.9), (228, P.BONE_COLOR, 0.9), (236, P.VESSEL_COLOR, 1.0)],
                                      name="abdomen",
                                      description="multi-material, after the thesis's Fig. 5.7: skin, liver and "
                                                  "kidneys semi-transparent, bone and dye opaque"),
                  "dye_bone": P.points([(150, P.BONE_COLOR, 0.0), (190, P.BONE_COLOR, 0.9), (228, P.BONE_COLOR, 0.9),
                                        (236, P.VESSEL_COLOR, 1.0)], name="dye_bone",
                                       description="opaque bone (ivory) and dye (red)")},
                 "abdomen", size=257, targets={"abdomen": {"nontransparent_fraction": 0.11}}),
        _phantom("sphere", controls.sphere,
                 "One band-limited sphere, radius 0.39 of the box: the view-independence control (note 003).",
                 ["lacroute1995"],
                 {"opaque": P.opaque(60, 140, P.BONE_COLOR, name="opaque"),
                  "binary": P.step(100, P.BONE_COLOR, name="binary")},
                 "opaque"),
        _phantom("tube", tubes.tube,
                 f"Parallel straight tubes along z, `radius` voxels ({tubes.MIN_RADIUS:g} to {tubes.MAX_RADIUS:g}), "
                 f"{tubes.TUBE_SPACING} voxels apart in a row along x through the box's centre voxel: a linear "
                 "radial ramp whose trilinear iso-surface at 0.5 is a "
                 "tube of that radius however thin. The stability atlas's thin features: where a sampled "
                 "iso-surface hit steps over a tube.",
                 [],
                 {"iso": P.points([(117, COPPER, 0.0), (138, COPPER, 1.0)], name="iso", isovalue=127.5,
                                  description="iso-surface at 0.5 (raw 127.5), the tube's radius; in dvr an "
                                              "opaque ramp over 117–138 about it")},
                 "iso", size=64),
        _phantom("constant_cube", controls.constant_cube,
                 "Every voxel equal to `value`; with the identity preset α = value/255 (note 003 Fig. 5.19).",
                 ["lacroute1995"],
                 {"identity": P.identity(name="identity")},
                 "identity"),
        _phantom("checkerboard", controls.checkerboard,
                 "Hard-edged 3-D checkerboard of `block`-voxel cubes: exact runs per scanline "
                 "(note 003 Figs 5.20–5.21).",
                 ["lacroute1995"],
                 {"identity": P.identity(name="identity"),
                  "step": P.step(1, P.WHITE, name="step", description="every non-zero voxel opaque")},
                 "identity", targets={"identity": {"nontransparent_fraction": 0.5}}),
        _phantom("fbm_control", controls.fbm_control,
                 "Smooth fBm filling the cube, values 50–200: the no-cue control (note 000, E2).",
                 ["kruger2003", "xue2005"],
                 {"no_cue": P.constant(0.003, name="no_cue",
                                       description="uniform α 0.003: no ray terminates, no block is empty")},
                 "no_cue", targets={"no_cue": {"empty_block_fraction": 0.0, "nonzero_fraction": 1.0}}),
        _phantom("smoke_cloud", clouds.smoke_cloud,
                 "A puff of smoke (fBm × radial falloff); each seed a different cloud (note 002, C8).",
                 ["kainz2009"],
                 {"smoke": P.points([(10, (0.7, 0.7, 0.75), 0.0), (255, P.WHITE, 0.08)], name="smoke",
                                    description="highly transparent (note 002's timing TF)"),
                  "dense": P.opaque(60, 160, (0.85, 0.85, 0.9), name="dense")},
                 "smoke", size=64),
        _phantom("golden_lady", clouds.golden_lady,
                 "A standing woman in a long dress inside a broad low-density haze (`haze` scales it): "
                 "iSBVR's fuzzy golden lady (note 001).",
                 ["xue2005"],
                 {"fuzzy": P.points([(28, GOLD, 0.0), (32, GOLD, 0.02), (60, GOLD, 0.05), (150, GOLD, 0.3),
                                     (190, GOLD, 1.0)], name="fuzzy"),
                  "isbvr": P.points([(30, GOLD, 0.0), (190, GOLD, 1.0)], name="isbvr",
                                    description="iso_t 30, iso_p 190 (note 001)")},
                 "fuzzy"),
        _phantom("seismic", geology.seismic,
                 "Layered seismic cube with folds and two faults, no empty space (note 004).",
                 ["ropinski2005"],
                 {"layers": P.points([(40, (0.2, 0.35, 0.9), 0.1), (128, (0.95, 0.95, 0.95), 0.3),
                                      (230, (0.9, 0.25, 0.15), 0.8)], name="layers")},
                 "layers"),
        _phantom("bonsai_like", bonsai.bonsai_like,
                 "Bonsai on a board: deep pot of soil, flaring trunk, branches and foliage pads of leaf "
                 "clusters, much air; the real bonsai's grey levels and classification (note 001).",
                 ["xue2005"],
                 {"tree": _bonsai_tree(),
                  "isbvr": P.points([(50, LEAF, 0.0), (170, WOOD, 1.0)], name="isbvr",
                                    description="iso_t 50, iso_p 170 (note 001)")},
                 "tree"),
    ]


def _real(name, description, papers, presets, default, modality, source=None, up_axis="z"):
    return DatasetSpec(name, "real", description, tuple(papers), presets, default, modality=modality, source=source,
                       up_axis=up_axis)


def _reals():
    return [
        _real("cthead", "CT head, 256×256×99, spacing 1:1:2 (an 8-bit CThead).",
              ["lacroute1995", "xue2005"],
              {"bone": P.opaque(110, 160, P.BONE_COLOR, name="bone"),
               "skin": _skin_and_bone(110, 160, band=(25, 40, 60, 75)),
               "isbvr": P.points([(40, P.SKIN_COLOR, 0.0), (160, P.BONE_COLOR, 1.0)], name="isbvr",
                                 description="iso_t 40 (skin), iso_p 160 (bone) (note 001)"),
               "volpack": P.volpack()}, "bone", "CT head"),
        _real("mrihead", "T1 MRI head with skull, 188×256×190, 0.88 mm.",
              ["kruger2003", "lacroute1995"],
              {"skin": P.opaque(40, 80, P.SKIN_COLOR, alpha=0.8, name="skin"),
               "volpack": P.volpack()}, "skin", "MRI T1 head"),
        _real("engine_real", "Industrial CT of two engine cylinders, 256×256×128 (the manifest's "
              "'engine'; the name 'engine' is the phantom).",
              ["kruger2003", "lacroute1995", "ropinski2005"],
              _engine_presets(90, 120, 165, 190), "semi", "industrial CT", source="engine"),
        _real("bonsai", "CT of a bonsai tree, 256³.", ["xue2005"],
              {"tree": _bonsai_tree(),
               "isbvr": P.points([(50, LEAF, 0.0), (170, WOOD, 1.0)], name="isbvr")}, "tree", "CT", up_axis="y"),
        _real("tooth", "Industrial CT of a tooth, 103×94×161 (background ≈75).", [],
              {"tooth": P.points([(100, (0.95, 0.9, 0.75), 0.0), (130, (0.95, 0.9, 0.75), 0.2),
                                  (180, (0.95, 0.9, 0.75), 0.4), (210, P.WHITE, 1.0)], name="tooth",
                                 description="dentin semi-transparent, enamel opaque")}, "tooth", "industrial CT"),
        _real("headsq", "CT head at quarter resolution, 64×64×93 uint16 (12-bit: range 0–4095).", [],
              {"skin": _skin_and_bone(1150, 1500, band=(300, 500, 800, 950), scale=4095.0),
               "bone": P.opaque(1150, 1500, P.BONE_COLOR, scale=4095.0, name="bone")}, "skin", "CT head"),
        _real("neghip", "Simulated negative potential of a high-potential iron protein, 66³.", [],
              {"potential": P.points([(20, (0.2, 0.3, 0.9), 0.0), (60, (0.2, 0.8, 0.9), 0.1),
                                      (120, (0.95, 0.85, 0.3), 0.3), (255, (0.9, 0.2, 0.1), 0.8)], name="potential")},
              "potential", "simulation"),
        _real("nucleon", "Simulated nucleon density, 41³.", [],
              {"density": P.points([(30, (0.2, 0.3, 0.9), 0.0), (100, (0.2, 0.8, 0.3), 0.1),
                                    (200, (0.9, 0.2, 0.1), 0.5)], name="density")}, "density", "simulation"),
        _real("brainsmall", "VolPack's example MR brain (brainsmall.den, 128×128×84), the thesis's brainsmall.",
              ["lacroute1995"],
              {"volpack": P.volpack(BRAIN), "opaque": P.opaque(30, 60, BRAIN, name="opaque")}, "volpack", "MRI"),
    ]


def generic_real_spec(name, entry):
    """A spec for a real-data manifest entry the table does not know: generic grey presets."""
    return _real(name, f"{entry.get('modality', 'volume')} from the real-data manifest ({entry['file']}).", [],
                 {"opaque": P.opaque(0.25, 0.5, P.WHITE, scale=1.0, name="opaque"),
                  "semi_transparent": P.opaque(0.1, 1.0, P.WHITE, alpha=0.3, scale=1.0, name="semi_transparent")},
                 "opaque", entry.get("modality", ""))


def _table(specs):
    table = {}
    for spec in specs:
        if spec.name in table:
            raise InputError(f"data set {spec.name!r} is registered twice")
        table[spec.name] = spec
    return table


DATASETS = _table((*_phantoms(), *_reals()))
"""Every registered data set by name: phantoms first, then real scans."""
