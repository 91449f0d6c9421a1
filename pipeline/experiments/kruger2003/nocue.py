"""``kruger2003-nocue`` (E2): what the intermediate pass costs on the control with no cue.

The control is dense and faint: no ray ends early and no block is empty, so the extra passes only cost.
"""

import pandas as pd

from pipeline.experiments.kit.checks import Measure, Ratio
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment
from pipeline.experiments.kit.pages import claim_takeaways, format_number, linked_table
from pipeline.experiments.kit.planning import is_registered, timed_frames, truth_run
from pipeline.experiments.kit.results import ok_rows, speed_points
from pipeline.experiments.kruger2003.methods import (RAYCAST, gl_not_measurable, method_name, method_runs,
                                                     no_cue_control, speedup)
from pipeline.experiments.kruger2003.tables import NO_CUE
from reports import blocks, plots

STAGES = ("time_setup", "time_main", "time_intermediate", "time_readback")
"""The GL ray caster's pass types, as timed stages."""


def _overhead(df):
    values = {c: speedup(df, c, "rc") for c in ("rc-a", "rc-b")}
    holds = all(1.1 <= v <= 1.6 for v in values.values())
    return ClaimResult(", ".join(f"{c} {format_number(100 * (v - 1))} % slower" for c, v in values.items()),
                       bool(holds), "time relative to RC")


def _main_fragments(config):
    return Measure(f"{method_name(config)}'s main-pass fragments", match={"config": config},
                   column="count_fragments_main", unit="")


NO_EMPTY_BLOCKS = Ratio(_main_fragments("rc-b"), _main_fragments("rc-a"), at_least=0.95)
"""RC-b culls no more than RC-a where no block is empty."""


class NoCue(Experiment):
    """A dense, faint volume: no ray terminates and no block is empty, so the extra passes only cost."""

    name = "kruger2003-nocue"
    paper = "kruger2003"
    title = "The no-cue control: what the intermediate pass costs (E2)"
    settings = frozenset({"volume_size", "image_size", "step_factor", "truth_step_factor", "repeat"})
    scales = {"smoke": {"volume_size": 32, "image_size": 64},
              "default": {"volume_size": 128, "image_size": 256},
              "full": {"volume_size": 256, "image_size": 512}}
    description = (
        "The paper reports a loss of about 30 % for semi-transparent data where neither early "
        "termination nor empty-space skipping applies: the intermediate pass writes depth, so the "
        "early z-test cannot cull it, and it runs after every main pass for every covered pixel. The "
        "control is smooth noise filling the whole cube with a tiny opacity per sample, so no ray "
        "reaches the threshold and no 8³ block is empty."
    )
    claims = (
        Claim("overhead", "Where neither acceleration applies, the intermediate passes cost about 30 % (Sec. 3)",
              "RC-a and RC-b slower than RC by 10–60 %", _overhead),
        Claim("no-empty-blocks", "The control has no empty space to skip: RC-b draws as many main-pass fragments "
              "as RC-a (only rays that end or leave are culled, by both)", NO_EMPTY_BLOCKS.expected, NO_EMPTY_BLOCKS),
    )

    def runs(self, profile):
        if not is_registered(RAYCAST):
            return []
        size = profile.setting(self, "volume_size", profile.volume_size)
        image = profile.setting(self, "image_size", profile.image_size)
        step = profile.setting(self, "step_factor", 0.5)
        scene_spec, views, tags = no_cue_control(size, image)
        truth_step = profile.setting(self, "truth_step_factor", 0.25)
        truth = truth_run(self.name, "no_cue", scene_spec, views, truth_step, tags)
        return [truth] + method_runs(self.name, "no_cue", scene_spec, views, ("rc", "rc-a", "rc-b", "single-pass"),
                                     step, truth.id, tags, timed_frames(profile, self))

    def paper_table(self):
        return pd.DataFrame(NO_CUE)

    def report(self, results, ctx):
        ok = ok_rows(results)
        tests = ok[ok.role == "test"] if "role" in ok else ok.iloc[:0]
        out = [claim_takeaways(self.claims, results)]
        if not tests.empty:
            timing = speed_points(tests)
            timing["method"] = [method_name(c) for c in timing.config]
            stages = [c for c in STAGES if c in timing]
            out.append(linked_table("Frame time per method on the control", timing,
                                    ["method", "time_ms", "time_ms_min", "time_ms_max", "psnr"] + stages, ctx,
                                    csv_name="nocue.csv", caption="Stage columns in seconds, timed on the device."))
            if stages:
                path, rel = ctx.plot_path("nocue-stages")
                plots.stage_breakdown(timing, path, stage_cols=stages, group_col="method",
                                      title="Where the frame time goes on the control")
                out.append(blocks.Figure("Time per pass type", rel, "Median time of each pass type per frame."))
        return out + gl_not_measurable()
