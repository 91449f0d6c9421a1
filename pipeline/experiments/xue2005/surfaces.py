"""``xue2005-surfaces`` (E7, E8; Fig. 4): the paper's "original" surfaces against its cube sets, and what
full-resolution isosurfaces cost.

Also the helpers :mod:`.octree` shares: each image against Basic's, and the lossless test (:mod:`.table1`'s bounds).
"""

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import STRICTLY_ABOVE_ONE, all_of, decision_words, median_count
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, scaled
from pipeline.experiments.kit.pages import (as_percent, as_ratio, claim_takeaways, difference_gallery, figure,
                                            format_number, linked_table, unless_missing)
from pipeline.experiments.kit.planning import listed, orbit_views, timed_frames, volume_and_image_size
from pipeline.experiments.kit.results import (nonempty, nonempty_or, numeric, ok_rows, read_exr, rows_matching, tagged,
                                              text_column)
from pipeline.experiments.xue2005.methods import ISBVR, isbvr_not_measurable, mode_runs, stand_in
from pipeline.experiments.xue2005.table1 import LOSSLESS_PIXEL, LOSSLESS_PSNR, LOSSLESS_SHARE
from pipeline.experiments.xue2005.tables import FULL_RES_TRIANGLES, PAPER_SIZE, STATEMENTS, TABLE1, statements
from reports import plots
from reports.metrics import fraction_over, max_error, psnr

VISIBLE_SHARE = 0.01
"""Visibly wrong: at least 1 % of the pixels off, ten times what lossless allows."""

FAR_ABOVE = 10.0
"""Full-resolution triangles "far above" the cube sets': an order of magnitude at least."""

INIT_SHARE = 0.1
"""Cube sets keep T_a ≪ T_m: the init passes at most a tenth of the volume pass."""

VARIANTS = {
    # variant: (gl-isbvr config of methods.MODES, surfaces option, name in tables and figures)
    "basic": ("basic", None, "Basic SBVR"),
    "reduced": ("ess+ert", "reduced", "ESS+ERT, cube sets (reduced)"),
    "coarse": ("ess+ert", "coarse", "ESS+ERT, coarse marching cubes (original)"),
    "full": ("ess+ert", "full", "ESS+ERT, full-resolution marching cubes"),
}
"""What the experiment compares, timed together per scene."""

SCENES = ("bonsai", "head")
"""The bonsai stand-in (the paper's Fig. 4) and the head (Table 1's keys)."""

TECHNIQUE = "slices + init passes + volume pass (time_technique)"
"""The scope of the speed claims: the technique's stages, without readback and Python."""


def image_errors(df, what, **match):
    """Each image of the rows matching ``match`` against its reference run's (Basic), view by view.

    Returns a frame of ``scene``, ``view``, ``run``, ``psnr`` (dB), ``off`` (share of pixels with a
    channel off by more than :data:`~.table1.LOSSLESS_PIXEL`) and ``max_error``; ValueError naming ``what`` when no row
    matches, or naming the run whose reference image is missing.
    """
    rows = nonempty(rows_matching(df, what, **match), what=what)
    runs, views = text_column(df, "run"), text_column(df, "view")
    out = []
    for _, row in rows.iterrows():
        reference = df[(runs == str(row["reference"])) & (views == str(row["view"]))]
        if reference.empty:
            raise ValueError(f"run {row['run']}, view {row['view']}: its reference {row['reference']!r} did not render")
        basic, image = read_exr(reference["exr"].iloc[0]), read_exr(row["exr"])
        out.append({"scene": row.get("scene", ""), "view": row["view"], "run": row["run"],
                    "psnr": float(psnr(basic, image)), "off": fraction_over(basic, image, threshold=LOSSLESS_PIXEL),
                    "max_error": max_error(basic, image)})
    return pd.DataFrame(out)


def _where(row):
    return f"{row.scene}, {row.view}" if row.scene else str(row.view)


def lossless_result(errors):
    """Lossless against Basic on every image of ``errors`` (:func:`image_errors`): ≥ 50 dB and ≤ 0.1 % off."""
    worst_psnr = errors.loc[errors.psnr.idxmin()]
    worst_off = errors.loc[errors.off.idxmax()]
    holds = bool(worst_psnr.psnr >= LOSSLESS_PSNR and worst_off.off <= LOSSLESS_SHARE)
    return ClaimResult(f"{format_number(worst_psnr.psnr)} dB ({_where(worst_psnr)}); "
                       f"{as_percent(worst_off.off)} of pixels off by > 1/255 ({_where(worst_off)})", holds,
                       f"worst of {len(errors)} images; largest error {format_number(errors.max_error.max())}")


def off_percent(rows, df, what, **match):
    """Each of ``rows``' pixels off against Basic in % (:func:`image_errors` of the rows of ``df`` matching
    ``match``; NaN where it has none)."""
    errors = unless_missing(image_errors, df, what, empty=None, **match)
    off = errors.set_index(["run", "view"]).off if errors is not None else pd.Series(dtype=float)
    return [100 * off.get((r, v), np.nan) for r, v in zip(rows.run, rows.view)]


def scenes_of(df):
    """The scenes of ``df`` in order of appearance; ValueError when there is none."""
    return nonempty(list(pd.unique(text_column(df, "scene"))))


def device_sentence(rows):
    """Which GL device timed the page, and what a CPU rasterizer's times mean (empty without rows)."""
    if rows.empty or "gl_renderer" not in rows:
        return []
    devices = ", ".join(sorted(set(rows.gl_renderer.dropna().astype(str)))) or "an unrecorded device"
    software = "gl_software_rasterizer" in rows and rows.gl_software_rasterizer.dropna().astype(bool).all()
    return [f"GL times on this page were measured on {devices}"
            + (", a CPU rasterizer (early depth test per 4×2-pixel block, no hierarchical Z): only ratios between "
               "runs timed together compare with the paper's Radeon, and the fragment counts beside them do not "
               "depend on the machine." if software else ".")]


def _variant(df, variant, **match):
    return nonempty_or(rows_matching(df, variant, variant=variant, **match),
                       f"no successful {VARIANTS[variant][2]} run" + (f" of {match['scene']}" if match else ""))


def _triangles(rows):
    """Φ_t's and Φ_p's triangles together (median over the views)."""
    return median_count(rows, "count_surface_triangles_t") + median_count(rows, "count_surface_triangles_p")


def _coarse_wrong(df):
    errors = image_errors(df, "ESS+ERT with the coarse surfaces", variant="coarse")
    least = errors.loc[errors.off.idxmin()]
    per_scene = errors.groupby("scene", sort=False).agg(off=("off", "min"), psnr=("psnr", "max"))
    return ClaimResult(f"{as_percent(least.off)} of pixels off by > 1/255 ({_where(least)}), the least of "
                       f"{len(errors)} images", bool(least.off >= VISIBLE_SHARE),
                       "; ".join(f"{s}: ≥ {as_percent(r.off)} off, PSNR ≤ {format_number(r.psnr)} dB"
                                 for s, r in per_scene.iterrows()))


def _full_triangles(df):
    ratios, words = {}, []
    for scene_name in scenes_of(df):
        full, reduced = (_triangles(_variant(df, v, scene=scene_name)) for v in ("full", "reduced"))
        if reduced == 0:
            raise ValueError(f"{scene_name}: the cube sets have no triangle")
        ratios[scene_name] = full / reduced
        words.append(f"{scene_name}: {format_number(full)} against {format_number(reduced)}")
    worst = min(ratios, key=ratios.get)
    return ClaimResult(f"{as_ratio(ratios[worst])} ({worst})", bool(ratios[worst] >= FAR_ABOVE),
                       "triangles of Φ_t and Φ_p, full resolution against the cube sets: " + "; ".join(words))


def _full_million(df):
    rows = _variant(df, "full")
    largest, where, size = -1.0, None, None
    for scene_name in scenes_of(rows):
        here = rows_matching(rows, scene_name, scene=scene_name)
        for surface in ("t", "p"):
            count = median_count(here, f"count_surface_triangles_{surface}")
            if count > largest:
                largest, where, size = count, f"{scene_name}, Φ_{surface}", float(numeric(here, "size").max())
    if size != PAPER_SIZE:
        estimate = largest * (PAPER_SIZE / size) ** 2
        return ClaimResult(f"not measured at {format_number(size)}³", None,
                           f"the paper's count is for {PAPER_SIZE}³ (full scale); here the largest surface has "
                           f"{format_number(largest)} triangles ({where}), about {format_number(estimate)} at "
                           f"{PAPER_SIZE}³ if its area grows with the square of the size (an estimate)")
    return ClaimResult(f"{format_number(largest)} triangles ({where})", bool(largest > FULL_RES_TRIANGLES),
                       "the largest single full-resolution isosurface over the scenes at the paper's size")


def _cube_init_small(df):
    resampler = intervals.Resampler()
    decisions = {s: intervals.ratio_decision(_variant(df, "reduced", scene=s), _variant(df, "reduced", scene=s),
                                             column="time_init", bottom_column="time_draw", at_most=INIT_SHARE,
                                             resampler=resampler) for s in scenes_of(df)}
    return all_of(decisions, show=format_number, what="T_a / T_m ",
                  extra="Median over the views of each view's median frame; init passes and volume pass of the "
                        "same frames")


def _speedup(df, variant, scene_name, resampler, **bounds):
    """Basic over ``variant`` on one scene: :data:`TECHNIQUE`, median over the views, judged against ``bounds``."""
    return intervals.ratio_decision(_variant(df, "basic", scene=scene_name), _variant(df, variant, scene=scene_name),
                                    column="time_technique", resampler=resampler, **bounds)


def _full_erodes(df):
    resampler = intervals.Resampler()
    decisions, notes = {}, {}
    for s in scenes_of(df):
        full, reduced = _variant(df, "full", scene=s), _variant(df, "reduced", scene=s)
        decisions[s] = intervals.ratio_decision(full, reduced, column="time_technique", at_least=STRICTLY_ABOVE_ONE,
                                                resampler=resampler)
        speedups = {v: _speedup(df, v, s, resampler) for v in ("reduced", "full")}
        share = intervals.ratio_decision(full, full, column="time_init", bottom_column="time_draw", resampler=resampler)
        shaded = median_count(full, "count_fragments") / median_count(reduced, "count_fragments")
        notes[s] = (f"Basic / ESS+ERT {decision_words(speedups['reduced'], as_ratio)} with the cube sets, "
                    f"{decision_words(speedups['full'], as_ratio)} with full-resolution surfaces, whose T_a / T_m is "
                    f"{format_number(share.value)} and whose shaded fragments F'_c are {as_ratio(shaded)} the cube "
                    "sets'")
    return all_of(decisions, show=as_ratio, notes=notes, what="time full / cube sets ",
                  extra=f"Times: {TECHNIQUE}, median over the views, timed together")


def _full_offsets(df):
    """Basic over ESS+ERT with full-resolution surfaces at most ×1: their cost leaves no speed-up (§4)."""
    resampler = intervals.Resampler()
    decisions = {s: _speedup(df, "full", s, resampler, at_most=1.0) for s in scenes_of(df)}
    return all_of(decisions, show=as_ratio, what="Basic / ESS+ERT with full-resolution surfaces ",
                  extra=f"Times: {TECHNIQUE}, median over the views, timed together")


CLAIMS = (
    Claim("reduced-lossless", "With the cube sets ESS+ERT renders Basic's image (Fig. 4b: holes removed)",
          f"PSNR against Basic ≥ {format_number(LOSSLESS_PSNR)} dB and ≤ {as_percent(LOSSLESS_SHARE)} of pixels off "
          "by > 1/255, every scene and view",
          lambda df: lossless_result(image_errors(df, "ESS+ERT with the cube sets", variant="reduced")),
          kind="accuracy"),
    Claim("coarse-visibly-wrong", "Marching cubes on the coarse max/min grids (the paper's original surfaces) cut "
          "holes by incorrect occlusion (Fig. 4a)", f"≥ {as_percent(VISIBLE_SHARE)} of pixels off by > 1/255 against "
          "Basic, every scene and view", _coarse_wrong, kind="accuracy"),
    Claim("full-triangles", "Full-resolution isosurfaces have far more triangles than the cube sets (§4)",
          f"full-resolution / cube-set triangles (Φ_t + Φ_p) ≥ {as_ratio(FAR_ABOVE)}, every scene", _full_triangles,
          kind="count"),
    Claim("full-million", "A full-resolution 256³ isosurface can exceed a million triangles (§4)",
          f"the largest full-resolution surface > {format_number(FULL_RES_TRIANGLES)} triangles at {PAPER_SIZE}³ "
          "(measured at full scale only)", _full_million, paper_value="> 1 million triangles", kind="count"),
    Claim("cube-init-small", "With the cube sets the init passes cost little beside the volume pass (T_a ≪ T_m, "
          "§3.5, Eqs. 7–9)", f"T_a / T_m (time_init / time_draw) ≤ {format_number(INIT_SHARE)}, every scene",
          _cube_init_small, kind="timing"),
    *Claim("full-erodes-paper", "Full-resolution surfaces offset any speed-up: their rendering cost cancels the gain "
           "(§4)", f"Basic / ESS+ERT with full-resolution surfaces ≤ ×1 ({TECHNIQUE}), every scene", _full_offsets,
           paper_value="offsets any speed-up", kind="timing").with_ours(
        "Full-resolution surfaces erode the speed-up (§4: their rendering cost cancels the gain)",
        f"time with full-resolution surfaces / with the cube sets > 1 ({TECHNIQUE}), every scene", _full_erodes,
        why="erodes: slower than with the cube sets, whether or not it is slower than Basic as well"))


COLUMNS = {"variant_name": "surfaces", "triangles_t": "Φ_t triangles", "triangles_p": "Φ_p triangles",
           "count_cubes_t": "Φ_t cubes", "count_cubes_p": "Φ_p cubes", "count_surface_fragments_t": "F_t",
           "count_surface_fragments_p": "F_p", "count_fragments_generated": "F (slice fragments)",
           "count_fragments": "F'_c (shaded)", "culled_percent": "culled (%)", "init_ms": "T_a init (ms)",
           "draw_ms": "T_m volume pass (ms)", "ta_tm": "T_a / T_m", "technique_ms": "technique (ms)",
           "off_percent": "pixels off > 1/255 (%)"}


def _page_rows(tests):
    rows = tests.assign(variant_name=[VARIANTS[v][2] for v in tests.variant],
                        triangles_t=numeric(tests, "count_surface_triangles_t"),
                        triangles_p=numeric(tests, "count_surface_triangles_p"),
                        culled_percent=100 * (1 - numeric(tests, "count_fragments")
                                              / numeric(tests, "count_fragments_generated")),
                        **{f"{stage}_ms": numeric(tests, f"time_{stage}") * 1e3
                           for stage in ("init", "draw", "technique")})
    rows["ta_tm"] = rows.init_ms / rows.draw_ms
    rows["off_percent"] = off_percent(rows, tests, "ESS+ERT", config="ess+ert")
    rows["order"] = rows.variant.map({v: i for i, v in enumerate(VARIANTS)})
    return rows.sort_values(["scene", "view", "order"], kind="stable")


def _triangle_takeaways(tests):
    """The full-resolution surfaces' triangles against the cube sets', scaled to the paper's 256³ where smaller."""
    sentences = []
    for scene_name in pd.unique(tests.scene):
        here = tests[tests.scene == scene_name]
        try:
            full, reduced = (_triangles(_variant(here, v)) for v in ("full", "reduced"))
        except (KeyError, ValueError):
            continue
        size = float(numeric(here, "size").max())
        scaled = (f" (about {format_number(full * (PAPER_SIZE / size) ** 2)} at {PAPER_SIZE}³ if the surface area "
                  "grows with the square of the size)" if size != PAPER_SIZE else "")
        sentences.append(f"{scene_name}: full-resolution surfaces draw {format_number(full)} triangles (Φ_t + Φ_p) "
                         f"at {format_number(size)}³{scaled}, the cube sets {format_number(reduced)}; the paper "
                         f"warns of over {format_number(FULL_RES_TRIANGLES)} at {PAPER_SIZE}³.")
    return sentences


def _gallery(rows, results, ctx):
    return difference_gallery(
        "Each surface kind and its difference from Basic (first view)", rows, ctx, against=results,
        label=lambda row: f"{row.scene}, {row.variant_name}",
        caption="Left the image, right |image − Basic| on the report's one difference scale; the coarse surfaces' "
                "holes show as bright regions (the paper's Fig. 4a).",
        note=lambda row: (f"{format_number(row.off_percent)} % off, PSNR {format_number(getattr(row, 'psnr', np.nan))} "
                          "dB" if row.variant != "basic" else f"{format_number(row.technique_ms)} ms"))


def _time_chart(rows, ctx):
    chart = rows[rows.variant != "basic"].copy()
    chart["scene · surfaces"] = [f"{s} · {v}" for s, v in zip(chart.scene, chart.variant)]
    chart["T_a: init passes"], chart["T_m: volume pass"] = chart.init_ms, chart.draw_ms
    shares = chart.groupby("variant").ta_tm.max()
    title = "T_a / T_m up to " + ", ".join(f"{format_number(shares[v])} ({v})" for v in VARIANTS if v in shares)
    return figure(ctx, "ta-tm", plots.bar_compare, chart, heading="Init passes (T_a) against the volume pass (T_m)",
                  caption="Bars: the median over the views of each view's median frame (the table gives every view "
                          "with its fastest and slowest frame; the claims give the intervals).",
                  category_col="scene · surfaces", value_cols=["T_a: init passes", "T_m: volume pass"],
                  value_label="median time per frame (ms, log scale)", title=title, log_y=True)


class Surfaces(Experiment):
    """The paper's original surfaces against its cube sets, and the cost of full-resolution isosurfaces."""

    name = "xue2005-surfaces"
    paper = "xue2005"
    title = "Original surfaces against the cube sets, and full-resolution isosurfaces (E7, E8, Fig. 4)"
    settings = frozenset({"scenes", "volume_size", "image_size", "orbit", "repeat"})
    scales = scaled(smoke={"orbit": 0}, default={"orbit": 2}, full={"orbit": 3})
    description = (
        "The paper first contoured Φ_t on the coarse grid of block maxima and Φ_p on the block minima, and found "
        "holes: the coarse surfaces occlude material that is visible (Fig. 4a). It then drew the faces of cube "
        "sets instead, inflating Φ_t and shrinking Φ_p, which removed them (Fig. 4b), and warned that "
        "full-resolution isosurfaces (over a million triangles at 256³) would cost as much as they save. Here "
        "ESS+ERT runs with each kind of surface on the bonsai stand-in and the head, timed together with Basic "
        "SBVR (no depth passes), whose image every other is compared with. The triangles and the fragments the "
        "passes draw and cull are counted by occlusion queries; T_a is the init passes' time, T_m the volume "
        "pass's.")
    claims = CLAIMS

    def runs(self, profile):
        wanted = listed(profile, self, "scenes", SCENES, known=TABLE1)
        size, image = map(int, volume_and_image_size(profile, self))
        orbit = int(profile.setting(self, "orbit", 1))
        frames = timed_frames(profile, self)
        runs = []
        for scene_name in wanted:
            spec, tags = stand_in(scene_name, size, image)
            views = orbit_views(tags["dataset"], orbit)
            tags["size"] = size
            basic = f"{scene_name}.basic"
            for variant, (config, surfaces, _name) in VARIANTS.items():
                prefix = scene_name if surfaces is None else f"{scene_name}.{variant}"
                runs += mode_runs(self.name, prefix, spec, views, [config], frames, {**tags, "variant": variant},
                                  options={"surfaces": surfaces} if surfaces else None, group=scene_name,
                                  reference=None if surfaces is None else basic)
        return runs

    def paper_table(self):
        rows = [s for s in STATEMENTS if "Fig. 4" in s["source"] or "million" in s["claim"]]
        return pd.DataFrame(rows + statements(("the init passes' time must stay well below the volume pass's, or the "
                                               "gain is lost", "§3.5 (Eqs. 7–9), §4", "no timing")))

    def report(self, results, ctx):
        ok = ok_rows(results)
        tests = tagged(ok, backend=ISBVR)
        out = [claim_takeaways(ctx, device_sentence(tests),
                               _triangle_takeaways(tests) if "variant" in tests else [])]
        if not tests.empty and "variant" in tests:
            rows = _page_rows(tests)
            out.append(_gallery(rows[rows.view == rows.view.iloc[0]], results, ctx))
            out.append(linked_table("Surfaces, triangles, fragments and times", rows,
                                    ["scene", "view", "variant_name", *list(COLUMNS)[1:], "psnr"], ctx,
                                    names=COLUMNS, csv_name="surfaces.csv",
                                    caption="Counts from occlusion queries (the same on every machine): F_t and F_p "
                                            "the fragments of Φ_t's back and Φ_p's front faces, F every slice "
                                            "fragment, F'_c those the depth test let through. Times: each view's "
                                            "median frame. PSNR and pixels off against Basic."))
            out.append(_time_chart(rows, ctx))
        return out + isbvr_not_measurable()
