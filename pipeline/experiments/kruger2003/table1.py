"""``kruger2003-table1`` (E1, E3, E5): Table 1's four methods on the paper's four kinds of data, and their images."""

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, scaled
from pipeline.experiments.kit.pages import (as_ratio, claim_takeaways, device_takeaways, difference_gallery, figure,
                                            format_number, frames_caption, linked_table, per_gl_device,
                                            speed_psnr_figure, unless_missing)
from pipeline.experiments.kit.planning import (is_registered, listed, orbit_views, phantom, scene,
                                               timed_frames, truth_run)
from pipeline.experiments.kit.results import (nonempty, nonempty_or, numeric, ok_rows, pair_metrics, read_exr,
                                              role_rows, rows_matching, text_column)
from pipeline.experiments.kit.judging import (STRICTLY_BELOW_ONE, all_of, image_pairs, point_speedup, time_ratio,
                                              worst_test_psnr)
from pipeline.experiments.kruger2003.methods import (METHODS, RAYCAST, SETTINGS, SIZE_SCALES, SLICER, UPLOADS,
                                                     gl_not_measurable, method_name, method_points, method_runs,
                                                     samples_note, sizes)
from pipeline.experiments.kruger2003.tables import (ENGINE_RC_OVER_RCA, HEAD_RCB_OVER_RC, HEAD_RCB_OVER_SBVR,
                                                    PAPER_DEVICE, RCA_OVER_RCB, REAL_SCANS, SBVR_OVER_RC, TABLE1)
from reports import blocks, plots

HEADS, ENGINES = ("head", "mrihead"), ("engine", "engine_real")
"""The scenes of the opaque head and of the semi-transparent engine (stand-in and real scan)."""

PAPER_METHODS = ("sbvr", "rc", "rc-a", "rc-b")
"""Table 1's methods; the single-pass caster (ours) is reported beside them, not judged with them."""

RATIOS = {"RC / SBVR": ("sbvr", "rc"), "RC-a / RC": ("rc", "rc-a"), "RC-b / RC-a": ("rc-a", "rc-b"),
          "RC-b / RC": ("rc", "rc-b"), "RC-b / SBVR": ("sbvr", "rc-b")}
"""Table 1's speed-ups as ``(slow, fast)`` methods: the paper's quotient of frame rates, ours of frame times."""


def _paper_ratio(scene_name, slow, fast):
    """The paper's speed-up of ``fast`` over ``slow`` on ``scene_name``'s row of Table 1 (its frame rates)."""
    fps = dict(zip(PAPER_METHODS, TABLE1[scene_name][3:]))
    return fps[fast] / fps[slow]


def _gain(df, slow, fast, scenes, low=None, high=None, what=""):
    """``time(slow) / time(fast)`` (whole frames, median over the views) within [low, high] on each of ``scenes``
    (``None``: every scene), each with its interval (the methods of a scene are interleaved)."""
    resampler = intervals.Resampler()
    scenes = nonempty([s for s in pd.unique(text_column(df, "scene")) if scenes is None or s in scenes],
                      what=", ".join(scenes) if scenes else "any scene")
    decisions = {s: time_ratio(df, slow, fast, resampler=resampler, at_least=low, at_most=high, scene=s)
                 for s in scenes}
    notes = {s: samples_note(df, slow, fast, scene=s) for s in scenes}
    return all_of(decisions, notes=notes, what=what,
                 extra="whole-frame times, median over the views (headline and orbit) of each view's median frame"
                       + ("; samples: the same ratio of the samples the shaders took (machine-independent)"
                          if any(notes.values()) else ""))


def _ess_lossless(df):
    values = {(s, v): pair_metrics(a.exr, b.exr)["psnr"] for s, v, a, b in image_pairs(df, "rc-a", "rc-b")}
    worst = min(values, key=values.get)
    return ClaimResult(f"{format_number(values[worst])} dB ({worst[0]}, {worst[1]})",
                       bool(values[worst] >= 60.0), f"{len(values)} views compared")


def _ert_bound(df):
    differences = {(s, v): float(np.abs(read_exr(rc.exr) - read_exr(rca.exr)).max())
                   for s, v, rc, rca in image_pairs(df, "rc", "rc-a")}
    where = max(reversed(differences), key=differences.get)  # of equal differences, the last pair's
    worst = differences[where]
    threshold = float(numeric(rows_matching(df, "rc-a", config="rc-a"), "option_opaque_threshold").median())
    bound = 1.0 - threshold + 1e-3
    return ClaimResult(f"{format_number(worst)} ({where[0]}, {where[1]})", bool(worst <= bound),
                       f"bound 1 − T = {format_number(1 - threshold)} with T = {format_number(threshold)}")


def _contributing_fragments(df, low=0.0, high=0.10):
    """The median share of slicing fragments that contribute, within [low, high] on every data set; the data set
    furthest from the band (or, all inside, the largest share) decides."""
    rows = nonempty_or(rows_matching(df, "sbvr", config="sbvr"), "no successful slicing run")
    fraction = numeric(rows, "count_fragments_contributing") / numeric(rows, "count_fragments")
    values = fraction.groupby(text_column(rows, "scene")).median().to_dict()
    if not all(np.isfinite(v) for v in values.values()):
        raise ValueError("a data set's slicing runs counted no fragments (count_fragments_contributing)")
    outside = {s: max(low - v, v - high) for s, v in values.items()}
    decisive = max(outside, key=outside.get)
    return ClaimResult(f"{format_number(100 * values[decisive])} % ({decisive})", outside[decisive] <= 0,
                       ", ".join(f"{s}: {format_number(100 * v)} %" for s, v in values.items()))


TIMES = "whole frames, median over the views"
"""The scope of Table 1's speed claims: the paper's frame rates are of whole frames from views it does not
give, so the views of an orbit stand for them (note 000 §5, E1)."""


def _band(band):
    """``"0.606–0.676"``: a band of the paper's ratios, to the digit that tells its ends from the rounded ones."""
    return f"{band[0]:.3f}–{band[1]:.3f}"


CLAIMS = (
    *Claim("rc-slower-than-sbvr-paper", "Unaccelerated ray casting runs at 0.61–0.68 of slicing's frame rate on every "
           "data set (paper)", f"time ratio SBVR / RC within {_band(SBVR_OVER_RC)} on every data set ({TIMES})",
           lambda df: _gain(df, "sbvr", "rc", None, *SBVR_OVER_RC, what="SBVR / RC time "), paper_value="×0.61–0.68",
           kind="timing").with_ours(
        "Unaccelerated ray casting is slower than slicing: it processes fragments outside the volume and all M samples "
        "of every pass (paper: RC/SBVR fps 0.61–0.68)", f"time ratio SBVR / RC < 1 on every data set ({TIMES})",
        lambda df: _gain(df, "sbvr", "rc", None, high=STRICTLY_BELOW_ONE, what="SBVR / RC time "),
        why="that slicing is faster: by how much follows what a pass and a slice cost a rasterizer, not the R300"),
    *Claim("ert-gain-opaque-paper", "Early ray termination pays most on the opaque head: RC-a 3.0× RC (paper)",
           f"RC / RC-a ≥ 3 on the head ({TIMES})", lambda df: _gain(df, "rc", "rc-a", HEADS, 3.0), paper_value="×3.0",
           kind="timing").with_ours(
        "Early ray termination pays most on the opaque head (paper: RC-a 3.0× RC)",
        f"RC / RC-a ≥ 2 on the head ({TIMES})", lambda df: _gain(df, "rc", "rc-a", HEADS, 2.0),
        why="the gain, not the paper's GPU's figure: a software rasterizer's passes cost differently"),
    *Claim("ert-none-semi-transparent-paper", "On the semi-transparent engine early termination gains nothing: RC-a "
           "6.3 fps = RC 6.3 fps, equal within the table's 0.1 fps (paper)",
           f"RC / RC-a within {_band(ENGINE_RC_OVER_RCA)} (6.25 / 6.35 to 6.35 / 6.25) on the engine ({TIMES})",
           lambda df: _gain(df, "rc", "rc-a", ENGINES, *ENGINE_RC_OVER_RCA), paper_value="6.3 = 6.3 fps",
           kind="timing").with_ours(
        "On the semi-transparent engine early termination gains nothing (paper: 6.3 = 6.3 fps)",
        f"RC / RC-a within 0.8–1.25 on the engine ({TIMES})", lambda df: _gain(df, "rc", "rc-a", ENGINES, 0.8, 1.25),
        why="no gain within ±25 %: the gain and the intermediate pass cancel on the R300, not on every rasterizer"),
    *Claim("ess-gain-paper", "Empty-space skipping adds 1.6–2.2× to early termination on every data set (paper)",
           f"RC-a / RC-b within {_band(RCA_OVER_RCB)} on every data set ({TIMES})",
           lambda df: _gain(df, "rc-a", "rc-b", None, *RCA_OVER_RCB), paper_value="×1.6–2.2", kind="timing").with_ours(
        "Empty-space skipping adds to early termination on every data set (paper: RC-b 1.6–2.2× RC-a)",
        f"RC-a / RC-b ≥ 1.1 on every data set ({TIMES})", lambda df: _gain(df, "rc-a", "rc-b", None, 1.1),
        why="that skipping gains at all: how much depends on the empty blocks of each data set's stand-in"),
    Claim("rcb-over-rc-head", "RC-b over RC on the opaque head at least the paper's 4.9× (23.4 / 4.8 fps)",
          f"RC / RC-b ≥ {format_number(HEAD_RCB_OVER_RC)} on the head ({TIMES})",
          lambda df: _gain(df, "rc", "rc-b", HEADS, HEAD_RCB_OVER_RC), paper_value="×4.9 (23.4 / 4.8 fps)",
          kind="timing"),
    Claim("rcb-over-sbvr-head", "RC-b over slicing on the head at least the paper's 3.3× (23.4 / 7.1 fps, "
          "\"up to a factor of 3\")", f"SBVR / RC-b ≥ {format_number(HEAD_RCB_OVER_SBVR)} on the head ({TIMES})",
          lambda df: _gain(df, "sbvr", "rc-b", HEADS, HEAD_RCB_OVER_SBVR), paper_value="×3.3 (23.4 / 7.1 fps)",
          kind="timing"),
    Claim("accuracy", "The paper's four methods render the reference's image (\"the same image quality\")",
          "PSNR ≥ 40 dB against the reference (SBVR, RC, RC-a, RC-b; every data set and view)",
          lambda df: worst_test_psnr(df, PAPER_METHODS, at_least=40.0), kind="accuracy"),
    Claim("ess-lossless", "Empty-space skipping is conservative: RC-b's image is RC-a's",
          "PSNR(RC-b, RC-a) ≥ 60 dB (every data set and view)", _ess_lossless, kind="accuracy"),
    Claim("ert-bound", "Early termination changes a pixel by at most what the opacity threshold leaves",
          "max |RC-a − RC| ≤ 1 − T (+ 1e-3) on every image", _ert_bound, kind="accuracy"),
    *Claim("fragments-contribute-paper", "0.2–4 % of the slicing fragments contribute to the image (paper)",
           "contributing / generated slicing fragments within 0.2–4 % on every data set (median over the views)",
           lambda df: _contributing_fragments(df, 0.002, 0.04), paper_value="0.2–4 %", kind="count").with_ours(
        "Only a small fraction of slicing fragments contributes to the image (paper: 0.2–4 %)",
        "contributing / generated slicing fragments ≤ 10 % on every data set (median over the views)",
        _contributing_fragments, why="a small fraction: the share follows each stand-in's transfer function, not the "
        "paper's data"),
)


def _ratio_table(tests):
    """Per scene, the paper's speed-ups between methods beside ours (quotients of median frame times over the views)."""
    rows = []
    for scene_name in pd.unique(tests.scene):
        here = tests[tests.scene == scene_name]
        row = {"scene": scene_name, "paper row": TABLE1[scene_name][2]}
        for label, (slow, fast) in RATIOS.items():
            row[f"{label} (paper)"] = round(_paper_ratio(scene_name, slow, fast), 2)
            row[f"{label} (ours)"] = round(unless_missing(point_speedup, here, slow, fast, empty=np.nan), 2)
        rows.append(row)
    return pd.DataFrame(rows)


def _bar_title(ratios):
    ours = ratios["RC-b / SBVR (ours)"].dropna()
    if ours.empty:
        return "RC-b over slicing"
    best = ratios.loc[ours.idxmax()]
    return f"RC-b over slicing: up to {as_ratio(best['RC-b / SBVR (ours)'])} here ({best.scene}), paper up to ×3.3"


def _device_takeaways(tests):
    """Which GL devices timed this page, and what a CPU rasterizer's numbers mean."""
    return device_takeaways(tests, software=(
        "fragment shaders run on the CPU's cores and early-z rejects whole tiles in software, so its frame times "
        "are not a GPU's and only ratios between methods measured in one run compare with the paper's (the "
        "samples-passed counts show what each method drew); no GPU run is in these results"))


def _peer_takeaways(ok):
    """RC-b against VTK's GPU ray caster, the peer users run (no claim: the paper could not compare with it)."""
    result = unless_missing(_gain, ok, "vtk-gpu", "rc-b", None, 1.0, empty=None)
    if result is None:
        return []
    return [f"RC-b against VTK's GPU ray caster (time of VTK / time of RC-b): {result.measured} ({result.detail})."]


def _ratio_blocks(tests, ctx):
    """Table 1's speed-ups beside ours, per device, and RC-b over slicing as bars (as the claims: every view)."""
    ratios = per_gl_device(tests, _ratio_table)
    if ratios.empty:
        return []
    return [blocks.Table("Table 1 beside ours: speed-ups between methods (median over the views)", ratios,
                         csv_name="table1_ratios.csv",
                         caption="Ours: the quotient of whole-frame times, each the median over the views "
                                 "(headline and orbit) of the view's median frame, the four methods of a scene "
                                 "timed interleaved; paper: the quotient of its frame rates. Real scans share the "
                                 "paper row of their kind; the claims give each ratio's interval."),
            figure(ctx, "table1-ratios", plots.bar_compare, ratios, heading="RC-b over slicing, paper and ours",
                   caption="Bars are the paper's ratio of frame rates and ours of median frame times.",
                   category_col="scene", value_cols=["RC-b / SBVR (paper)", "RC-b / SBVR (ours)"],
                   value_label="speed-up of RC-b over slicing (×)", title=_bar_title(ratios))]


def _speed_blocks(headline, tests, ctx):
    """Frame times and PSNR in the headline view, speed against accuracy, and times over the orbit."""
    timing = method_points(headline)
    summary = method_points(tests).groupby(["scene", "method"]).time_ms.agg(**{
        "median over views (ms)": "median", "fastest view (ms)": "min", "slowest view (ms)": "max"}).reset_index()
    return [linked_table("Frame times and accuracy (headline view)", timing,
                         ["scene", "method", "time_ms", "time_ms_min", "time_ms_max", "psnr", "ssim"], ctx,
                         csv_name="table1.csv", caption=frames_caption(timing, untimed=UPLOADS)),
            speed_psnr_figure(ctx, "table1-speed-accuracy", timing, heading="Speed against accuracy",
                              caption="One series per scene, each point one method (labelled), headline view; "
                                      "higher and further left is better.",
                              title="Median frame time against PSNR, every method and scene", group="scene",
                              label="method"),
            blocks.Table("Over the orbit", summary, csv_name="table1_orbit.csv",
                         caption="Median frame time per view, then median, fastest and slowest view.")]


class Table1(Experiment):
    """SBVR, RC, RC-a and RC-b on the paper's four kinds of data, and the images against the reference."""

    name = "kruger2003-table1"
    paper = "kruger2003"
    title = "Table 1: slicing against multi-pass ray casting with early termination and empty-space skipping (E1, E3, E5)"
    settings = SETTINGS | {"scenes", "truth_step_factor", "orbit"}
    scales = scaled(base=SIZE_SCALES, smoke={"scenes": ["head"], "orbit": 1}, default={"orbit": 2}, full={"orbit": 8})
    description = (
        "The paper times 3D-texture slicing (SBVR) against its multi-pass GPU ray caster without acceleration (RC), "
        "with early ray termination through the depth test (RC-a) and with empty-space skipping on top (RC-b), on an "
        "MRI head, an aneurysm, a foot and an engine at 512². Here the same four renderers (and the modern single-pass "
        "caster, not in the paper, and VTK's GPU ray caster, the peer users run, with its default early termination) "
        "render phantom stand-ins of the four kinds and the real scans of the same kinds, at one sampling distance, "
        "from the headline view (30° yaw, 20° pitch) and around an orbit. Every image is compared with the reference "
        "ray caster at a fine step. The paper's frame rates come from a 2003 GPU; the claims compare ratios between "
        "methods measured in one run: the four methods of a data set are timed interleaved, frame against frame, and "
        "each ratio of whole-frame times (the median over the views) is judged with its bootstrap interval."
    )
    SCENES = tuple(TABLE1)
    claims = CLAIMS

    def runs(self, profile):
        if not (is_registered(RAYCAST) or is_registered(SLICER)):
            return []
        wanted = listed(profile, self, "scenes", self.SCENES, known=TABLE1)
        size, image, step = sizes(self, profile)
        truth_step = profile.setting(self, "truth_step_factor", 0.25)
        orbit = int(profile.setting(self, "orbit", 4))
        frames = timed_frames(profile, self)
        runs = []
        for scene_name in wanted:
            dataset, preset = TABLE1[scene_name][:2]
            scene_spec = scene(scene_name, image, volumes=[phantom(dataset, size, preset=preset)])
            views = orbit_views(dataset, orbit)
            tags = {"scene": scene_name, "dataset": dataset, "preset": preset}
            truth = truth_run(self.name, scene_name, scene_spec, views, truth_step, tags)
            runs += [truth] + method_runs(self.name, scene_name, scene_spec, views, METHODS, step, truth.id, tags,
                                          frames, together=PAPER_METHODS)
        return runs

    def paper_table(self):
        rows = [{"data set (paper)": row[2], **{f"{method_name(c)} fps": fps for c, fps in zip(PAPER_METHODS, row[3:])},
                 **{label: _paper_ratio(scene_name, *pair) for label, pair in RATIOS.items()}}
                for scene_name, row in TABLE1.items() if scene_name not in REAL_SCANS]
        return pd.DataFrame(rows).round(2).assign(device=PAPER_DEVICE)

    def report(self, results, ctx):
        ok = ok_rows(results)
        tests = role_rows(ok)
        out = [claim_takeaways(ctx, _device_takeaways(tests), _peer_takeaways(ok))]
        if not tests.empty:
            headline = tests[tests.view == "headline"]
            out += _ratio_blocks(tests, ctx) + _speed_blocks(headline, tests, ctx)
            out.append(difference_gallery(
                "Headline view: each method and its difference from the reference",
                headline.sort_values(["scene", "config"]), ctx, against=results,
                label=lambda row: f"{row.scene}, {method_name(row.config)}",
                caption="Left the method's image, right |method − reference|."))
        return out + gl_not_measurable()
