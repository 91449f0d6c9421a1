"""``ropinski2005-appearance`` (E6): one lens, four appearances: clip, transparency, isosurface, MIP.

Note 004 §4.2 E6: "Clipping is cheapest inside the lens but exposes region₀ (longer traversal behind).
Isosurface stops at the first hit." The segments method casts region₀ whole behind whatever the lens shows
(back to front), so what a lens exposes behind it shows only where early termination runs across the
regions: the ``fused`` method. The runs: :attr:`Appearances.description`.
"""

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import STRICTLY_ABOVE_ONE, all_of, counted, counts_compared
from pipeline.experiments.kit.model import Claim, scaled
from pipeline.experiments.kit.pages import (as_percent, claim_takeaways, difference_gallery, figure, format_number,
                                            frames_caption)
from pipeline.experiments.kit.planning import listed, timed_frames
from pipeline.experiments.kit.results import nonempty_or, numeric, rows_matching, text_column
from pipeline.experiments.ropinski2005.methods import (OFF, PAPER_METHOD, TIMED_SCALES, TIMES, LensExperiment,
                                                       device_takeaways, lens_coverage, lens_run, lens_settings,
                                                       method_name, raycast_not_measurable, scenes_of)
from pipeline.experiments.ropinski2005.pages import (PERCENT_CI, headline, interval_columns, median_ms, overhead_figure,
                                                     region_samples, rounded_table, run_table, samples_ratio,
                                                     scene_by_scene, tests_of)
from pipeline.experiments.ropinski2005.scenes import (BONE_ISOVALUE, SETUPS, lens_scene, lens_views, scene_tags,
                                                      without_lens)
from reports import plots

APPEARANCES = {"clip": "clipping (nothing inside)", "transparency": "transparency (opacity × 0.2)",
               "iso": "isosurface (first crossing)", "mip": "MIP (largest sample)"}
"""The lens appearances swept, in words."""

TRANSPARENCY = 0.2
"""Opacity scale of the transparency lens (the skull's and the engine's own lenses scale by the same)."""

ISOVALUES = {"seismic": 0.6, "skull": 0.631, "foot": BONE_ISOVALUE, "cthead": 0.435, "engine": 0.7}
"""The isosurface lens's value per scene (normalised): a horizon between the seismic cube's bands (0.2–0.9),
the skull's and the CT head's bone presets' isovalues, the foot's bone (:data:`~.scenes.BONE_ISOVALUE`), the
engine's dense inserts (0.85–1 against its body's 0.45–0.55, note 004 §5)."""

EXPOSURE_METHOD = "fused"
"""The method whose early termination runs across the regions (one loop over the three segments)."""

EXPOSED = ("clip", "iso")
"""The appearances ``fused`` renders: the one that shows nothing in front of region₀ and the opaque one."""

REGION_COLUMNS = {region: f"count_samples_{region}" for region in ("region2", "region1", "region0")}


def appearance_entry(scene, appearance):
    """The ``appearance`` entry of ``scene``'s lens showing ``appearance`` (a key of :data:`APPEARANCES`)."""
    if appearance == "transparency":
        return {"mode": "dvr", "preset": SETUPS[scene].preset, "opacity_scale": TRANSPARENCY}
    return {"mode": "iso", "isovalue": ISOVALUES[scene]} if appearance == "iso" else {"mode": appearance}


def appearance_rows(frame, scene, appearance, method=PAPER_METHOD):
    return nonempty_or(rows_matching(frame, scene, scene=scene, appearance=appearance, config=method),
                       f"no successful {method} run of {scene} with a {appearance} lens")


def swept(frame, scene):
    present = set(text_column(rows_matching(frame, scene, scene=scene, config=PAPER_METHOD), "appearance"))
    return [a for a in APPEARANCES if a in present]


def _clip_cheapest(df):
    resampler = intervals.Resampler()
    decisions, notes = {}, {}
    for scene in scenes_of(df):
        clip = appearance_rows(df, scene, "clip")
        for appearance in (a for a in swept(df, scene) if a != "clip"):
            other = appearance_rows(df, scene, appearance)
            label = f"{scene}, {appearance}"
            decisions[label] = intervals.ratio_decision(other, clip, at_least=STRICTLY_ABOVE_ONE, resampler=resampler)
            inside = (counted(other, REGION_COLUMNS["region1"], label),
                      counted(clip, REGION_COLUMNS["region1"], f"{scene}, clip"))
            notes[label] = f"region₁ samples {format_number(inside[0])} against {format_number(inside[1])}"
    return all_of(nonempty_or(decisions, "no scene rendered with a clipping lens and another appearance"),
                  notes=notes, what="time(appearance) / time(clip) ",
                  extra=f"{TIMES}; the segments method; every appearance of a scene timed together")


def _iso_stops(df):
    return counts_compared(
        scenes_of(df), lambda scene: tuple(
            counted(appearance_rows(df, scene, a), REGION_COLUMNS["region1"], f"{scene}, {a}")
            for a in ("iso", "transparency")), fewer=True,
        measured=lambda share, scene: f"{as_percent(share)} ({scene})",
        words=lambda s, i, d: f"{s}: iso {format_number(i)}, transparency {format_number(d)} region₁ samples",
        extra="; the segments method, counted")


def _clip_exposes(df):
    return counts_compared(
        scenes_of(df), lambda scene: tuple(
            counted(appearance_rows(df, scene, a, EXPOSURE_METHOD), REGION_COLUMNS["region0"], f"{scene}, {a}")
            for a in ("clip", "iso")), fewer=False, measured=lambda ratio, scene: f"×{format_number(ratio)} ({scene})",
        words=lambda s, c, i: f"{s}: clip {format_number(c)}, iso {format_number(i)} region₀ samples",
        extra=f"; the {EXPOSURE_METHOD} method (early termination across the regions), counted")


CLAIMS = (
    Claim("clip-cheapest", "A clipping lens is the cheapest appearance: it takes no sample inside the lens (note 004 "
          "§4.2 E6)", f"time(transparency, iso, mip lens) / time(clip lens) > ×1, every scene ({TIMES}; the "
          "segments method; 95 % paired bootstrap interval wholly above ×1)", _clip_cheapest, kind="timing"),
    Claim("iso-stops", "An isosurface lens stops each ray at its first hit: it takes fewer samples inside the lens "
          "than a transparency lens (note 004 §4.2 E6)",
          "region₁ samples of the isosurface lens < region₁ samples of the transparency lens, every scene "
          "(counted, the segments method)", _iso_stops, kind="count"),
    Claim("clip-exposes", "But a clipping lens exposes region₀: where early termination runs across the regions, "
          "rays take more samples behind a clipping lens than behind an (opaque) isosurface lens (note 004 §4.2 E6)",
          f"region₀ samples behind the clipping lens > behind the isosurface lens, every scene (counted, the "
          f"{EXPOSURE_METHOD} method: one loop over the three segments)", _clip_exposes, kind="count"),
)


def appearance_table(tests):
    """Per scene and appearance: frame time, overhead over no lens with its interval, samples per region."""
    rows = []
    resampler = intervals.Resampler()
    for scene in scenes_of(tests):
        off = rows_matching(tests, scene, scene=scene, config=OFF)
        if off.empty:
            continue
        for appearance in swept(tests, scene):
            for method in (PAPER_METHOD, EXPOSURE_METHOD):
                lens = rows_matching(tests, scene, scene=scene, appearance=appearance, config=method)
                if lens.empty:
                    continue
                decision = intervals.ratio_decision(lens, off, resampler=resampler)
                rows.append({"scene": scene, "appearance": appearance, "method": method, "frame (ms)": median_ms(lens),
                             **interval_columns(decision.value, decision.interval, "overhead (%)", ends=PERCENT_CI,
                                                scale=lambda v: 100 * (v - 1)),
                             **{f"{words} pass (ms)": 1e3 * numeric(lens, f"time_{region}").median()
                                if f"time_{region}" in lens else np.nan
                                for region, words in (("region0", "region₀"), ("region1", "region₁"))},
                             "samples lens / no lens": samples_ratio(lens, off), **region_samples(lens),
                             "rays through the lens (%)": 100 * lens_coverage(lens)})
    return pd.DataFrame(rows)


def _figures(paper, ctx):
    bars = paper.pivot_table(index="scene", columns="appearance", values="region1 samples", sort=False) / 1e6
    bars = bars.rename(columns=APPEARANCES).reset_index()
    return overhead_figure(
        paper.assign(series=[APPEARANCES[a] for a in paper.appearance]), ctx, "overhead",
        heading="Overhead against samples, per appearance", x="samples lens / no lens",
        title="Each appearance's overhead against the samples it takes",
        x_label="samples with the lens / samples without it (counted)",
        caption="One point per scene and appearance, the segments method (a line joins an appearance's scenes; the "
                "table names each point); bars: 95 % paired bootstrap interval (every appearance timed together "
                "with the lens-off frame).") + [
        figure(ctx, "region1", plots.bar_compare, bars, heading="Samples inside the lens, per appearance",
               caption="Region₁ samples counted by the caster (the segments method, median over the views).",
               category_col="scene", value_cols=[APPEARANCES[a] for a in APPEARANCES if APPEARANCES[a] in bars],
               value_label="region₁ samples per frame (millions)", title="What each appearance takes inside the lens")]


def _takeaways(paper):
    """The overhead of each appearance by the segments method in words, per scene (measured, not judged)."""
    sentences = []
    for scene, part in paper.groupby("scene", sort=False):
        words = [f"{row['appearance']} {format_number(row['overhead (%)'])} % (95 % CI "
                 f"{format_number(row['95 % CI low (%)'])}–{format_number(row['95 % CI high (%)'])} %)"
                 for row in part.to_dict("records")]
        sentences.append(f"Overhead of each lens appearance on the {scene} (segments): {', '.join(words)}.")
    return sentences


def _gallery(tests, ctx):
    shown = scene_by_scene(headline(tests), lambda here: here[text_column(here, "config").isin([OFF, PAPER_METHOD])])
    return difference_gallery(
        "Headline view: the lens's four appearances", shown, ctx,
        label=lambda row: f"{row.scene}, "
                          + ("no lens" if row.config == OFF else APPEARANCES.get(row.appearance, row.appearance)),
        caption="No lens first, then the segments method's image with each appearance.")


class Appearances(LensExperiment):
    name = "ropinski2005-appearance"
    title = "Lens appearances: clip, transparency, isosurface, MIP (E6)"
    settings = frozenset({"scenes", "appearances", "volume_size", "image_size", "orbit", "step_factor", "repeat",
                          "min_time"})
    scales = scaled(base=TIMED_SCALES, smoke={"scenes": ["seismic", "skull", "foot"]},
                    default={"scenes": ["seismic", "skull", "foot"]})
    description = (
        "The paper shows a transparency lens (the engine), a clipping lens (the seismic cube) and an isosurface "
        "lens (the foot); note 004 §4.2 E6 sweeps the appearance on each data set. Here each scene's lens keeps "
        "its shape and place and shows in turn nothing (clip), the volume's table with its opacity × 0.2 "
        "(transparency), the first crossing of an isovalue (iso: a horizon of the seismic cube, bone on the skull, "
        "the foot and the CT head, the engine's dense inserts) and the largest sample (MIP, not in the paper). "
        "gl-raycast renders the scene without the lens and with each appearance by the paper's segments method, "
        "and the clipping and isosurface lenses also by the fused method (one loop over the three segments, so "
        "that early termination runs across the regions), all timed together in one job per scene; it counts "
        "each region's samples. The Table 1 stand-ins at default scale, every lens scene at full scale."
    )
    claims = CLAIMS

    def lens_runs(self, profile):
        wanted = listed(profile, self, "scenes", tuple(SETUPS), known=SETUPS)
        appearances = listed(profile, self, "appearances", tuple(APPEARANCES), known=APPEARANCES)
        size, image, orbit, step = lens_settings(profile, self)
        frames = timed_frames(profile, self)
        runs = []
        for scene_name in wanted:
            views = lens_views(scene_name, orbit)
            tags = scene_tags(scene_name, image_size=image, role="test")
            spec = lens_scene(scene_name, image, size=size, real_data=profile.real_data)
            runs.append(lens_run(self.name, f"{scene_name}.{OFF}", without_lens(spec), views, OFF, frames,
                                 {**tags, "appearance": "none"}, step_factor=step, group=scene_name))
            for appearance in appearances:
                spec = lens_scene(scene_name, image, size=size, real_data=profile.real_data,
                                  appearance=appearance_entry(scene_name, appearance))
                methods = (PAPER_METHOD,) + ((EXPOSURE_METHOD,) if appearance in EXPOSED else ())
                for method in methods:
                    runs.append(lens_run(self.name, f"{scene_name}.{appearance}.{method}", spec, views, method,
                                         frames, {**tags, "appearance": appearance}, step_factor=step,
                                         group=scene_name))
        return runs

    def report(self, results, ctx):
        tests = tests_of(results)
        table = appearance_table(tests) if not tests.empty else pd.DataFrame()
        paper = table[table.method == PAPER_METHOD] if not table.empty else table
        out = [claim_takeaways(ctx, device_takeaways(tests), _takeaways(paper) if not paper.empty else [])]
        if not paper.empty:
            out += _figures(paper, ctx)
        out += rounded_table("Each appearance: overhead and samples per region", table, csv_name="appearance.csv",
                             caption="Overhead: frame time with the lens over without it, minus one, with its 95 % "
                                     "paired bootstrap interval; region₀ and region₁ pass: their stage times (segments "
                                     "only; region₀ takes the same samples whatever the lens shows); samples counted "
                                     "by the caster. " + frames_caption(tests))
        if not tests.empty:
            out.append(_gallery(tests, ctx))
            out.append(run_table(tests, ["scene", "appearance", "method", "time_ms", "time_ms_min", "time_ms_max",
                                         *REGION_COLUMNS.values(), "count_samples"], ctx, method=method_name,
                                 names={c: f"{r} samples" for r, c in REGION_COLUMNS.items()},
                                 csv_name="appearance_runs.csv"))
        return out + raycast_not_measurable([PAPER_METHOD, EXPOSURE_METHOD])
