"""volbench's data sets: seeded synthetic stand-ins for the papers' volumes, the real scans, their
classification presets and the statistics the papers report.

>>> import datasets
>>> datasets.names(kind="phantom")[:3]
['mri_head', 'ct_skull', 'folded_brain']
>>> volume = datasets.load("ct_skull", size=64, seed=0)          # doctest: +SKIP
>>> datasets.statistics(volume, datasets.preset("ct_skull", "bone"))["nontransparent_fraction"]  # doctest: +SKIP
0.04...

Phantoms are generated on first use and cached on disk (``$VOLBENCH_CACHE``, default
``<repo>/.cache/volumes``) under :func:`cache_key`; real scans are read from the real-data folder
(``$VOLBENCH_REAL_DATA``, default ``<repo>/../shared/data/real``) and raise
:class:`DataUnavailableError` when it is absent.
"""

import hashlib
import json
import time

from datasets import cache as _cache
from datasets import real as _real
from datasets.loaders import load_den, load_nrrd, load_raw
from datasets.real import DataUnavailableError
from datasets.registry import DATASETS, KINDS, PAPERS, DatasetSpec, generic_real_spec
from datasets.stats import statistics
from core.volume import Volume
from core.errors import InputError
from core.validation import check_positive_int

__all__ = [
    "DATASETS", "DataUnavailableError", "DatasetSpec", "PAPERS", "Volume", "cache_key", "get", "load",
    "load_den", "load_nrrd", "load_raw", "names", "preset", "statistics",
]

MIN_SIZE = 8
"""Smallest phantom size: below it the one-voxel edges swallow every structure."""


def _manifest_extras():
    """Real data sets listed in the data folder's manifest that the registry does not know."""
    try:
        entries = _real.read_manifest()
    except InputError:
        return {}
    known = {spec.source for spec in DATASETS.values() if spec.kind == "real"}
    return {name: generic_real_spec(name, entry) for name, entry in entries.items()
            if name not in known and name not in DATASETS}


def names(kind=None):
    """Names of the registered data sets.

    Parameters
    ----------
    kind : {None, "phantom", "real"}, optional
        Only data sets of this kind.

    Returns
    -------
    list of str
        Phantoms first, then real scans (including any extra entries of the real-data manifest).
    """
    if kind is not None and kind not in KINDS:
        raise InputError(f"datasets.names: kind must be one of {KINDS} or None, got {kind!r}")
    specs = {**DATASETS, **_manifest_extras()}
    return [name for name, spec in specs.items() if kind is None or spec.kind == kind]


def get(name):
    """The :class:`DatasetSpec` registered as ``name``.

    Raises
    ------
    InputError
        Unknown name; the message lists the known ones.
    """
    if name in DATASETS:
        return DATASETS[name]
    extras = _manifest_extras()
    if name in extras:
        return extras[name]
    raise InputError(f"unknown data set {name!r}; known: {', '.join(names())}")


def preset(name, preset_name=None):
    """The classification preset ``preset_name`` of data set ``name`` (its default when ``None``)."""
    return get(name).preset(preset_name)


def _resolve(spec, size, seed, params):
    """Fill in defaults and check a phantom request: ``(size, seed, params)``."""
    size = spec.default_size if size is None else check_positive_int(size, name=f"{spec.name} size", minimum=MIN_SIZE)
    seed = check_positive_int(seed, name=f"{spec.name} seed", minimum=0)
    accepted = spec.parameters
    unknown = sorted(set(params) - set(accepted))
    if unknown:
        allowed = ", ".join(accepted) or "none"
        raise InputError(f"data set {spec.name!r} has no parameter {', '.join(unknown)}; parameters: {allowed}")
    params = {**accepted, **params}
    try:
        json.dumps(params)
    except TypeError:
        raise InputError(f"data set {spec.name!r}: parameters must be plain numbers or strings, got {params!r}") from None
    return size, seed, params


def cache_key(name, *, size=None, seed=0, **params):
    """Stable hex key naming one volume: what the pipeline uses for file names.

    For a phantom it hashes the name, the generator's version and source digest, the size, the
    seed and the full parameter set (defaults filled in), so equal requests get equal keys and
    editing a generator changes them. A real data set's key depends on its name only.

    Parameters
    ----------
    name : str
    size : int, optional
        Phantoms: voxels along the longest axis (default: the data set's default size).
    seed : int, optional
    **params
        Generator parameters (see ``get(name).parameters``).
    """
    spec = get(name)
    if spec.kind == "real":
        return hashlib.sha256(json.dumps({"dataset": name, "kind": "real"}).encode()).hexdigest()[:20]
    size, seed, params = _resolve(spec, size, seed, params)
    return _cache.make_key(spec, size, seed, params)


def load(name, *, size=None, seed=0, cache_dir=None, data_dir=None, **params):
    """Load a registered data set as a :class:`Volume`.

    Parameters
    ----------
    name : str
        See :func:`names`.
    size : int, optional
        Phantoms: voxels along the longest axis (other axes follow the phantom's aspect, e.g.
        the engine is size × size × size/2). Defaults to the data set's ``default_size``. Real
        scans have their own size and refuse this.
    seed : int, optional
        Phantoms: the random seed; the same seed gives the same bytes. Ignored for real scans.
    cache_dir : str or Path or False, optional
        Phantom cache folder (default ``$VOLBENCH_CACHE`` or ``<repo>/.cache/volumes``);
        ``False`` generates without touching the disk.
    data_dir : str or Path, optional
        Real-data folder (default ``$VOLBENCH_REAL_DATA`` or ``<repo>/../shared/data/real``).
    **params
        Phantom generator parameters (``get(name).parameters`` lists them with defaults).

    Returns
    -------
    Volume
        ``meta`` records the data set, kind and provenance; a phantom's also its size, seed,
        parameters, cache key, ``generation_seconds`` (wall time of the generator when it was
        generated, kept by the cache) and ``cache`` (``key``, ``path``, ``hit``).

    Raises
    ------
    InputError
        Unknown data set or parameter, bad size or seed, a file that does not match its header.
    DataUnavailableError
        A real scan whose folder or file is missing (a subclass of InputError).
    """
    spec = get(name)
    if spec.kind == "real":
        if size is not None or params:
            raise InputError(f"real data set {name!r} takes no size or generator parameters "
                             f"(got size={size!r}, {sorted(params)})")
        return _real.load_real(spec.source, data_dir=data_dir, name=name)
    size, seed, params = _resolve(spec, size, seed, params)
    key = _cache.make_key(spec, size, seed, params)
    directory = None if cache_dir is False else _cache.cache_dir(cache_dir)
    if directory is not None:
        cached = _cache.read(directory, key)
        if cached is not None:
            return cached
    started = time.perf_counter()
    generated = spec.generator(size, seed, **params)
    meta = {**generated.meta, "dataset": name, "kind": "phantom", "generator": spec.generator.__module__
            + "." + spec.generator.__name__, "version": spec.version, "size": size, "seed": seed,
            "params": params, "key": key, "targets": spec.targets_by_preset,
            "generation_seconds": time.perf_counter() - started}
    volume = Volume(generated.data, spacing=generated.spacing, value_range=generated.value_range, name=name,
                    labels=generated.labels, meta=meta)
    if directory is not None:
        _cache.write(directory, key, volume)
        volume.meta["cache"] = {"key": key, "path": str(directory / f"{key}.npy"), "hit": False}
    return volume
