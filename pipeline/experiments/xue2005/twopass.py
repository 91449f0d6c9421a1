"""``xue2005-twopass`` (E3): Eq. 5 against the per-slice two-pass early termination it models.

α is set by the transfer function (:func:`opacity_for`) and measured from the occlusion queries. At opacity 1,
ESS+ERT joins the group: where both cull nearly everything, slice-ert's first passes draw every slice fragment
(F_s = F) while iSBVR's draw one surface (φ = (F_t + F_p) / F ≪ 1), the reason its bound is 1 / γ.
"""

import numpy as np
import pandas as pd

import datasets
from core.errors import InputError
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import (STRICTLY_ABOVE_ONE, all_of, config_rows, median_count, ratio_of_draws,
                                              ratio_pair, summed)
from pipeline.experiments.kit.model import Claim, Experiment, scaled
from pipeline.experiments.kit.pages import (as_ratio, claim_takeaways, difference_gallery, figure, format_number,
                                            frame_note, linked_table, unless_missing)
from pipeline.experiments.kit.planning import phantom, scene, timed_frames, volume_and_image_size
from pipeline.experiments.kit.results import interleave_groups, nonempty_or, numeric, ok_rows, text_column
from pipeline.experiments.kit.words import short_duration
from pipeline.experiments.xue2005 import costmodel
from pipeline.experiments.xue2005.costmodel_check import BAND, shared_views, stacked, timed_model
from pipeline.experiments.xue2005.earlyz import DATASET, EXTRA_TAPS, FILL, FRONT_VIEW, can_plan, isbvr_run
from pipeline.experiments.xue2005.methods import MODES, isbvr_not_measurable, runs_table
from pipeline.experiments.xue2005.sweeps import interval_columns
from pipeline.experiments.xue2005.tables import TWOPASS_STATEMENTS
from reports import blocks, plots

CULLING = (0.0, 0.3, 0.6, 0.9)
"""The culled fractions the constant opacities aim at (:func:`opacity_for`); α is measured, not assumed."""

THRESHOLD = 0.99
"""``opaque_threshold``: a pixel whose accumulated opacity reaches it is culled from the next slice on."""

OPAQUE = 1.0
"""The opacity of the contrast point: the first slice is opaque, so slice-ert culls all but one slice, and the
transfer function has an opaque value, so ESS+ERT has a Φ_p to cull with."""

MARGIN = 0.05
"""How far (absolute culling rate) a point's α must lie from the break-even γ / (1 − γ) for the break-even claim
to judge it: near γ ≈ 0.1 that is about 5 % of Eq. 5's δ. Fixed before any measurement; points inside the band
are shown, not judged."""

PREFIX = {"order": "front-to-back"}
"""Every run slices front to back, which ``slice-ert`` needs (the others match it)."""

CONFIGS = {
    # config: (gl-isbvr options, what it is)
    "simple": ({"zinit": "none", "shader": "simple"}, "trivial shader (T_s)"),
    "basic": (MODES["basic"][0], "Basic (T_c)"),
    "slice-ert": ({"zinit": "slice-ert", "opaque_threshold": THRESHOLD}, "per-slice two-pass ERT"),
    "ess+ert": (MODES["ess+ert"][0], "ESS+ERT (iSBVR)"),
}
"""The configurations of a point; ``ess+ert`` only at :data:`OPAQUE`."""

SCOPE = "the first passes and the volume passes (time_init + time_draw)"
"""The scope of a measured speed-up: the passes Eq. 4 prices (Basic has no first pass)."""


def opacity_for(culling, slices, *, threshold=THRESHOLD):
    """The constant per-slice opacity at which front-to-back compositing reaches ``threshold`` (the accumulated
    opacity from which slice-ert culls) so that about ``culling`` of ``slices`` slices lie behind it.

    The accumulated opacity after k slices is 1 − (1 − a)^k; it is made to reach ``threshold`` half a slice
    after (1 − ``culling``)·``slices``, so rounding cannot move the crossing by a slice: the culled fraction is
    ``culling`` − 1/``slices`` where that is positive, and 0 for ``culling`` 0.
    """
    if not 0.0 <= culling < 1.0:
        raise InputError(f"culling: expected a culled fraction in [0, 1), got {culling!r}")
    if slices <= 0:
        raise InputError(f"slices: expected a number of slices > 0, got {slices!r}")
    if not 0.0 < threshold < 1.0:
        raise InputError(f"threshold: expected an accumulated opacity in (0, 1), got {threshold!r}")
    return float(1.0 - (1.0 - threshold) ** (1.0 / ((1.0 - culling) * slices + 0.5)))


def constant_tf(opacity):
    """A ``transfer_function`` entry (scene format): ``opacity`` for every value, the phantom's preset colours."""
    table = datasets.preset(DATASET, "no_cue").transfer_function.table
    low, high = (np.round(table[i, :3].astype(float), 6).tolist() for i in (0, -1))
    return {"points": [[0.0, *low, opacity], [1.0, *high, opacity]], "name": f"constant-{opacity:.4g}"}


def point_model(group, resampler):
    """Eq. 5 and the measured speed-up of slice-ert over Basic at one (opacity, taps) point: one interleave group.

    Returns a dict: the point's tags, F, F'_c, the first passes' depth writes and α from slice-ert's counts;
    ``gamma``, ``predicted`` (Eq. 4 per view, its times summed: Eq. 5 with each view's α and γ), ``measured``
    (Basic over slice-ert, :data:`SCOPE`), ``whole`` (whole frames), ``ceiling_share`` (measured δ over
    1 / (2γ)) as ``(value, draws)`` pairs; T_s, T_c and slice-ert's first-pass time per fragment; the
    break-even α and which side of it (``"loss"``, ``"gain"`` or ``None`` inside :data:`MARGIN`) Eq. 6 puts
    the point; ESS+ERT's α', φ and speed-up where the group has it.
    """
    simple, basic, two = shared_views([config_rows(group, c) for c in ("simple", "basic", "slice-ert")],
                                      "the runs of a point")
    fragments = numeric(two, "count_fragments_generated").to_numpy(float)
    shaded = numeric(two, "count_fragments").to_numpy(float)
    if not (fragments > 0).all():
        raise ValueError(f"run {two.run.iloc[0]} counted no slice fragments (count_fragments_generated)")

    timed = timed_model(simple, basic, two, lambda t_simple, t_complex: costmodel.per_slice_time(
        fragments=fragments, shaded=shaded, t_simple=t_simple, t_complex=t_complex), resampler)
    gamma, measured = ratio_pair(timed["t_simple"], timed["t_complex"]), timed["measured"]
    alpha = costmodel.culling_rate(fragments.sum(), shaded.sum())
    break_even = float(costmodel.break_even_culling(gamma[0]))
    side = "loss" if alpha < break_even - MARGIN else "gain" if alpha > break_even + MARGIN else None
    first = two.iloc[0]
    out = {"group": str(first.interleave), "kind": str(first.kind), "opacity": float(first.opacity),
           "taps": int(float(first.extra_taps)), "views": len(two), "F": float(fragments.sum()),
           "F_c": float(shaded.sum()), "depth_writes": float(numeric(two, "count_init_fragments").sum()),
           "alpha": alpha, "gamma": gamma, "t_simple": timed["t_simple"][0], "t_complex": timed["t_complex"][0],
           "t_first": float(numeric(two, "time_init").sum() / fragments.sum()), "predicted": timed["predicted"],
           "measured": measured, "whole": timed["whole"],
           "ceiling_share": (measured[0] * 2 * gamma[0],
                             None if measured[1] is None or gamma[1] is None else measured[1] * 2 * gamma[1]),
           "break_even": break_even, "side": side, "pays_off": bool(costmodel.pays_off(alpha, gamma[0])),
           "psnr": float(numeric(two, "psnr").min()) if "psnr" in two else np.nan,
           "timing": first.get("info_timing"), "record": first.get("record"), "exr": first.get("exr")}
    if "ess+ert" in set(text_column(group, "config")):
        basic, isbvr = shared_views([basic, config_rows(group, "ess+ert")], "the runs of a point")
        generated = median_count(isbvr, "count_fragments_generated")
        out["isbvr"] = {"alpha": costmodel.culling_rate(generated, median_count(isbvr, "count_fragments")),
                        "phi": costmodel.surface_share(generated, median_count(isbvr, "count_surface_fragments_t"),
                                                       median_count(isbvr, "count_surface_fragments_p")),
                        "measured": ratio_pair(summed(basic, "time_passes", resampler),
                                               summed(isbvr, "time_passes", resampler))}
    return out


def point_models(df):
    """:func:`point_model` of every group with a slice-ert run, by extra taps and then α (one resampler)."""
    groups = nonempty_or(interleave_groups(df, config="slice-ert"), "no successful slice-ert run")
    resampler = intervals.Resampler()
    models = [point_model(df[text_column(df, "interleave") == name], resampler) for name in groups]
    return sorted(models, key=lambda m: (m["taps"], m["alpha"]))


def _label(m):
    return f"α {format_number(m['alpha'])}, {m['taps']} taps"


def _counts(m):
    """α with the counts it comes from (occlusion queries: the same on any device)."""
    return f"α {format_number(m['alpha'])} = 1 − {format_number(m['F_c'])}/{format_number(m['F'])}"


def _break_even(df):
    models = point_models(df)
    sides = {side: [m for m in models if m["side"] == side] for side in ("loss", "gain")}
    for side, found in sides.items():
        if not found:
            raise ValueError(f"no point where Eq. 6 predicts a {side} by more than {MARGIN:g} in α (α against "
                             "break-even: " + ", ".join(f"{format_number(m['alpha'])} against "
                                                        f"{format_number(m['break_even'])}" for m in models) + ")")
    decisions = {_label(m): intervals.decide(m["measured"][0], intervals.interval_of(m["measured"][1]),
                                             **({"at_most": 1.0} if side == "loss" else
                                                {"at_least": STRICTLY_ABOVE_ONE}))
                 for side, found in sides.items() for m in found}
    notes = {_label(m): f"{_counts(m)}; Eq. 6 predicts a {m['side']}: break-even α {format_number(m['break_even'])} "
                        f"at γ {format_number(m['gamma'][0])}" for side in sides.values() for m in side}
    skipped = [_label(m) for m in models if m["side"] is None]
    return all_of(decisions, notes=notes, what="Basic / slice-ert ",
                  extra=(f"within ±{MARGIN:g} of the break-even, not judged: {', '.join(skipped)}; " if skipped else "")
                  + f"over {SCOPE}, interleaved")


def _below_ceiling(df):
    models = point_models(df)
    decisions = {_label(m): intervals.decide(m["ceiling_share"][0], intervals.interval_of(m["ceiling_share"][1]),
                                             at_most=1.0) for m in models}
    notes = {_label(m): f"δ ×{format_number(m['measured'][0])}, 1/(2γ) ×{format_number(0.5 / m['gamma'][0])}"
             for m in models}
    return all_of(decisions, notes=notes, what="measured δ / 1/(2γ) ", extra=f"δ over {SCOPE}, interleaved")


def _eq5_within(df):
    models = point_models(df)
    decisions = {_label(m): ratio_of_draws(m["predicted"], m["measured"], at_least=1 - BAND, at_most=1 + BAND)
                 for m in models}
    notes = {_label(m): f"Eq. 5 ×{format_number(m['predicted'][0])}, measured ×{format_number(m['measured'][0])}; "
                        f"{_counts(m)}, γ {format_number(m['gamma'][0])}" for m in models}
    return all_of(decisions, notes=notes, what="predicted / measured ",
                  extra=f"measured over {SCOPE}; Eq. 5 from slice-ert's counts and T_s, T_c timed with it")


CLAIMS = (
    Claim("break-even", "Per-slice two-pass rendering pays off only above the culling rate γ / (1 − γ) (Eq. 6, "
          "judged at the γ measured here; the paper's example: γ = 0.2 needs α > 25 %)",
          f"Basic / slice-ert time ≤ 1 where α < γ / (1 − γ) − {MARGIN:g}, > 1 where α > γ / (1 − γ) + {MARGIN:g}, "
          f"each point with γ measured with it (over {SCOPE}; points within ±{MARGIN:g} not judged; needs both)",
          _break_even, paper_value="α > 25 % at γ = 0.2", kind="cost model"),
    Claim("below-ceiling", "Per-slice two-pass rendering gains at most 1 / (2γ) (Eq. 5 as α → 1)",
          f"measured Basic / slice-ert time × 2γ ≤ 1 at every point (over {SCOPE})", _below_ceiling, kind="cost model"),
    Claim("eq5-within-20", "Eq. 5 predicts the per-slice two-pass speed-up from the culled fraction and the shader "
          "ratio within 20 % (issue 23's target for the cost model)",
          f"Eq. 5 δ / measured δ within ×{format_number(1 - BAND)}–×{format_number(1 + BAND)} at every point "
          f"(measured over {SCOPE})", _eq5_within, kind="cost model"))


def _table(models):
    return pd.DataFrame([
        {"point": m["group"], "extra taps": m["taps"], "opacity": m["opacity"], "F": m["F"], "F'_c": m["F_c"],
         "α": m["alpha"], "depth writes": m["depth_writes"], "T_s (ns)": 1e9 * m["t_simple"],
         "T_c (ns)": 1e9 * m["t_complex"], "first pass (ns / F)": 1e9 * m["t_first"],
         **interval_columns("γ", m["gamma"], value="γ"), "break-even α": m["break_even"],
         "Eq. 6": "gain" if m["pays_off"] else "loss", "judged as": m["side"] or "within margin",
         **interval_columns("Eq. 5", m["predicted"]), **interval_columns("measured", m["measured"]),
         "Eq. 5 / measured": m["predicted"][0] / m["measured"][0], "1/(2γ)": 0.5 / m["gamma"][0],
         "measured / 1/(2γ)": m["ceiling_share"][0], "whole frames δ": m["whole"][0],
         "PSNR vs Basic (dB)": m["psnr"], "record": m["record"], "exr": m["exr"]} for m in models])


def _takeaways(models):
    by_taps = {k: [m for m in models if m["taps"] == k] for k in dict.fromkeys(m["taps"] for m in models)}
    out = [f"The opacities set α = 1 − F'_c / F (occlusion queries, the same on any device) from "
           f"{format_number(min(m['alpha'] for m in models))} to {format_number(max(m['alpha'] for m in models))}; "
           "γ = T_s / T_c and the break-even α it gives: "
           + ", ".join(f"{k} taps γ {format_number(np.median([m['gamma'][0] for m in ms]))} (break-even α "
                       f"{format_number(np.median([m['break_even'] for m in ms]))}, ceiling "
                       f"×{format_number(np.median([0.5 / m['gamma'][0] for m in ms]))})" for k, ms in by_taps.items())
           + "."]
    crossings = []
    for k, ms in by_taps.items():
        losing = [m["alpha"] for m in ms if m["measured"][0] <= 1.0]
        winning = [m["alpha"] for m in ms if m["measured"][0] > 1.0]
        where = (f"loses up to α {format_number(max(losing))} and wins from α {format_number(min(winning))}"
                 if losing and winning else f"wins at every α measured (from {format_number(min(winning))})"
                 if winning else f"loses at every α measured (up to {format_number(max(losing))})")
        crossings.append(f"{k} taps: {where}, Eq. 6's break-even α "
                         f"{format_number(np.median([m['break_even'] for m in ms]))}")
    out.append("Measured over the passes, slice-ert against Basic: " + "; ".join(crossings) + ".")
    first = np.median([m["t_first"] for m in models])
    simple = np.median([m["t_simple"] for m in models])
    waits = any(m["timing"] == "finish" for m in models)
    out.append(f"slice-ert's first passes cost {short_duration(first)} per slice fragment against T_s "
               f"{short_duration(simple)} (medians over the points): Eq. 3 prices them F·T_s; the rest is per-slice "
               "work the model leaves out, the copy of the accumulated image each first pass reads"
               + (" and the wait that ends each of the two timed passes per slice (timing 'finish': this device's "
                  "pass times are wall clock to the pass's end)" if waits else "") + ".")
    contrast = [m for m in models if "isbvr" in m]
    for m in contrast:
        isbvr, gamma = m["isbvr"], m["gamma"][0]
        out.append(f"At opacity {format_number(m['opacity'])} ({m['taps']} taps) slice-ert culls α "
                   f"{format_number(m['alpha'])} but its first passes draw every slice fragment (F_s = F, φ = 1): "
                   f"×{format_number(m['measured'][0])} against its ceiling 1/(2γ) = ×{format_number(0.5 / gamma)}; "
                   f"ESS+ERT culls α' {format_number(isbvr['alpha'])} with φ = (F_t + F_p) / F = "
                   f"{format_number(isbvr['phi'])}: ×{format_number(isbvr['measured'][0])} against its ceiling "
                   f"1/γ = ×{format_number(1 / gamma)} (γ {format_number(gamma)}).")
    swept = [m["alpha"] for m in models if m["kind"] == "sweep"]
    if swept:
        out.append("Below opacity 1 these transfer functions have neither a transparent nor an opaque value, so "
                   "ESS+ERT has no surface to draw and culls nothing (xue2005-tf's controls measure that), where "
                   f"slice-ert, terminating on accumulated opacity, culls up to α {format_number(max(swept))}.")
    return out


def _chart(table, ctx):
    gammas = table.groupby("extra taps")["γ"].median()
    series = [f"{k} taps (γ {format_number(gammas[k])})" for k in table["extra taps"]]
    long = stacked(table, [([f"{name}, {s}" for s in series], name) for name in ("measured", "Eq. 5")])
    ratios = table["Eq. 5 / measured"]
    return figure(ctx, "speedup", plots.lines, long, x="α", y="value", group="series", y_range=("low", "high"),
                  heading="Measured and predicted speed-up against the culled fraction",
                  caption="One series per shader complexity (γ = T_s / T_c measured at every point; the median in the "
                          "legend). Bars: 95 % bootstrap intervals from the interleaved frames (Eq. 5's from those of "
                          "T_s and T_c). Dotted: the break-even α = γ / (1 − γ) of each complexity's median γ "
                          "(Eq. 6); grey: δ = 1.",
                  vlines=sorted({float(costmodel.break_even_culling(g)) for g in gammas}),
                  guides=[("δ = 1: break-even", (0.0, 1.0), (1.0, 1.0))],
                  title=f"Eq. 5 / measured {as_ratio(ratios.min())}–{format_number(ratios.max())} "
                        f"(target ×{format_number(1 - BAND)}–×{format_number(1 + BAND)})",
                  x_label="culled fraction α = 1 − F'_c / F (share of slice fragments)",
                  y_label="speed-up of slice-ert over Basic (×, first + volume passes)")


def _contrast_table(models):
    rows = []
    for m in (m for m in models if "isbvr" in m):
        gamma, isbvr = m["gamma"][0], m["isbvr"]
        rows += [{"extra taps": m["taps"], "method": "per-slice two-pass (slice-ert)", "α": m["alpha"], "φ": 1.0,
                  "measured δ": m["measured"][0], "ceiling": 0.5 / gamma, "ceiling's form": "1/(2γ)"},
                 {"extra taps": m["taps"], "method": "ESS+ERT (iSBVR)", "α": isbvr["alpha"], "φ": isbvr["phi"],
                  "measured δ": isbvr["measured"][0], "ceiling": 1 / gamma, "ceiling's form": "1/γ"}]
    return pd.DataFrame(rows)


def _gallery(ok, results, ctx):
    """Basic once and slice-ert at each opacity (fewest extra taps), with its difference from Basic."""
    taps = numeric(ok, "extra_taps")
    rows = ok[(taps == taps.min()) & ok.config.isin(("basic", "slice-ert"))].assign(opacity=numeric(ok, "opacity"))
    basic = rows[rows.config == "basic"].sort_values("opacity").head(1)
    return difference_gallery(
        "slice-ert at each opacity and its difference from Basic",
        pd.concat([basic, rows[rows.config == "slice-ert"].sort_values("opacity")]), ctx, against=results,
        caption=f"Right of each slice-ert image: |slice-ert − Basic|; its error is at most 1 − opaque_threshold = "
                f"{format_number(1 - THRESHOLD)} where a pixel is cut.",
        label=lambda row: f"opacity {format_number(row.opacity)}, {CONFIGS[row.config][1]}",
        note=lambda row: frame_note(row, psnr="PSNR vs Basic"))


RUN_COLUMNS = {"interleave": "point", "config": "configuration", "extra_taps": "extra taps", "opacity": "opacity",
               "init_ms": "first passes (ms)", "draw_ms": "volume passes (ms)", "time_ms": "whole frame (ms)",
               "count_fragments_generated": "F", "count_fragments": "F'_c", "count_init_fragments": "depth writes",
               "count_surface_fragments_t": "F_t", "count_surface_fragments_p": "F_p"}


class TwoPass(Experiment):
    """Eq. 5 against the per-slice two-pass early termination it models, over controlled α and swept γ."""

    name = "xue2005-twopass"
    paper = "xue2005"
    title = "Eq. 5 against per-slice two-pass early termination: break-even and ceiling (E3)"
    settings = frozenset({"volume_size", "image_size", "culling", "extra_taps", "opaque", "repeat"})
    scales = scaled(smoke={"culling": [0.0, 0.9], "extra_taps": [0]},
                    full={"culling": [0.0, 0.1, 0.25, 0.5, 0.75, 0.9], "repeat": 5})
    description = (
        "The paper's cost model starts from a generic two-pass slicer (§2): each slice drawn twice, a simple "
        "shader writing depth where the opacity buffer is already opaque, then the complex shader culled there "
        "by early z. Its speed-up over one pass is Eq. 5, δ = 1 / (αγ + 1 − α + γ), with the culled fraction "
        "α and the shader ratio γ = T_s / T_c; it pays off only above α = γ / (1 − γ) (Eq. 6: γ = 0.2 needs "
        "25 %) and never beats 1 / (2γ), which is why iSBVR replaces the per-slice pass with a few surface "
        "fragments. gl-isbvr's slice-ert is that renderer (opaque_threshold 0.99, front to back). Here the "
        "smooth-noise phantom, seen straight at a face and filling the picture, gets constant opacities chosen "
        "so that the threshold is reached after a known share of the slices; α is measured from occlusion "
        "queries (1 − F'_c / F), γ at every point from the trivial shader's and Basic's draw time over F, with "
        "0, 4 and 16 extra texture taps in the volume shader. The trivial shader, Basic and slice-ert of one "
        "(opacity, taps) point are timed interleaved in one job; the speed-up is over the first and volume "
        "passes, whole frames beside it. At opacity 1, ESS+ERT joins each group for iSBVR's φ.")
    claims = CLAIMS

    def runs(self, profile):
        if not can_plan("opaque_threshold"):
            return []
        size, image = map(int, volume_and_image_size(profile, self))
        where = f"profile {profile.name!r} settings.{self.name}"
        culling = [float(c) for c in profile.setting(self, "culling", list(CULLING))]
        if not culling or not all(0.0 <= c < 1.0 for c in culling) or len(set(culling)) < len(culling):
            raise InputError(f"{where}.culling: expected distinct culled fractions in [0, 1), got {culling}")
        taps = [int(k) for k in profile.setting(self, "extra_taps", list(EXTRA_TAPS))]
        if not taps or min(taps) < 0 or len(set(taps)) < len(taps):
            raise InputError(f"{where}.extra_taps: expected distinct counts >= 0, got {taps}")
        opaque = profile.setting(self, "opaque", True)
        if not isinstance(opaque, bool):
            raise InputError(f"{where}.opaque: expected true or false (the opacity-1 point with ESS+ERT), got "
                             f"{opaque!r}")
        frames = timed_frames(profile, self)
        # Straight at a face, slices one voxel apart: every ray crosses ``size`` slices.
        points = [(f"a{100 * c:g}", "sweep", round(opacity_for(c, size), 6)) for c in culling]
        points += [("opaque", "opaque", OPAQUE)] if opaque else []
        runs = []
        for k in taps:
            for label, kind, opacity in points:
                spec = scene(DATASET, image, volumes=[phantom(DATASET, size, transfer_function=constant_tf(opacity))],
                             camera={"projection": "orthographic", "view_height": FILL * size})
                group = f"{label}.t{k}"
                tags = {"scene": DATASET, "dataset": DATASET, "kind": kind, "opacity": opacity, "extra_taps": k}
                configs = ("simple", "basic", "slice-ert") + (("ess+ert",) if kind == "opaque" else ())
                for config in configs:
                    options = {**PREFIX, **CONFIGS[config][0], **({"extra_taps": k} if config != "simple" else {})}
                    runs.append(isbvr_run(self.name, f"{group}.{config}", spec, (FRONT_VIEW,), options, frames,
                                          {**tags, "config": config}, group=group,
                                          reference=None if config in ("simple", "basic") else f"{group}.basic"))
        return runs

    def paper_table(self):
        return pd.DataFrame(TWOPASS_STATEMENTS)

    def report(self, results, ctx):
        ok = ok_rows(results)
        models = unless_missing(point_models, ok, empty=[])
        out = [claim_takeaways(ctx, _takeaways(models) if models else [])]
        if models:
            table = _table(models)
            out.append(_chart(table, ctx))
            out.append(linked_table("Every point: counts, γ, Eq. 5 and the measured speed-up", table,
                                    list(table.columns.drop(["record", "exr"])), ctx, csv_name="twopass.csv",
                                    caption=f"Counts from slice-ert's occlusion queries (depth writes: its first "
                                            f"passes' fragments that wrote depth); T_s and T_c: the trivial shader's "
                                            f"and Basic's draw time over F; first pass: slice-ert's first passes "
                                            f"(with the image copies) over F. δ: Basic over slice-ert, {SCOPE}, with "
                                            f"95 % intervals (low, high); judged as: the side of Eq. 6's break-even "
                                            f"the break-even claim judges, ±{MARGIN:g} in α left out. Links: the "
                                            f"slice-ert run."))
            contrast = _contrast_table(models)
            if not contrast.empty:
                out.append(blocks.Table("At opacity 1: per-slice two-pass against iSBVR", contrast,
                                        caption="φ: the first or init passes' fragments over F (slice-ert's first "
                                                "passes draw every slice fragment); δ over Basic, each method's "
                                                "passes; ceilings from the point's γ."))
            out.append(_gallery(ok, results, ctx))
        if not ok.empty:
            out.append(runs_table(ok, ctx, RUN_COLUMNS))
        return out + isbvr_not_measurable("count_fragments", "opaque_threshold")
