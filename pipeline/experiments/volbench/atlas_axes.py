"""The stability atlas's stress axes (:class:`Axis`): what each sweeps, on which scene, and who renders it."""

import math
from dataclasses import dataclass
from types import SimpleNamespace

import renderers
from datasets.phantoms.tubes import TUBE_SPACING, tube_axes
from pipeline.experiments.kit.planning import dataset_view, phantom, scene

BASE = ("engine", "semi")
"""The semi-transparent engine: the data set and preset of every axis that does not need its own."""

ENGINE_ASPECT = (1.0, 1.0, 0.5)
"""The engine phantom's box proportions (its generator's grid): ``size`` voxels along x and y."""


@dataclass(frozen=True)
class Axis:
    """One stress axis of the atlas.

    ``key`` names it in run ids, tags and anchors; ``words`` is the swept quantity with its unit (the heat map's
    column, the charts' x label), ``unit`` what a value takes in sentences (``" voxels"``, ``"°"``; ``""`` for none),
    ``scene_words`` its scene in words ("the semi-transparent engine") and ``values`` ``{scale: [values]}``.
    ``harsher`` is ``"up"`` where larger values stress the backends more (a failure threshold reads "≥ v"), else
    ``"down"`` ("≤ v").

    It sweeps a backend ``option`` (backends without it are left out, ``option_reason`` says why), or the camera
    field ``view_key`` over the views of one run (``"azimuth"``, ``"fov_y"``), or else the scene itself, a scene per
    value. ``backend_options`` are ``{backend: options}`` a backend needs to render the axis at all (gl-raycast's
    lenses); ``dataset`` the data set and preset of its scene (an option axis's, the thin axis's tubes); ``mode``
    the scene's rendering mode (an ``"iso"`` axis leaves out the backends without iso-surfaces); ``log_x`` whether
    its chart spaces the values logarithmically (a sweep that halves them).
    """

    key: str
    words: str
    unit: str
    scene_words: str
    values: dict
    harsher: str = "up"
    option: str | None = None
    option_reason: str = ""
    view_key: str | None = None
    backend_options: dict = None
    dataset: tuple = BASE
    mode: str = "dvr"
    log_x: bool = False

    def point(self, value):
        """A value with its unit, as sentences write it."""
        unit = self.unit[:-1] if self.unit.endswith("s") and value == 1 else self.unit
        return f"{value:g}{unit}"

    def threshold(self, value):
        """"words ≥ value": where the harsher side of the sweep starts."""
        return f"{self.words.split(' (')[0]} {'≥' if self.harsher == 'up' else '≤'} {self.point(value)}"


CLOUD_ISOVALUE = 0.3
"""The iso axis of overlapping clouds: each cloud's surface (its 90th percentile of scalars at 48³)."""

STEPS = {"smoke": [1.0, 0.5], "default": [2.0, 1.0, 0.5, 0.25], "full": [2.0, 1.0, 0.5, 0.25, 0.125]}

NO_STEP = "samples once per slice, so it has no step size"

AXES = (  # in the heat map's column order
    Axis("step", "step size (voxels)", " voxels", "the semi-transparent engine", STEPS,
         option="step_factor", option_reason=NO_STEP, log_x=True),
    Axis("angle", "view angle (°)", "°", "the semi-transparent engine",
         {"smoke": [0.0, 25.0, 45.0], "default": [float(a) for a in range(0, 50, 5)],
          "full": [float(a) for a in range(0, 46, 3)]},
         view_key="azimuth"),
    Axis("tf", "TF ramp width (raw values; 1 = binary)", "", "the engine, one opaque ramp",
         {"smoke": [32.0, 1.0], "default": [64.0, 16.0, 4.0, 1.0], "full": [64.0, 32.0, 16.0, 8.0, 4.0, 2.0, 1.0]},
         harsher="down"),
    Axis("min_opacity", "min opacity", "", "the semi-transparent engine",
         {"smoke": [0.0, 0.05], "default": [0.0, 0.005, 0.01, 0.02, 0.05],
          "full": [0.0, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1]},
         option="min_opacity", option_reason="composites every sample", log_x=True),
    Axis("termination", "termination threshold (opacity)", "", "the semi-transparent engine",
         {"smoke": [0.9, 1.0], "default": [0.8, 0.9, 0.95, 0.99, 1.0], "full": [0.7, 0.8, 0.9, 0.95, 0.99, 1.0]},
         harsher="down", option="opaque_threshold", option_reason="its early termination is fixed or absent"),
    Axis("shell", "shell thickness (voxels)", " voxels", "an opaque sphere shell",
         {"smoke": [4.0, 1.0], "default": [8.0, 4.0, 2.0, 1.0], "full": [8.0, 6.0, 4.0, 3.0, 2.0, 1.0]},
         harsher="down"),
    Axis("image", "image size (px)", " px", "the semi-transparent engine",
         {"smoke": [24.0, 48.0], "default": [32.0, 64.0, 128.0], "full": [64.0, 128.0, 256.0, 512.0]}),
    Axis("volume", "volume size (voxels)", " voxels", "the semi-transparent engine",
         {"smoke": [32.0, 16.0], "default": [64.0, 32.0, 16.0], "full": [128.0, 64.0, 32.0, 16.0]},
         harsher="down"),
    Axis("fov", "field of view (°)", "°", "the semi-transparent engine, perspective",
         {"smoke": [30.0, 90.0], "default": [15.0, 30.0, 60.0, 90.0], "full": [15.0, 30.0, 45.0, 60.0, 75.0, 90.0]},
         view_key="fov_y"),
    Axis("volumes", "overlapping volumes", " volumes", "overlapping smoke clouds",
         {"smoke": [1.0, 2.0], "default": [1.0, 2.0, 4.0], "full": [1.0, 2.0, 4.0, 7.0]}),
    Axis("inside", "eye inside (distance from the centre, edges)", " of the edge",
         "the semi-transparent engine, perspective eye inside",
         {"smoke": [0.2], "default": [0.1, 0.2, 0.3], "full": [0.05, 0.1, 0.2, 0.3, 0.4]}, harsher="down"),
    Axis("lens", "lens radius (box fractions)", " of the box", "the semi-transparent engine, spherical lens",
         {"smoke": [0.25], "default": [0.15, 0.25, 0.35], "full": [0.1, 0.15, 0.2, 0.25, 0.3, 0.35]},
         backend_options={"gl-raycast": {"variant": "single-pass"}}),
    Axis("iso-step", "iso-surface step size (voxels)", " voxels", "the engine's casting", STEPS,
         option="step_factor", option_reason=NO_STEP, dataset=("engine", "binary"), mode="iso", log_x=True),
    Axis("thin", "tube radius (voxels)", " voxels", "parallel tubes",
         {"smoke": [2.0, 0.5], "default": [4.0, 2.0, 1.0, 0.5, 0.25],
          "full": [4.0, 3.0, 2.0, 1.5, 1.0, 0.75, 0.5, 0.375, 0.25]},
         harsher="down", dataset=("tube", "iso"), mode="iso", log_x=True),
    Axis("iso-volumes", "overlapping iso-surfaces (volumes)", " volumes",
         f"overlapping smoke clouds, each its surface at {CLOUD_ISOVALUE:g}",
         {"smoke": [1.0, 2.0], "default": [1.0, 2.0, 4.0], "full": [1.0, 2.0, 4.0, 7.0]}, mode="iso"),
)

AXIS_BY_KEY = {axis.key: axis for axis in AXES}

ISOLATING_OPTIONS = {"shearwarp": {"min_opacity": 0.0}, "volpack": {"min_opacity": 0.0}}
"""Options every axis but the min-opacity one gives these backends, so that each column shows its own stress.

Shear-warp and VolPack skip voxels below ``min_opacity`` (0.05 by default) before compositing, which drops
the semi-transparent engine's whole casing on every scene; the min-opacity axis shows that (its sweep
includes the default), and the other axes would otherwise only show it again."""


def backend_options(axis, backend):
    """The fixed options ``backend`` renders every point of ``axis`` with (besides the swept one)."""
    isolating = ISOLATING_OPTIONS.get(backend, {}) if axis.option != "min_opacity" else {}
    return {**isolating, **(axis.backend_options or {}).get(backend, {})}


RAMP_CENTER = 170
"""The engine's metal (raw 160–200 in its presets): where the sharpness axis puts its ramp."""

IVORY = (0.95, 0.92, 0.85)
ANGLE_ELEVATION = 0.0
"""The angle sweep turns about the body axis at eye level, so 45° is exactly between two principal axes."""

TUBES_VIEW = (15.0, 20.0, 20.0)
"""The thin axis's azimuth and elevation about the upright tubes and its roll (°): 15° off broadside, the tubes
(``TUBE_SPACING`` apart) stay apart in the picture up to radius 4; rolled, they cross the pixel rows at a slant,
so that each row meets a tube at another sub-pixel offset (upright, a whole column of pixels hits or misses
together and one column moves the PSNR by decibels)."""


def ramp(width, center=RAMP_CENTER, color=IVORY):
    """A transfer function rising from α 0 to 1 over ``width`` raw values about ``center`` (1: a step)."""
    low, high = center - width / 2, center + width / 2
    if width <= 1:
        low, high = center - 1, center
    return {"points": [[0.0, *color, 0.0], [low / 255, *color, 0.0], [high / 255, *color, 1.0], [1.0, *color, 1.0]],
            "name": f"ramp{width:g}"}


def headline(dataset="engine"):
    """The view every non-view axis uses: 30° yaw, 20° pitch of the upright data set."""
    return dataset_view(dataset, "atlas", 30.0, 20.0)


def tubes_view(dataset):
    """The thin axis's view of ``dataset`` (upright along z, as the tubes are): :data:`TUBES_VIEW`."""
    azimuth, elevation, roll = TUBES_VIEW
    view = dataset_view(dataset, "atlas", azimuth, elevation)
    # Rolled about the line of sight: the upright view's up (z) leans towards its right, (cos a, sin a, 0).
    a, r = math.radians(azimuth), math.radians(roll)
    view["up"] = [round(math.sin(r) * math.cos(a), 6), round(math.sin(r) * math.sin(a), 6), round(math.cos(r), 6)]
    return view


def clouds(count, size, **extra):
    """``count`` smoke clouds (``size``³, seeds 0…), cloud ``i`` shifted by ``i/8`` of an edge in x and y."""
    shift = [{"transform": {"translate": [round(i * size / 8, 4), round(-i * size / 8, 4), 0.0]}} if i else {}
             for i in range(count)]
    return [phantom("smoke_cloud", size, preset="smoke", name=f"cloud{i}", seed=i, **shift[i], **extra)
            for i in range(count)]


def points(axis, scale_values, *, size, image):
    """``[(value, scene, views)]``: each point's scene and views (a view axis: one scene, every value a view), for
    the values swept at this profile's scale, phantoms ``size`` voxels along their longest edge and images ``image``
    pixels high and wide."""
    engine = [phantom(BASE[0], size, preset=BASE[1])]
    name = f"atlas-{axis.key}"
    if axis.option:
        dataset, preset = axis.dataset
        spec = scene(name, image, volumes=[phantom(dataset, size, preset=preset)], mode=axis.mode)
        return [(None, spec, (headline(dataset),))]
    if axis.view_key == "azimuth":
        views = tuple(dataset_view(BASE[0], f"at{v:g}", v, ANGLE_ELEVATION) for v in scale_values)
        return [(None, scene(name, image, volumes=engine), views)]
    if axis.view_key == "fov_y":
        spec = scene(name, image, volumes=engine, camera={"projection": "perspective"})
        return [(None, spec, tuple({**headline(), "view": f"at{v:g}", "fov_y": v} for v in scale_values))]
    out = []
    for value in scale_values:
        label, view = f"{name}-{value:g}", headline()
        if axis.key == "tf":
            spec = scene(label, image, volumes=[phantom(BASE[0], size, transfer_function=ramp(value))])
        elif axis.key == "shell":
            spec = scene(label, image, volumes=[phantom("sphere", size, preset="opaque", params={"shell": value})])
            view = headline("sphere")
        elif axis.key == "image":
            spec = scene(label, int(value), volumes=engine)
        elif axis.key == "volume":
            spec = scene(label, image, volumes=[phantom(BASE[0], int(value), preset=BASE[1])])
        elif axis.key in ("volumes", "iso-volumes"):
            iso = {"isovalue": CLOUD_ISOVALUE} if axis.mode == "iso" else {}
            spec = scene(label, image, volumes=clouds(int(value), size, **iso), mode=axis.mode,
                         camera={"view_height": 1.5 * size})
            view = headline("smoke_cloud")
        elif axis.key == "thin":
            dataset, preset = axis.dataset
            volumes = [phantom(dataset, size, preset=preset, params={"radius": value})]
            # The picture spans the tubes' slabs, so that a tube thinner than a voxel still covers a share of pixels.
            window = float(len(tube_axes(size)) * TUBE_SPACING)
            spec = scene(label, image, volumes=volumes, mode=axis.mode, camera={"view_height": window})
            view = tubes_view(dataset)
        elif axis.key == "inside":
            spec = scene(label, image, volumes=engine,
                         camera={"projection": "perspective", "fov_y": 60.0, "distance": round(value * size, 4)})
        elif axis.key == "lens":
            radius = round(value * max(max(1, round(size * a)) for a in ENGINE_ASPECT), 4)  # a voxel: a world unit
            spec = scene(label, image, volumes=engine)
            spec["lenses"] = [{"shape": "sphere", "center": [0.0, 0.0, 0.0], "radius": radius,
                               "appearance": {"mode": "dvr", "preset": BASE[1], "opacity_scale": 0.2}}]
        else:
            raise ValueError(f"atlas axis {axis.key!r} has no scene of its own")
        out.append((value, spec, (view,)))
    return out


class _Needs:
    """What a scene mapping needs, shaped as :meth:`Capabilities.missing` reads a Scene: no volume is loaded."""

    def __init__(self, spec, view):
        camera = {**spec.get("camera", {}), **{k: v for k, v in view.items() if k != "view"}}
        self.camera = SimpleNamespace(projection=camera.get("projection", "orthographic"))
        self._inside = "distance" in camera and camera.get("projection") == "perspective"
        self._features = {"projections": self.camera.projection, "modes": spec["mode"],
                          "shading": spec["shading"]["model"], "max_volumes": len(spec["volumes"])}
        if any("transform" in v for v in spec["volumes"]):
            self._features["transforms"] = True
        if spec.get("lenses"):
            self._features["lenses"] = True

    def features(self):
        return dict(self._features)

    def camera_inside_volume(self):
        # The inside axis puts the eye at a fraction of an edge from the centre: inside the box by construction.
        return ["engine"] if self._inside else []


def option_names(backend):
    """The options ``backend`` takes (``None`` if its class cannot be imported: the runner records why)."""
    try:
        return set(renderers.option_names(renderers.backend_class(backend)) or ())
    except Exception:  # noqa: BLE001 - an unimportable backend is planned and recorded as skipped
        return None


def axis_reason(axis, backend, planned):
    """Why ``backend`` is left out of ``axis`` (short, for its heat-map cell), or ``""``: every one of the ``planned``
    points must be renderable, and a missing feature comes first (without iso-surfaces, no iso step to sweep)."""
    capabilities = renderers.backend_class(backend).capabilities
    for _, spec, views in planned:
        for view in views:
            missing = capabilities.missing(_Needs(spec, view))
            if missing:
                feature, reason = missing[0]
                return f"{feature}: {short(reason)}"
    if axis.option:
        names = option_names(backend)
        if names is not None and axis.option not in names:
            return f"no {axis.option} option: {axis.option_reason}"
    return ""


def short(reason, limit=110):
    """A capability's reason cut at its first clause, at most ``limit`` characters."""
    first = reason.split(";")[0].split(" (")[0].strip()
    return first if len(first) <= limit else first[: limit - 1].rstrip() + "…"
