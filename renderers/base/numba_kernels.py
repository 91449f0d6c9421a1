"""Numba pieces the CPU backends share, so that they classify by one rule.

Imported only by backends that use Numba (the reference and shear-warp), never by
:mod:`renderers.base` itself, so the registry and the GPU backends do not need Numba.
"""

import math
import os
import tempfile
import threading
from pathlib import Path

from numba import config, njit
from numba.core import event

try:
    import fcntl
except ImportError:  # not POSIX: no lock, as Numba itself has none
    fcntl = None

JIT = dict(cache=True, fastmath=False, nogil=True, error_model="numpy")
"""Options of every Numba kernel of the CPU backends: cached, IEEE arithmetic (bit-reproducible), no GIL.
Importing this module first makes their compilation take :class:`CompileLock`."""


def compile_lock_path():
    """The file :class:`CompileLock` locks: beside the kernels' disk cache, so that every process writing
    that cache (a cluster's nodes too, where it lies on a shared file system) takes the same lock.

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
                return candidate / "numba-compile.lock"
        except OSError:
            continue
    return None


class CompileLock(event.Listener):
    """An exclusive lock on :func:`compile_lock_path` while this process is inside Numba's compiler lock.

    Numba's disk cache is not safe between processes: ``IndexDataCacheFile.save`` writes the index,
    then the data file, and two processes saving different signatures of one kernel at once can both
    claim data file *n*, leaving the index pointing at the other signature's code ("can't unbox array
    from PyObject", or a crash, on every later load: numba/numba#4807, #10128). Numba loads, compiles
    and saves a kernel under its global compiler lock, which is one lock per process; this listener
    on that lock's event makes it one lock per machine (per shared cache). It is re-entrant, as
    Numba's is (a kernel's callees compile inside it), and costs a ``flock`` per compilation or
    cache load, never a frame.
    """

    def __init__(self, path):
        self._path = path
        self._guard = threading.Lock()
        self._depth = 0
        self._fd = None

    def on_start(self, event):
        with self._guard:
            if self._depth == 0:
                # Read-only: flock needs no write access, so a lock file another user made serves as well.
                self._fd = os.open(self._path, os.O_RDONLY | os.O_CREAT, 0o666)
                fcntl.flock(self._fd, fcntl.LOCK_EX)
            self._depth += 1

    def on_end(self, event):
        with self._guard:
            self._depth -= 1
            if self._depth == 0:
                fcntl.flock(self._fd, fcntl.LOCK_UN)
                os.close(self._fd)
                self._fd = None


def _install_compile_lock():
    path = compile_lock_path()
    if fcntl is None or path is None:
        return None
    lock = CompileLock(path)
    event.register("numba:compiler_lock", lock)
    return lock


COMPILE_LOCK = _install_compile_lock()
"""The listener this process's Numba compilations take (None where there is no ``fcntl`` or no writable folder)."""


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
