"""The Numba pieces the CPU backends share: the classification rule and the compile lock on the disk cache."""

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


def test_a_compilation_holds_the_lock_and_releases_it():
    lock = numba_kernels.COMPILE_LOCK
    assert lock is not None
    seen = _SeenDuringCompilation(lock._path)
    with event.install_listener("numba:compile", seen):
        njit(lambda x: x + 1)(1)
    assert seen.free == [False]  # the kernel compiled while the file was locked
    assert _lock_is_free(lock._path)  # and the lock was let go after it
    assert lock._depth == 0


def test_the_lock_lies_beside_the_cache_it_guards(tmp_path):
    script = "from renderers.base import numba_kernels as k; print(k.compile_lock_path())"
    out = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, check=True,
                         env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}).stdout
    assert Path(out.strip()) == tmp_path / "numba-compile.lock"


def test_another_process_waits_for_the_lock_before_it_compiles(tmp_path):
    """Two processes compiling into one disk cache take turns: one that finds the lock held compiles
    (here a shared kernel, into an empty cache) only after it is let go. Numba's own lock is per
    process (numba/numba#4807)."""
    path = tmp_path / "numba-compile.lock"
    compiler = ("import time; from renderers.base.numba_kernels import table_position; "
                "assert table_position(0.5, 3) == (1, 0.0); print(time.time())")
    with open(path, "a+b") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        child = subprocess.Popen([sys.executable, "-c", compiler], cwd=ROOT, stdout=subprocess.PIPE, text=True,
                                 env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)})
        time.sleep(3.0)  # time for the child to import Numba and reach its first compilation
        assert child.poll() is None, "the child compiled although the lock was held"
        released = time.time()
        fcntl.flock(held, fcntl.LOCK_UN)
    out, _ = child.communicate(timeout=100)
    assert child.returncode == 0
    assert float(out.strip()) >= released
    assert list(tmp_path.glob("**/*.nbi"))  # it compiled into the cache the lock guards
