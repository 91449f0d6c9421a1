"""Planning an experiment's runs: frames, backends and their options, views, scenes, phantoms, truth runs.

Every paper's experiments build their :class:`~pipeline.experiments.kit.model.Run` s from these, so
that two papers ask for a ground-truth render, a headline view or an untimed frame the same way.
"""

import math
import os

import datasets
import renderers
from core.errors import InputError
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.model import Run

REFERENCE = "reference"
"""The ground-truth backend."""

UNTIMED = {"warmup": 0, "repeat": 1}
"""Frames of a ground-truth or picture-only run: one untimed frame."""

HEADLINE_VIEW = {"view": "headline", "azimuth": 30.0, "elevation": 20.0}
"""The oblique view note 000 recommends for headline numbers (30° yaw, 20° pitch)."""

UPRIGHT = {"rotate": {"axis": [1, 0, 0], "degrees": -90}}
"""Scanner z (the body axis of the phantoms and CT stacks) to world y (up), the face to +z."""

CONTROLS = frozenset({"sphere", "constant_cube", "checkerboard", "fbm_control"})
"""Symmetric controls: viewed with plain orbit angles (their up axis means nothing)."""


def timed_frames(profile, experiment=None):
    """Frames and processes of a timed comparison: the profile's ``replicates`` processes, each with at least one
    untimed frame that compiled nothing (:mod:`pipeline.timing`) and its share of the arm's frames budget.

    An arm's budget is :data:`~.intervals.MIN_FRAMES` timed frames at least (fewer would leave the comparison's
    claims inconclusive whatever they measure: :func:`~.intervals.timing_decision`) and the profile's
    ``min_time``; an experiment's ``repeat`` setting raises the frames above the profile's (these frames take
    milliseconds, and on a shared machine the median of five is at the mercy of two interruptions). The
    budget is shared among the processes, each taking at least :data:`~.intervals.PROCESS_FRAMES`: replicates
    spread the frames over processes, whose spread the intervals then show, and add each process's start,
    warm-up and cold frame rather than multiplying the frames.
    """
    repeat = int(profile.repeat if experiment is None else profile.setting(experiment, "repeat", profile.repeat))
    min_time = float(profile.min_time if experiment is None else profile.setting(experiment, "min_time", profile.min_time))
    processes = int(profile.replicates)
    per_process = max(intervals.PROCESS_FRAMES if processes > 1 else 1,
                      math.ceil(max(intervals.MIN_FRAMES, repeat) / processes))
    return {"warmup": max(1, int(profile.warmup)), "repeat": per_process, "min_time": min_time / processes,
            "replicates": processes}


def volume_and_image_size(profile, experiment):
    """``(volume size, image size)`` of ``experiment``'s runs: its ``volume_size`` and ``image_size`` settings.

    Parameters
    ----------
    profile : Profile
    experiment : Experiment
        Its settings at the profile's scale; where it has none, the profile's own sizes.
    """
    return (profile.setting(experiment, "volume_size", profile.volume_size),
            profile.setting(experiment, "image_size", profile.image_size))


def usable_cores():
    """Cores this process may use (the render jobs take them all)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def is_registered(backend):
    return backend in renderers.names()


def unregistered(*backends):
    """``[(what, reason)]`` for each backend of ``backends`` the registry does not hold."""
    return [(backend, f"backend {backend!r} is not registered (renderers.names(): {', '.join(renderers.names())})")
            for backend in backends if not is_registered(backend)]


def accepts(backend, *options):
    """Whether ``backend`` is registered and its constructor takes every option name given.

    A backend whose module cannot be imported is planned anyway: the runner records its runs as
    skipped with the import error, which the report shows.
    """
    if not is_registered(backend):
        return False
    try:
        valid = renderers.option_names(renderers.backend_class(backend))
    except Exception:  # noqa: BLE001 - import failure: let the runner record the reason
        return True
    return valid is None or set(options) <= set(valid)


def missing_options(backend, *options):
    """``[(what, reason)]`` for options of ``backend`` that it does not take."""
    if not is_registered(backend):
        return []
    try:
        valid = renderers.option_names(renderers.backend_class(backend))
    except Exception:  # noqa: BLE001
        return []
    if valid is None:
        return []
    return [(f"{backend} option {o!r}", f"backend {backend!r} has no option {o!r} (options: {', '.join(valid)})")
            for o in options if o not in valid]


def z_up(name):
    """Whether data set ``name`` stores its body axis along z (heads, brains, the engine)."""
    return name not in CONTROLS and datasets.get(name).up_axis == "z"


def upright_view(view, azimuth, elevation=0.0):
    """The camera override that sees a z-up volume (untransformed) as an upright one at these angles.

    The gallery rotates such volumes by :data:`UPRIGHT` (scanner z up, the face to +z); here the
    volume keeps its own frame and the camera moves instead, with ``up`` along the scanner's z.
    Azimuth turns about the body axis, as the thesis's Fig. 5.3 turntable does.
    """
    a, e = math.radians(azimuth), math.radians(elevation)
    upright = (math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a))  # y up, face +z
    x, y, z = upright[0], -upright[2], upright[1]  # scanner frame: z up, face −y
    el = math.degrees(math.asin(max(-1.0, min(1.0, y))))
    az = math.degrees(math.atan2(x, z)) if math.hypot(x, z) > 1e-12 else 0.0
    return {"view": view, "azimuth": round(az, 6), "elevation": round(el, 6), "up": [0.0, 0.0, 1.0]}


def dataset_view(dataset, view, azimuth, elevation=0.0):
    """A view of ``dataset`` at orbit angles of its upright rendering."""
    if z_up(dataset):
        return upright_view(view, azimuth, elevation)
    return {"view": view, "azimuth": float(azimuth), "elevation": float(elevation)}


def headline_view(dataset):
    """The gallery's headline view (30° yaw, 20° pitch) of ``dataset``."""
    return dataset_view(dataset, HEADLINE_VIEW["view"], HEADLINE_VIEW["azimuth"], HEADLINE_VIEW["elevation"])


def phantom(dataset, /, size=None, **extra):
    """A volume entry of ``dataset``; ``size`` applies to phantoms only (a real scan has its own).

    ``extra`` are the entry's other keys (``preset``, ``name``, ``transform``, ...).
    """
    spec = {"dataset": dataset, **extra}
    if size is not None and datasets.get(dataset).kind == "phantom":
        spec["size"] = size
    return spec


def scene(name, image, *, volumes=(), meshes=(), mode="dvr", shading="phong", width=None, camera=None):
    """A scene mapping (:mod:`pipeline.scene_io`): ``image`` pixels high (and wide unless ``width``).

    Only what the scene uses is in it: ``meshes`` and ``camera`` appear when given.
    """
    spec = {"name": name, "width": int(width or image), "height": int(image), "mode": mode,
            "shading": {"model": shading}, "volumes": list(volumes)}
    if meshes:
        spec["meshes"] = list(meshes)
    if camera:
        spec["camera"] = dict(camera)
    return spec


def truth_run(experiment, prefix, scene_spec, views, step_factor, tags, *, options=None, suffix="", **extra_tags):
    """The ground truth ``<prefix>.truth<suffix>``: the reference renderer, one untimed frame.

    Parameters
    ----------
    experiment, prefix : str
        The experiment's name and the run id's prefix.
    scene_spec : dict
    views : tuple of dict
    step_factor : float
        The reference's step, as a fraction of a voxel.
    tags : dict
        The run's tags; ``role="truth"`` and then ``extra_tags`` are added.
    options : dict, optional
        More reference options (``classification="pre"``).
    suffix : str
        Appended to the run id (``"-pre"``).
    """
    return Run(experiment, f"{prefix}.truth{suffix}", REFERENCE, scene_spec, tuple(views),
               options={"step_factor": step_factor, **(options or {})}, **UNTIMED,
               tags={**tags, "role": "truth", **extra_tags})


def listed(profile, experiment, key, default, known=None):
    """The list setting ``key`` of ``experiment`` (:meth:`Profile.setting`), every value among ``known``."""
    values = list(profile.setting(experiment, key, list(default)))
    if known is not None:
        unknown = [v for v in values if v not in known]
        if unknown:
            name = experiment if isinstance(experiment, str) else experiment.name
            raise InputError(f"profile {profile.name!r} settings.{name}.{key}: unknown {unknown}; "
                             f"known: {list(known)}")
    return values


def voxels(step):
    """A step in voxels as the notes write it: ``1/32`` rather than 0.03125."""
    inverse = 1 / step
    return f"1/{inverse:g}" if step < 1 and float(inverse).is_integer() else f"{step:g}"


def orbit_views(dataset, orbit, *, repeat_headline=False):
    """The headline view of ``dataset`` and ``orbit`` more around it at 20° elevation, evenly spaced from 0°.

    Parameters
    ----------
    dataset : str
        The data set viewed (:func:`dataset_view`: a z-up one is turned upright).
    orbit : int
        How many orbit views (``"orbit000"``, ``"orbit090"``, …); 0: the headline view alone.
    repeat_headline : bool
        Keep an orbit view at the headline's azimuth (30°) too; by default it is left out.

    Returns
    -------
    tuple of dict
    """
    return (headline_view(dataset),) + tuple(
        dataset_view(dataset, f"orbit{int(a):03d}", a, 20.0) for a in (i * 360.0 / max(orbit, 1) for i in range(orbit))
        if repeat_headline or a != HEADLINE_VIEW["azimuth"])
