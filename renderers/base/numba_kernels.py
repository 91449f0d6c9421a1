"""Numba pieces the CPU backends share, so that they classify by one rule.

Imported only by backends that use Numba (the reference and shear-warp), never by
:mod:`renderers.base` itself, so the registry and the GPU backends do not need Numba.
"""

import functools
import math
import os
import tempfile
from pathlib import Path

from numba import config, njit
from numba.core.caching import IndexDataCacheFile

try:
    import fcntl
except ImportError:  # not POSIX: no lock, as Numba itself has none
    fcntl = None

JIT = dict(cache=True, fastmath=False, nogil=True, error_model="numpy")
"""Options of every Numba kernel of the CPU backends: cached, IEEE arithmetic (bit-reproducible), no GIL.
Importing this module first makes their disk cache take :func:`cache_lock_path`'s lock."""


def cache_lock_path():
    """The file the disk cache's reads and writes lock: beside that cache, so that every process using it
    (a cluster's nodes too, where it lies on a shared file system) takes the same lock.

    ``$NUMBA_CACHE_DIR`` where it is set, else the backends' own ``__pycache__`` (Numba's in-tree cache),
    else the temporary folder.
    """
    if config.CACHE_DIR:
        folder = Path(config.CACHE_DIR)
    else:
        folder = Path(__file__).resolve().parents[1] / "__pycache__"
    for candidate in (folder, Path(tempfile.gettempdir())):
        try:
            candidate.mkdir(parents=True, exist_ok=True)
            if os.access(candidate, os.W_OK):
                return candidate / "numba-cache.lock"
        except OSError:
            continue
    return None


def _locked(method, path, mode):
    """``method`` of :class:`~numba.core.caching.IndexDataCacheFile` run under a ``flock`` of ``mode`` on ``path``."""
    @functools.wraps(method)
    def run_locked(self, *args, **kwargs):
        # Read-only: flock needs no write access, so a lock file another user made serves as well.
        fd = os.open(path, os.O_RDONLY | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, mode)
            return method(self, *args, **kwargs)
        finally:
            os.close(fd)  # closing lets the lock go

    run_locked.volbench_lock = path
    return run_locked


def _lock_cache_files():
    """Make reading and writing Numba's disk cache safe between processes; return the lock file, or None.

    Numba's disk cache is not: ``IndexDataCacheFile.save`` writes the index, then the data file, so two
    processes saving different signatures of one kernel at once can both claim data file *n*, and a process
    loading between the two writes can read another signature's code ("can't unbox array from PyObject", or
    a crash, on every later load: numba/numba#4807, #10128). Here a save (and a flush) takes an exclusive
    ``flock`` and a load a shared one, for the file I/O only: compilation itself holds no lock, so two
    processes compile different kernels side by side (a fresh clone's test workers and render workers), and
    a process that loads a cached kernel never waits for another's compilation. A save re-reads the index
    under the lock, so a kernel two processes compiled at once is saved twice under one data file, never
    under two numbers. Costs a ``flock`` per cache load or save, never a frame.
    """
    path = cache_lock_path()
    if fcntl is None or path is None:
        return None
    if hasattr(IndexDataCacheFile.save, "volbench_lock"):  # already wrapped in this process
        return IndexDataCacheFile.save.volbench_lock
    for name, mode in (("save", fcntl.LOCK_EX), ("flush", fcntl.LOCK_EX), ("load", fcntl.LOCK_SH)):
        setattr(IndexDataCacheFile, name, _locked(getattr(IndexDataCacheFile, name), path, mode))
    return path


CACHE_LOCK = _lock_cache_files()
"""The file this process's reads and writes of Numba's disk cache lock (None where there is no ``fcntl`` or no
writable folder)."""


@njit(**JIT)
def table_position(x, size):
    """Lower entry and weight of ``x`` in [0, 1] on a table of ``size`` entries (clamped at the ends).

    Entry ``i`` sits at ``x = i/(size − 1)``, the rule of
    :meth:`core.transfer.TransferFunction.lookup`.
    """
    if x <= 0.0:
        return 0, 0.0
    if x >= 1.0:
        return size - 2, 1.0
    f = x * (size - 1)
    i0 = min(int(math.floor(f)), size - 2)
    return i0, f - i0
