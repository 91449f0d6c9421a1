"""``ropinski2005-size`` (E5): the lens's overhead against how much of the picture it covers."""

import numpy as np
import pandas as pd

from core.errors import InputError
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import all_of, decision_words
from pipeline.experiments.kit.model import Claim, scaled
from pipeline.experiments.kit.pages import (as_percent, claim_takeaways, difference_gallery, format_number, frame_note,
                                            frames_caption, silent_without_runs)
from pipeline.experiments.kit.planning import listed, timed_frames
from pipeline.experiments.kit.results import nonempty_or, numeric, rows_matching, text_column
from pipeline.experiments.ropinski2005.methods import (OFF, PAPER_METHOD, TIMED_SCALES, TIMES, LensExperiment,
                                                       device_takeaways, lens_coverage, lens_run, lens_settings,
                                                       raycast_not_measurable, scenes_of)
from pipeline.experiments.ropinski2005.pages import (PERCENT_CI, headline, interval_columns, median_ms, overhead_figure,
                                                     region_samples, rounded_table, run_table, samples_ratio,
                                                     scene_by_scene, tests_of)
from pipeline.experiments.ropinski2005.scenes import (SETUPS, lens_scene, lens_views, outside_appearance, scene_tags,
                                                      without_lens)

RADII = (0.05, 0.1, 0.2, 0.3, 0.45, 0.6)
"""Sphere radii, fractions of the volume's longest edge (note 004 §4.2 E5: 0.05 to 0.6)."""

SCENES = ("skull", "seismic")
"""A transparency lens over a thin shell in empty space, and a clipping lens in a dense, opaque cube."""

SLOPE_BOUND = 0.0
"""The least slope of the overhead against the coverage (percentage points of frame time per percentage
point of rays through the lens) for "grows": the whole 95 % interval above 0, i.e. a positive association
the frames resolve. No steeper bound is claimed: the paper gives no cost model, and how much a covered ray
costs depends on the lens's appearance and on the data behind it."""

APPEARANCES = {"outside": "the outside appearance", "own": "the scene's own appearance"}
"""What the swept lens shows: the volume's own appearance (so the lens changes only how rays are cut, the
cost the claim is about) or the scene's lens appearance."""


def sweep_points(frame, scene, appearance, *, resampler):
    """``(radius, coverage, overhead, draws)`` per radius, ascending, of ``scene``'s lens showing ``appearance``
    (a key of :data:`APPEARANCES`): the rays meeting lens ∩ box (%, counted), the overhead (% of the lens-off frame)
    and its bootstrap draws, paired round by round with the lens-off run (``None`` without frames)."""
    rows = rows_matching(frame, scene, scene=scene)
    off = nonempty_or(rows[text_column(rows, "config") == OFF], f"no successful lens-off run of {scene}")
    on = rows[(text_column(rows, "config") != OFF) & (text_column(rows, "appearance") == appearance)]
    radii = sorted(numeric(on, "radius").dropna().unique())
    if len(radii) < 3:
        raise ValueError(f"need three lens radii on {scene} ({APPEARANCES[appearance]}), got {len(radii)}")
    off_time = numeric(off, "time_total").median()
    off_draws = intervals.statistic_draws(off, "time_total", "median", resampler)
    points = []
    for radius in radii:
        lens = on[numeric(on, "radius") == radius]
        coverage = lens_coverage(lens)
        if not np.isfinite(coverage):
            raise ValueError(f"the rays through the lens of radius {format_number(radius)} on {scene} were not "
                             "counted (lens_rays, rays)")
        draws = intervals.statistic_draws(lens, "time_total", "median", resampler)
        overhead_draws = 100 * (draws / off_draws - 1) if draws is not None and off_draws is not None else None
        points.append((float(radius), 100 * coverage, 100 * (numeric(lens, "time_total").median() / off_time - 1),
                       overhead_draws))
    return points


def slope_decision(points, *, at_least=SLOPE_BOUND):
    """The least-squares slope of the overhead against the coverage, judged with its bootstrap interval."""
    coverage = np.array([p[1] for p in points])
    if np.ptp(coverage) == 0:
        raise ValueError("every radius covers the same rays: no slope against the coverage")
    slope = float(np.polyfit(coverage, [p[2] for p in points], 1)[0])
    draws = [p[3] for p in points]
    interval = None
    if all(d is not None for d in draws):
        # One slope per draw: polyfit fits every column of a (points, draws) array at once.
        interval = intervals.interval_of(np.polyfit(coverage, np.vstack(draws), 1)[0])
    return intervals.decide(slope, interval, at_least=at_least)


def rank_correlation(points):
    """Spearman's rank correlation of the overhead with the coverage (point values)."""
    frame = pd.DataFrame({"coverage": [p[1] for p in points], "overhead": [p[2] for p in points]})
    return float(frame.rank().corr().iloc[0, 1])


def slopes(frame, appearance):
    """``({scene: Decision}, {scene: note})``: each scene's slope with ``appearance``, and its points in words."""
    resampler = intervals.Resampler()
    decisions, notes = {}, {}
    for scene in scenes_of(frame):
        points = sweep_points(frame, scene, appearance, resampler=resampler)
        decisions[scene] = slope_decision(points)
        notes[scene] = (f"coverage {format_number(points[0][1])}–{format_number(points[-1][1])} % of the rays, "
                        f"overhead {format_number(points[0][2])} to {format_number(points[-1][2])} %, rank "
                        f"correlation {format_number(rank_correlation(points))}")
    return decisions, notes


def _grows(df):
    decisions, notes = slopes(df, "outside")
    return all_of(decisions, show=format_number, notes=notes,
                 what="slope of the overhead against the coverage (% of the frame per % of the rays) ",
                 extra=f"the lens showing the outside appearance; {TIMES}; every radius and the lens-off frame "
                       "timed together")


CLAIMS = (
    Claim("overhead-grows", "The lens costs more the more of the picture it covers: every ray through it is cut "
          "into three segments cast in three passes, back to front (note 004 §4.2 E5)",
          "least-squares slope of the overhead (100 · (t(lens) / t(no lens) − 1), %) against the rays meeting "
          f"lens ∩ box (%) > {format_number(SLOPE_BOUND)}, 95 % bootstrap interval wholly above, every swept scene, "
          f"the lens showing the outside appearance (radius {format_number(RADII[0])}–{format_number(RADII[-1])} of "
          f"the edge; {TIMES})", _grows, kind="timing"),
)


@silent_without_runs
def own_takeaways(tests):
    """The slope with each scene's own lens appearance, in words (measured, not judged: see the description)."""
    decisions, _ = slopes(tests, "own")
    words = [f"{scene} ({SETUPS[scene].appearance['mode']}) {decision_words(d, format_number)}"
             for scene, d in decisions.items()]
    return [f"With each scene's own lens appearance, the slope of the overhead against the coverage (% of the frame "
            f"per % of the rays; measured, not judged: a clipping lens also takes away its region₁ samples) is "
            f"{', '.join(words)}."]


def sweep_table(tests):
    """Per scene, appearance and radius: coverage, frame time, overhead with its interval, samples per region."""
    rows = []
    resampler = intervals.Resampler()
    for scene in scenes_of(tests):
        here = rows_matching(tests, scene, scene=scene)
        off = here[text_column(here, "config") == OFF]
        for appearance in APPEARANCES:
            try:
                points = sweep_points(tests, scene, appearance, resampler=resampler)
            except (KeyError, ValueError):
                continue
            mine = here[text_column(here, "appearance") == appearance]
            for radius, coverage, overhead, draws in points:
                lens = mine[numeric(mine, "radius") == radius]
                rows.append({"scene": scene, "lens shows": appearance, "radius (edge)": radius,
                             "rays through the lens (%)": coverage, "frame (ms)": median_ms(lens),
                             **interval_columns(overhead, intervals.interval_of(draws), "overhead (%)",
                                                ends=PERCENT_CI),
                             "samples lens / no lens": samples_ratio(lens, off), **region_samples(lens)})
    return pd.DataFrame(rows)


def _figure(table, ctx):
    if table.empty:
        return []
    return overhead_figure(
        table.assign(series=[f"{scene}, {APPEARANCES[a]}" for scene, a in zip(table.scene, table["lens shows"])]),
        ctx, "overhead", heading="Overhead against lens coverage", x="rays through the lens (%)",
        title="The lens's overhead against the rays it covers",
        x_label="rays meeting lens ∩ box (% of the rays meeting the box)",
        guides=(("no overhead", [0.0, float(table["rays through the lens (%)"].max())], [0.0, 0.0]),),
        caption="One point per radius (small to large, left to right), one line per scene and lens appearance; bars: "
                "95 % paired bootstrap interval (every radius timed together with the lens-off frame). The claim is "
                "judged on the outside appearance.")


def _gallery(tests, ctx):
    def note(row):
        coverage = lens_coverage(shown[shown.run == row.run])
        return frame_note(row) + (f", lens on {as_percent(coverage)} of the rays" if np.isfinite(coverage) else "")

    off_then_radii = lambda here: pd.concat([here[text_column(here, "config") == OFF],
                                             here[text_column(here, "appearance") == "own"].sort_values("radius")])
    shown = scene_by_scene(headline(tests), off_then_radii)
    return difference_gallery(
        "Headline view at each radius, the lens with the scene's own appearance", shown, ctx, note=note,
        label=lambda row: f"{row.scene}, {'no lens' if row.config == OFF else f'radius {format_number(row.radius)}'}",
        caption="The lens-off image first, then each radius.")


class LensSize(LensExperiment):
    name = "ropinski2005-size"
    title = "Lens size: overhead against lens coverage (E5)"
    settings = frozenset({"scenes", "radii", "volume_size", "image_size", "orbit", "step_factor", "lens_method",
                          "repeat", "min_time"})
    scales = scaled(base=TIMED_SCALES, smoke={"radii": [0.1, 0.3, 0.6]}, full={"scenes": ["skull", "seismic", "foot"]})
    description = (
        "Not in the paper. A scene's sphere lens keeps its centre while its radius goes from 0.05 to 0.6 of the "
        "volume's longest edge, showing the outside appearance (the volume's own table: the lens then changes only how "
        "each ray is cut, into three segments cast in three passes back to front) and the scene's own lens appearance. "
        "gl-raycast renders the scene without the lens and with each lens by the paper's segments method, all timed "
        "together in one job per scene, and counts the rays whose lens segment inside the box is not empty. The "
        "overhead of each radius (frame time with the lens over without it, minus one) is plotted against that "
        "coverage. The claim, on the outside appearance, is that it grows: the slope of a least-squares line through "
        "the points has a 95 % bootstrap interval (the frames resampled round by round) wholly above zero; no steeper "
        "bound, since the paper gives no cost model. With the scene's own appearance the slope is reported, not "
        "judged: a clipping lens also removes its region₁ samples, so its overhead may fall as it grows. The skull (a "
        "transparency lens over a thin shell) and the seismic cube (a clipping lens in a dense, opaque volume) are "
        "swept, and the foot's isosurface lens at full scale."
    )
    claims = CLAIMS

    def lens_runs(self, profile):
        wanted = listed(profile, self, "scenes", SCENES, known=SETUPS)
        boxes = [s for s in wanted if SETUPS[s].shape != "sphere"]
        if boxes:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.scenes: {', '.join(boxes)} has a box "
                             "lens, and the sweep sets a sphere's radius; choose among "
                             f"{', '.join(s for s, setup in SETUPS.items() if setup.shape == 'sphere')}")
        radii = sorted({float(r) for r in profile.setting(self, "radii", list(RADII))})
        if len(radii) < 3 or radii[0] <= 0:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.radii: expected three different radii "
                             f"> 0 (fractions of the longest edge; the slope needs three points), got {radii}")
        size, image, orbit, step = lens_settings(profile, self)
        method = profile.setting(self, "lens_method", PAPER_METHOD)
        frames = timed_frames(profile, self)
        runs = []
        for scene_name in wanted:
            views = lens_views(scene_name, orbit)
            tags = scene_tags(scene_name, image_size=image, role="test",
                              lens_mode=SETUPS[scene_name].appearance["mode"])
            spec = lens_scene(scene_name, image, size=size, real_data=profile.real_data)
            runs.append(lens_run(self.name, f"{scene_name}.{OFF}", without_lens(spec), views, OFF, frames,
                                 {**tags, "appearance": "none"}, step_factor=step, group=scene_name))
            for radius in radii:
                spec = lens_scene(scene_name, image, size=size, real_data=profile.real_data, radius=radius)
                for appearance, shown in (("own", spec), ("outside", outside_appearance(spec))):
                    runs.append(lens_run(self.name, f"{scene_name}.r{radius:g}.{appearance}", shown, views, method,
                                         frames, {**tags, "radius": radius, "appearance": appearance},
                                         step_factor=step, group=scene_name))
        return runs

    def report(self, results, ctx):
        tests = tests_of(results)
        out = [claim_takeaways(ctx, device_takeaways(tests), own_takeaways(tests))]
        if not tests.empty:
            table = sweep_table(tests)
            out += _figure(table, ctx) + rounded_table(
                "Overhead and samples per radius", table, csv_name="size.csv",
                caption="Rays through the lens: rays meeting lens ∩ box over the rays meeting the box (counted). "
                        "Overhead with its 95 % paired bootstrap interval. Samples with the lens over without it, and "
                        "per region (counted). " + frames_caption(tests))
            out.append(_gallery(tests, ctx))
            out.append(run_table(tests, ["scene", "config", "appearance", "radius", "time_ms", "time_ms_min",
                                         "time_ms_max", "count_lens_rays", "count_rays", "count_samples"], ctx,
                                 names={"appearance": "lens shows", "radius": "radius (edge)"},
                                 csv_name="size_runs.csv"))
        return out + raycast_not_measurable([PAPER_METHOD])
