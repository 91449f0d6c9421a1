"""Renderer interface, capabilities and the result record (CONVENTIONS, Results)."""

import abc
from dataclasses import dataclass, field

import numpy as np

from core.errors import InputError, UnsupportedFeatureError
from core.scene import Scene
from renderers.base import options as declared

GEOMETRY_FEATURES = ("csg", "translucent_geometry", "homogeneous_media")
"""Features that build on ``meshes``: a backend without meshes lacks them for the same reason."""


@dataclass(frozen=True)
class Capabilities:
    """What a backend can render, and why not where it cannot.

    The defaults are the contract's common case (one orthographic, unshaded ``dvr`` volume); a
    backend states only what differs from them, and a reason for each feature it lacks.

    Parameters
    ----------
    projections, modes, shading : frozenset of str
        Supported camera projections, render modes and shading models.
    max_volumes : int
        Largest number of volume instances in one scene.
    gradient_opacity, transforms, anisotropic_spacing, meshes, lenses : bool
        Optional features. ``meshes``: closed mesh instances and polygonal volume boundaries
        (:mod:`core.mesh`) with opaque surfaces.
    csg, translucent_geometry, homogeneous_media : bool
        CSG trees, surfaces with alpha < 1, and mesh interiors filled with a homogeneous medium
        (:class:`core.scene.Scene` keys of the same names). Where the reason for one of them is
        not given, a backend without ``meshes`` refuses it with its reason for ``meshes``.
    camera_inside_volume : bool
        Whether a perspective eye may sit inside a volume box.
    reasons : dict
        ``feature name → why it is missing``; every unsupported feature has an entry.
    """

    projections: frozenset = frozenset({"orthographic"})
    modes: frozenset = frozenset({"dvr"})
    shading: frozenset = frozenset({"none"})
    max_volumes: int = 1
    gradient_opacity: bool = False
    transforms: bool = False
    anisotropic_spacing: bool = True
    meshes: bool = False
    csg: bool = False
    translucent_geometry: bool = False
    homogeneous_media: bool = False
    lenses: bool = False
    camera_inside_volume: bool = False
    reasons: dict = field(default_factory=dict)

    def missing(self, scene):
        """``[(feature, reason), ...]`` for every feature ``scene`` needs that is missing."""
        problems = []
        for feature, value in scene.features().items():
            supported = getattr(self, feature)
            if isinstance(supported, frozenset):
                ok = value in supported
                label = f"{feature} {value!r}"
            elif feature == "max_volumes":
                ok = value <= supported
                label = f"{value} volumes"
            else:
                ok = bool(supported)
                label = feature
            if not ok:
                fallback = "not implemented"
                if feature in GEOMETRY_FEATURES and not self.meshes:
                    fallback = self.reasons.get("meshes", fallback)
                problems.append((label, self.reasons.get(feature, fallback)))
        if scene.camera.projection == "perspective" and not self.camera_inside_volume:
            inside = scene.camera_inside_volume()
            if inside:
                problems.append(
                    (f"camera inside volume {', '.join(inside)}",
                     self.reasons.get("camera_inside_volume", "rays must start outside every volume box"))
                )
        return problems

    def as_dict(self):
        out = {}
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            out[name] = sorted(value) if isinstance(value, frozenset) else value
        return out


@dataclass
class RenderResult:
    """One rendered frame (or the median of repeated frames, see ``pipeline.timing``).

    Parameters
    ----------
    image : numpy.ndarray
        ``(H, W, 4)`` float32, linear, premultiplied RGBA, row 0 at the top.
    timings : dict
        Stage name → seconds, always with ``"total"``.
    counters : dict
        Counter name → integer (samples taken, rays terminated early, ...).
    timings_min, timings_max : dict
        Per-stage minimum and maximum over repeated frames (filled by the timing harness).
    info : dict
        Backend facts for the record (e.g. the step actually used).
    frames : dict
        Stage name → the seconds of every timed frame, in the order taken (filled by the timing
        harness; claims take their confidence intervals from them).
    """

    image: np.ndarray
    timings: dict
    counters: dict = field(default_factory=dict)
    timings_min: dict = field(default_factory=dict)
    timings_max: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    frames: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.image.ndim != 3 or self.image.shape[2] != 4 or self.image.dtype != np.float32:
            raise ValueError(f"RenderResult.image must be (H, W, 4) float32, got {self.image.dtype} {self.image.shape}")
        if "total" not in self.timings:
            raise ValueError("RenderResult.timings must contain 'total'")


class Renderer(abc.ABC):
    """A volume-rendering backend.

    Subclasses set ``name``, ``description``, ``capabilities`` (what differs from the defaults)
    and ``option_table``, and implement :meth:`_render`; a subclass's ``__init__``, where it needs
    one, calls ``super().__init__(**options)`` and then checks what relates several options.
    :meth:`render` checks the scene against the capabilities first, so a missing feature raises
    :class:`UnsupportedFeatureError` before any work starts.
    """

    name = "abstract"
    description = ""
    capabilities = Capabilities()
    option_table = ()
    """The keyword options (:class:`renderers.base.options.Option`), each declared once: they make the
    constructor's signature and validation, the attributes, :attr:`options` and the docstring's
    Parameters section, in this order."""
    quality_sweep = ({},)
    """Option sets from fast/coarse to slow/fine for the speed-versus-accuracy study."""
    graphics_stack = None
    """The OpenGL stack the backend renders through in its process (``"moderngl"``, ``"vtk"``), or ``None``.
    Two stacks in one process do not mix: a job timing vtk-gpu beside a moderngl backend rendered every
    image of both empty (llvmpipe, measured), so an interleave group that mixes them is timed in a process per
    stack (:func:`pipeline.experiments.stack_parts`)."""

    scheduling_dependent = ()
    """Names of counters and info entries whose values follow how threads or work-items were
    scheduled, not only the scene and options: they may differ from run to run (and between a
    loaded and an idle machine) where the image does not. Comparisons of two runs leave them out."""

    @classmethod
    def quality_sweep_for(cls, mode):
        """The settings of :attr:`quality_sweep` that change something in ``mode``: a setting that varies an option
        of other modes only (:attr:`Option.modes <renderers.base.options.Option.modes>`) would repeat another. Where no
        setting changes anything in ``mode`` (an exact method has no step), the defaults ``({},)`` are the one setting."""
        modes = {option.name: option.modes for option in cls.option_table}
        kept = tuple(setting for setting in cls.quality_sweep
                     if all(modes.get(name) is None or mode in modes[name] for name in setting))
        return kept or ({},)

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        own = vars(cls)
        if "option_table" in own and cls.__doc__:
            cls.__doc__ = declared.document(cls.__doc__, cls.option_table)
        # A subclass with an __init__ of its own and no table says in that __init__ what it takes.
        if "option_table" in own or "__init__" not in own:
            cls.__signature__ = declared.signature(cls.option_table)

    def __init__(self, **options):
        """Set each option of :attr:`option_table`, given or default, validated (unknown ones refused)."""
        for attribute, value in declared.take_options(self.name, self.option_table, options).items():
            setattr(self, attribute, value)

    @classmethod
    def probe(cls):
        """``(True, "")`` if the backend can run on this machine, else ``(False, reason)``."""
        return True, ""

    @property
    def options(self):
        """The recorded options' values, recorded with every result (a subclass adds derived entries)."""
        return {option.name: getattr(self, option.holder) for option in self.option_table if option.recorded}

    def environment(self):
        """Backend-specific environment facts (GL renderer, OpenCL device, library version)."""
        return {}

    def check(self, scene):
        """Raise :class:`UnsupportedFeatureError` if ``scene`` needs a missing feature, and
        :class:`InputError` if an ``iso`` scene has a volume without an isovalue."""
        if not isinstance(scene, Scene):
            raise InputError(f"render: expected a Scene, got {type(scene).__name__}")
        missing = self.capabilities.missing(scene)
        if missing:
            feature, reason = missing[0]
            raise UnsupportedFeatureError(self.name, feature, reason)
        if scene.mode == "iso":
            for instance in scene.volumes:
                if instance.isovalue is None:
                    raise InputError(f"volume instance {instance.name!r}: iso mode needs an isovalue; "
                                     "set VolumeInstance.isovalue")

    def render(self, scene):
        """Render ``scene`` once and return a :class:`RenderResult`."""
        self.check(scene)
        return self._render(scene)

    @abc.abstractmethod
    def _render(self, scene):
        """Backend-specific rendering of a validated scene."""

    technique_stages = ()
    """The stages that are the technique itself (its kernels or its library call), whose sum the timing
    harness records as the stage ``technique`` beside ``total`` (the whole frame, Python and conversions
    included): a speed claim compares like with like, technique against technique or frame against frame.
    Empty: the backend's frame is not split, and ``technique`` is not recorded."""

    caches_preprocessing = False
    """Whether a frame reuses preprocessing an earlier frame built (a classified volume, extracted
    surfaces), which :meth:`drop_caches` forgets. The timing harness then times the preprocessing as
    stages of their own, once per view, from a frame that built it with its code compiled
    (:mod:`pipeline.timing`); such a backend compiles only where :mod:`renderers.base.compilation`
    counts it."""

    def drop_caches(self):
        """Forget cached preprocessing, so that the next frame builds it again.

        Only a backend that sets :attr:`caches_preprocessing` overrides it.
        """

    def close(self):
        """Release contexts and device memory."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
