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

Closed meshes, their materials, instancing and CSG (Kainz et al. 2009; semantics in
:mod:`core.scene`) are optional; a scene may hold meshes only::

    meshes:
      - name: rods
        generator: rod               # a generator of datasets.meshes ...
        params: {sides: 20, radius: 0.05}
        surface: {colour: [1, 0.8, 0.2], alpha: 0.4, specular: 0.5}   # SurfaceMaterial fields
        medium: {colour: [1, 0.5, 0], extinction: 2.0}                 # HomogeneousMedium fields
        transform: {rotate: {axis: [1, 0, 0], degrees: 30}}             # no centring for meshes
      - name: rod2
        instance_of: rods            # ... or the mesh of an earlier entry (instancing) ...
        transform: {translate: [0.3, 0, 0]}
      - file: models/liver.obj       # ... or a file trimesh reads (OBJ, STL, PLY, OFF, glTF)
    volumes:
      - dataset: sphere
        boundary: {generator: phantom_isosurface, params: {dataset: sphere, level: 0.3}}
    csg:
      - difference: [sphere, {union: [rods, rod2]}]   # one operation key: a list of names or nodes

An entry's own keys do not carry over to the instances of its mesh.

A lens volume (Ropinski et al. 2005; semantics in :mod:`core.lens`): at most one per scene, over
the scene's one volume in mode ``dvr``; one entry of each shape here::

    lenses:
      - shape: sphere                # sphere | box | mesh
        center: [0, 10, 0]           # world units
        radius: 30                   # sphere
        appearance: {mode: clip}
      - shape: box
        center: [0, 0, 0]
        size: [20, 10, 10]           # edge lengths in the box's own frame
        transform: {rotate: {axis: [0, 0, 1], degrees: 30}}   # about the centre (no translate needed)
        appearance: {mode: dvr, preset: bone, opacity_scale: 0.3}   # a preset of the volume's data set,
                                     # or transfer_function (+ gradient_opacity) points
      - shape: mesh
        center: [0, 0, 0]
        mesh: {generator: ..., params: {}}    # or {file: ...}: a closed convex mesh
        appearance: {mode: iso, isovalue: 0.5}  # iso: isovalue (or a preset's); mip: {mode: mip}

``preset`` and ``transfer_function`` of ``iso``/``mip`` give the classification (colour) and
default to the volume's own.

Unknown keys are errors, so a typo never silently falls back to a default. Files are read
strictly (:mod:`core.yaml_io`: UTF-8, no key given twice, no number that YAML 1.1 would read as
text or as octal), and the image, every phantom's size and every table are checked against this
machine's memory (:mod:`core.resources`) before any volume is loaded or generated.
"""

from pathlib import Path

import numpy as np

import datasets
from core.volume import Volume
from core.camera import Camera
from core.errors import InputError
from core.lens import Lens, LensAppearance
from core.mesh import HomogeneousMedium, MeshInstance, SurfaceMaterial
from core.scene import CSG_OPERATIONS, CsgNode, Scene, Shading, VolumeInstance, centering_transform, check_image_size
from core.transfer import GradientOpacity, TransferFunction
from core.validation import (check_finite_vector, check_matrix4, check_positive_int, check_positive_vector, check_scalar,
                             check_value_range)
from core.yaml_io import load_yaml_file

SCENE_KEYS = {"name", "width", "height", "mode", "shading", "camera", "volumes", "meshes", "csg", "lenses"}
VOLUME_KEYS = {"dataset", "size", "seed", "params", "file", "spacing", "value_range", "preset",
               "transfer_function", "gradient_opacity", "isovalue", "transform", "name", "boundary"}
MESH_KEYS = {"name", "generator", "params", "file", "instance_of", "transform", "surface", "medium"}
MESH_SOURCE_KEYS = ("generator", "file", "instance_of")
TRANSFORM_KEYS = {"translate", "rotate", "scale", "matrix"}
LENS_KEYS = {"name", "shape", "center", "radius", "size", "transform", "mesh", "appearance"}
LENS_APPEARANCE_KEYS = {"mode", "preset", "transfer_function", "gradient_opacity", "opacity_scale", "isovalue"}
TEXT_KEYS = {"volume": ("dataset", "file", "preset", "name"), "mesh": ("name", "generator", "file", "instance_of"),
             "table": ("name",), "lens": ("name", "shape"), "appearance": ("mode", "preset")}
"""Keys whose values are names or paths: a number or a list there is a mistake, not a name."""


def _check_keys(mapping, allowed, *, where):
    if not isinstance(mapping, dict):
        raise InputError(f"{where}: expected a mapping, got {type(mapping).__name__}")
    unknown = set(mapping) - allowed
    if unknown:
        raise InputError(f"{where}: unknown keys {sorted(unknown)}; allowed: {sorted(allowed)}")


def _points(points, width, *, where):
    """Control points as a float array ``(n, 1 + width)``, or an :class:`InputError` naming them."""
    example = "[x, r, g, b, a]" if width == 4 else "[x, g]"
    try:
        array = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        array = None
    if array is None or array.ndim != 2 or array.shape[1] != width + 1 or len(array) < 1:
        raise InputError(f"{where}: expected a list of {example} rows of numbers, got {points!r}")
    return array


def rotation_matrix(axis, degrees):
    """4×4 rotation about ``axis`` by ``degrees`` (right-handed)."""
    axis = np.asarray(check_finite_vector(axis, length=3, name="transform rotate axis"))
    norm = np.linalg.norm(axis)
    if norm == 0 or not np.isfinite(norm):
        raise InputError(f"transform rotate axis: must be a non-zero finite vector, got {axis.tolist()}")
    x, y, z = axis / norm
    theta = np.radians(check_scalar(degrees, name="transform rotate degrees"))
    c, s, t = np.cos(theta), np.sin(theta), 1 - np.cos(theta)
    matrix = np.eye(4)
    matrix[:3, :3] = [[t * x * x + c, t * x * y - s * z, t * x * z + s * y],
                      [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
                      [t * x * z - s * y, t * y * z + s * x, t * z * z + c]]
    return matrix


def build_transform(spec, volume, *, where="transform"):
    """Object→world matrix from a ``transform`` mapping (see the module docstring).

    ``volume`` is the volume whose box is centred first; ``None`` (meshes) centres nothing.
    """
    if spec is None:
        return None
    _check_keys(spec, TRANSFORM_KEYS, where=where)
    if "matrix" in spec:
        if len(spec) > 1:
            raise InputError(f"{where}: 'matrix' cannot be combined with translate/rotate/scale")
        return check_matrix4(spec["matrix"], name=f"{where} matrix")
    scale = np.eye(4)
    factors = spec.get("scale", 1.0)
    if np.ndim(factors) == 0:
        factors = (check_scalar(factors, name=f"{where} scale", low=0, low_open=True),) * 3
    else:
        factors = check_positive_vector(factors, length=3, name=f"{where} scale")
    scale[:3, :3] = np.diag(factors)
    rotate = np.eye(4)
    if "rotate" in spec:
        _check_keys(spec["rotate"], {"axis", "degrees"}, where=f"{where} rotate")
        rotate = rotation_matrix(spec["rotate"].get("axis", (0, 1, 0)), spec["rotate"].get("degrees", 0))
    translate = np.eye(4)
    translate[:3, 3] = check_finite_vector(spec.get("translate", (0, 0, 0)), length=3, name=f"{where} translate")
    return translate @ rotate @ scale @ (np.eye(4) if volume is None else centering_transform(volume))


def dataset_arguments(spec, *, size=None, where=None):
    """Keyword arguments of :func:`datasets.load` for a ``dataset`` volume entry.

    Phantoms get the entry's ``size`` (else ``size``) and ``seed`` (else 0); the pipeline names
    its cached phantom files with the same arguments, so both must come from here. A phantom
    this machine cannot generate is refused here, before anything is generated. A real scan
    has its own size: ``size``, ``seed`` or ``params`` on one is an error, never ignored.
    ``where`` names the entry in messages (default: ``volume '<dataset>'``).
    """
    if not isinstance(spec["dataset"], str):
        raise InputError(f"{where or 'volume'} dataset: expected a data set name (volbench list datasets), "
                         f"got {spec['dataset']!r}")
    where = where or f"volume {spec['dataset']!r}"
    params = spec.get("params") or {}
    if not isinstance(params, dict):
        raise InputError(f"{where} params: expected a mapping of generator parameters, got {params!r}")
    kwargs = dict(params)
    dataset = datasets.get(spec["dataset"])
    if dataset.kind == "phantom":
        kwargs["size"] = spec.get("size", size)
        kwargs["seed"] = spec.get("seed", 0)
        if kwargs["size"] is not None:
            check_positive_int(kwargs["size"], name=f"{where} size", minimum=datasets.MIN_SIZE)
        effective = dataset.default_size if kwargs["size"] is None else kwargs["size"]
        dataset.check_memory(effective, where=f"{where} size")
    else:
        given = [key for key in ("size", "seed", "params") if key in spec]
        if given:
            raise InputError(f"volume {spec['dataset']!r} is a real scan with its own size; remove "
                             f"{', '.join(repr(k) for k in given)} (only phantoms take them)")
    return kwargs


def phantom_requests(entries, *, size=None):
    """``{cache key: {"dataset": name, "kwargs": ...}}`` for the generated phantoms among volume ``entries``.

    What the pipeline generates (and caches) before any run reads it: one request per distinct
    phantom, keyed as :func:`datasets.cache_key` names its cache files; files and real scans are
    read in place and are left out.
    """
    requests = {}
    for entry in entries:
        if "dataset" not in entry or datasets.get(entry["dataset"]).kind != "phantom":
            continue
        kwargs = dataset_arguments(entry, size=size)
        requests[datasets.cache_key(entry["dataset"], **kwargs)] = {"dataset": entry["dataset"], "kwargs": kwargs}
    return requests


def load_volume(spec, *, cache_dir=None, size=None, base_dir=None, data_dir=None, where="volume"):
    """The :class:`Volume` a volume entry refers to (a registered data set or a file)."""
    if ("dataset" in spec) == ("file" in spec):
        raise InputError(f"{where}: give exactly one of 'dataset' or 'file'")
    value_range = None
    if "value_range" in spec:
        value_range = check_value_range(spec["value_range"], name=f"{where} value_range")
    if "spacing" in spec:
        check_positive_vector(spec["spacing"], length=3, name=f"{where} spacing")
    if "dataset" in spec:
        volume = datasets.load(spec["dataset"], cache_dir=cache_dir, data_dir=data_dir,
                               **dataset_arguments(spec, size=size, where=where))
    else:
        path = Path(spec["file"])
        if base_dir is not None and not path.is_absolute():
            path = Path(base_dir) / path
        suffix = path.suffix.lower()
        # The range goes to the reader: a float32 file outside [0, 1] is refused without one.
        if suffix == ".den":
            volume = datasets.load_den(path)
        elif suffix in (".nrrd", ".nhdr"):
            volume = datasets.load_nrrd(path, value_range=value_range)
        else:
            volume = datasets.load_raw(path, value_range=value_range)
    if "spacing" in spec or "value_range" in spec:
        volume = Volume(volume.data, spacing=spec.get("spacing", volume.spacing),
                        value_range=value_range or volume.value_range,
                        name=volume.name, labels=volume.labels, meta=volume.meta)
    return volume


def build_transfer_function(spec, *, where):
    """A :class:`TransferFunction` from ``{points:, size:, reference_step:, name:}``."""
    _check_keys(spec, {"points", "size", "reference_step", "name"}, where=where)
    spec = dict(spec)
    points = _points(spec.pop("points", None), 4, where=f"{where} points")
    return TransferFunction.from_points(points, **spec)


def build_gradient_opacity(spec, *, where):
    """A :class:`GradientOpacity` from ``{points:, size:, name:}``; ``None`` for none."""
    if spec is None:
        return None
    _check_keys(spec, {"points", "size", "name"}, where=where)
    spec = dict(spec)
    points = _points(spec.pop("points", None), 1, where=f"{where} points")
    return GradientOpacity.from_points(points, **spec)


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
        transfer_function = build_transfer_function(spec["transfer_function"], where=f"{where} transfer_function")
    elif preset is not None:
        transfer_function = preset.transfer_function
    else:
        raise InputError(f"{where}: a file volume needs a 'transfer_function'")
    gradient_opacity = preset.gradient_opacity if preset is not None else None
    if "gradient_opacity" in spec:
        gradient_opacity = build_gradient_opacity(spec["gradient_opacity"], where=f"{where} gradient_opacity")
    isovalue = spec.get("isovalue", preset.effective_isovalue if preset is not None else None)
    boundary = None
    if spec.get("boundary") is not None:
        boundary = load_mesh_source(spec["boundary"], base_dir=base_dir, cache_dir=cache_dir,
                                    where=f"{where} boundary")
    return VolumeInstance(
        volume=volume,
        transfer_function=transfer_function,
        transform=build_transform(spec.get("transform"), volume, where=f"{where} transform"),
        gradient_opacity=gradient_opacity,
        isovalue=isovalue,
        name=spec.get("name", volume.name),
        boundary=boundary,
    )


def load_mesh_source(spec, *, base_dir=None, cache_dir=None, where="mesh"):
    """The :class:`~core.mesh.Mesh` of a ``{generator:, params:}`` or ``{file:}`` mapping."""
    from datasets import meshes

    _check_keys(spec, {"generator", "params", "file", "name"}, where=where)
    if ("generator" in spec) == ("file" in spec):
        raise InputError(f"{where}: give exactly one of 'generator' or 'file'")
    if "file" in spec:
        if "params" in spec:
            raise InputError(f"{where}: 'params' belongs to a 'generator', not a 'file'")
        path = Path(spec["file"])
        if base_dir is not None and not path.is_absolute():
            path = Path(base_dir) / path
        return meshes.load_mesh(path, name=spec.get("name"))
    params = spec.get("params") or {}
    if not isinstance(params, dict):
        raise InputError(f"{where} params: expected a mapping of generator parameters, got {params!r}")
    if spec["generator"] == "phantom_isosurface":
        params = {"cache_dir": cache_dir, **params}
    mesh = meshes.generate(spec["generator"], **params)
    return mesh if "name" not in spec else type(mesh)(mesh.vertices, mesh.faces, name=spec["name"], meta=mesh.meta)


def _material(spec, cls, *, where):
    if spec is None:
        return None
    _check_keys(spec, set(cls.__dataclass_fields__), where=where)
    return cls(**spec)


def build_mesh_instances(entries, *, base_dir=None, cache_dir=None):
    """The :class:`~core.mesh.MeshInstance` of every entry of ``meshes``, in order (see the module docstring)."""
    if not isinstance(entries, list):
        raise InputError(f"scene meshes: expected a list of mesh entries, got {type(entries).__name__}")
    instances = []
    by_name = {}
    for index, spec in enumerate(entries):
        where = f"meshes[{index}]"
        _check_keys(spec, MESH_KEYS, where=where)
        sources = [key for key in MESH_SOURCE_KEYS if key in spec]
        if len(sources) != 1:
            raise InputError(f"{where}: give exactly one of {', '.join(repr(k) for k in MESH_SOURCE_KEYS)}, "
                             f"got {sources or 'none'}")
        transform = build_transform(spec.get("transform"), None, where=f"{where} transform")
        surface = _material(spec.get("surface"), SurfaceMaterial, where=f"{where} surface")
        medium = _material(spec.get("medium"), HomogeneousMedium, where=f"{where} medium")
        if "instance_of" in spec:
            if "params" in spec:
                raise InputError(f"{where}: 'params' belongs to a 'generator', not to 'instance_of'")
            if spec["instance_of"] not in by_name:
                raise InputError(f"{where} instance_of: {spec['instance_of']!r} is not the name of an earlier mesh "
                                 f"entry; earlier: {sorted(by_name)}")
            mesh = by_name[spec["instance_of"]].mesh
        else:
            source = {key: spec[key] for key in ("generator", "params", "file") if key in spec}
            mesh = load_mesh_source(source, base_dir=base_dir, cache_dir=cache_dir, where=where)
        instance = MeshInstance(mesh, transform=transform, surface=surface, medium=medium,
                                name=spec.get("name", ""))
        by_name[instance.name] = instance
        instances.append(instance)
    return tuple(instances)


def build_csg(spec, *, where="csg"):
    """A :class:`~core.scene.CsgNode` from ``{operation: [child, ...]}``; a child is a name or such a mapping."""
    if isinstance(spec, str):
        return spec
    if not isinstance(spec, dict) or len(spec) != 1:
        raise InputError(f"{where}: expected an instance name or a mapping with one operation key "
                         f"({', '.join(CSG_OPERATIONS)}), got {spec!r}")
    (operation, children), = spec.items()
    if operation not in CSG_OPERATIONS:
        raise InputError(f"{where}: unknown operation {operation!r}; expected one of {list(CSG_OPERATIONS)}")
    if not isinstance(children, list):
        raise InputError(f"{where} {operation}: expected a list of instance names or operations, got {children!r}")
    return CsgNode(operation, [build_csg(child, where=f"{where} {operation}[{i}]") for i, child in enumerate(children)])


def build_lens_appearance(spec, *, volume_spec, where):
    """A :class:`~core.lens.LensAppearance` from an ``appearance`` mapping.

    ``preset`` names a preset of the data set of ``volume_spec`` (the lens's volume): its transfer
    function, with ``dvr`` its gradient opacity, with ``iso`` its isovalue unless one is given.
    """
    _check_keys(spec, LENS_APPEARANCE_KEYS, where=where)
    if "mode" not in spec:
        raise InputError(f"{where}: needs a mode (clip, dvr, iso or mip)")
    mode = spec["mode"]
    if mode == "clip" and set(spec) != {"mode"}:
        raise InputError(f"{where}: a clip lens shows nothing inside, so {sorted(set(spec) - {'mode'})} does not "
                         "apply; remove it")
    if "preset" in spec and "transfer_function" in spec:
        raise InputError(f"{where}: give one of 'preset' or 'transfer_function'")
    transfer_function = gradient_opacity = isovalue = None
    if "preset" in spec:
        if volume_spec is None or "dataset" not in volume_spec:
            raise InputError(f"{where} preset: a preset belongs to the data set of the scene's one volume, and the "
                             "scene has no such 'dataset' volume; give transfer_function points instead")
        preset = datasets.preset(volume_spec["dataset"], spec["preset"])
        transfer_function = preset.transfer_function
        if mode == "dvr":
            gradient_opacity = preset.gradient_opacity
        if mode == "iso":
            isovalue = preset.effective_isovalue
    if "transfer_function" in spec:
        transfer_function = build_transfer_function(spec["transfer_function"], where=f"{where} transfer_function")
    if "gradient_opacity" in spec:
        gradient_opacity = build_gradient_opacity(spec["gradient_opacity"], where=f"{where} gradient_opacity")
    return LensAppearance(mode, transfer_function=transfer_function, gradient_opacity=gradient_opacity,
                          opacity_scale=spec.get("opacity_scale", 1.0), isovalue=spec.get("isovalue", isovalue))


def build_lens(spec, *, volume_spec=None, base_dir=None, cache_dir=None, index=0):
    """A :class:`~core.lens.Lens` from one entry of ``lenses`` (see the module docstring).

    ``volume_spec`` is the entry of the scene's one volume (presets are its data set's).
    """
    where = f"lenses[{index}]"
    _check_keys(spec, LENS_KEYS, where=where)
    _check_text(spec, TEXT_KEYS["lens"], where=where)
    _check_text(spec.get("appearance"), TEXT_KEYS["appearance"], where=f"{where} appearance")
    _check_text(spec.get("mesh"), TEXT_KEYS["mesh"], where=f"{where} mesh")
    for key in ("shape", "center", "appearance"):
        if key not in spec:
            raise InputError(f"{where}: needs '{key}' (shape: sphere | box | mesh, center: [x, y, z], "
                             "appearance: {mode: ...})")
    mesh = None
    if spec.get("mesh") is not None:
        mesh = load_mesh_source(spec["mesh"], base_dir=base_dir, cache_dir=cache_dir, where=f"{where} mesh")
    return Lens(spec["shape"], center=spec["center"], radius=spec.get("radius"), size=spec.get("size"), mesh=mesh,
                transform=build_transform(spec.get("transform"), None, where=f"{where} transform"),
                appearance=build_lens_appearance(spec["appearance"], volume_spec=volume_spec,
                                                 where=f"{where} appearance"),
                name=spec.get("name", "lens"))


def _entries(spec, key):
    """The list under ``key`` of a scene mapping (``[]`` when absent or empty)."""
    entries = spec.get(key)
    if entries is None:
        return []
    if not isinstance(entries, list):
        raise InputError(f"scene {key}: expected a list of entries (each line starting with '- '), "
                         f"got {type(entries).__name__} {entries!r}")
    return entries


def _check_text(mapping, keys, *, where):
    for key in keys:
        if isinstance(mapping, dict) and key in mapping and not isinstance(mapping[key], str):
            raise InputError(f"{where} {key}: expected text (a name or a path), got {mapping[key]!r}")


def _check_before_building(spec, *, size):
    """Everything about a scene mapping that can be checked before a volume is loaded or generated.

    The image size, the entries' keys and every phantom's size against this machine's memory: a
    bad last entry must not wait for the first one's generation.
    """
    _check_keys(spec, SCENE_KEYS, where="scene")
    volumes, meshes = _entries(spec, "volumes"), _entries(spec, "meshes")
    if not volumes and not meshes:
        raise InputError("scene: 'volumes' or 'meshes' must list at least one volume or mesh")
    name = spec.get("name", "scene")
    if not isinstance(name, str):
        raise InputError(f"scene name: expected text, got {name!r}")
    check_image_size(spec.get("width", 256), spec.get("height", 256), name=f"scene {name!r}")
    for index, entry in enumerate(volumes):
        where = f"volumes[{index}]"
        _check_keys(entry, VOLUME_KEYS, where=where)
        _check_text(entry, TEXT_KEYS["volume"], where=where)
        for table in ("transfer_function", "gradient_opacity"):
            _check_text(entry.get(table), TEXT_KEYS["table"], where=f"{where} {table}")
        _check_text(entry.get("boundary"), TEXT_KEYS["mesh"], where=f"{where} boundary")
        if "dataset" in entry and "file" not in entry:
            dataset_arguments(entry, size=size, where=where)
    for index, entry in enumerate(meshes):
        _check_keys(entry, MESH_KEYS, where=f"meshes[{index}]")
        _check_text(entry, TEXT_KEYS["mesh"], where=f"meshes[{index}]")
    return volumes, meshes


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

    Raises
    ------
    InputError
        A wrong key or value, named; sizes this machine cannot hold are refused before any
        volume is loaded or generated.
    """
    volumes, meshes = _check_before_building(spec, size=size)
    csg_spec = spec.get("csg") or []
    if not isinstance(csg_spec, list):
        raise InputError(f"scene csg: expected a list of operations, got {csg_spec!r}")
    # CSG is checked before any volume or mesh is built.
    csg = tuple(build_csg(tree, where=f"csg[{i}]") for i, tree in enumerate(csg_spec))
    if any(isinstance(tree, str) for tree in csg):
        raise InputError("scene csg: each entry must be an operation such as {union: [a, b]}, not a bare name")
    # Lenses are built before any volume is loaded: a wrong one is refused without that wait.
    lenses = tuple(build_lens(entry, volume_spec=volumes[0] if len(volumes) == 1 else None, base_dir=base_dir,
                              cache_dir=cache_dir, index=i) for i, entry in enumerate(_entries(spec, "lenses")))
    instances = tuple(
        build_volume_instance(v, cache_dir=cache_dir, size=size, base_dir=base_dir, data_dir=data_dir, index=i)
        for i, v in enumerate(volumes)
    )
    meshes = build_mesh_instances(meshes, base_dir=base_dir, cache_dir=cache_dir)
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
        meshes=meshes,
        csg=csg,
        lenses=lenses,
    )


def load_scene(path, **kwargs):
    """Read a YAML scene file and build it; relative ``file`` entries resolve beside it.

    The file is read strictly (:func:`core.yaml_io.load_yaml_file`: UTF-8, no key given twice, no
    number that YAML 1.1 would silently read as text, octal or base 60) and must hold a mapping.
    """
    path = Path(path)
    spec = load_yaml_file(path, what="scene file")
    if not isinstance(spec, dict):
        found = "an empty file" if spec is None else f"{type(spec).__name__} {spec!r}"
        raise InputError(f"scene file {path}: expected a mapping of scene keys (width, volumes, ...), got {found}")
    kwargs.setdefault("base_dir", path.parent)
    return build_scene(spec, **kwargs)
