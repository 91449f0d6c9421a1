"""Per-pass device timing and fragment counts for the OpenGL backends.

Two ways to time a pass, chosen per renderer (option ``timing``):

* ``"query"``: a ``GL_TIME_ELAPSED`` query around each pass, read after the frame. This is the
  device's own clock and adds no synchronisation; it is what a GPU should use.
* ``"finish"``: the wall clock around the pass followed by ``glFinish``, so the pass has
  completed when the clock stops. On a CPU rasterizer this is the only meaningful measure:
  llvmpipe defers rasterisation to its worker threads and its ``GL_TIME_ELAPSED`` does not
  cover that work (measured: 2 ms reported for a 512² draw that takes 57 ms to finish; over a
  40-pass frame the reported passes summed to 1.6 s in a 0.6 s frame). The price is a wait
  after every pass, which a frame's ``total`` then includes.

Every pass gets its own query objects (llvmpipe flushes when a query is reused within a frame),
taken from a pool that grows as needed. ``GL_SAMPLES_PASSED`` queries count the fragments that
survived the depth test of a pass, which with early fragment tests are the fragments whose
shader ran.
"""

import time
from collections import defaultdict

TIMING_METHODS = ("auto", "query", "finish")


class PassTimer:
    """Times passes by stage name and counts their fragments.

    Parameters
    ----------
    ctx : moderngl.Context
    method : {"query", "finish"}
    """

    def __init__(self, ctx, method):
        self.ctx = ctx
        self.method = method
        self._pools = {True: [], False: []}
        self._used = {True: 0, False: 0}
        self._records = []

    def start_frame(self):
        """Forget the previous frame's passes (their query objects are reused)."""
        self._used = {True: 0, False: 0}
        self._records = []

    def _query(self, samples):
        pool = self._pools[samples]
        index = self._used[samples]
        if index == len(pool):
            pool.append(self.ctx.query(samples=samples, time=self.method == "query"))
        self._used[samples] = index + 1
        return pool[index]

    def run(self, stage, draw, *, count=False):
        """Issue ``draw()`` as one pass of ``stage``; ``count`` its passing fragments."""
        if self.method == "query" or count:
            query = self._query(count)
        else:
            query = None
        start = time.perf_counter()
        if query is None:
            draw()
        else:
            with query:
                draw()
        if self.method == "finish":
            self.ctx.finish()
        self._records.append((stage, query, count, time.perf_counter() - start))

    def results(self):
        """``(seconds per stage, fragment counts per stage as lists)`` of this frame's passes.

        Reading the queries waits for the device to finish the frame.
        """
        seconds = defaultdict(float)
        fragments = defaultdict(list)
        for stage, query, count, wall in self._records:
            seconds[stage] += query.elapsed * 1e-9 if self.method == "query" else wall
            if count:
                fragments[stage].append(int(query.samples))
        return dict(seconds), dict(fragments)
