"""The timing harness: warm-up frames, repeated frames, median with min and max per stage."""

import statistics

from tqdm import tqdm

from core.validation import check_positive_int
from renderers.base import RenderResult


def measure(renderer, scene, *, warmup=1, repeat=3, progress=False):
    """Render ``scene`` ``warmup + repeat`` times and summarise the timed frames.

    Parameters
    ----------
    renderer : renderers.base.Renderer
    scene : core.scene.Scene
    warmup : int
        Untimed frames first (JIT compilation, shader compilation, uploads, caches).
    repeat : int
        Timed frames.
    progress : bool
        Show a progress bar over the frames (for the command line).

    Returns
    -------
    RenderResult
        The last frame's image and counters; ``timings`` holds each stage's median over the
        timed frames, ``timings_min``/``timings_max`` the extremes, and ``info["frames"]`` the
        number of timed frames.
    """
    warmup = check_positive_int(warmup, name="warmup", minimum=0)
    repeat = check_positive_int(repeat, name="repeat", minimum=1)
    # The bar closes (ends its line) however the frames end, so that a message after Ctrl-C or an
    # error starts a line of its own instead of being followed by the bar drawn again at exit.
    with tqdm(total=warmup + repeat, desc=f"{renderer.name} frames", disable=not progress, unit="frame") as bar:
        for _ in range(warmup):
            renderer.render(scene)
            bar.update()
        frames = []
        for _ in range(repeat):
            frames.append(renderer.render(scene))
            bar.update()
    stages = list(dict.fromkeys(stage for frame in frames for stage in frame.timings))
    per_stage = {stage: [frame.timings[stage] for frame in frames if stage in frame.timings] for stage in stages}
    last = frames[-1]
    return RenderResult(
        image=last.image,
        timings={stage: statistics.median(values) for stage, values in per_stage.items()},
        counters=dict(last.counters),
        timings_min={stage: min(values) for stage, values in per_stage.items()},
        timings_max={stage: max(values) for stage, values in per_stage.items()},
        info={**last.info, "frames": repeat, "warmup": warmup},
    )
