"""The timing harness: a cold frame of its own, warm-up until settled, then timed frames by budget.

A timing is a distribution, not a number. For one view of one run (or several runs timed together,
:func:`measure_together`) the harness

1. renders the **first frame** alone and records its time as the stage ``first_frame``: Numba's and the
   drivers' compilation, first uploads and the backend's preprocessing happen here, never in a timed
   frame;
2. where the backend caches preprocessing (:attr:`renderers.base.Renderer.caches_preprocessing`), the
   cold frame builds it (the caches dropped first) and the preprocessing stages (``classify``,
   ``rle_build``, ...) are its, timed as their own stages, unless it compiled a kernel
   (:mod:`renderers.base.compilation`): then the caches are dropped and a **preprocessing frame**
   builds them again with the code compiled (``info["preprocessing_frame"]``: ``"cold"`` or ``"own"``).
   In a warm worker that compiled the backend's kernels before, a view so costs one frame fewer;
3. renders **warm-up frames** until the frame time settles (two consecutive frames within
   :data:`SETTLED` of each other), at least ``warmup`` and at most :data:`MAX_WARMUP` (or
   :data:`MAX_WARMUP_TIME` seconds); the frame that agrees with the one before is the first timed
   frame, so a view whose time settles at once costs one warm-up frame, not two. A cold or
   preprocessing frame that compiled nothing counts as a warm-up frame (its wall time, uploads and
   preprocessing included, is what the next frame must agree with): in a warm worker, a view whose
   first frame was already a warm frame costs no warm-up frame of its own. Runs timed together
   warm up in rounds once each has had ``warmup`` frames: an arm has settled once one of its frames
   agrees with its frame before (or its warm-up is capped), and the round in which the last arm
   settles is their first timed round;
4. renders **timed frames** until there are at least ``repeat`` of them *and* they took at least
   ``min_time`` seconds *and* the span the load is read over (from the cold frame on) is long enough
   to read (:data:`pipeline.disturbance.MIN_SPAN`), at most ``max_frames``.

Each stage's every timed frame is kept (``frames``), with the median, fastest and slowest; claims take
their confidence intervals from the frames (:mod:`pipeline.experiments.kit.intervals`). The machine's
load over the timed frames is measured (:mod:`pipeline.disturbance`) and returned with the result, and
so is what the frames cost the harness (``info``: ``cold_seconds``, the first frame; ``untimed_seconds``,
the preprocessing and warm-up frames; ``timed_seconds``, the timed frames' wall time), which the
report's account of the harness sums (:mod:`pipeline.harness`).
A run of one untimed frame (``warmup=0, repeat=1``, a ground truth or a picture) renders that frame only.
"""

import statistics
import time

from tqdm import tqdm

from core.validation import check_positive_int, check_scalar
from pipeline import disturbance
from renderers.base import RenderResult, compilation

SETTLED = 0.1
"""Relative difference of two consecutive warm-up frames under which the frame time has settled."""

MAX_WARMUP = 20
"""Warm-up frames after which the timed frames start even if the frame time has not settled."""

MAX_WARMUP_TIME = 5.0
"""Seconds of warm-up after which the timed frames start even if the frame time has not settled."""

MAX_FRAMES = 400
"""Timed frames at most, however short they are."""

GROUP_TIME_FACTOR = 4
"""Runs timed together take rounds until each has ``min_time`` seconds of frames, unless the slowest has
this many times ``min_time`` already: a group of a 1 ms and a 500 ms frame stops there, with the fast
run's frames fewer than its budget rather than the slow run's hundreds."""


def _unreadable(start):
    """Whether the load since ``start`` is still too short a span for the counters to tell
    (:data:`pipeline.disturbance.MIN_SPAN`): a view is timed on until it is not, so that a disturbance
    is seen in every view, fast frames too, instead of the view passing as quiet unmeasured."""
    return time.monotonic() - start.wall < disturbance.MIN_SPAN


def _total(result, wall):
    return result.timings.get("total", wall)


def _check(warmup, repeat, min_time, max_frames):
    warmup = check_positive_int(warmup, name="warmup", minimum=0)
    repeat = check_positive_int(repeat, name="repeat", minimum=1)
    min_time = check_scalar(min_time, name="min_time (seconds of timed frames)", low=0)
    max_frames = check_positive_int(max_frames, name="max_frames", minimum=repeat)
    return warmup, repeat, min_time, max_frames


class _Arm:
    """One renderer and scene being measured: its cold frame, preprocessing, warm-up and timed frames."""

    def __init__(self, renderer, scene):
        self.renderer, self.scene = renderer, scene
        self.frames, self.walls, self.waits = [], [], []  # every timed frame's stage times; walls; waits
        self.last = None  # the last timed frame's whole result (its image is the run's picture)
        self.first_frame = None
        self.preprocessing = {}
        self.compiled = None  # whether the cold frame compiled (where the preprocessing is cached)
        self.warmup = 0
        self.settled = False
        self.previous = None  # the last frame's time, for the settling test
        self.warm_started = None
        self.untimed_seconds = 0.0  # the preprocessing and warm-up frames' wall time (the harness's own account)

    def render(self):
        start = time.perf_counter()
        result = self.renderer.render(self.scene)
        wall = time.perf_counter() - start
        _add_technique(self.renderer, result)
        return result, wall

    def prepare(self, warmup, bar):
        """The cold frame, the preprocessing frame where it compiled, then warm-up frames until ``max(warmup, 1)``
        untimed frames that compiled nothing have been rendered (the cold frame among them, where it compiled
        nothing)."""
        caches = self.renderer.caches_preprocessing
        if caches:
            self.renderer.drop_caches()  # a view after the first builds its preprocessing again too
        before = compilation.count()
        result, self.first_frame = self.render()
        bar.update()
        compiled = compilation.count() != before
        last = max(_total(result, self.first_frame), self.first_frame)
        if caches:
            self.compiled = compiled
            if self.compiled:
                self.renderer.drop_caches()
                result, wall = self.render()
                self.untimed_seconds += wall
                last = max(_total(result, wall), wall)
                compiled = False  # the preprocessing frame runs the code the cold frame compiled
                bar.update()
            self.preprocessing = dict(result.timings)
        # An untimed frame that compiled nothing is a warm-up frame in all but name: the next frame is timed if
        # it agrees with it. Its wall time where longer than its total (preprocessing, uploads and all) is the
        # reference, so a frame that did more than render never passes for a warm one. In a warm worker a next
        # view or replicate so costs a frame fewer; after a cold frame that compiled, warm-up frames settle it.
        if not compiled:
            self.previous = last
        self.warm_started = time.perf_counter()
        for _ in range(max(warmup, 1) - (not compiled)):
            result, wall = self.render()
            if self.agrees(result, wall):
                self.settled = True
            self.warm_up(wall)
            bar.update()

    def agrees(self, result, wall):
        """Whether this frame's time is within :data:`SETTLED` of the frame before (and remember it)."""
        now = _total(result, wall)
        agrees = self.previous is not None and abs(now - self.previous) <= SETTLED * max(now, self.previous)
        self.previous = now
        return agrees

    def warm_up(self, wall):
        """Count a frame as warm-up."""
        self.untimed_seconds += wall
        self.warmup += 1

    def capped(self):
        """Whether the warm-up has had its most frames or time (:data:`MAX_WARMUP`, :data:`MAX_WARMUP_TIME`)."""
        return self.warmup >= MAX_WARMUP or time.perf_counter() - self.warm_started > MAX_WARMUP_TIME

    def frame(self):
        """One frame of a round: ``(result, wall, wait for a CPU)``; :meth:`keep` makes it a timed frame."""
        before = disturbance.thread_waits()
        result, wall = self.render()
        after = disturbance.thread_waits()
        return result, wall, (after - before if None not in (before, after) else 0.0)

    def keep(self, result, wall, wait):
        # Only the stage times are kept of every frame: keeping each frame's image alive would hand every
        # next frame fresh pages to fault in, a cost of the harness that would be timed as the backend's.
        self.frames.append(result.timings)
        self.last = result
        self.walls.append(wall)
        self.waits.append(wait)

    def result(self, load):
        frames = self.frames
        stages = list(dict.fromkeys(stage for frame in frames for stage in frame))
        per_stage = {stage: [frame[stage] for frame in frames if stage in frame] for stage in stages}
        timings = {stage: statistics.median(values) for stage, values in per_stage.items()}
        # Preprocessing happens once: its stages are the preprocessing frame's, not in any timed frame.
        once = {stage: value for stage, value in self.preprocessing.items() if stage not in timings}
        last = self.last
        info = {**last.info, "frames": len(frames), "warmup": self.warmup, "settled": self.settled,
                "first_frame": self.first_frame, "load": load, "cold_seconds": self.first_frame,
                "preprocessing_frame": None if self.compiled is None else "own" if self.compiled else "cold",
                "untimed_seconds": self.untimed_seconds, "timed_seconds": sum(self.walls),
                "disturbed": disturbance.verdict(load, per_stage.get("total", []), self.waits, self.walls),
                "starved": disturbance.starvation(load, _workers(self.renderer))}
        return RenderResult(
            image=last.image,
            timings={**timings, **once, **({"first_frame": self.first_frame} if self.first_frame else {})},
            counters=dict(last.counters),
            timings_min={stage: min(values) for stage, values in per_stage.items()},
            timings_max={stage: max(values) for stage, values in per_stage.items()},
            info=info, frames=per_stage,
        )


def _add_technique(renderer, result):
    """Add the stage ``technique``: the sum of the renderer's :attr:`~renderers.base.Renderer.technique_stages`."""
    present = [stage for stage in renderer.technique_stages if stage in result.timings]
    if present:
        result.timings["technique"] = sum(result.timings[stage] for stage in present)


def _workers(renderer):
    """How many threads the renderer's technique runs on, where it says (``workers``)."""
    workers = getattr(renderer, "workers", None)
    return workers if isinstance(workers, int) else None


def _untimed(renderer, scene, bar):
    start = time.perf_counter()
    result = renderer.render(scene)
    wall = time.perf_counter() - start
    _add_technique(renderer, result)
    bar.update()
    per_stage = {stage: [value] for stage, value in result.timings.items()}
    return RenderResult(image=result.image, timings=dict(result.timings), counters=dict(result.counters),
                        timings_min=dict(result.timings), timings_max=dict(result.timings),
                        info={**result.info, "frames": 1, "warmup": 0, "untimed": True, "untimed_seconds": wall},
                        frames=per_stage)


def measure(renderer, scene, *, warmup=1, repeat=3, min_time=0.0, max_frames=MAX_FRAMES, progress=False):
    """Time ``scene`` on ``renderer``: a cold frame, warm-up until settled, then timed frames by budget.

    Parameters
    ----------
    renderer : renderers.base.Renderer
    scene : core.scene.Scene
    warmup : int
        Untimed frames at least before the timed ones (more until the frame time settles): warm-up frames,
        and the cold or preprocessing frame where it compiled nothing.
        ``warmup=0`` with ``repeat=1`` and no ``min_time``: one untimed frame only.
    repeat : int
        Timed frames at least.
    min_time : float
        Seconds the timed frames take at least (more frames until they do).
    max_frames : int
        Timed frames at most.
    progress : bool
        Show a progress bar over the frames (for the command line).

    Returns
    -------
    RenderResult
        The last frame's image and counters; ``timings`` holds each stage's median over the timed
        frames (with ``first_frame``, the cold frame, and the preprocessing stages, timed once),
        ``timings_min``/``timings_max`` the extremes, ``frames`` every timed frame's stages and
        ``info`` the frame counts, the load the machine carried (``load``) and why the frames were
        disturbed (``disturbed``, empty when they were not).
    """
    return measure_together([(renderer, scene)], warmup=warmup, repeat=repeat, min_time=min_time,
                            max_frames=max_frames, progress=progress)[0]


def measure_together(arms, *, warmup=1, repeat=3, min_time=0.0, max_frames=MAX_FRAMES, progress=False):
    """Time several ``(renderer, scene)`` arms together, interleaved frame by frame; a result per arm.

    Each arm gets its cold frame, preprocessing and warm-up first, one arm after another; then the
    timed frames alternate in rounds, A B, B A, A B, ... (the order reversed every round, so neither
    arm always follows the other), until every arm has ``repeat`` frames and ``min_time`` seconds of
    them. Frame ``i`` of every arm is from round ``i``: a claim's ratio resamples them by round
    (:mod:`pipeline.experiments.kit.intervals`), so a disturbance that slowed one round slowed both.
    The load over the whole interleaved span is every arm's ``load``.
    """
    warmup, repeat, min_time, max_frames = _check(warmup, repeat, min_time, max_frames)
    if not arms:
        raise ValueError("measure_together: no arms to time")
    names = ", ".join(dict.fromkeys(renderer.name for renderer, _ in arms))
    untimed = warmup == 0 and repeat == 1 and min_time == 0
    # The bar closes (ends its line) however the frames end, so that a message after Ctrl-C or an
    # error starts a line of its own instead of being followed by the bar drawn again at exit.
    with tqdm(desc=f"{names} frames", disable=not progress, unit="frame") as bar:
        if untimed:
            return [_untimed(renderer, scene, bar) for renderer, scene in arms]
        states = [_Arm(renderer, scene) for renderer, scene in arms]
        # The load is read from the warm-up on: the timed frames alone may be too short for the
        # kernel's 10 ms counters (pipeline.disturbance.MIN_SPAN).
        start = disturbance.snapshot()
        for state in states:
            state.prepare(warmup, bar)
        started, waited = time.perf_counter(), disturbance.thread_waits()
        spent = [0.0] * len(states)
        rounds = played = 0  # timed rounds; every round, warm-up rounds included
        warming = True
        while rounds < max_frames and (rounds < repeat or (min(spent) < min_time
                                                          and max(spent) < GROUP_TIME_FACTOR * min_time)
                                       or _unreadable(start)):
            order = states if played % 2 == 0 else states[::-1]
            frames = {}
            for state in order:
                began = time.perf_counter()
                frames[id(state)] = state.frame()
                frames[id(state)] += (time.perf_counter() - began,)
                bar.update()
            played += 1
            if warming:
                # Warm-up goes on in rounds until every arm has settled (a frame that agreed with its
                # frame before; an arm stays settled) or had its most warm-up: the round in which the
                # last one does is the first timed round. Waiting for every arm to agree in one round
                # would keep a group of five noisy arms warming up to the cap.
                for state in states:
                    if state.agrees(*frames[id(state)][:2]):
                        state.settled = True
                if not all(state.settled or state.capped() for state in states):
                    for state in states:
                        state.warm_up(frames[id(state)][1])
                    continue
                warming = False
            for i, state in enumerate(states):
                result, wall, wait, took = frames[id(state)]
                state.keep(result, wall, wait)
                spent[i] += took
            rounds += 1
        elapsed, now_waited = time.perf_counter() - started, disturbance.thread_waits()
        load = {**disturbance.between(start, disturbance.snapshot()),
                "load_average": disturbance.load_average(), "elapsed": elapsed,
                "waited_share": (now_waited - waited) / elapsed if None not in (waited, now_waited) and elapsed > 0
                else None}
    return [state.result(load) for state in states]
