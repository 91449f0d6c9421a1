"""How many kernels this process has compiled: whether a frame compiled anything.

The timing harness renders a view's first frame cold. Where a backend caches preprocessing
(:attr:`renderers.base.Renderer.caches_preprocessing`), it takes that frame's preprocessing stages
as the view's unless the frame compiled something, in which case it drops the caches and builds
them once more, compiled (:mod:`pipeline.timing`). A warm worker process that has compiled a
backend's kernels already so renders one frame fewer per view.

Counted here: every Numba compilation or load from Numba's disk cache (each takes Numba's compiler
lock: the event ``numba:compiler_lock``; Numba's own import counts as one, so that a frame that
first imports it counts as compiling) and every program a backend links through :func:`record`
(the OpenGL backends' :func:`renderers.gl.context.program`). A backend that caches preprocessing
compiles only through these paths.
"""

import sys

_count = 0
_numba_counted = False


def record(n=1):
    """Count ``n`` compilations done outside Numba (a linked shader program)."""
    global _count
    _count += n


def count():
    """Compilations so far in this process (Numba's and those :func:`record` counted)."""
    _count_numba()
    return _count


def _count_numba():
    # Numba is imported only by the backends that use it (an import costs a third of a second):
    # its compilations are counted from the first call after it was imported.
    global _numba_counted
    if _numba_counted or "numba" not in sys.modules:
        return
    from numba.core import event

    class NumbaCompilations(event.Listener):
        def on_start(self, event):
            record()

        def on_end(self, event):
            pass

    event.register("numba:compiler_lock", NumbaCompilations())
    _numba_counted = True
    record()
