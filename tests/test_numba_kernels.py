"""The Numba pieces the CPU backends share: the classification rule and the lock on their disk cache."""

import fcntl
import os
import subprocess
import sys
import time
from pathlib import Path

from numba import njit
from numba.core import event

from renderers.base import numba_kernels

ROOT = Path(__file__).resolve().parents[1]


def _lock_is_free(path):
    with open(path, "a+b") as other:  # a second open file: flock conflicts with this process's own lock too
        try:
            fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False
        fcntl.flock(other, fcntl.LOCK_UN)
        return True


class _SeenDuringCompilation(event.Listener):
    def __init__(self, path):
        self.path = path
        self.free = []

    def on_start(self, event):
        self.free.append(_lock_is_free(self.path))

    def on_end(self, event):
        pass


def test_compiling_holds_no_lock_so_processes_compile_side_by_side():
    path = numba_kernels.CACHE_LOCK
    assert path is not None
    seen = _SeenDuringCompilation(path)
    with event.install_listener("numba:compile", seen):
        njit(lambda x: x + 1)(1)
    assert seen.free == [True]  # a process compiling a kernel leaves every other one free to compile its own


def test_the_lock_lies_beside_the_cache_it_guards(tmp_path):
    script = "from renderers.base import numba_kernels as k; print(k.cache_lock_path())"
    out = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, check=True,
                         env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}).stdout
    assert Path(out.strip()) == tmp_path / "numba-cache.lock"


# A child that compiles a shared kernel into an empty cache, printing when its call returned.
_COMPILER = ("import time; from renderers.base.numba_kernels import table_position; "
             "assert table_position(0.5, 3) == (1, 0.0); print(time.time())")


def _held_while_a_child_compiles(cache, mode):
    """Hold ``mode`` on the cache's lock while a child compiles into ``cache``; return (when the lock was let go,
    when the child's call returned). Numba's own lock is per process (numba/numba#4807)."""
    with open(cache / "numba-cache.lock", "a+b") as held:
        fcntl.flock(held, mode)
        child = subprocess.Popen([sys.executable, "-c", _COMPILER], cwd=ROOT, stdout=subprocess.PIPE, text=True,
                                 env={**os.environ, "NUMBA_CACHE_DIR": str(cache)})
        time.sleep(3.0)  # time for the child to import Numba and compile (about 1 s unlocked)
        assert child.poll() is None, "the child used the cache while the lock was held"
        saved = list(cache.glob("**/*.nbi"))
        released = time.time()
        fcntl.flock(held, fcntl.LOCK_UN)
    out, _ = child.communicate(timeout=100)
    assert child.returncode == 0
    assert not saved  # nothing written while the lock was held
    assert list(cache.glob("**/*.nbi"))  # and its kernel saved into the cache once it was let go
    return released, float(out.strip())


def test_a_process_saves_a_kernel_only_when_no_other_reads_the_cache(tmp_path):
    """A save waits for every reader: a shared hold (another process loading a kernel) keeps the child from
    writing the index and its data file, so no reader sees one written without the other."""
    released, returned = _held_while_a_child_compiles(tmp_path, fcntl.LOCK_SH)
    assert returned >= released


def test_a_process_loads_from_the_cache_only_when_no_other_writes_it(tmp_path):
    """A load waits for a writer: an exclusive hold (another process saving a kernel) keeps the child from
    reading the cache, so it never reads an index whose data file is not yet written."""
    released, returned = _held_while_a_child_compiles(tmp_path, fcntl.LOCK_EX)
    assert returned >= released


def test_processes_load_from_the_cache_side_by_side(tmp_path):
    """Loads share the lock: a child loads a kernel from a warm cache while another process reads it too."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    subprocess.run([sys.executable, "-c", _COMPILER], cwd=ROOT, env=env, check=True, capture_output=True)
    with open(tmp_path / "numba-cache.lock", "a+b") as held:
        fcntl.flock(held, fcntl.LOCK_SH)
        subprocess.run([sys.executable, "-c", _COMPILER], cwd=ROOT, env=env, check=True, capture_output=True,
                       timeout=60)
        fcntl.flock(held, fcntl.LOCK_UN)
