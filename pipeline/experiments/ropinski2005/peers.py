"""``ropinski2005-peers``: the lens in the tools users have, beside the paper's method, by time and error.

The paper compares with no other system. VTK's GPU ray caster offers three partial answers (``vtk-gpu`` option
``lens_method``): a label-map mask (the lens voxelised: any shape, ``clip`` and ``dvr``), cropping regions (an
axis-aligned ``clip`` box, tested per sample) and clipping planes (a ``clip`` lens cutting the box with one face).
Object-order renderers classify voxels, not samples: ``shearwarp`` puts the lens into its pre-classification (the
contrast note 004 names), which costs a reclassification and a re-encoding whenever the lens moves. Each
implementation's runs are timed in a job of their own (VTK's OpenGL stack and moderngl's cannot share one).
"""

from contextlib import suppress

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import decision_words, measured
from pipeline.experiments.kit.model import Claim, ClaimResult, Run
from pipeline.experiments.kit.pages import (as_percent, claim_takeaways, difference_gallery, figure, format_number,
                                            frames_caption, linked_table, not_measurable)
from pipeline.experiments.kit.planning import accepts, is_registered, listed, timed_frames, truth_run, unregistered
from pipeline.experiments.kit.results import nonempty_or, numeric, ok_rows, rows_matching, speed_points, text_column
from pipeline.experiments.ropinski2005.correctness import ACCURACY_PSNR
from pipeline.experiments.ropinski2005.methods import (LENS_SCALES, OFF, OPTIONS, PAPER_METHOD, RAYCAST, STEP,
                                                       LensExperiment, device_takeaways, lens_run, lens_settings)
from pipeline.experiments.ropinski2005.pages import CI, headline, interval_columns, median_ms, psnr_note
from pipeline.experiments.ropinski2005.scenes import lens_scene, lens_views, scene_tags, without_lens
from reports import blocks, plots

VTK = "vtk-gpu"
SHEARWARP = "shearwarp"

SCENES = ("seismic", "skull", "engine", "seismic-cutaway")
"""The scenes: three of Table 1's and Fig. 1's (the foot's iso lens has no peer: VTK's label map and
shear-warp's pre-classification composite samples, they take no first hit in one segment) and the cutaway."""

PEERS = {
    # config: (backend, options beside the step, the scenes it can render, words)
    "vtk-label-map": (VTK, {"lens_method": "label-map"}, SCENES,
                      "VTK, label-map mask (the lens voxelised, a transfer function per label)"),
    "vtk-cropping": (VTK, {"lens_method": "cropping"}, ("seismic-cutaway",),
                     "VTK, cropping regions (an axis-aligned box, per sample)"),
    "vtk-clipping-planes": (VTK, {"lens_method": "clipping-planes"}, ("seismic-cutaway",),
                            "VTK, clipping planes (the ray segment shortened)"),
    "shearwarp": (SHEARWARP, {}, SCENES, "shear-warp, the lens in its per-voxel pre-classification"),
}
"""The peers: which backend and options, and which scenes each can render (the others refuse them)."""

EXACT = {RAYCAST: {"opaque_threshold": 1.0}, VTK: {"early_termination": False},
         SHEARWARP: {"early_termination": False, "min_opacity": 0.0}}
"""Every implementation without early ray termination or an opacity floor: the reference has neither, and each
implementation's own thresholds (0.95, VTK's 1 − 1/255, shear-warp's 0.05 floor) would otherwise decide the
accuracy comparison; so the overheads are the lens's own, not what early termination hides of it."""

PREPARATION = ("time_classify", "time_rle_build", "time_sat_build")
"""Shear-warp's stages that a moved lens re-runs (its classification and the encodings built from it)."""


def signed(value):
    """``+1.2`` / ``−0.4``: a change in dB with its sign."""
    return ("+" if value >= 0 else "−") + format_number(abs(value))


def config_words(config):
    """The words for a run's ``config`` tag."""
    if config == PAPER_METHOD:
        return "gl-raycast, segments (the paper)"
    if config == OFF or config.endswith(f"-{OFF}"):
        return f"{RAYCAST if config == OFF else config[:-len(OFF) - 1]}, no lens"
    return PEERS[config][3] if config in PEERS else config


def implementation(config):
    """The backend a config's runs belong to (its lens-off control has the same)."""
    return PEERS[config][0] if config in PEERS else RAYCAST


def overhead(frame, scene, config, *, resampler):
    """time(lens) / time(no lens) of ``config``'s implementation on ``scene``, with its paired interval."""
    on = rows_matching(frame, scene, scene=scene, config=config, lens="on")
    off = rows_matching(frame, scene, scene=scene, implementation=implementation(config), lens="off")
    if on.empty or off.empty:
        raise ValueError(f"no successful lens-on and lens-off runs of {config} on {scene}")
    return intervals.ratio_decision(on, off, resampler=resampler)


def lens_psnr(frame, scene, config):
    return float(measured(rows_matching(frame, scene, scene=scene, config=config, lens="on"), "psnr",
                          f"no lens image of {config} on {scene} compared with the reference").psnr.min())


def psnr_cost(frame, scene, config):
    """dB the lens costs ``config``: its no-lens image's PSNR minus its lens image's (each against the reference's)."""
    off = numeric(rows_matching(frame, scene, scene=scene, implementation=implementation(config), lens="off"), "psnr")
    return float(off.min()) - lens_psnr(frame, scene, config) if off.notna().any() else np.nan


def _accuracy(df):
    tests = df[text_column(df, "lens") == "on"] if "lens" in df else df.iloc[:0]
    values = {}
    for (scene, config), _ in tests.groupby(["scene", "config"], sort=False):
        with suppress(ValueError):
            values[(scene, config)] = lens_psnr(df, scene, config)
    worst = min(nonempty_or(values, "no lens image compared with the reference"), key=values.get)
    failing = [f"{config} on {scene}" for (scene, config), v in values.items() if v < ACCURACY_PSNR]
    return ClaimResult(f"{format_number(values[worst])} dB ({worst[1]}, {worst[0]})", not failing,
                       "; ".join(f"{config} on {scene}: {format_number(v)} dB" for (scene, config), v in values.items())
                       + (f". Below {format_number(ACCURACY_PSNR)} dB: {', '.join(failing)}" if failing else ""))


CLAIMS = (
    Claim("peers-accuracy", "Every implementation renders its lens scenes as the reference does (issue 24's accuracy "
          "target, held to the peers as to the paper's method)",
          f"PSNR ≥ {format_number(ACCURACY_PSNR)} dB against the reference, every implementation, scene and view",
          _accuracy, kind="accuracy"),
)


def summary_table(tests):
    """Per scene and implementation: lens-off and lens-on times, the overhead with its interval, PSNR."""
    rows = []
    resampler = intervals.Resampler()
    for (scene, config), on in tests[text_column(tests, "lens") == "on"].groupby(["scene", "config"], sort=False):
        try:
            decision = overhead(tests, scene, config, resampler=resampler)
        except (KeyError, ValueError):
            continue
        off = rows_matching(tests, scene, scene=scene, implementation=implementation(config), lens="off")
        row = {"scene": scene, "implementation": config_words(config), "ms, no lens": median_ms(off),
               "ms, lens": median_ms(on),
               **interval_columns(decision.value, decision.interval, "time ratio lens / no lens"),
               "PSNR with the lens (dB)": float(numeric(on, "psnr").min()) if "psnr" in on else np.nan,
               "PSNR without it (dB)": float(numeric(off, "psnr").min()) if "psnr" in off else np.nan}
        moved = sum(numeric(on, c).median() for c in PREPARATION if c in on and numeric(on, c).notna().any())
        row["ms to move the lens (preparation)"] = 1e3 * moved if moved else np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def _takeaways(tests):
    """The overheads in words per implementation, and what moving the lens costs the object-order one."""
    out = []
    resampler = intervals.Resampler()
    for config in pd.unique(text_column(tests[text_column(tests, "lens") == "on"], "config")):
        words, costs = [], []
        for scene in pd.unique(text_column(tests, "scene")):
            with suppress(KeyError, ValueError):
                words.append(f"{scene} {decision_words(overhead(tests, scene, config, resampler=resampler))}")
            with suppress(KeyError, ValueError):
                costs.append(psnr_cost(tests, scene, config))
        costs = [c for c in costs if np.isfinite(c)]
        if words:
            accuracy = (f"; its PSNR against the reference changes by {signed(-max(costs))} to {signed(-min(costs))} "
                        "dB with the lens (against its own without it)") if costs else ""
            out.append(f"{config_words(config)}: time with / without the lens {', '.join(words)}{accuracy}.")
    table = summary_table(tests)
    moved = table.dropna(subset=["ms to move the lens (preparation)"]) if not table.empty else table
    if not moved.empty:
        ms = moved["ms to move the lens (preparation)"]
        share = ms / moved["ms, lens"]
        out.append(f"Moving the lens costs shear-warp a reclassification and re-encoding of the volume: "
                   f"{format_number(ms.min())}–{format_number(ms.max())} ms, {as_percent(share.min())}–"
                   f"{as_percent(share.max())} of a lens frame's time on top of it (the ray casters pay nothing: the "
                   "lens is a uniform or two images per frame).")
    return out


def _figure(table, ctx):
    return figure(ctx, "peers-overhead-accuracy", plots.speed_accuracy, table,
                  heading="The lens's cost in time and in accuracy, per implementation",
                  caption="Each point one scene: the overhead, whole-frame time with the lens over without it, timed "
                          "together in the implementation's own job (bars: its 95 % bootstrap interval), against the "
                          "PSNR of the lens image against the reference. Overheads compare across implementations; "
                          "absolute times, taken in different jobs and stacks, do not.",
                  time_col="time ratio lens / no lens", error_col="PSNR with the lens (dB)",
                  group_col="implementation", label_col="scene", log_x=False, log_y=False, join=False,
                  time_range_cols=CI, better="upper left", x_label="frame time with the lens / without it (ratio)",
                  y_label="PSNR with the lens against the reference (dB)",
                  title="What the lens costs each implementation: time and accuracy")


class Peers(LensExperiment):
    name = "ropinski2005-peers"
    title = "The lens in VTK and in shear-warp, beside the paper's method"
    settings = frozenset({"scenes", "peers", "volume_size", "image_size", "orbit", "repeat", "min_time"})
    scales = LENS_SCALES
    description = (
        "Not in the paper. Each implementation renders each lens scene it can without and with the lens, the two timed "
        "together in the implementation's own job: gl-raycast with the paper's segments method; VTK's GPU ray caster "
        "with a label-map mask (the lens voxelised, a transfer function per label), cropping regions and clipping "
        "planes where the scene allows them; the Numba shear-warp with the lens in its per-voxel pre-classification. "
        "Early ray termination and opacity floors are off everywhere (the reference has neither, and each "
        "implementation's own thresholds would decide the accuracy comparison). Each overhead is the whole-frame time "
        "with the lens over without it, with its paired bootstrap interval; each image, with and without the lens, is "
        "compared with the reference's, so the page shows what the lens itself costs in accuracy. For shear-warp the "
        "page also gives what a moved lens costs: its classification and encoding stages, which a lens frame re-runs."
    )
    claims = CLAIMS

    def runs(self, profile):
        if not is_registered(RAYCAST):
            return []
        wanted = listed(profile, self, "scenes", SCENES, known=SCENES)
        peers = listed(profile, self, "peers", tuple(PEERS), known=PEERS)
        size, image, orbit, _ = lens_settings(profile, self)
        frames = timed_frames(profile, self)
        runs = []
        for scene_name in wanted:
            spec = lens_scene(scene_name, image, size=size, real_data=profile.real_data)
            views = lens_views(scene_name, orbit)
            tags = scene_tags(scene_name)
            truth = truth_run(self.name, scene_name, spec, views, STEP, {**tags, "config": "reference"})
            truth_off = truth_run(self.name, scene_name, without_lens(spec), views, STEP,
                                  {**tags, "config": "reference"}, suffix=f".{OFF}")
            runs += [truth, truth_off]
            if accepts(RAYCAST, *OPTIONS):
                group = f"{scene_name}.gl"
                runs += [lens_run(self.name, f"{scene_name}.gl.{OFF}", without_lens(spec), views, OFF, frames,
                                  {**tags, "lens": "off", "implementation": "gl-raycast"}, group=group,
                                  reference=truth_off.id, options=EXACT[RAYCAST]),
                         lens_run(self.name, f"{scene_name}.{PAPER_METHOD}", spec, views, PAPER_METHOD, frames,
                                  {**tags, "lens": "on", "implementation": "gl-raycast"}, group=group,
                                  reference=truth.id, options=EXACT[RAYCAST])]
            for backend in (VTK, SHEARWARP):
                configs = [c for c in peers if PEERS[c][0] == backend and scene_name in PEERS[c][2]
                           and accepts(backend, *PEERS[c][1], *EXACT[backend])]
                if not configs or not is_registered(backend):
                    continue
                group = f"{scene_name}.{backend}"
                base = {**({"step_factor": STEP} if accepts(backend, "step_factor") else {}), **EXACT[backend]}
                runs.append(Run(self.name, f"{scene_name}.{backend}.{OFF}", backend, without_lens(spec), views,
                                options={**base, **PEERS[configs[0]][1]}, **frames, interleave=group,
                                reference=truth_off.id,
                                tags={**tags, "config": f"{backend}-{OFF}", "lens": "off", "implementation": backend}))
                for config in configs:
                    runs.append(Run(self.name, f"{scene_name}.{config}", backend, spec, views,
                                    options={**base, **PEERS[config][1]}, **frames, interleave=group,
                                    reference=truth.id,
                                    tags={**tags, "config": config, "lens": "on", "implementation": backend}))
        return runs

    def report(self, results, ctx):
        ok = ok_rows(results)
        tests = ok[text_column(ok, "lens").isin(["on", "off"])].copy() if "lens" in ok else ok.iloc[:0]
        out = [claim_takeaways(ctx, device_takeaways(tests), _takeaways(tests))]
        if not tests.empty:
            table = summary_table(tests)
            if not table.empty:
                out.append(blocks.Table(
                    "Each implementation's lens overhead and accuracy", table.round(3), csv_name="peers.csv",
                    caption="Median whole-frame times over the views without and with the lens, timed together in the "
                            "implementation's own job; the ratio's 95 % interval is a paired bootstrap over the "
                            "frames. PSNR: the worst view against the reference's image of the same scene, with and "
                            "without the lens (their difference is what the lens costs in accuracy). Moving the lens: "
                            "shear-warp's classification and encoding stages, which a frame with a moved lens re-runs "
                            "(the frames above reuse them: the lens stood still)."))
                out.append(_figure(table, ctx))
            points = speed_points(tests)
            points["implementation"] = [config_words(c) for c in text_column(points, "config")]
            out.append(linked_table("Every run", points,
                                    ["scene", "implementation", "lens", "view", "time_ms", "time_ms_min",
                                     "time_ms_max", "psnr"], ctx, csv_name="peers_runs.csv",
                                    caption=frames_caption(points)))
            lens = headline(tests)
            out.append(difference_gallery(
                "Headline view: each implementation's lens image against the reference",
                lens[text_column(lens, "lens") == "on"].sort_values(["scene", "config"]), ctx, against=results,
                label=lambda row: f"{row.scene}, {config_words(row.config)}", note=psnr_note,
                caption="Left the image with the lens, right |it − reference|."))
        return out + not_measurable(unregistered(VTK, SHEARWARP))
