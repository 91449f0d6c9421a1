"""E10: the common world step in a mixed-resolution scene (``kainz2009-step``)."""

import numpy as np
import pandas as pd

from pipeline.experiments.kainz2009 import tables
from pipeline.experiments.kainz2009.methods import TILED, PaperExperiment, frames_caption, table
from pipeline.experiments.kainz2009.ratios import KERNELS
from pipeline.experiments.kainz2009.scenes import CLOUD_SIZES, clouds, volume
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import TECHNIQUE, counts, decided, decision_words, timed
from pipeline.experiments.kit.model import Claim, ClaimResult, Run, scaled
from pipeline.experiments.kit.pages import claim_takeaways, figure, format_number
from pipeline.experiments.kit.planning import HEADLINE_VIEW, scene, timed_frames, truth_run
from pipeline.experiments.kit.results import numeric, ok_rows, role_rows, speed_points
from reports import plots

STEPS = (2.0, 1.0, 0.5, 0.25)


def _step_rows(ok):
    tests = role_rows(ok)
    if tests.empty:
        return pd.DataFrame()
    rows = speed_points(tests)
    return rows.assign(step_factor=numeric(rows, "step_factor"),
                       ns_per_sample=rows.time_ms * 1e6 / numeric(rows, "count_samples")).sort_values("step_factor")


def _marginal(rows, times):
    """Seconds per added sample between consecutive steps of ``rows`` (sorted coarse → fine): ``times`` is
    the rows' times (one column per row, draws along the first axis or one value each)."""
    samples = numeric(rows, "count_samples").to_numpy()
    return (times[..., 1:] - times[..., :-1]) / (samples[1:] - samples[:-1])


def _per_sample(df):
    """The cost of the samples the finest steps add over the cost of those the coarsest add (kernels)."""
    rows = timed(df, "the swept steps", TECHNIQUE, role="test")
    rows = rows.assign(step_factor=numeric(rows, "step_factor")).sort_values("step_factor", ascending=False)
    if len(rows) < 3:
        raise ValueError("fewer than three steps: no finest and coarsest pair of steps")
    if not (numeric(rows, "count_samples").diff().dropna() > 0).all():
        raise ValueError("a finer step took no more samples")
    marginal = _marginal(rows, numeric(rows, TECHNIQUE).to_numpy())
    resampler = intervals.Resampler()
    draws = intervals.row_draws(rows, TECHNIQUE, resampler)
    draws = None if draws is None else _marginal(rows, draws)
    decision = decided(marginal[-1] / marginal[0], None if draws is None else draws[:, -1] / draws[:, 0], at_most=1.0,
                       frames=resampler.arms())
    steps = [format_number(f) for f in rows.step_factor]
    return ClaimResult.decided(
        f"{decision_words(decision)}: {format_number(marginal[-1] * 1e9)} ns per added sample from {steps[-2]} to "
        f"{steps[-1]}, {format_number(marginal[0] * 1e9)} ns from {steps[0]} to {steps[1]}", decision,
        f"{KERNELS}; samples " + counts(rows, "count_samples", label="step_factor"))


def _step_error(df):
    rows = _step_rows(df)
    psnr = numeric(rows, "psnr").to_numpy()
    if len(rows) < 2 or np.isnan(psnr).all():
        raise ValueError("fewer than two steps compared with the reference")
    falls = bool(np.all(np.diff(psnr) <= 0.05))  # rows run fine → coarse
    return ClaimResult(", ".join(f"{format_number(s)}: {format_number(p)} dB" for s, p in zip(rows.step_factor, psnr)),
                       falls, "step factor: PSNR")


class Step(PaperExperiment):
    name = "kainz2009-step"
    paper_rows = tables.STEP
    title = "The common world step with mixed resolutions: oversampling cost and error (E10)"
    settings = frozenset({"small_size", "large_size", "count", "image_size", "step_factors", "truth_step_factor",
                          "repeat"})
    scales = scaled(base=CLOUD_SIZES, smoke={"count": 2, "step_factors": [1.0, 0.5, 0.25]}, default={"large_size": 128})
    description = (
        "Every volume a ray meets is sampled at one world step, the smallest of their voxel sizes, so that samples "
        "line up for blending; low-resolution volumes are oversampled. The paper says this costs little because "
        "neighbouring samples hit the texture cache. Here one high-resolution skull overlaps a few low-resolution "
        "clouds stretched over half of it (a cloud voxel is several skull voxels), and the step factor (in units of "
        "the skull's voxel) is swept, every step timed together: the cost of the samples the finest steps add, against "
        "that of the samples the coarsest add (a frame's fixed cost cancels in both), shows what oversampling costs, "
        "the error against the reference what it buys."
    )

    def plan(self, profile):
        small = int(profile.setting(self, "small_size", 64))
        large = int(profile.setting(self, "large_size", 256))
        count = int(profile.setting(self, "count", 4))
        image = int(profile.setting(self, "image_size", profile.image_size))
        frames = timed_frames(profile, self)
        volumes = [volume("ct_skull", large, "bone", "skull")] + clouds(count, small, scale=large / (2.0 * small))
        spec = scene("mixed", image, volumes=volumes)
        views = (dict(HEADLINE_VIEW),)
        tags = {"scene": "mixed"}
        truth = truth_run(self.name, "mixed", spec, views, profile.setting(self, "truth_step_factor", 0.125), tags,
                          config="reference")
        return [truth] + [Run(self.name, f"mixed.step{factor:g}", TILED, spec, views,
                              options={"step_factor": float(factor)}, reference=truth.id, **frames, interleave="mixed",
                              tags={**tags, "role": "test", "config": TILED, "step_factor": float(factor)})
                          for factor in profile.setting(self, "step_factors", list(STEPS))]

    claims = (
        Claim("oversampling-cheap", "Oversampling is cheap: finer steps cost no more per sample (texture-cache "
              "coherence, §3.3)", "time per added sample between the two finest steps / between the two coarsest "
              f"≤ ×1 ({KERNELS}: the fixed cost of a frame cancels)", _per_sample, kind="timing"),
        Claim("error-falls", "A finer common step brings the image closer to the reference",
              "PSNR against the reference never falls as the step shrinks", _step_error, kind="accuracy"),
    )

    def report(self, results, ctx):
        out = [claim_takeaways(ctx)]
        rows = _step_rows(ok_rows(results))
        if not rows.empty:
            out += [figure(ctx, what, plots.lines, rows.assign(method="cl-tiled"),
                           heading=f"{what.capitalize()} against the step",
                           caption="Mixed-resolution scene, headline view. " + frames_caption(rows),
                           x="step_factor", y=y, group="method", y_range=y_range,
                           title=f"{label[0].upper()}{label[1:]} against the step",
                           x_label="step (voxels of the finest volume, log scale)", y_label=label, log_x=True)
                    for y, label, y_range, what in (
                        ("time_ms", "median frame time (ms)", ("time_ms_min", "time_ms_max"), "time"),
                        ("ns_per_sample", "time per volume sample (ns)", None, "per-sample"),
                        ("psnr", "PSNR against the reference (dB)", None, "psnr"))]
            out.append(table("Every step", rows.sort_values("step_factor"),
                             ["step_factor", "time_ms", "time_ms_min", "time_ms_max", "count_samples", "ns_per_sample",
                              "psnr"], ctx, csv_name="step.csv"))
        return out
