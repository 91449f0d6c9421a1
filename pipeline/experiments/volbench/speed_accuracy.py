"""``volbench-speed-accuracy``: every registered backend over its quality settings, time against error."""

import functools

import numpy as np
import pandas as pd

import renderers
from pipeline.experiments.kit import intervals, judging as kit_judging
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, Run
from pipeline.experiments.kit.pages import (as_ratio, difference_gallery, figure, format_number, setting_words,
                                            timed_metrics_table)
from pipeline.experiments.kit.planning import HEADLINE_VIEW, listed, timed_frames
from pipeline.experiments.kit.results import nonempty_or, speed_points
from pipeline.experiments.volbench.scenes import scene_and_truth
from reports import blocks, decision, takeaways

SPEED_ACCURACY_SCENES = {
    "skull-bone": ("ct_skull", "bone", "phong"),
    "engine-semi": ("engine", None, "phong"),
    "skull-mip": ("ct_skull", None, "none"),
    "foot-iso": ("foot", "iso", "phong"),
}
"""Scene → (data set, preset or None for its default, shading)."""

SCENE_KINDS = {"skull-bone": "opaque", "engine-semi": "semi-transparent", "skull-mip": "mip", "foot-iso": "iso"}
"""Scene → its kind: the index's decision panel has one chart per kind (opaque surfaces, semi-transparent
material, maximum intensity projection, iso-surface). The mode is the kind's where it names one."""

EXACT_KINDS = ("mip", "iso")
"""Scene kinds the reference renders exactly at any step (it solves each cell: :mod:`renderers.reference.raycast`),
so its step sweep there trades nothing: the trade-off claim reads the other scenes."""


def _tradeoff(df):
    """The reference's time ratio per halving of the step (median over scenes and halvings, with the interval of
    the frames its sweep took together), and its error falling at every halving."""
    rows = df[(df.backend == "reference") & (df.role == "sweep") & ~df["kind"].isin(EXACT_KINDS)].copy()
    rows["step_factor"] = rows.setting.str.extract(r"step_factor=([0-9.e-]+)")[0].astype(float)
    resampler = intervals.Resampler()
    ratios, draws, frames, monotone = [], [], {}, True
    for scene_name, group in rows.groupby("scene"):
        group = group.sort_values("step_factor", ascending=False)
        times = group.time_total.to_numpy()
        ratios.extend(times[1:] / times[:-1])
        per_run = intervals.row_draws(group, "time_total", resampler)  # the sweep's runs, paired round by round
        draws.append(None if per_run is None else per_run[:, 1:] / per_run[:, :-1])
        frames.update({f"{scene_name} at step {format_number(row.step_factor)}":
                       intervals.frame_count(group.loc[[index]], "time_total") for index, row in group.iterrows()})
        monotone &= bool((np.diff(group.rmse.to_numpy()) < 0).all())
    value = float(np.median(nonempty_or(ratios, "no reference sweep")))
    draws = None if any(d is None for d in draws) else np.median(np.hstack(draws), axis=1)
    decision = kit_judging.decided(value, draws, frames=frames, at_least=1.5, at_most=2.5)
    detail = f"ratios {', '.join(format_number(r) for r in ratios)}; error decreasing: {monotone}"
    measured = kit_judging.with_interval(f"{as_ratio(value)} per halving", decision)
    if not monotone:  # the error's order is no timing: it fails the claim whatever the times say
        return ClaimResult(measured, False, detail, decision.interval, decision.margin, frames=decision.frames)
    return ClaimResult.decided(measured, decision, detail)


def _ranking(df, *, scene):
    """On ``scene``, the next technique's time over the fastest's at the accuracy bar (the decision panel's order),
    with the interval of their frames timed together: the order is read from these same times, so the ratio is
    never below ×1; the interval tells whether the order is resolved or the two tie."""
    sweep = df[(df.role == "sweep") & (df.scene == scene)]
    panels = nonempty_or(decision.panel(decision.technique_rows(sweep), None), f"no technique rendered {scene}")
    accurate = [row for row in panels[0]["table"] if row["accurate"]]
    if len(accurate) < 2:
        raise ValueError(f"{len(accurate)} technique(s) reach {takeaways.PSNR_GOOD:g} dB on {scene}: nothing to rank")
    best, runner = accurate[:2]
    if best["timed_with"] != runner["timed_with"]:
        raise ValueError(f"{best['backend']} and {runner['backend']} were timed in separate jobs "
                         f"({best['timed_with']}, {runner['timed_with']}): their times do not compare")
    decided = kit_judging.ratio(sweep[sweep.run == runner["run"]], sweep[sweep.run == best["run"]], "time_total",
                                intervals.Resampler(), at_least=kit_judging.STRICTLY_ABOVE_ONE)
    names = f"{runner['backend']} ({runner['setting']}) / {best['backend']} ({best['setting']})"
    detail = (f"{best['backend']} {best['ms']} ms at {best['psnr']} dB, {runner['backend']} {runner['ms']} ms at "
              f"{runner['psnr']} dB")
    return ClaimResult.decided(kit_judging.with_interval(f"{names}: {as_ratio(decided.value)}", decided), decided,
                               detail)


def _ranking_claim(scene):
    kind = decision.KIND_WORDS[SCENE_KINDS[scene]]
    return Claim(f"ranking-{scene}", f"The index's ranking on {scene} ({kind}): the fastest technique at "
                                     f"≥ {takeaways.PSNR_GOOD:g} dB PSNR is faster than the next, the two timed together",
                 "the next's time / the fastest's > ×1 with its whole interval; an interval that reaches ×1 is a tie",
                 functools.partial(_ranking, scene=scene), kind="timing")


EXACT_AT_ONE, SAMPLED_AT_QUARTER = "step_factor=1.0", "iso_hit=sampled,step_factor=0.25"
"""gl-raycast's settings the exact-iso claim compares: the cell walk at step 1 and the paper's sampling at step ¼."""


def _exact_beats_oversampling(df):
    """On the iso-surface scene, gl-raycast's exact hit at step 1 against its sampled hit at step ¼ (timed together):
    the sampled frame's time over the exact one's, and the exact one at least as accurate."""
    rows = df[(df.role == "sweep") & (df.backend == "gl-raycast") & (df["kind"] == "iso")]
    exact, sampled = rows[rows.setting == EXACT_AT_ONE], rows[rows.setting == SAMPLED_AT_QUARTER]
    if exact.empty or sampled.empty:
        raise ValueError(f"no gl-raycast run of {EXACT_AT_ONE if exact.empty else SAMPLED_AT_QUARTER} on an "
                         "iso-surface scene")
    decided = kit_judging.ratio(sampled, exact, "time_total", intervals.Resampler(),
                                at_least=kit_judging.STRICTLY_ABOVE_ONE)
    psnr_exact, psnr_sampled = float(exact.psnr.median()), float(sampled.psnr.median())
    detail = (f"exact at step 1: {format_number(float(exact.time_total.median()) * 1e3)} ms, PSNR "
              f"{format_number(psnr_exact)} dB{_work(exact, 'cells walked')}; sampled at step ¼: "
              f"{format_number(float(sampled.time_total.median()) * 1e3)} ms, PSNR {format_number(psnr_sampled)} dB"
              f"{_work(sampled, 'samples')}")
    measured = kit_judging.with_interval(f"{as_ratio(decided.value)} faster", decided)
    if not psnr_exact >= psnr_sampled:  # less accurate: no speed makes up for it
        return ClaimResult(measured, False, detail + "; the exact hit is less accurate", decided.interval,
                           decided.margin, frames=decided.frames)
    return ClaimResult.decided(measured, decided, detail)


def _work(rows, samples):
    """``", 3.5e+05 cells walked, 1.7e+04 cells solved, 988 crossings"``: the counts of a run that do not depend on the
    machine (those it reported)."""
    words = (("count_samples", samples), ("count_iso_cells_solved", "cells solved"), ("count_crossings", "crossings"))
    found = [f"{format_number(float(rows[column].iloc[0]))} {label}" for column, label in words
             if column in rows and pd.notna(rows[column].iloc[0])]
    return ", " + ", ".join(found) if found else ""


class SpeedAccuracy(Experiment):
    """Every registered backend over its quality settings: time against error."""

    name = "volbench-speed-accuracy"
    title = "Speed against accuracy, every backend"
    settings = frozenset({"scenes", "volume_size", "image_size"})
    scales = {"smoke": {"scenes": ["skull-bone"]}}
    description = (
        "Each registered backend renders the same scenes over its own quality settings (its ``quality_sweep``: step "
        "size, and later slice count, thresholds, ...). Error is measured against the reference at 1/16 voxel, time is "
        "the median frame after warm-up. Every technique's settings on a scene are timed together, interleaved round "
        "by round in each of the profile's replicate processes, so the index's ranking compares like with like and its "
        "ratios have intervals. A backend that could not run, or lacks a scene's mode, is listed below with the reason "
        "its runs recorded."
    )
    TRUTH_FACTOR = 1 / 16

    def runs(self, profile):
        runs = []
        for scene_name in listed(profile, self, "scenes", SPEED_ACCURACY_SCENES, SPEED_ACCURACY_SCENES):
            kind = SCENE_KINDS[scene_name]
            scene, truth = scene_and_truth(self, profile, scene_name, SPEED_ACCURACY_SCENES[scene_name],
                                           self.TRUTH_FACTOR, {"setting": "truth", "kind": kind},
                                           mode=kind if kind in ("mip", "iso") else "dvr")
            runs.append(truth)
            mode = scene["mode"]
            for backend in renderers.names():
                backend_class = renderers.backend_class(backend)
                sweep = backend_class.quality_sweep_for(mode)
                # Whatever the panel ranks is timed together, interleaved in every replicate process: the
                # contenders' settings on a scene (the ranking claims), and apart from them the reference's
                # steps (the trade-off claim).
                group = f"{scene_name}.{'reference' if backend == 'reference' else 'contenders'}"
                timing = dict(**timed_frames(profile, self), interleave=group)
                if mode not in backend_class.capabilities.modes:  # one run, skipped with its reason, says why
                    sweep, timing = sweep[:1], dict(warmup=profile.warmup, repeat=profile.repeat)
                for index, options in enumerate(sweep):
                    setting = ",".join(f"{k}={v}" for k, v in sorted(options.items())) or "default"
                    runs.append(Run(self.name, f"{scene_name}.{backend}.{index}", backend, scene, (HEADLINE_VIEW,),
                                    options=dict(options), reference=truth.id, **timing,
                                    tags={"scene": scene_name, "setting": setting, "role": "sweep", "kind": kind}))
        return runs

    claims = (
        Claim("tradeoff", "For the reference's ray integration (its MIP and iso-surfaces are exact at any step), "
                          "halving the step roughly doubles the time and lowers the error",
              "time ratio per halving in [1.5, 2.5]; error decreasing", _tradeoff, kind="timing"),
        *(_ranking_claim(scene) for scene in SPEED_ACCURACY_SCENES),
        Claim("exact-iso-beats-oversampling", "gl-raycast's exact iso-surface hit at step 1 is faster than its sampled "
                                              "hit at step ¼ while at least as accurate (issue 36: resolving each cell "
                                              "beats sampling four times as often)",
              "time(sampled, step ¼) / time(exact, step 1) > ×1 with its whole interval; PSNR(exact) ≥ PSNR(sampled)",
              _exact_beats_oversampling, kind="timing"),
    )

    overview = True
    """The index's techniques × data sets table is built from this experiment's runs."""

    def report(self, results, ctx):
        from reports import plots  # matplotlib: only when the report is built

        ok = results[(results.status == "ok") & (results.role == "sweep")]
        ok = speed_points(ok.assign(setting=ok.setting.fillna("default").astype(str), technique=lambda frame: [
            decision.technique_label(b, s) for b, s in zip(frame.backend, frame.setting)]))
        out = [blocks.Takeaways(takeaways.fastest_at_accuracy(ok) + takeaways.accuracy_failures(ok)
                                + _stage_takeaways(ok))]
        fronts = decision.panel(decision.technique_rows(results[results.role == "sweep"]), None)
        techniques = sorted({b for item in fronts for b in item["points"].backend})
        out += [figure(ctx, f"speed-accuracy-{item['scene']}", plots.pareto_fronts, item["points"],
                       heading=f"{item['scene']} ({item['kind']}): median frame time against PSNR",
                       caption="Each technique's Pareto front over its settings (the settings no other setting of it "
                               "beats in both time and PSNR) as a line, its other settings as hollow markers; higher "
                               "and further left is better. Bars span the fastest and slowest timed frame. The "
                               "reference's own sweep is its convergence study, not drawn here; every setting is in "
                               "the table below.",
                       title=_speed_title(item["scene"], ok[(ok.scene == item["scene"]) & (ok.backend != "reference")]),
                       psnr_min=takeaways.PSNR_GOOD, techniques=techniques)
                for item in fronts]
        stages = _frame_stages(ok)
        if stages:
            # One bar per backend: its first quality setting (the run id's last part is the setting's index),
            # median over the scenes it rendered; every setting's stages are in the table below.
            first = ok[ok.run.str.endswith(".0")]
            out.append(figure(ctx, "stages", plots.stage_breakdown, first,
                              heading="Time per stage: each backend's first setting (median over scenes)",
                              caption="Each backend's own stages, as it reports them (CONVENTIONS, Results), at the "
                                      "first setting of its quality sweep; the table below has every setting.",
                              stage_cols=stages, group_col="backend", title=_stage_title(first, stages)))
        out.append(timed_metrics_table("All settings", ok.assign(setting=ok.setting.map(setting_words)),
                                       ["scene", "backend", "setting"], ctx, by=["scene", "backend", "time (ms)"],
                                       csv_name="speed_accuracy.csv"))
        out += [difference_gallery(f"{scene}: every setting against the reference", group.sort_values("time_total"),
                                   ctx, against=results, label=lambda row: row.technique,
                                   note=lambda row: f"{format_number(row.time_ms)} ms, PSNR {format_number(row.psnr)} "
                                                    f"dB, largest error {format_number(row.max_error)}")
                for scene, group in ok.groupby("scene")]
        return out


def _speed_title(scene, group, psnr_min=takeaways.PSNR_GOOD):
    """The finding of a speed-accuracy chart: the fastest setting that reaches ``psnr_min``."""
    accurate = group[group.psnr >= psnr_min]
    if accurate.empty:
        return f"{scene}: no setting reaches {psnr_min:g} dB (best {format_number(group.psnr.max())} dB)"
    best = accurate.loc[accurate.time_ms.idxmin()]
    return f"{scene}: {psnr_min:g} dB at {format_number(best.time_ms)} ms with {best.technique}"


NOT_FRAME_STAGES = ("time_total", "time_ms", "time_first_frame", "time_technique")
"""Time columns that are no stage of a frame: the frame itself, the cold first frame (compilation, first uploads),
and ``technique``, the sum of the stages that are the technique (stacked, it would count them twice)."""


def _frame_stages(ok):
    """The stage columns of ``ok`` a frame's time is split into."""
    return [c for c in ok.columns if c.startswith("time_") and c not in NOT_FRAME_STAGES
            and not c.endswith(("_min", "_max"))]


def _stage_shares(ok, stages):
    medians = ok[stages].median()
    return (medians / medians.sum()).sort_values(ascending=False) if medians.sum() > 0 else pd.Series(dtype=float)


def _stage_title(ok, stages):
    shares = _stage_shares(ok, stages)
    if shares.empty:
        return "Time per stage"
    return f"The {shares.index[0].removeprefix('time_')} stage takes {shares.iloc[0]:.0%} of the median frame"


def _stage_takeaways(ok):
    shares = _stage_shares(ok, _frame_stages(ok))
    if shares.empty:
        return []
    parts = ", ".join(f"{name.removeprefix('time_')} {share:.0%}" for name, share in shares.items())
    return [f"Where the time goes (median over every setting and scene): {parts}."]
