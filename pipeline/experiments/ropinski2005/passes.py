"""``ropinski2005-passes`` (E2): the segments method's frame, pass by pass."""

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import all_of, milliseconds
from pipeline.experiments.kit.model import Claim
from pipeline.experiments.kit.pages import as_percent, claim_takeaways, figure, format_number, frames_caption
from pipeline.experiments.kit.planning import listed, timed_frames
from pipeline.experiments.kit.results import numeric, rows_matching, text_column
from pipeline.experiments.ropinski2005.methods import (PAPER_METHOD, REGIONS, STAGES, TIMED_SCALES, LensExperiment,
                                                       device_takeaways, lens_coverage, lens_run, lens_settings,
                                                       raycast_not_measurable, scenes_of)
from pipeline.experiments.ropinski2005.pages import headline, interval_columns, run_table, tests_of
from pipeline.experiments.ropinski2005.scenes import SETUPS, lens_scene, lens_views, scene_tags
from reports import blocks, plots

GEOMETRY_SHARE = 0.10
"""The most of a frame the lens's geometry stage may take: note 004 §4.2 (E2) expects "a small share of the
frame", which the lead's brief for issue 24 puts at 10 %."""

GROUP = "passes"
"""The interleave group of every run: one job, each scene's frames alternating with the others'."""


def stage_share(rows, stage, *, resampler, at_most=None):
    """``time_<stage> / time_total`` of ``rows``, judged against ``at_most`` with its interval.

    Numerator and denominator are the same frames, so the interval resamples them together.
    """
    return intervals.ratio_decision(rows, rows, column=f"time_{stage}", bottom_column="time_total", at_most=at_most,
                                    resampler=resampler)


def _geometry(df):
    resampler = intervals.Resampler()
    rows = {scene: rows_matching(df, scene, scene=scene) for scene in scenes_of(df)}
    decisions = {s: stage_share(r, "lens_geometry", resampler=resampler, at_most=GEOMETRY_SHARE)
                 for s, r in rows.items()}
    notes = {s: f"{milliseconds(r, 'time_lens_geometry')} of {milliseconds(r, 'time_total')}" for s, r in rows.items()}
    return all_of(decisions, show=as_percent, notes=notes, what="lens geometry / frame ",
                 extra="median frames of each run; the share's interval is a bootstrap over the run's own frames")


CLAIMS = (
    Claim("geometry-small", "The lens's geometry passes (its faces rasterised into entry and exit images, the "
          "region transitions resolved) are a small share of the frame: the ray casting dominates (note 004 §4.2, E2)",
          f"time(lens_geometry) / time(total) ≤ {as_percent(GEOMETRY_SHARE)} on every scene (the segments method, "
          "median frames)", _geometry, kind="timing"),
)


def stage_columns(frame):
    """The ``time_<stage>`` columns of :data:`STAGES` that ``frame`` reports, in the order the stages run."""
    return [f"time_{s}" for s in STAGES if f"time_{s}" in frame and numeric(frame, f"time_{s}").notna().any()]


def pass_table(tests):
    """Per scene: each stage's median ms and share of the frame, each region's samples and ns per sample."""
    rows = []
    for scene, here in tests.groupby("scene", sort=False):
        total = numeric(here, "time_total").median()
        row = {"scene": scene, "frame (ms)": 1e3 * total, "rays through the lens (%)": 100 * lens_coverage(here)}
        for column in stage_columns(here):
            stage = column.removeprefix("time_")
            value = numeric(here, column).median()
            row |= {f"{stage} (ms)": 1e3 * value, f"{stage} (%)": 100 * value / total}
            if f"count_samples_{stage}" in here:
                count = numeric(here, f"count_samples_{stage}").median()
                row |= {f"{stage} samples": count, f"{stage} ns/sample": 1e9 * value / count if count else np.nan}
        rows.append(row)
    return pd.DataFrame(rows)


def share_points(tests):
    """Per scene and stage (lens geometry, region₁): the share of the frame with its interval, against coverage."""
    points = []
    resampler = intervals.Resampler()
    for scene, here in tests.groupby("scene", sort=False):
        for stage, label in (("lens_geometry", "lens geometry"), ("region1", REGIONS["region1"])):
            try:
                decision = stage_share(here, stage, resampler=resampler)
            except (KeyError, ValueError):
                continue
            points.append({"stage": label, "scene": scene, "coverage": 100 * lens_coverage(here),
                           **interval_columns(decision.value, decision.interval, "share", ends=("low", "high"),
                                              scale=lambda v: 100 * v)})
    return pd.DataFrame(points)


def _share_title(points):
    """The figure's finding: the largest share of a frame the lens geometry took, and where."""
    geometry = points[points.stage == "lens geometry"]
    if geometry.empty:
        return "Share of the frame against the rays the lens covers"
    worst = geometry.loc[geometry.share.idxmax()]
    return f"Lens geometry: at most {format_number(worst.share)} % of a frame ({worst.scene})"


def _pass_blocks(tests, ctx):
    out = []
    stages = stage_columns(tests)
    if stages:
        out.append(figure(ctx, "passes-stages", plots.stage_breakdown, tests, heading="Time per pass (segments method)",
                          caption="Median time of each stage per frame, one bar per scene (headline view); "
                                  + frames_caption(tests),
                          stage_cols=stages, group_col="scene", title="Time per pass of a lens frame (segments)"))
    points = share_points(tests)
    if not points.empty and points.coverage.notna().any():
        out.append(figure(ctx, "passes-shares", plots.lines, points,
                          heading="Geometry and lens-region shares against lens coverage",
                          caption="One point per scene and pass (not joined: the scenes are not a sweep); bars: 95 % "
                                  "bootstrap interval over the run's frames; dashed: the claim's bound on the geometry "
                                  "share.",
                          x="coverage", y="share", group="stage", y_range=("low", "high"), join=False, label="scene",
                          title=_share_title(points), x_label="rays meeting lens ∩ box (% of the rays)",
                          y_label="share of the frame time (%)",
                          guides=(("the claim's bound", [points.coverage.min(), points.coverage.max()],
                                   [100 * GEOMETRY_SHARE] * 2),)))
    out.append(blocks.Table("Passes and samples per scene (median frame)", pass_table(tests).round(3),
                            csv_name="passes.csv",
                            caption="Stage times and their share of the whole frame; region samples counted by the "
                                    "caster (machine-independent), and the time per sample of each region pass."))
    return out


class Passes(LensExperiment):
    name = "ropinski2005-passes"
    title = "The lens frame pass by pass: geometry against the three region passes (E2)"
    settings = frozenset({"scenes", "volume_size", "image_size", "orbit", "step_factor", "lens_method", "repeat",
                          "min_time"})
    scales = TIMED_SCALES
    description = (
        "Not in the paper, which reports whole frames only (note 004 §3.4). The segments method rasterises the "
        "lens's faces into per-pixel entry and exit images and resolves the region transitions from them "
        "(stage lens_geometry), then casts region₀ (behind and beside the lens), region₁ (inside lens ∩ box) "
        "and region₂ (in front of it) in three passes, back to front. gl-raycast times every stage and counts "
        "each region's samples, on every lens scene from the headline view; the scenes are timed together in "
        "one job. The claim: the geometry is a small share of the frame."
    )
    claims = CLAIMS

    def lens_runs(self, profile):
        wanted = listed(profile, self, "scenes", tuple(SETUPS), known=SETUPS)
        size, image, orbit, step = lens_settings(profile, self)
        method = profile.setting(self, "lens_method", PAPER_METHOD)
        frames = timed_frames(profile, self)
        runs = []
        for scene_name in wanted:
            spec = lens_scene(scene_name, image, size=size, real_data=profile.real_data)
            runs.append(lens_run(self.name, f"{scene_name}.{method}", spec, lens_views(scene_name, orbit), method,
                                 frames, scene_tags(scene_name, image_size=image, role="test"), step_factor=step,
                                 group=GROUP))
        return runs

    def report(self, results, ctx):
        tests = tests_of(results)
        out = [claim_takeaways(ctx, device_takeaways(tests))]
        methods = sorted(set(text_column(tests, "config"))) if not tests.empty else [PAPER_METHOD]
        if not tests.empty:
            out += _pass_blocks(headline(tests), ctx)
            out.append(run_table(tests, ["scene", "time_ms", "count_samples", "count_samples_region0",
                                         "count_samples_region1", "count_samples_region2", "count_lens_rays"], ctx,
                                 csv_name="passes_runs.csv"))
        return out + raycast_not_measurable(methods)
