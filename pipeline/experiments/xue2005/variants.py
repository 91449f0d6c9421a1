"""``xue2005-variants`` (E12, E13): front-to-back against back-to-front, front-based against exit-based leaping."""

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import (STRICTLY_ABOVE_ONE, all_of, config_rows, image_pairs, ratio_pair, speedup,
                                              time_ratio)
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, scaled
from pipeline.experiments.kit.pages import (as_ratio, by_scene, claim_takeaways, difference_gallery, figure,
                                            format_number, linked_table, unless_missing)
from pipeline.experiments.kit.planning import accepts, listed, orbit_views, timed_frames, volume_and_image_size
from pipeline.experiments.kit.results import numeric, ok_rows, speed_points, tagged
from pipeline.experiments.xue2005.methods import (ISBVR, OPTIONS, culled_fraction, isbvr_not_measurable, mode_name,
                                                  mode_runs, stand_in)
from pipeline.experiments.xue2005.table1 import (LOSSLESS_PSNR, TIMES, culling_note, device_takeaways, pair_psnr,
                                                 scenes_of, view_count)
from pipeline.experiments.xue2005.tables import LEAPING_STATEMENTS, STATEMENTS, TABLE1
from reports import blocks, plots

BACK, FRONT = "back-to-front", "front-to-back"
"""The slice orders (``gl-isbvr``'s ``order``): back to front with "over" (the paper's), front to back with "under"."""

ORDER_CONFIGS = ("basic", "ess+ert")
"""The modes timed in both orders: the speed-up of ESS+ERT over Basic in each."""

LEAPING_CONFIGS = ("ess", "front")
"""Exit-based and front-based leaping, timed back to front beside Basic and ESS+ERT."""

ORDER_TOLERANCE = 1.10
""""The same speed-up" in both orders: their ratio within ×1/1.1–×1.1."""


def _order_speedup(df):
    """``(Basic/ESS+ERT front to back) / (Basic/ESS+ERT back to front)`` on every scene, with its paired interval."""
    resampler = intervals.Resampler()
    decisions, notes = {}, {}
    for s in scenes_of(df, "ess+ert"):
        front, back = (speedup(df, *ORDER_CONFIGS, resampler=resampler, scene=s, order=o) for o in (FRONT, BACK))
        value, draws = ratio_pair(front, back)
        decisions[s] = intervals.decide(value, None if draws is None else intervals.interval_of(draws),
                                        at_least=1.0 / ORDER_TOLERANCE, at_most=ORDER_TOLERANCE)
        notes[s] = f"front to back {as_ratio(front[0])}, back to front {as_ratio(back[0])}"
    return all_of(decisions, notes=notes, what="front-to-back / back-to-front speed-up ",
                  extra=f"speed-up: time(Basic) / time(ESS+ERT) in one order, {TIMES}; the four runs of a scene "
                        "timed interleaved")


def _order_image(df):
    values, basic = (pair_psnr(image_pairs(df, config, config, first_match={"order": FRONT},
                                           second_match={"order": BACK})) for config in ("ess+ert", "basic"))
    worst = min(values, key=lambda k: values[k][0])
    return ClaimResult(f"{format_number(values[worst][0])} dB ({worst[0]}, {worst[1]})",
                       all(p >= LOSSLESS_PSNR for p, _share in values.values()),
                       f"{view_count(len(values))} compared; Basic's two orders: ≥ "
                       f"{format_number(min(p for p, _share in basic.values()))} dB")


def _front_culls(df):
    found = {s: (culled_fraction(config_rows(df, "front", scene=s)), culled_fraction(config_rows(df, "ess", scene=s)))
             for s in scenes_of(df, "front")}
    worst = min(found, key=lambda s: found[s][0] - found[s][1])
    return ClaimResult(f"α' front-based {format_number(found[worst][0])}, exit-based {format_number(found[worst][1])} "
                       f"({worst})", all(front > ess for front, ess in found.values()),
                       ", ".join(f"{s}: {format_number(front)} against {format_number(ess)}"
                                 for s, (front, ess) in found.items())
                       + "; α' = 1 − F'_c/F, occlusion queries, median over the views")


def _leaping_gain(df, slow, fast, what):
    resampler = intervals.Resampler()
    decisions = {s: time_ratio(df, slow, fast, resampler=resampler, at_least=STRICTLY_ABOVE_ONE, scene=s, order=BACK)
                 for s in scenes_of(df, fast)}
    notes = {s: f"{slow} {culling_note(df, slow, scene=s)}, {fast} {culling_note(df, fast, scene=s)}"
             for s in decisions}
    return all_of(decisions, notes=notes, what=what, extra=f"{TIMES}; slices back to front")


CLAIMS = (
    Claim("order-speedup", "iSBVR works equally well front-to-back and back-to-front (§3.5): the same speed-up "
          "over Basic in either order", f"speed-up of ESS+ERT over Basic front-to-back / back-to-front within "
          f"×{format_number(1 / ORDER_TOLERANCE)}–×{format_number(ORDER_TOLERANCE)} on every scene ({TIMES})",
          _order_speedup, kind="timing"),
    Claim("order-image", "Either slice order renders the same image (§3.5)",
          f"PSNR(ESS+ERT front-to-back, ESS+ERT back-to-front) ≥ {format_number(LOSSLESS_PSNR)} dB, every scene "
          "and view", _order_image, kind="accuracy"),
    Claim("front-culls-more", "Front-based leaping culls the front space that exit-based leaping shades (note 001 "
          "E13, the combined mode's known gap), and that space outweighs the back space it shades in turn",
          "α'(front-based) > α'(exit-based ESS): fewer fragments shaded, on every scene (occlusion queries, median "
          "over the views; both cull the rays that miss Φ_t, so the difference is front space less back space)",
          _front_culls, kind="count"),
    Claim("front-faster", "Front-based leaping is faster than exit-based leaping alone",
          f"time(ESS) / time(front-based) > 1 on every scene ({TIMES})",
          lambda df: _leaping_gain(df, "ess", "front", "ESS / front-based "), kind="timing"),
    Claim("exit-combines", "Exit-based leaping is built because it combines with ERT (§3.3): ESS+ERT beats "
          "front-based leaping, which cannot", f"time(front-based) / time(ESS+ERT) > 1 on every scene ({TIMES})",
          lambda df: _leaping_gain(df, "front", "ess+ert", "front-based / ESS+ERT "), kind="timing"))


def _mode_label(row):
    return f"{mode_name(row.config)}, {row.order}"


def _summary(tests):
    """Per scene, mode and order: F'_c, α', the median whole-frame time and the speed-up over Basic in that order."""
    rows = []
    for (scene_name, order, config), part in tests.groupby(["scene", "order", "config"], sort=False):
        gain, alpha = unless_missing(lambda: (time_ratio(tests, "basic", config, resampler=intervals.Resampler(),
                                                         scene=scene_name, order=order).value,
                                              culled_fraction(part)), empty=(np.nan, np.nan))
        rows.append({"scene": scene_name, "order": order, "mode": mode_name(config),
                     "F'c (median)": numeric(part, "count_fragments").median(), "α'": round(alpha, 3),
                     "median frame (ms)": round(numeric(part, "time_total").median() * 1e3, 2),
                     "speed-up over Basic (same order)": round(gain, 2)})
    return pd.DataFrame(rows)


def _blocks(tests, ctx):
    summary = _summary(tests)
    back = summary[summary.order == BACK]
    culled = back.pivot_table(index="scene", columns="mode", values="α'", sort=False).reset_index()
    headline = speed_points(tests[tests.view == "headline"])
    headline["mode"] = [_mode_label(r) for r in headline.itertuples()]
    return [blocks.Table("Modes and orders: fragments shaded, culled share and speed-up over Basic", summary,
                         csv_name="variants.csv",
                         caption="Median over the views; times are whole frames; the speed-up divides Basic's time "
                                 "in the same order by the mode's. Every run of a scene timed interleaved; the "
                                 "claims give each ratio's interval."),
            figure(ctx, "variants-culled", plots.bar_compare, culled, heading="Culled share per mode",
                   caption="Front-based leaping culls in front of Φ_t, exit-based behind it; both cull the rays that "
                           "miss Φ_t, so their difference is the front space less the back space (each alone would "
                           "need the depth band, not built).",
                   category_col="scene", value_cols=[c for c in culled.columns if c != "scene"],
                   value_label="culled share of slice fragments α' = 1 − F'_c/F",
                   title="Fragments culled by each depth-init mode (back to front, median over the views)"),
            linked_table("Headline view: every run", headline,
                         ["scene", "mode", "time_ms", "time_ms_min", "time_ms_max", "count_fragments",
                          "count_fragments_generated"], ctx, csv_name="variants_headline.csv",
                         names={"count_fragments": "F'c", "count_fragments_generated": "F"})]


def _against(row):
    """``(config, name)`` of the image a headline run is compared with: the same mode back to front for a run front to
    back, Basic back to front for the others."""
    return (row.config, mode_name(row.config)) if row.order == FRONT else ("basic", "Basic")


def _gallery(tests, ctx):
    """Headline images: ESS+ERT front to back against back to front, the leaping modes against Basic."""
    headline = tests[tests.view == "headline"]
    exrs = {(row.scene, row.config, row.order): row.exr for row in headline.itertuples()}
    return difference_gallery(
        "Headline view: the orders against each other, the leaping modes against Basic",
        by_scene(headline[(headline.config != "basic") | (headline.order != BACK)]), ctx,
        label=lambda row: f"{row.scene}, {_mode_label(row)}",
        caption="Left the run's image, right its difference from the image named.",
        against=lambda row: exrs.get((row.scene, _against(row)[0], BACK)),
        note=lambda row: f"against {_against(row)[1]}, {BACK}")


class Variants(Experiment):
    """Front-to-back against back-to-front (E12) and front-based against exit-based leaping (E13)."""

    name = "xue2005-variants"
    paper = "xue2005"
    title = "Slice order and the leaping variant: front-to-back against back-to-front, front-based against " \
            "exit-based leaping (E12, E13)"
    settings = frozenset({"scenes", "volume_size", "image_size", "orbit", "repeat", "min_time"})
    scales = scaled(smoke={"scenes": ["head"], "orbit": 0},
                    default={"scenes": ["head", "aneurysm", "bonsai"], "orbit": 1},
                    full={"scenes": ["head", "aneurysm", "bonsai"], "orbit": 4})
    description = (
        "Two variants the paper describes without measuring. Slice order (§3.5: iSBVR \"works equally well\" "
        "either way): Basic and ESS+ERT are rendered back to front with \"over\" (the paper's order) and front to "
        "back with \"under\"; the speed-up of ESS+ERT over Basic in one order is divided by the other's, and the "
        "images are compared. Leaping (§3.2–3.4): front-based leaping draws Φ_t's front faces and tests the volume "
        "pass with GREATER, culling the space in front of the data; exit-based leaping (Table 1's ESS) draws the "
        "box's front faces and Φ_t's back faces, culling behind the data; both remove the rays that miss Φ_t. "
        "Only exit-based leaping combines with ERT. Occlusion queries count the fragments each mode shaded; "
        "every run of a scene is timed interleaved, so every ratio comes with a paired interval.")
    claims = CLAIMS

    def runs(self, profile):
        if not accepts(ISBVR, *OPTIONS):
            return []
        wanted = listed(profile, self, "scenes", ("head", "aneurysm"), known=TABLE1)
        size, image = volume_and_image_size(profile, self)
        orbit = int(profile.setting(self, "orbit", 2))
        frames = timed_frames(profile, self)
        runs = []
        for scene_name in wanted:
            scene_spec, tags = stand_in(scene_name, size, image)
            views = orbit_views(tags["dataset"], orbit, repeat_headline=True)
            tags["role"] = "test"
            runs += mode_runs(self.name, scene_name, scene_spec, views, ORDER_CONFIGS + LEAPING_CONFIGS, frames,
                              {**tags, "order": BACK}, options={"order": BACK}, group=scene_name)
            runs += mode_runs(self.name, f"{scene_name}.f2b", scene_spec, views, ORDER_CONFIGS, frames,
                              {**tags, "order": FRONT}, options={"order": FRONT}, group=scene_name)
        return runs

    def paper_table(self):
        rows = [s for s in STATEMENTS if "front-to-back" in s["claim"]] + LEAPING_STATEMENTS
        return pd.DataFrame(rows)

    def report(self, results, ctx):
        ok = ok_rows(results)
        tests = tagged(ok, role="test")
        out = [claim_takeaways(ctx, device_takeaways(tests))]
        if not tests.empty:
            out += _blocks(tests, ctx)
            out.append(_gallery(tests, ctx))
        band = [("the depth-band combination (cull in front of Φ_t's entry and behind its exit at once)",
                 "not built: it needs two depth tests per fragment, the dual z-buffer the paper only wishes for "
                 "(§3.4); GL_DEPTH_BOUNDS_TEST_EXT tests the stored depth, not the fragment's, and an entry-depth "
                 "texture read in the shader is a branch, not an early depth test")]
        return out + isbvr_not_measurable(also=band)
