"""``kruger2003-stability``: where the accelerations break: the early-termination threshold and the block size."""

import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, Run, scaled
from pipeline.experiments.kit.pages import change_words, claim_takeaways, figure, format_number, linked_table
from pipeline.experiments.kit.planning import accepts, headline_view, phantom, scene, timed_frames, truth_run
from pipeline.experiments.kit.results import (nonempty_or, numeric, ok_rows, role_rows, rows_matching, speed_points,
                                              stage_time, tagged, text_column)
from pipeline.experiments.kit.judging import STRICTLY_ABOVE_ONE, decision_words, median_count
from pipeline.experiments.kruger2003.methods import RAYCAST, SETTINGS, SIZE_SCALES, gl_not_measurable, sizes
from pipeline.experiments.kruger2003.tables import TABLE1
from reports import plots

THRESHOLDS = (0.8, 0.9, 0.95, 0.99, 1.0)
"""Early-termination thresholds T swept (the paper leaves T unspecified; 1 never ends a ray early)."""

BLOCK_SIZES = (4, 8, 16, 32)
"""Block edges of the empty-space grid swept (the paper's 8 among them)."""

SCENES = ("head", "aneurysm")
"""The opaque head and the sparse aneurysm (scenes of Table 1)."""

SWEEPS = (("threshold", "the early-termination threshold", "early-termination threshold T (fraction of full opacity)"),
          ("block", "the block size", "block edge of the min–max grid (voxels)"))
"""Each sweep's tag, its name in titles and its axis label."""


def _sweep_rows(df, sweep, scene_name):
    rows = rows_matching(df, f"the {sweep} sweep on {scene_name}", sweep=sweep, scene=scene_name)
    if len(rows) < 2:
        raise ValueError(f"fewer than two settings of the {sweep} sweep on {scene_name}")
    return rows.assign(setting=numeric(rows, "value"), psnr=numeric(rows, "psnr")).sort_values("setting")


def _threshold(df):
    """Time at T = 1 over time at the lowest T (> 1, with its interval) and the PSNR at the lowest T the lower."""
    rows = _sweep_rows(df, "threshold", "head")
    low, high = (rows[rows.setting == rows.setting.iloc[end]] for end in (0, -1))
    decision = intervals.ratio_decision(high, low, at_least=STRICTLY_ABOVE_ONE)
    low_psnr, high_psnr = float(low.psnr.iloc[0]), float(high.psnr.iloc[0])
    low_t, high_t = format_number(low.setting.iloc[0]), format_number(high.setting.iloc[0])
    measured = (f"T {low_t} {change_words(1 / decision.value)} than T {high_t} (time at T {high_t} / at T {low_t} "
                f"{decision_words(decision)}); {format_number(low_psnr)} dB against {format_number(high_psnr)} dB")
    detail = (f"RC-b on the head, whole frames interleaved: {format_number(stage_time(low.iloc[0]) * 1e3)} ms and "
              f"{format_number(stage_time(high.iloc[0]) * 1e3)} ms; samples {format_number(median_count(low, 'count_samples'))} and "
              f"{format_number(median_count(high, 'count_samples'))}")
    if low_psnr < high_psnr:
        return ClaimResult.decided(measured, decision, detail)
    # The accuracy half fails whatever the frames say: no interval can rescue it.
    return ClaimResult(measured, False, detail + "; the lower threshold is not less accurate", decision.interval,
                       decision.margin)


def _blocks_lossless(df):
    spreads = {scene_name: _sweep_rows(df, "block", scene_name).psnr.pipe(lambda psnr: float(psnr.max() - psnr.min()))
               for scene_name in pd.unique(text_column(rows_matching(df, "the block sweep", sweep="block"), "scene"))}
    worst = max(nonempty_or(spreads, "no block sweep"), key=spreads.get)
    return ClaimResult(f"{format_number(spreads[worst])} dB ({worst})", bool(spreads[worst] <= 0.1),
                       ", ".join(f"{s}: {format_number(v)} dB" for s, v in spreads.items()))


def _sweep_blocks(rows, sweep, words, label, ctx):
    """Time and PSNR against one sweep's setting, as figures and a linked table."""
    rows = speed_points(rows).assign(setting=numeric(rows, "value"))
    out = [figure(ctx, f"stability-{sweep}-{name}", plots.lines, rows, heading=f"{sweep.capitalize()} sweep: {name}",
                  caption="RC-b, headline view.", x="setting", y=y, group="scene", y_range=y_range,
                  title=f"{what} against {words}", x_label=label, y_label=y_label, log_x=sweep == "block")
           for y, y_label, y_range, name, what in (
               ("time_ms", "median frame time (ms)", ("time_ms_min", "time_ms_max"), "time", "Median frame time"),
               ("psnr", "PSNR against the reference (dB)", None, "psnr", "PSNR"))]
    out.append(linked_table(f"{sweep.capitalize()} sweep", rows.rename(columns={"setting": label}),
                            ["scene", label, "time_ms", "time_ms_min", "time_ms_max", "psnr"], ctx,
                            csv_name=f"stability_{sweep}.csv"))
    return out


class Stability(Experiment):
    """Where the accelerations break: the early-termination threshold and the empty-space block size."""

    name = "kruger2003-stability"
    paper = "kruger2003"
    title = "Stability: the early-termination threshold and the block size of empty-space skipping"
    settings = SETTINGS | {"thresholds", "block_sizes"}
    scales = scaled(base=SIZE_SCALES, smoke={"thresholds": [0.9, 1.0], "block_sizes": [8, 16]})
    description = (
        "The paper leaves the threshold T unspecified and fixes 8³ blocks. A lower T ends rays sooner and drops up to "
        "1 − T of their light; a threshold of 1 never ends a ray early. The block size trades a finer empty-space map "
        "(more skipped segments) against a larger grid and more tests; skipping is conservative, so it must never "
        "change the image. Both are swept with RC-b on the opaque head and on the sparse aneurysm, speed and error "
        "against the reference; the settings of each sweep are timed interleaved, frame against frame."
    )
    claims = (
        Claim("threshold-trades-error", "A lower threshold is faster and less accurate", "on the head: time at T = 1 "
              "/ time at the lowest T > 1 (whole frames), and PSNR at the lowest T < PSNR at T = 1", _threshold,
              kind="timing"),
        Claim("blocks-lossless", "Empty-space skipping never changes the image, whatever the block size",
              "PSNR spread over block sizes ≤ 0.1 dB (each scene)", _blocks_lossless, kind="accuracy"),
    )

    def runs(self, profile):
        if not accepts(RAYCAST, "opaque_threshold", "block_size"):
            return []
        size, image, step = sizes(self, profile)
        frames = timed_frames(profile, self)
        # (sweep, option, its type, values): a run id is the sweep's initial and the value (head.t0.9, head.b8)
        sweeps = (("threshold", "opaque_threshold", float, profile.setting(self, "thresholds", list(THRESHOLDS))),
                  ("block", "block_size", int, profile.setting(self, "block_sizes", list(BLOCK_SIZES))))
        runs = []
        for scene_name in SCENES:
            dataset, preset = TABLE1[scene_name][:2]
            scene_spec = scene(scene_name, image, volumes=[phantom(dataset, size, preset=preset)])
            view = (headline_view(dataset),)
            tags = {"scene": scene_name, "dataset": dataset}
            truth = truth_run(self.name, scene_name, scene_spec, view, 0.25, tags)
            runs += [truth] + [Run(self.name, f"{scene_name}.{sweep[0]}{value:g}", RAYCAST, scene_spec, view,
                                   options={"variant": "rc-b", option: value, "step_factor": step},
                                   reference=truth.id, **frames, interleave=f"{scene_name}.{sweep}",
                                   tags={**tags, "role": "test", "config": "rc-b", "sweep": sweep, "value": value})
                               for sweep, option, cast, values in sweeps for value in map(cast, values)]
        return runs

    def report(self, results, ctx):
        out = [claim_takeaways(ctx)]
        tests = role_rows(ok_rows(results))
        for sweep, words, label in SWEEPS:
            rows = tagged(tests, sweep=sweep)
            out += _sweep_blocks(rows, sweep, words, label, ctx) if not rows.empty else []
        return out + gl_not_measurable()
