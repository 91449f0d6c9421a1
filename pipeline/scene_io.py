"""Scenes as plain data: build a :class:`~core.scene.Scene` from a dict or a YAML file.

A scene file lists only what it uses; every key has a default except ``volumes``::

    name: skull-bone
    width: 256
    height: 256
    mode: dvr                      # dvr | mip | iso
    shading: {model: phong}        # ambient, diffuse, specular, shininess, light_direction
    camera: {azimuth: 30, elevation: 20, projection: orthographic}
    volumes:
      - dataset: ct_skull          # a registered data set (``volbench list``) ...
        size: 128                  # ... phantoms: voxels along the longest axis
        seed: 0
        params: {}                 # generator parameters
        preset: bone               # a preset of the data set (its default if omitted)
      - file: scans/head_64x64x93_uint16.raw   # ... or a file (raw, .den, .nrrd/.nhdr)
        spacing: [3.2, 3.2, 1.5]
        value_range: [0, 4095]
        transfer_function: {points: [[0, 1, 1, 1, 0], [1, 1, 1, 1, 1]]}
        gradient_opacity: {points: [[0, 0], [0.1, 1], [1, 1]]}
        isovalue: 0.5
        transform: {translate: [10, 0, 0], rotate: {axis: [0, 1, 0], degrees: 30}, scale: 1}

The box is centred on the world origin first; ``transform`` then scales, rotates and translates
it (``matrix:`` gives a full object→world 4×4 instead, no centring).
Unknown keys are errors, so a typo never silently falls back to a default.
"""

from pathlib import Path

import numpy as np
import yaml

import datasets
from core.volume import Volume
from core.camera import Camera
from core.errors import InputError
from core.scene import Scene, Shading, VolumeInstance, centering_transform
from core.transfer import GradientOpacity, TransferFunction

SCENE_KEYS = {"name", "width", "height", "mode", "shading", "camera", "volumes"}
VOLUME_KEYS = {"dataset", "size", "seed", "params", "file", "spacing", "value_range", "preset",
               "transfer_function", "gradient_opacity", "isovalue", "transform", "name"}
TRANSFORM_KEYS = {"translate", "rotate", "scale", "matrix"}


def _check_keys(mapping, allowed, *, where):
    if not isinstance(mapping, dict):
        raise InputError(f"{where}: expected a mapping, got {type(mapping).__name__}")
    unknown = set(mapping) - allowed
    if unknown:
        raise InputError(f"{where}: unknown keys {sorted(unknown)}; allowed: {sorted(allowed)}")


def rotation_matrix(axis, degrees):
    """4×4 rotation about ``axis`` by ``degrees`` (right-handed)."""
    axis = np.asarray(axis, dtype=np.float64)
    norm = np.linalg.norm(axis)
    if norm == 0 or not np.isfinite(norm):
        raise InputError(f"transform rotate axis: must be a non-zero finite vector, got {axis.tolist()}")
    x, y, z = axis / norm
    theta = np.radians(float(degrees))
    c, s, t = np.cos(theta), np.sin(theta), 1 - np.cos(theta)
    matrix = np.eye(4)
    matrix[:3, :3] = [[t * x * x + c, t * x * y - s * z, t * x * z + s * y],
                      [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
                      [t * x * z - s * y, t * y * z + s * x, t * z * z + c]]
    return matrix


def build_transform(spec, volume, *, where="transform"):
    """Object→world matrix from a ``transform`` mapping (see the module docstring)."""
    if spec is None:
        return None
    _check_keys(spec, TRANSFORM_KEYS, where=where)
    if "matrix" in spec:
        if len(spec) > 1:
            raise InputError(f"{where}: 'matrix' cannot be combined with translate/rotate/scale")
        return np.asarray(spec["matrix"], dtype=np.float64)
    scale = np.eye(4)
    factors = spec.get("scale", 1.0)
    scale[:3, :3] = np.diag(np.broadcast_to(np.asarray(factors, dtype=np.float64), (3,)))
    rotate = np.eye(4)
    if "rotate" in spec:
        _check_keys(spec["rotate"], {"axis", "degrees"}, where=f"{where} rotate")
        rotate = rotation_matrix(spec["rotate"].get("axis", (0, 1, 0)), spec["rotate"].get("degrees", 0))
    translate = np.eye(4)
    translate[:3, 3] = np.asarray(spec.get("translate", (0, 0, 0)), dtype=np.float64)
    return translate @ rotate @ scale @ centering_transform(volume)


def dataset_arguments(spec, *, size=None):
    """Keyword arguments of :func:`datasets.load` for a ``dataset`` volume entry.

    Phantoms get the entry's ``size`` (else ``size``) and ``seed`` (else 0); the pipeline names
    its cached phantom files with the same arguments, so both must come from here.
    """
    kwargs = dict(spec.get("params") or {})
    if datasets.get(spec["dataset"]).kind == "phantom":
        kwargs["size"] = spec.get("size", size)
        kwargs["seed"] = spec.get("seed", 0)
    return kwargs


def load_volume(spec, *, cache_dir=None, size=None, base_dir=None, data_dir=None, where="volume"):
    """The :class:`Volume` a volume entry refers to (a registered data set or a file)."""
    if ("dataset" in spec) == ("file" in spec):
        raise InputError(f"{where}: give exactly one of 'dataset' or 'file'")
    if "dataset" in spec:
        return datasets.load(spec["dataset"], cache_dir=cache_dir, data_dir=data_dir,
                             **dataset_arguments(spec, size=size))
    path = Path(spec["file"])
    if base_dir is not None and not path.is_absolute():
        path = Path(base_dir) / path
    suffix = path.suffix.lower()
    if suffix == ".den":
        volume = datasets.load_den(path)
    elif suffix in (".nrrd", ".nhdr"):
        volume = datasets.load_nrrd(path)
    else:
        volume = datasets.load_raw(path)
    if "spacing" in spec or "value_range" in spec:
        volume = Volume(volume.data, spacing=spec.get("spacing", volume.spacing),
                        value_range=spec.get("value_range", volume.value_range),
                        name=volume.name, labels=volume.labels, meta=volume.meta)
    return volume


def build_volume_instance(spec, *, cache_dir=None, size=None, base_dir=None, data_dir=None, index=0):
    """A :class:`VolumeInstance` from one entry of ``volumes``."""
    where = f"volumes[{index}]"
    _check_keys(spec, VOLUME_KEYS, where=where)
    volume = load_volume(spec, cache_dir=cache_dir, size=size, base_dir=base_dir, data_dir=data_dir, where=where)
    preset = None
    if "dataset" in spec and ("transfer_function" not in spec or "preset" in spec):
        preset = datasets.preset(spec["dataset"], spec.get("preset"))
    elif "preset" in spec:
        raise InputError(f"{where}: 'preset' needs a 'dataset'; give a 'transfer_function' for files")
    if "transfer_function" in spec:
        tf_spec = dict(spec["transfer_function"])
        _check_keys(tf_spec, {"points", "size", "reference_step", "name"}, where=f"{where} transfer_function")
        transfer_function = TransferFunction.from_points(tf_spec.pop("points", None), **tf_spec)
    elif preset is not None:
        transfer_function = preset.transfer_function
    else:
        raise InputError(f"{where}: a file volume needs a 'transfer_function'")
    gradient_opacity = preset.gradient_opacity if preset is not None else None
    if "gradient_opacity" in spec:
        g_spec = spec["gradient_opacity"]
        if g_spec is None:
            gradient_opacity = None
        else:
            _check_keys(g_spec, {"points", "size", "name"}, where=f"{where} gradient_opacity")
            g_spec = dict(g_spec)
            gradient_opacity = GradientOpacity.from_points(g_spec.pop("points", None), **g_spec)
    isovalue = spec.get("isovalue", preset.effective_isovalue if preset is not None else None)
    return VolumeInstance(
        volume=volume,
        transfer_function=transfer_function,
        transform=build_transform(spec.get("transform"), volume, where=f"{where} transform"),
        gradient_opacity=gradient_opacity,
        isovalue=isovalue,
        name=spec.get("name", volume.name),
    )


def build_scene(spec, *, cache_dir=None, size=None, base_dir=None, data_dir=None):
    """Build a :class:`Scene` from a scene mapping.

    Parameters
    ----------
    spec : dict
        See the module docstring.
    cache_dir : path, optional
        Where generated phantoms are cached (see :func:`datasets.load`).
    size : int, optional
        Phantom size used where a volume entry gives none (profiles set it).
    base_dir : path, optional
        Directory that relative ``file`` paths are resolved against.
    data_dir : path, optional
        Folder of the real scans (see :func:`datasets.load`).
    """
    _check_keys(spec, SCENE_KEYS, where="scene")
    if not spec.get("volumes"):
        raise InputError("scene: 'volumes' must list at least one volume")
    instances = tuple(
        build_volume_instance(v, cache_dir=cache_dir, size=size, base_dir=base_dir, data_dir=data_dir, index=i)
        for i, v in enumerate(spec["volumes"])
    )
    camera_spec = spec.get("camera") or {}
    _check_keys(camera_spec, set(Camera.__dataclass_fields__), where="scene camera")
    shading_spec = spec.get("shading") or {}
    _check_keys(shading_spec, set(Shading.__dataclass_fields__), where="scene shading")
    return Scene(
        volumes=instances,
        camera=Camera(**camera_spec),
        width=spec.get("width", 256),
        height=spec.get("height", 256),
        mode=spec.get("mode", "dvr"),
        shading=Shading(**shading_spec),
        name=spec.get("name", "scene"),
    )


def load_scene(path, **kwargs):
    """Read a YAML scene file and build it; relative ``file`` entries resolve beside it."""
    path = Path(path)
    try:
        spec = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise InputError(f"scene file {path}: cannot be read ({exc.strerror})") from exc
    except yaml.YAMLError as exc:
        raise InputError(f"scene file {path}: invalid YAML ({exc})") from exc
    kwargs.setdefault("base_dir", path.parent)
    return build_scene(spec, **kwargs)
