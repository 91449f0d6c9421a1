"""``kruger2003-occluder`` (E8): an opaque plane in front of the volume covering 0–100 % of its footprint."""

import pandas as pd

from core.errors import InputError
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, Run, scaled
from pipeline.experiments.kit.pages import (as_percent, claim_takeaways, figure, format_number, frames_caption,
                                            linked_table)
from pipeline.experiments.kit.planning import accepts, timed_frames
from pipeline.experiments.kit.results import fit_line, nonempty_or, numeric, ok_rows, rows_matching, stage_points
from pipeline.experiments.kit.judging import decided, r_squared, with_interval
from pipeline.experiments.kruger2003.methods import (RAYCAST, SETTINGS, SIZE_SCALES, UPLOADS, gl_not_measurable,
                                                     method_points, no_cue_control, sizes)
from pipeline.experiments.kruger2003.tables import OCCLUDER
from reports import plots

OCCLUDED = (0.0, 0.25, 0.5, 0.75, 1.0)
"""The plane's share of the footprint's bounding rectangle, swept."""

COLUMN_NAMES = {"main_ms": "main passes (ms)", "occluded_percent": "rays occluded (%)",
                "fraction": "plane's share of the footprint", "count_fragments_main": "main-pass fragments"}
"""Report names of the sweep's own columns."""


def _occluder_rows(ok):
    """Test rows of the occluder sweep with the measured occluded share and main-pass milliseconds."""
    if "fraction" not in ok:
        return pd.DataFrame()
    rows = method_points(ok[ok.fraction.notna() & (ok.get("role") == "test")])
    if rows.empty:
        return rows
    rays = numeric(rows, "count_rays")
    occluded = pd.to_numeric(rows.get("count_rays_occluded", 0.0), errors="coerce").fillna(0.0)
    rows["occluded_percent"] = 100 * occluded / rays
    return stage_points(rows, "time_main", name="main_ms").sort_values(["config", "occluded_percent"])


def _occluded_culled(df):
    rows = nonempty_or(_occluder_rows(rows_matching(df, "RC with an occluder", config="rc")),
                       "no successful RC run with an occluder")
    expected = numeric(rows, "count_passes_main") * (numeric(rows, "count_rays")
                                                     - numeric(rows, "count_rays_occluded").fillna(0))
    drawn = numeric(rows, "count_fragments_main")
    exact = bool((drawn == expected).all())
    worst = rows.loc[(drawn - expected).abs().idxmax()]
    return ClaimResult("exact at every coverage" if exact else
                       f"off by {format_number(float(abs(worst.count_fragments_main - expected[worst.name])))} "
                       f"fragments at {format_number(worst.occluded_percent)} % occluded", exact,
                       f"{len(rows)} coverages, up to {format_number(rows.occluded_percent.max())} % of the rays hidden")


def _occluder_fit(df, config):
    """R² of main-pass time against the occluded share (≥ 0.9) and the time left when all is hidden (≤ 25 %), both
    with bootstrap intervals from the frames of the coverage sweep, which is timed interleaved."""
    rows = _occluder_rows(rows_matching(df, f"{config} with an occluder", config=config))
    if len(rows) < 3:
        raise ValueError(f"fewer than three coverages of {config}")
    slope, intercept, r2 = fit_line(rows.occluded_percent, rows.main_ms)
    none, full = rows.iloc[0], rows.iloc[-1]
    if not none.main_ms > 0:
        raise ValueError(f"{config}: no main-pass time without the occluder")
    # float(): decide() on a numpy scalar gives a numpy.bool_, which combine()'s `is False` would miss.
    left = float(full.main_ms / none.main_ms)
    resampler = intervals.Resampler()
    draws = intervals.row_draws(rows, "time_main", resampler)
    fit = decided(r2, r_squared(rows.occluded_percent.to_numpy(float), draws), at_least=0.9, frames=resampler.arms())
    rest = decided(left, None if draws is None else draws[:, -1] / draws[:, 0], at_most=0.25, frames=resampler.arms())
    decision = intervals.combine([fit, rest])
    measured = (f"R² {with_interval(format_number(r2), fit, format_number)}; "
                f"{with_interval(as_percent(left), rest, as_percent)} of the main-pass time left at "
                f"{format_number(full.occluded_percent)} % occluded")
    fragments = [format_number(row.get("count_fragments_main")) for row in (none, full)]
    detail = (f"{format_number(none.main_ms)} ms → {format_number(full.main_ms)} ms (main passes, interleaved); "
              f"slope {format_number(slope)} ms per % occluded; main-pass fragments {fragments[0]} → {fragments[1]}")
    if slope < 0 and full.occluded_percent >= 99:
        return ClaimResult.decided(measured, decision, detail)
    # A sweep that does not fall, or never hides every ray, fails whatever the frames say.
    return ClaimResult(measured, False, detail + "; the time does not fall to a fully hidden volume",
                       decision.interval, decision.margin)


class Occluder(Experiment):
    """An opaque plane in front of the volume: early-z culls the rays it hides, in every main pass."""

    name = "kruger2003-occluder"
    paper = "kruger2003"
    title = "The occluder demonstration: frame time against the occluded area (E8)"
    settings = SETTINGS | {"fractions"}
    scales = scaled(base=SIZE_SCALES, smoke={"fractions": [0, 0.5, 1]})
    description = (
        "The paper motivates early-z with an opaque polygon drawn before the volume: the rays it hides are culled by "
        "the depth test, so the speed-up is “directly proportional to the area of the occluded parts of the volume” "
        "(Sec. 1; no numbers are given). Here an opaque plane covers the left part of the volume's screen footprint, "
        "from none to all of it, in front of the no-cue control seen straight at a face (no ray ends or leaves early "
        "and no block is empty, so the plane is the only thing that culls). RC shows the pure effect; RC-a adds the "
        "intermediate pass, which early-z cannot cull because it writes depth. The occluded share is measured: the "
        "plane's fragments that passed, over the rays. The coverages of each method are timed interleaved, frame "
        "against frame, and the claim reads the main passes, where early-z culls."
    )
    claims = (
        Claim("occluded-rays-culled", "Early-z drops every fragment of an occluded ray in every main pass (Sec. 1)",
              "RC: main-pass fragments = passes × (rays − occluded rays) at every coverage", _occluded_culled,
              kind="count"),
        Claim("time-proportional", "The speed-up is directly proportional to the occluded area (Sec. 1)",
              "RC main-pass time (the stage early-z culls) linear in the occluded share (R² ≥ 0.9) and ≤ 25 % "
              "of the unoccluded time when all is hidden", lambda df: _occluder_fit(df, "rc"), kind="timing"),
    )

    def runs(self, profile):
        if not accepts(RAYCAST, "variant", "occluder"):
            return []
        size, image, step = sizes(self, profile)
        fractions = [float(f) for f in profile.setting(self, "fractions", list(OCCLUDED))]
        if len(fractions) < 3 or not all(0 <= f <= 1 for f in fractions):
            raise InputError(f"profile {profile.name!r} settings.{self.name}.fractions: need at least three "
                             f"fractions in [0, 1] to fit a line, got {fractions}")
        scene_spec, views, tags = no_cue_control(size, image)
        frames = timed_frames(profile, self)
        return [Run(self.name, f"no_cue.{config}.f{fraction:g}", RAYCAST, scene_spec, views,
                    options={"variant": config, "occluder": fraction, "step_factor": step}, **frames,
                    tags={**tags, "role": "test", "config": config, "fraction": fraction}, interleave=config)
                for config in ("rc", "rc-a") for fraction in fractions]

    def paper_table(self):
        return pd.DataFrame(OCCLUDER)

    def report(self, results, ctx):
        out = [claim_takeaways(ctx)]
        rows = _occluder_rows(ok_rows(results))
        if not rows.empty:
            for y, words, name in (("main_ms", "main-pass time", "main"), ("time_ms", "frame time", "total")):
                out.append(figure(ctx, f"occluder-{name}", plots.lines, rows,
                                  heading=f"{words.capitalize()} against the occluded area",
                                  caption="Bars from the fastest to the slowest frame; no-cue control, seen straight "
                                          "at a face. " + frames_caption(rows, untimed=UPLOADS),
                                  x="occluded_percent", y=y, group="method", y_range=(f"{y}_min", f"{y}_max"),
                                  title=f"Median {words} against the occluded share of the footprint",
                                  x_label="rays hidden by the plane (% of the volume's rays)",
                                  y_label=f"median {words} (ms)"))
            out.append(linked_table("Occluder sweep", rows, ["method", "fraction", "occluded_percent", "main_ms",
                                                              "time_ms", "time_ms_min", "time_ms_max",
                                                              "count_fragments_main"], ctx,
                                    names=COLUMN_NAMES, csv_name="occluder.csv",
                                    caption="fraction: the plane's share of the footprint's bounding "
                                            "rectangle; occluded: the rays it hid, measured."))
        return out + gl_not_measurable()
