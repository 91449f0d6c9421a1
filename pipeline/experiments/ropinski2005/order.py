"""``ropinski2005-order`` (E9): the region passes back to front (the paper) against front to back."""

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import (STRICTLY_ABOVE_ONE, all_of, config_rows, counted, counts_compared,
                                              measured, median_count, time_ratio)
from pipeline.experiments.kit.model import Claim, ClaimResult
from pipeline.experiments.kit.pages import (claim_takeaways, difference_gallery, format_number, frames_caption,
                                            unless_missing)
from pipeline.experiments.kit.planning import listed, timed_frames
from pipeline.experiments.kit.results import nonempty, text_column
from pipeline.experiments.ropinski2005.correctness import SEAM_TOLERANCE
from pipeline.experiments.ropinski2005.methods import (PAPER_METHOD, TIMED_SCALES, TIMES, LensExperiment,
                                                       device_takeaways, lens_run, lens_settings,
                                                       raycast_not_measurable, scenes_of)
from pipeline.experiments.ropinski2005.pages import headline, interval_columns, median_ms, run_table, tests_of
from pipeline.experiments.ropinski2005.scenes import BONE_ISOVALUE, lens_scene, lens_views, scene_tags
from reports import blocks

FRONT_TO_BACK = "segments-ftb"
"""The front-to-back region order's config (:data:`~.methods.METHODS`)."""

THRESHOLD = 0.95
"""Opacity at which a ray stops (``gl-raycast``'s ``opaque_threshold``, its default) in the timed runs."""

NO_TERMINATION = 1.0
"""``opaque_threshold`` of the control runs: no ray stops, so both orders composite every sample."""

OPAQUE_SCALE = 4.0
"""Opacity scale of the skull's lens made opaque: its bone table × 4 (a transparency lens's table × 0.2)."""

OPAQUE_BONE = {"points": [[0.0, 0.93, 0.89, 0.8, 1.0], [1.0, 0.93, 0.89, 0.8, 1.0]]}
"""The foot's isosurface lens's table: bone white, opacity 1. An isosurface lens takes its colour and opacity from
a table at the crossing (the volume's by default, whose opacity at the foot's bone isovalue is below 1), so this
one makes region₁ opaque wherever the surface is met."""

SCENES = {
    "foot": ({"appearance": {"mode": "iso", "isovalue": BONE_ISOVALUE, "transfer_function": OPAQUE_BONE}},
             "region₁ opaque where the surface is met: the foot's bone isosurface lens, drawn opaque"),
    "skull": ({"appearance": {"mode": "dvr", "preset": "bone", "opacity_scale": OPAQUE_SCALE}},
              f"region₁ opaque: the skull's lens with its bone table's opacity × {format_number(OPAQUE_SCALE)}"),
    "seismic": ({"center": (0.0, 0.0, 0.0)},
                "region₂ opaque: the clipping lens moved to the cube's centre, behind the dense layers in front of it"),
}
"""The scenes where region₁ or region₂ is opaque: what changes in the scene's lens (:func:`~.scenes.lens_scene`'s
keywords) and why."""


def termination_rows(frame, termination):
    """The rows with early termination ``"on"`` (:data:`THRESHOLD`) or ``"off"`` (:data:`NO_TERMINATION`)."""
    return frame[text_column(frame, "termination") == termination]


def order_difference(frame, termination, scene):
    """The largest |front-to-back − back-to-front| (``max_error`` of the front-to-back run against its reference)."""
    rows = config_rows(termination_rows(frame, termination), FRONT_TO_BACK, scene=scene)
    return float(measured(rows, "max_error", f"the front-to-back image of {scene} (early termination {termination}) "
                                             "was not compared with the back-to-front one").max_error.max())


def _faster(df):
    rows = termination_rows(df, "on")
    resampler = intervals.Resampler()
    decisions, notes = {}, {}
    for scene in nonempty(scenes_of(rows)):
        decisions[scene] = time_ratio(rows, PAPER_METHOD, FRONT_TO_BACK, resampler=resampler,
                                      at_least=STRICTLY_ABOVE_ONE, scene=scene)
        region0 = [median_count(config_rows(rows, c, scene=scene), "count_samples_region0")
                   for c in (PAPER_METHOD, FRONT_TO_BACK)]
        if all(np.isfinite(region0)):
            notes[scene] = (f"region₀ samples {format_number(region0[0])} back to front, {format_number(region0[1])} "
                            "front to back")
    return all_of(decisions, notes=notes, what="time(back to front) / time(front to back) ",
                  extra=f"{TIMES}; both orders timed together, early termination at opacity "
                        f"{format_number(THRESHOLD)}")


def _fewer_samples(df):
    rows = termination_rows(df, "on")
    return counts_compared(
        nonempty(scenes_of(rows)), lambda scene: tuple(  # (front, back), counted back to front first
            counted(config_rows(rows, config, scene=scene), "count_samples_region0", f"{scene} {order}")
            for config, order in ((PAPER_METHOD, "back to front"), (FRONT_TO_BACK, "front to back")))[::-1],
        fewer=True, measured=lambda share, scene: f"front to back takes {format_number(100 * share)} % of the "
                                                  f"region₀ samples ({scene})",
        words=lambda s, f, b: f"{s}: {format_number(f)} of {format_number(b)}",
        extra=f"; counted, early termination at opacity {format_number(THRESHOLD)}")


def _differ_at_most(termination, bound, how):
    """A check: every scene's largest |front to back − back to front| with early termination ``termination`` is at
    most ``bound``; ``how`` ends the claim's note."""
    def check(df):
        differences = {scene: order_difference(df, termination, scene)
                       for scene in nonempty(scenes_of(termination_rows(df, termination)))}
        scene = max(differences, key=differences.get)
        return ClaimResult(f"{format_number(differences[scene])} ({scene})",
                           all(v <= bound for v in differences.values()),
                           ", ".join(f"{s}: {format_number(v)}" for s, v in differences.items()) + how)
    return check


CLAIMS = (
    Claim("front-to-back-faster", "Front to back is faster where region₁ or region₂ is opaque: the rays stop before "
          "the regions behind (note 004 §2.8, §4.2 E9; not in the paper)",
          f"time(back to front) / time(front to back) > ×1, every scene ({TIMES}; 95 % paired bootstrap interval "
          "wholly above ×1)", _faster, kind="timing"),
    Claim("front-to-back-samples", "Because it takes fewer samples behind the lens", "region₀ samples front to "
          "back < back to front, every scene (counted)", _fewer_samples, kind="count"),
    Claim("same-image", "Both orders composite the same samples into the same image",
          f"max |front to back − back to front| ≤ {SEAM_TOLERANCE:g} on every pixel and channel, early termination "
          "off, every scene",
          _differ_at_most("off", SEAM_TOLERANCE, "; largest |front to back − back to front| over every pixel and RGBA "
                                                 "channel, early termination off"), kind="accuracy"),
    Claim("drops-only-terminated", "With early termination on, front to back drops only what early termination drops",
          f"max |front to back − back to front| ≤ 1 − the opacity threshold ({format_number(1 - THRESHOLD)}), every "
          "scene",
          _differ_at_most("on", 1.0 - THRESHOLD, f"; early termination at opacity {format_number(THRESHOLD)} drops at "
                          f"most the light behind it, {format_number(1.0 - THRESHOLD)} of a pixel in either order"),
          kind="accuracy"),
)


def order_table(tests):
    """Per scene and early termination: both orders' frame times, their ratio with its interval, samples, difference."""
    rows = []
    resampler = intervals.Resampler()
    for termination in ("on", "off"):
        part = termination_rows(tests, termination)
        for scene in pd.unique(part.scene):
            try:
                decision = time_ratio(part, PAPER_METHOD, FRONT_TO_BACK, resampler=resampler, scene=scene)
                back, front = (config_rows(part, c, scene=scene) for c in (PAPER_METHOD, FRONT_TO_BACK))
            except (KeyError, ValueError):
                continue
            row = {"scene": scene, "early termination": termination, "back to front (ms)": median_ms(back),
                   "front to back (ms)": median_ms(front),
                   **interval_columns(decision.value, decision.interval, "back / front")}
            for region in ("region2", "region1", "region0"):
                for name, rows_ in (("back", back), ("front", front)):
                    row[f"{region} samples, {name}"] = median_count(rows_, f"count_samples_{region}")
            row["max |front − back|"] = unless_missing(order_difference, tests, termination, scene, empty=np.nan)
            rows.append(row)
    return pd.DataFrame(rows)


class Order(LensExperiment):
    name = "ropinski2005-order"
    title = "Region order: back to front (the paper) against front to back (E9)"
    settings = frozenset({"scenes", "volume_size", "image_size", "orbit", "step_factor", "repeat", "min_time"})
    scales = TIMED_SCALES
    description = (
        "Not in the paper, which casts region₀, region₁ and region₂ back to front, each blended over the "
        "image: opacity in front of the lens cannot stop the rays behind it, cast first. gl-raycast's "
        "region_order front-to-back casts region₂, region₁, region₀, each pass continuing the accumulation of "
        "the ones before, so a ray that is opaque in front of the lens takes no samples behind it (note 004 "
        "§2.8's ablation). Three scenes where region₁ or region₂ is opaque: the foot's bone isosurface lens "
        f"(drawn opaque), the skull's lens with its bone table's opacity × {format_number(OPAQUE_SCALE)}, and the "
        "seismic cube whose "
        "clipping lens, moved to the centre, lies behind dense layers. Both orders are timed together with early "
        f"termination at opacity {format_number(THRESHOLD)}, and again without early termination (every sample "
        "composited), in one job per scene; each front-to-back image is compared with the back-to-front one."
    )
    claims = CLAIMS

    def lens_runs(self, profile):
        wanted = listed(profile, self, "scenes", tuple(SCENES), known=SCENES)
        size, image, orbit, step = lens_settings(profile, self)
        frames = timed_frames(profile, self)
        runs = []
        for scene_name in wanted:
            lens, why = SCENES[scene_name]
            spec = lens_scene(scene_name, image, size=size, real_data=profile.real_data, **lens)
            views = lens_views(scene_name, orbit)
            tags = scene_tags(scene_name, image_size=image, role="test", opaque=why)
            for termination, threshold in (("on", THRESHOLD), ("off", NO_TERMINATION)):
                suffix = "" if termination == "on" else ".all"
                back = lens_run(self.name, f"{scene_name}.back{suffix}", spec, views, PAPER_METHOD, frames,
                                {**tags, "termination": termination}, step_factor=step, group=scene_name,
                                options={"opaque_threshold": threshold})
                runs += [back, lens_run(self.name, f"{scene_name}.front{suffix}", spec, views, FRONT_TO_BACK, frames,
                                        {**tags, "termination": termination}, step_factor=step, group=scene_name,
                                        reference=back.id, options={"opaque_threshold": threshold})]
        return runs

    def report(self, results, ctx):
        tests = tests_of(results)
        out = [claim_takeaways(ctx, device_takeaways(tests))]
        if not tests.empty:
            out.append(blocks.Table("Both orders, with and without early termination", order_table(tests).round(4),
                                    csv_name="order.csv",
                                    caption="Median frame times over the views; back / front with its 95 % paired "
                                            "bootstrap interval; samples per region counted by the caster; max "
                                            "|front − back| over every pixel and RGBA channel. "
                                            + frames_caption(tests)))
            front = headline(tests)
            out.append(difference_gallery(
                "Front to back against back to front (headline view)",
                front[text_column(front, "config") == FRONT_TO_BACK], ctx, against=results,
                label=lambda row: f"{row.scene}, early termination {row.termination}",
                note=lambda row: f"max difference {format_number(getattr(row, 'max_error', np.nan))}",
                caption="Left the front-to-back image, right |front to back − back to front| (early termination on, "
                        "then off)."))
            out.append(run_table(tests, ["scene", "config", "termination", "time_ms", "time_ms_min", "time_ms_max",
                                         "count_samples", "count_samples_region0", "max_error"], ctx,
                                 names={"termination": "early termination", "max_error": "max |front − back|"},
                                 csv_name="order_runs.csv"))
        return out + raycast_not_measurable([PAPER_METHOD, FRONT_TO_BACK])
