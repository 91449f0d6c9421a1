"""On-disk cache of generated phantoms: ``<key>.npy`` (+ ``<key>.labels.npy``) and ``<key>.json``.

The key hashes the data set name, its generator version, a digest of the generator's source
(its module and every ``datasets`` module it uses, so editing a generator invalidates its cache
without anyone remembering to bump a number), the size, the seed and the full parameter set.

Files are written to a temporary name in the cache folder and moved into place with
``os.replace``, which is atomic on one file system, so parallel Snakemake jobs never see a
half-written volume. The JSON is written last and marks the entry complete; an entry without it,
or one that fails to read, is regenerated.
"""

import hashlib
import inspect
import json
import os
import sys
import tempfile
from functools import lru_cache
from pathlib import Path

import numpy as np

from core.volume import Volume

ENV_VAR = "VOLBENCH_CACHE"
REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_CACHE_DIR = REPO_ROOT / ".cache" / "volumes"


def cache_dir(path=None):
    """The cache folder: ``path``, else ``$VOLBENCH_CACHE``, else ``<repo>/.cache/volumes``."""
    if path is not None:
        return Path(path)
    env = os.environ.get(ENV_VAR)
    return Path(env) if env else DEFAULT_CACHE_DIR


@lru_cache(maxsize=None)
def source_digest(module_name):
    """Digest of a module's source and of every ``datasets.*`` and ``core.*`` module it uses, transitively."""
    seen, files, stack = set(), [], [sys.modules[module_name]]
    while stack:
        module = stack.pop()
        if module.__name__ in seen:
            continue
        seen.add(module.__name__)
        files.append(Path(module.__file__))
        for value in vars(module).values():
            dependency = value if inspect.ismodule(value) else sys.modules.get(getattr(value, "__module__", None) or "")
            if dependency is not None and dependency.__name__.startswith(("datasets.", "core.")) and dependency.__name__ not in seen:
                stack.append(dependency)
    digest = hashlib.sha256()
    for path in sorted(files):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def make_key(spec, size, seed, params):
    """Stable hex key of one generated volume."""
    record = {"dataset": spec.name, "version": spec.version, "code": source_digest(spec.generator.__module__),
              "size": size, "seed": seed, "params": params}
    return hashlib.sha256(json.dumps(record, sort_keys=True).encode()).hexdigest()[:20]


def _paths(directory, key):
    return directory / f"{key}.npy", directory / f"{key}.labels.npy", directory / f"{key}.json"


def read(directory, key):
    """The cached volume for ``key``, or ``None`` when there is no complete, readable entry."""
    data_path, labels_path, meta_path = _paths(Path(directory), key)
    if not (meta_path.is_file() and data_path.is_file()):
        return None
    try:
        record = json.loads(meta_path.read_text())
        data = np.load(data_path)
        labels = np.load(labels_path) if record["labels"] else None
        if list(data.shape) != record["shape"] or data.dtype.str != record["dtype"]:
            return None
        meta = {**record["meta"], "cache": {"key": key, "path": str(data_path), "hit": True}}
        return Volume(data, spacing=tuple(record["spacing"]), value_range=tuple(record["value_range"]),
                      name=record["name"], labels=labels, meta=meta)
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _file_mode():
    """Permissions of a newly created file under the current umask (mkstemp would give 0600)."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


_FILE_MODE = _file_mode()  # read once, at import: os.umask is process-wide


def _atomic_write(path, write):
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
        os.chmod(tmp, _FILE_MODE)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write(directory, key, volume):
    """Store ``volume`` under ``key`` (data and labels first, the JSON marker last)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    data_path, labels_path, meta_path = _paths(directory, key)
    if volume.labels is not None:
        _atomic_write(labels_path, lambda f: np.save(f, volume.labels))
    _atomic_write(data_path, lambda f: np.save(f, volume.data))
    record = {"key": key, "name": volume.name, "shape": list(volume.data.shape), "dtype": volume.data.dtype.str,
              "spacing": list(volume.spacing), "value_range": list(volume.value_range),
              "labels": volume.labels is not None, "meta": volume.meta}
    _atomic_write(meta_path, lambda f: f.write(json.dumps(record, indent=1, sort_keys=True).encode()))
