"""``xue2005-fuzziness`` (E11): the golden-lady stand-in's haze grows, and iSBVR's gains shrink.

The haze is the phantom's ``haze`` parameter (:func:`datasets.phantoms.clouds.golden_lady`).
"""

import pandas as pd

from core.errors import InputError
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import (STRICTLY_ABOVE_ONE, all_of, config_rows, median_count, ratio_of_draws,
                                              speedup)
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, scaled
from pipeline.experiments.kit.pages import (as_percent, as_ratio, claim_takeaways, difference_gallery, figure,
                                            format_number, frame_note, linked_table, unless_missing)
from pipeline.experiments.kit.planning import headline_view, phantom, scene, timed_frames, volume_and_image_size
from pipeline.experiments.kit.results import numeric, ok_rows, tagged
from pipeline.experiments.xue2005.methods import culled_fraction, isbvr_not_measurable, mode_name, mode_runs, short_name
from pipeline.experiments.xue2005.sweeps import SCOPE, speedups
from pipeline.experiments.xue2005.tables import PAPER_DEVICE, TABLE1, paper_speedup
from reports import plots

SCENE = "golden_lady"

HAZES = (0.0, 0.5, 1.0, 1.5)
"""The haze swept (0: the figure alone; 1: the registry's golden lady, the paper's row; 1.5: nearly the whole box)."""

PAPER_HAZE = 1.0
"""The haze of the data set as registered: the stand-in for the paper's golden lady."""

CONFIGS = ("basic", "ess", "ert", "ess+ert")
"""Table 1's modes, each haze's interleave group."""

GAINS = ("ess", "ert", "ess+ert")


def _groups(df):
    """``[(haze, rows)]`` of the sweep, by increasing haze; ValueError with fewer than two hazes."""
    hazes = numeric(df, "haze")
    values = sorted(hazes.dropna().unique())
    if len(values) < 2:
        raise ValueError("fewer than two haze values ran")
    return [(float(h), df[hazes == h]) for h in values]


def _alpha(rows, config="ess+ert"):
    return culled_fraction(config_rows(rows, config, what=f"haze {rows.haze.iloc[0]:g}"))


def _speedup_falls(df):
    """ESS+ERT / Basic speed-up at each haze over the next: strictly above 1 at every step."""
    groups = _groups(df)
    resampler = intervals.Resampler()
    speeds = [(haze, speedup(rows, "basic", "ess+ert", resampler=resampler)) for haze, rows in groups]
    decisions = {f"haze {a:g} / {b:g}": ratio_of_draws(sa, sb, at_least=STRICTLY_ABOVE_ONE)
                 for (a, sa), (b, sb) in zip(speeds, speeds[1:])}
    trend = ", ".join(f"{h:g}: {as_ratio(s[0])}" for h, s in speeds)
    return all_of(decisions, what="speed-up over the next haze's ",
                  extra=f"ESS+ERT / Basic by haze {trend} ({SCOPE}; each haze's modes interleaved)")


def _culled_falls(df):
    groups = _groups(df)
    alphas = [(haze, _alpha(rows)) for haze, rows in groups]
    falls = all(b < a for (_, a), (_, b) in zip(alphas, alphas[1:]))
    trend = " → ".join(as_percent(a) for _, a in alphas)
    return ClaimResult(f"α' {trend} (haze {alphas[0][0]:g} → {alphas[-1][0]:g})", falls,
                       "ESS+ERT's culled fraction (F − F'_c)/F from occlusion queries; cubes Φ_t "
                       + " → ".join(format_number(median_count(config_rows(rows, "ess+ert"), "count_cubes_t"))
                                    for _, rows in groups))


def _gains_fall(df):
    """ESS / Basic and ERT / Basic each lower at the largest haze than at the smallest."""
    groups = _groups(df)
    resampler = intervals.Resampler()
    (low, first), (high, last) = groups[0], groups[-1]
    decisions, notes = {}, []
    for config in ("ess", "ert"):
        ends = [speedup(rows, "basic", config, resampler=resampler) for rows in (first, last)]
        decisions[short_name(config)] = ratio_of_draws(*ends, at_least=STRICTLY_ABOVE_ONE)
        notes.append(f"{config.upper()} {as_ratio(ends[0][0])} → {as_ratio(ends[1][0])}, α' "
                     f"{as_percent(_alpha(first, config))} → {as_percent(_alpha(last, config))}")
    return all_of(decisions, what=f"speed-up at haze {low:g} over haze {high:g} ",
                  extra="; ".join(notes) + f" ({SCOPE})")


CLAIMS = (
    Claim("speedup-falls", "The fuzzier the data, the less iSBVR gains (the golden lady gains least, Table 1)",
          f"ESS+ERT / Basic speed-up strictly falls from each haze to the next: its ratio to the next haze's > 1 "
          f"({SCOPE})", _speedup_falls, kind="timing"),
    Claim("culled-falls", "The haze leaves less to cull", "ESS+ERT's culled fraction α' = (F − F'_c)/F strictly "
          "falls from each haze to the next (occlusion-query counts)", _culled_falls, kind="count"),
    Claim("gains-fall-separately", "Both accelerations lose to the haze (note 001 E11: \"ESS and ERT gains fall as "
          "the fuzzy volume grows\")", f"ESS / Basic and ERT / Basic each lower at the largest haze than at the "
          f"smallest: ratio > 1 ({SCOPE})", _gains_fall, kind="timing"))


def summary(ok):
    """One row per haze and mode: speed-up over Basic with its interval, α', cubes, fragments, PSNR vs Basic
    (:func:`~.sweeps.speedups`), and the paper's ratio at the registered haze."""
    return pd.DataFrame([{"haze": haze, "config": config, "mode": mode_name(config), **row,
                          "paper": as_ratio(paper_speedup(SCENE, config)) if haze == PAPER_HAZE else ""}
                         for haze, config, _rows, row in speedups(_groups(ok), GAINS)])


COLUMNS = {"haze": "haze", "mode": "mode", "speedup": "speed-up over Basic (×)", "low": "95 % CI low",
           "high": "95 % CI high", "paper": "paper (Table 1, golden lady)", "alpha": "α' culled",
           "phi": "φ = (F_t + F_p) / F", "F": "F (slice fragments)", "F_c": "F'_c (shaded)", "cubes_t": "Φ_t cubes",
           "cubes_p": "Φ_p cubes", "psnr": "PSNR vs Basic (dB)"}


def _figure(table, ctx):
    both = table[table.config == "ess+ert"].sort_values("haze")
    span = " → ".join(as_ratio(v) for v in both.speedup.iloc[[0, -1]]) if not both.empty else ""
    ends = [table.haze.min(), table.haze.max()]
    guides = [(f"paper {short_name(c)} {as_ratio(paper_speedup(SCENE, c))} (golden lady)", ends,
               [paper_speedup(SCENE, c)] * 2) for c in GAINS]
    return figure(ctx, "speedup-haze", plots.lines, table.assign(mode=[short_name(c) for c in table.config]),
                  heading="Speed-ups against the haze",
                  caption="Each point: Basic over the mode's whole-frame time, the four modes of a haze timed "
                          "interleaved; bars: 95 % bootstrap interval from the frames. Grey: the paper's golden-lady "
                          f"ratios ({PAPER_DEVICE}); dotted: the registered haze.",
                  x="haze", y="speedup", group="mode", y_range=("low", "high"),
                  title=f"ESS+ERT speed-up vs haze: {span}",
                  x_label="haze (extent of the fuzzy region, 0 = none, 1 = the registered golden lady)",
                  y_label="speed-up, Basic / mode time (×)", vlines=(PAPER_HAZE,), guides=guides)


def _gallery(ok, results, ctx):
    """Basic and ESS+ERT per haze (headline view), ESS+ERT's difference from Basic on the one scale."""
    rows = ok[(ok.view == "headline") & ok.config.isin(("basic", "ess+ert"))].assign(haze=numeric(ok, "haze"))
    return difference_gallery(
        "Headline view per haze: Basic, and ESS+ERT with its difference from Basic",
        rows.sort_values(["haze", "config"]), ctx, against=results, caption="Right of ESS+ERT: |ESS+ERT − Basic|.",
        label=lambda row: f"haze {row.haze:g}, {mode_name(row.config)}",
        note=lambda row: frame_note(row, psnr="PSNR vs Basic"))


class Fuzziness(Experiment):
    """E11: the golden lady's haze against iSBVR's gains."""

    name = "xue2005-fuzziness"
    paper = "xue2005"
    title = "The golden lady's haze against iSBVR's gains (E11)"
    settings = frozenset({"hazes", "volume_size", "image_size", "repeat"})
    scales = scaled(smoke={"hazes": [0, 1.5]})
    description = (
        "The paper's golden lady, with its \"large fuzzy area\", gains least of its four data sets (Table 1: ESS "
        "1.95×, ERT 1.18×, ESS+ERT 2.23×): a haze just above iso_t fills the Φ_t envelope, so few rays are empty "
        "and the exit from Φ_t lies far back. Here the stand-in's haze grows from none (the figure alone) through "
        "the registered golden lady (haze 1) to nearly the whole box, under the paper's ramp (iso_t 30, iso_p "
        "190). The four modes of every haze are timed interleaved, frame against frame, so one haze's speed-up is "
        "compared with another's from the same processes; the culled fraction α' = "
        "(F − F'_c)/F comes from occlusion queries and is the same on every machine.")
    claims = CLAIMS

    def runs(self, profile):
        hazes = [float(h) for h in profile.setting(self, "hazes", list(HAZES))]
        if len(hazes) < 2 or hazes != sorted(set(hazes)) or not all(0 <= h <= 3 for h in hazes):
            raise InputError(f"profile {profile.name!r} settings.{self.name}.hazes: need at least two increasing "
                             f"values in [0, 3] (golden_lady's haze), got {hazes}")
        size, image = volume_and_image_size(profile, self)
        frames = timed_frames(profile, self)
        dataset, preset = TABLE1[SCENE][:2]
        views = (headline_view(dataset),)
        runs = []
        for haze in hazes:
            prefix = f"{SCENE}.h{haze:g}"
            spec = scene(SCENE, image, volumes=[phantom(dataset, size, preset=preset, params={"haze": haze})])
            tags = {"scene": SCENE, "dataset": dataset, "preset": preset, "haze": haze}
            runs += mode_runs(self.name, prefix, spec, views, ("basic",), frames, tags, group=SCENE)
            runs += mode_runs(self.name, prefix, spec, views, CONFIGS[1:], frames, tags, group=SCENE,
                              reference=f"{prefix}.basic")
        return runs

    def paper_table(self):
        _d, _p, row, *fps = TABLE1[SCENE]
        return pd.DataFrame([{"data set (paper)": row, "mode": mode_name(c), "fps": f, "speed-up over Basic":
                              round(paper_speedup(SCENE, c), 2), "device": PAPER_DEVICE}
                             for c, f in zip(CONFIGS, fps)])

    def report(self, results, ctx):
        ok = ok_rows(results)
        out = [claim_takeaways(ctx)]
        table = unless_missing(summary, tagged(ok, scene=SCENE), empty=pd.DataFrame())
        if not table.empty:
            out.append(_figure(table, ctx))
            out.append(linked_table("Speed-ups and culled fractions per haze", table, list(COLUMNS), ctx,
                                    names=COLUMNS, csv_name="fuzziness.csv",
                                    caption="Speed-up: Basic over the mode's whole-frame time, its 95 % bootstrap "
                                            "interval from the interleaved frames. α' and φ from the mode's occlusion "
                                            "queries; cubes of Φ_t at 8³ and Φ_p at 2³ voxels. Paper: its golden "
                                            "lady, beside the registered haze."))
            out.append(_gallery(ok[numeric(ok, "haze").notna()], results, ctx))
        return out + isbvr_not_measurable()
