"""``ropinski2005-methods`` (E4): the paper's segments against per-sample lens tests and depth-based clipping."""

from contextlib import suppress

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import (STRICTLY_ABOVE_ONE, all_of, config_rows, decision_words, measured,
                                              median_count, ratio_pair, time_ratio)
from pipeline.experiments.kit.model import Claim, ClaimResult
from pipeline.experiments.kit.pages import (as_percent, as_ratio, claim_takeaways, difference_gallery, figure,
                                            format_number, frames_caption, silent_without_runs, unless_missing)
from pipeline.experiments.kit.planning import listed, timed_frames, truth_run
from pipeline.experiments.kit.results import nonempty, numeric, speed_points, text_column
from pipeline.experiments.ropinski2005.methods import (CONFIGS, PAPER_METHOD, TIMED_SCALES, TIMES, LensExperiment,
                                                       device_takeaways, lens_coverage, lens_run, lens_settings,
                                                       method_name, raycast_not_measurable)
from pipeline.experiments.ropinski2005.pages import (PERCENT_CI, headline, interval_columns, median_ms, rounded_table,
                                                     run_table, tests_of)
from pipeline.experiments.ropinski2005.scenes import SETUPS, lens_scene, lens_views, scene_tags
from reports import blocks, plots

TABLE1_SCENES = tuple(name for name, setup in SETUPS.items() if setup.paper_row)
"""The scenes standing for Table 1's rows (the stand-ins and the real CT head)."""

BASELINES = ("per-sample", "per-sample-mask", "frag-depth")
"""The methods the paper argues against: a test per sample (analytic, or a 3-D mask fetch) and depth-based
clipping (issue 24's targets: the segments method faster than each)."""

OCCLUDED = ("segments", "per-sample", "frag-depth")
"""The methods also timed behind the occluder: the paper's, a per-sample test that keeps early-z, and the
one that writes ``gl_FragDepth``."""

OCCLUDER = 0.5
"""Fraction of the box's screen footprint the opaque plane hides (``gl-raycast`` option ``occluder``)."""

TRANSPARENCY = 0.2
"""Opacity scale of the transparency lens that stands in for a ``mip`` or ``iso`` lens (the skull's and the
engine's lens scale their table by the same)."""

DROP_TOLERANCE = 0.01
"""Share of the covered rays by which the early-z counts may miss their bounds (the occluder's edge falls
through pixel centres the same way in every pass, so they meet them exactly here)."""


def comparable_appearance(setup):
    """The lens appearance every method renders: the setup's own, or a transparency lens for ``mip``/``iso``."""
    if setup.appearance.get("mode") in ("mip", "iso"):
        return {"mode": "dvr", "preset": setup.preset, "opacity_scale": TRANSPARENCY}


def occluded_rows(frame, occluded):
    return frame[text_column(frame, "occluded") == occluded]


def table1_scenes(frame):
    """The Table 1 scenes among ``frame``'s rows, in their order; ValueError if none."""
    return nonempty([s for s in pd.unique(text_column(frame, "scene")) if s in TABLE1_SCENES], what="a Table 1 scene")


def _at_image(frame):
    """``(rows, image)``: the rows of ``frame`` at the largest image size (pixels per side) they report."""
    image = int(measured(frame, "image_size", "no run reported its image size").image_size.max())
    return frame[numeric(frame, "image_size") == image], image


def behind_and_open(frame, scene, config):
    return (config_rows(occluded_rows(frame, "yes"), config, scene=scene),
            config_rows(occluded_rows(frame, "no"), config, scene=scene))


def shaded(frame, scene, config, *, nonzero=False):
    """``(with the occluder, without)``: the fragments ``config`` shaded on ``scene`` (``fragments_shaded``);
    ValueError where either was not counted (or, with ``nonzero``, none were shaded without the occluder)."""
    behind, open_ = (median_count(rows, "count_fragments_shaded") for rows in behind_and_open(frame, scene, config))
    if not (np.isfinite(behind) and np.isfinite(open_)) or (nonzero and open_ == 0):
        raise ValueError(f"{config} on {scene} counted no shaded fragments (fragments_shaded)")
    return behind, open_


def shaded_share(frame, scene, config):
    """Fragments shaded with the occluder over without it, ``config`` on ``scene``."""
    behind, open_ = shaded(frame, scene, config, nonzero=True)
    return behind / open_


def covered_share(frame, scene):
    """The share of the box's rays the occluder covers: ``rays_occluded`` over the rays without it (segments)."""
    behind, open_ = behind_and_open(frame, scene, PAPER_METHOD)
    rays = median_count(open_, "count_rays")
    occluded = median_count(behind, "count_rays_occluded")
    if not (np.isfinite(rays) and np.isfinite(occluded)) or rays == 0:
        raise ValueError(f"the occluder's covered rays on {scene} were not counted (rays, rays_occluded)")
    return occluded / rays


def occluder_saving(frame, scene, config, *, resampler):
    """``(value, draws)``: time with the occluder over time without it, ``config`` on ``scene`` (paired)."""
    value, draws = ratio_pair(*((numeric(rows, "time_total").median(),
                                 intervals.statistic_draws(rows, "time_total", "median", resampler))
                                for rows in behind_and_open(frame, scene, config)))
    return float(value), draws


def earlyz_decision(frame, scene, *, resampler, method="frag-depth"):
    """``[t_method(occluded) / t_method(open)] / [t_segments(occluded) / t_segments(open)]``, judged ≥ 1: above 1,
    the occluder saves the segments method a larger share of its frame than ``method``."""
    value, draws = ratio_pair(*(occluder_saving(frame, scene, config, resampler=resampler)
                                for config in (method, PAPER_METHOD)))
    return intervals.decide(value, intervals.interval_of(draws), at_least=1.0)


def _faster(occluded, baselines):
    def check(df):
        rows, image = _at_image(occluded_rows(df, occluded))
        resampler = intervals.Resampler()
        decisions, notes = {}, {}
        for scene in table1_scenes(rows):
            paper = config_rows(rows, PAPER_METHOD, scene=scene)
            for baseline in baselines:
                label = f"{scene}, {baseline}"
                decisions[label] = time_ratio(rows, baseline, PAPER_METHOD, resampler=resampler,
                                              at_least=STRICTLY_ABOVE_ONE, scene=scene)
                other = config_rows(rows, baseline, scene=scene)
                shaded = (median_count(other, "count_fragments_shaded"), median_count(paper, "count_fragments_shaded"))
                if all(np.isfinite(shaded)):
                    notes[label] = f"fragments shaded {format_number(shaded[0])} against {format_number(shaded[1])}"
        extra = f"{TIMES}; every method of a scene timed together, frame against frame"
        if occluded == "yes":
            extra += f"; an opaque plane hides {as_percent(OCCLUDER)} of the box's footprint"
        return all_of(decisions, notes=notes, what=f"time(baseline) / time(segments) at {image}² ", extra=extra)
    return check


def dropped_share(frame, scene, config):
    """Fragments the occluder saved ``config`` on ``scene`` (``fragments_shaded`` without it − with it), over
    the rays it covers (``rays_occluded``)."""
    behind, open_ = shaded(frame, scene, config)
    covered = median_count(behind_and_open(frame, scene, config)[0], "count_rays_occluded")
    if not np.isfinite(covered) or covered == 0:
        raise ValueError(f"the occluder's covered rays on {scene} were not counted (rays_occluded)")
    return (open_ - behind) / covered


def _earlyz_fragments(df):
    compared = []  # (how far the scene misses the bounds, scene, {config: fragments dropped per covered ray})
    for scene in table1_scenes(occluded_rows(df, "yes")):
        dropped = {config: dropped_share(df, scene, config) for config in (PAPER_METHOD, "frag-depth")}
        compared.append((max(dropped["frag-depth"], 1.0 - dropped[PAPER_METHOD]), scene, dropped))
    wrong, scene, dropped = max(compared, key=lambda c: c[0])
    said = lambda d: f"segments ×{format_number(d[PAPER_METHOD])}, frag-depth ×{format_number(d['frag-depth'])}"
    return ClaimResult(f"fragments dropped per covered ray: {said(dropped)} ({scene})", bool(wrong <= DROP_TOLERANCE),
                       "; ".join(f"{s}: {said(d)}" for _, s, d in compared) + "; fragments_shaded (the volume "
                       "passes' fragment-shader invocations) without the occluder − with it, over rays_occluded; "
                       "segments' region₀ pass alone draws every ray, its region₁ and region₂ passes the lens's "
                       "footprint")


def _earlyz_time(df):
    resampler = intervals.Resampler()
    decisions = {scene: earlyz_decision(df, scene, resampler=resampler)
                 for scene in table1_scenes(occluded_rows(df, "yes"))}
    saving = lambda scene, config: as_ratio(occluder_saving(df, scene, config, resampler=resampler)[0])
    notes = {scene: f"with / without the occluder: frag-depth {saving(scene, 'frag-depth')}, segments "
                    f"{saving(scene, PAPER_METHOD)}" for scene in decisions}
    return all_of(decisions, notes=notes, what="frag-depth's saving / segments' saving ",
                 extra=f"{TIMES}; the four runs of a scene timed together")


CLAIMS = (
    Claim("segments-faster", "The segments method is faster than testing every sample against the lens "
          "(analytically or by a 3-D mask fetch) and than depth-based clipping, on every Table 1 scene (§2, §3; "
          "issue 24's target)",
          f"time(baseline) / time(segments) > ×1 for {', '.join(BASELINES)}, every Table 1 scene, at the "
          f"experiment's image size ({TIMES}; 95 % paired bootstrap interval wholly above ×1)",
          _faster("no", BASELINES), kind="timing"),
    Claim("segments-faster-occluded", f"The same with an opaque plane hiding {as_percent(OCCLUDER)} of the "
          "volume's footprint, where early-z can drop the covered fragments",
          f"time(baseline) / time(segments) ≥ ×1 for {', '.join(b for b in OCCLUDED if b != PAPER_METHOD)}, every "
          f"Table 1 scene, occluder {format_number(OCCLUDER)} ({TIMES})",
          _faster("yes", tuple(b for b in OCCLUDED if b != PAPER_METHOD)), kind="timing"),
    Claim("earlyz-fragments", "Writing gl_FragDepth turns early-z off: behind the occluder frag-depth still shades "
          "every fragment, while the segments method (fragment depth never written) drops the covered ones (§3)",
          "(fragments shaded without the occluder − with it) / rays it covers: frag-depth ≤ "
          f"{format_number(DROP_TOLERANCE)}, segments ≥ {format_number(1 - DROP_TOLERANCE)} (its region₀ pass "
          "drops every covered ray), every Table 1 scene (counted, exact)", _earlyz_fragments, kind="count"),
    Claim("earlyz-time", "So the occluder saves the segments method's frames a larger share of their time than "
          "frag-depth's",
          "[time(frag-depth, occluder) / time(frag-depth, none)] / [time(segments, occluder) / time(segments, none)] "
          f"≥ ×1, every Table 1 scene ({TIMES}; paired bootstrap interval)", _earlyz_time, kind="timing"),
)


def method_table(tests):
    """Per scene and method, without the occluder: frame time, ratio to segments with its interval, PSNR, counts."""
    rows = []
    resampler = intervals.Resampler()
    open_ = occluded_rows(tests, "no")
    for scene in pd.unique(open_.scene):
        for config in CONFIGS:
            try:
                chosen = config_rows(open_, config, scene=scene)
            except ValueError:
                continue
            row = {"scene": scene, "method": config, "frame (ms)": median_ms(chosen)}
            with suppress(ValueError):
                decision = time_ratio(open_, config, PAPER_METHOD, resampler=resampler, scene=scene)
                row |= interval_columns(decision.value, decision.interval, "time / segments")
            rows.append(row | {"PSNR (dB)": numeric(chosen, "psnr").min() if "psnr" in chosen else np.nan,
                               "samples": median_count(chosen, "count_samples"),
                               "fragments shaded": median_count(chosen, "count_fragments_shaded"),
                               "rays through the lens (%)": 100 * lens_coverage(chosen)})
    return pd.DataFrame(rows)


def occluder_table(tests):
    """Per scene and method timed behind the occluder: time and shaded fragments with / without it."""
    rows = []
    resampler = intervals.Resampler()
    for scene in pd.unique(occluded_rows(tests, "yes").scene):
        covered = unless_missing(covered_share, tests, scene, empty=np.nan)
        for config in OCCLUDED:
            try:
                value, draws = occluder_saving(tests, scene, config, resampler=resampler)
                shaded = shaded_share(tests, scene, config)
            except (KeyError, ValueError):
                continue
            rows.append({"scene": scene, "method": config, "rays covered (%)": 100 * covered,
                         **interval_columns(value, intervals.interval_of(draws), "time with / without (%)",
                                            ends=PERCENT_CI, scale=lambda v: 100 * v),
                         "fragments shaded with / without (%)": 100 * shaded})
    return pd.DataFrame(rows)


@silent_without_runs
def _other_takeaways(tests):
    """The methods not judged (fused, the stencil sequence) against segments, in words."""
    open_, image = _at_image(occluded_rows(tests, "no"))
    scenes = table1_scenes(open_)
    sentences = []
    for config in ("fused", "segments-stencil"):
        words = []
        for scene in scenes:
            with suppress(KeyError, ValueError):
                decision = time_ratio(open_, config, PAPER_METHOD, resampler=intervals.Resampler(), scene=scene)
                words.append(f"{scene} {decision_words(decision)}")
        if words:
            sentences.append(f"{method_name(config)[0].upper()}{method_name(config)[1:]}, time / segments at "
                             f"{image}² (measured, not judged): {', '.join(words)}.")
    return sentences


def _speed_accuracy(tests, ctx):
    points = speed_points(occluded_rows(tests, "no"))
    if "psnr" not in points or numeric(points, "psnr").notna().sum() == 0:
        return []
    configs = text_column(points, "config")
    # One marker per method; each scene's cluster is named once, at the paper's method, so labels do not pile up.
    points = points.assign(psnr=numeric(points, "psnr"), method=configs,
                           label=np.where(configs == PAPER_METHOD, text_column(points, "scene"), ""))
    return [figure(ctx, "speed-accuracy", plots.speed_accuracy, points, heading="Speed against accuracy",
                   caption="One marker per lens method, one cluster per scene (named at the segments method's point; "
                           "every view its own point); bars: fastest and slowest frame. Early termination at the "
                           "caster's opacity threshold drops light the reference keeps, the same for every method. "
                           + frames_caption(points),
                   time_col="time_ms", error_col="psnr", group_col="method", label_col="label", log_y=False,
                   join=False, time_range_cols=("time_ms_min", "time_ms_max"),
                   title="Frame time against accuracy, each lens method on each Table 1 scene",
                   x_label="median frame time (ms)", y_label="PSNR against the reference (dB)", better="upper left")]


def _earlyz_figure(table, ctx):
    if table.empty:
        return []
    return [figure(ctx, "earlyz", plots.bar_compare, table, heading="Early-z behind an occluder",
                   caption="Frame time and fragment-shader invocations with the opaque plane over without it; 100 %: "
                           "the occluder saved nothing.",
                   category_col="method", value_cols=["time with / without (%)", "fragments shaded with / without (%)"],
                   value_label="with the occluder / without it (%, median over the scenes)",
                   title=f"An occluder on {as_percent(OCCLUDER)} of the footprint: who drops the covered fragments")]


class MethodsCompared(LensExperiment):
    name = "ropinski2005-methods"
    title = "Segments against per-sample lens tests and depth-based clipping, and early-z (E4)"
    needs = ("occluder",)
    settings = frozenset({"scenes", "methods", "volume_size", "image_size", "orbit", "step_factor", "occluder",
                          "repeat", "min_time"})
    scales = TIMED_SCALES
    description = (
        "The paper argues, without measuring it, that cutting rays into regions beats testing each sample against "
        "the lens (Weiskopf et al.'s volumetric clipping: an extra texture fetch per sample) and depth-based "
        "clipping (a depth comparison per sample, and gl_FragDepth written, which turns early-z off). gl-raycast "
        "renders every Table 1 scene by each of its lens methods: segments (the paper: lens images, three region "
        "passes back to front), segments-stencil (the paper's transition images by stencil and second depth "
        "test), fused (one loop over the three segments), per-sample (an analytic inside test per sample), "
        "per-sample-mask (a 3-D lens-mask fetch per sample) and frag-depth (a depth comparison per sample, "
        "writing gl_FragDepth); the per-sample methods cannot render an isosurface or MIP lens, so the foot's "
        "bone isosurface lens is replaced by a transparency lens of the same shape and place. Then segments, "
        f"per-sample and frag-depth again, with an opaque plane hiding {as_percent(OCCLUDER)} of the box's "
        "footprint (the early-z test). All runs of a scene are timed together in one job; every time ratio has a "
        "paired bootstrap interval. Each method's image without the occluder is compared with the reference's."
    )
    claims = CLAIMS

    def lens_runs(self, profile):
        wanted = listed(profile, self, "scenes", TABLE1_SCENES, known=SETUPS)
        methods = listed(profile, self, "methods", CONFIGS, known=CONFIGS)
        size, image, orbit, step = lens_settings(profile, self)
        occluder = float(profile.setting(self, "occluder", OCCLUDER))
        frames = timed_frames(profile, self)
        runs = []
        for scene_name in wanted:
            spec = lens_scene(scene_name, image, size=size, real_data=profile.real_data,
                              appearance=comparable_appearance(SETUPS[scene_name]))  # None: the scene's own
            views = lens_views(scene_name, orbit)
            tags = scene_tags(scene_name, image_size=image, lens_mode=spec["lenses"][0]["appearance"]["mode"])
            truth = truth_run(self.name, scene_name, spec, views, step, tags, occluded="no")
            runs.append(truth)
            runs += [lens_run(self.name, f"{scene_name}.{method}", spec, views, method, frames,
                              {**tags, "role": "test", "occluded": "no"}, step_factor=step, group=scene_name,
                              reference=truth.id) for method in methods]
            runs += [lens_run(self.name, f"{scene_name}.{method}.occluded", spec, views, method, frames,
                              {**tags, "role": "test", "occluded": "yes", "occluder": occluder}, step_factor=step,
                              group=scene_name, options={"occluder": occluder})
                     for method in OCCLUDED if method in methods]
        return runs

    def report(self, results, ctx):
        tests = tests_of(results)
        out = [claim_takeaways(ctx, device_takeaways(tests), _other_takeaways(tests))]
        if not tests.empty:
            out += rounded_table("Every lens method against segments (no occluder)", method_table(tests),
                                 csv_name="methods.csv",
                                 caption="Median frame time over the views; time / segments with its 95 % paired "
                                         "bootstrap interval (every method of a scene timed together); PSNR against "
                                         "the reference (worst view); samples and fragment-shader invocations counted "
                                         "by the caster. " + frames_caption(tests))
            out += _speed_accuracy(tests, ctx)
            occluded = occluder_table(tests)
            out += rounded_table("Behind the occluder: what early-z saves each method", occluded, digits=2,
                                 csv_name="methods_occluder.csv",
                                 caption="Frame time and fragment-shader invocations with the occluder over without "
                                         "it (the same method, timed together); rays covered: rays_occluded over the "
                                         "rays without the occluder.")
            out += _earlyz_figure(occluded, ctx)
            out.append(difference_gallery(
                "Headline view: each method's image and its difference from the reference",
                headline(occluded_rows(tests, "no")), ctx, against=results,
                label=lambda row: f"{row.scene}, {row.config}",
                caption="Left the method's image (no occluder), right |method − reference|."))
            out.append(run_table(tests, ["scene", "config", "occluded", "time_ms", "time_ms_min", "time_ms_max",
                                         "psnr", "count_samples", "count_fragments_shaded", "count_rays",
                                         "count_rays_occluded"], ctx,
                                 names={"occluded": "occluder", "count_fragments_shaded": "fragments shaded",
                                        "count_rays_occluded": "rays occluded"},
                                 csv_name="methods_runs.csv", caption=frames_caption(headline(tests))))
        return out + raycast_not_measurable(CONFIGS) + _refused()


def _refused():
    """The note that the foot's isosurface lens could not be compared as it is."""
    replaced = [name for name in TABLE1_SCENES if comparable_appearance(SETUPS[name])]
    if not replaced:
        return []
    return [blocks.Text(f"Not measured as in the other experiments: the {', '.join(replaced)} scene's own "
                        f"{', '.join(SETUPS[n].appearance['mode'] for n in replaced)} lens by the per-sample methods "
                        "(per-sample, per-sample-mask, frag-depth classify one sample at a time and refuse a lens "
                        "that needs its segment whole); here it is a transparency lens (its table's opacity × "
                        f"{format_number(TRANSPARENCY)}) of the same shape and place.")]
