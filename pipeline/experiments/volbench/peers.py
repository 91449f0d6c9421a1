"""``volbench-peers``: every backend present against VTK's mappers on the same scenes (a backend that cannot render
one is recorded as skipped with its own reason, which the report lists)."""

import numpy as np
import pandas as pd

import renderers
from pipeline.experiments.kit.checks import worst_psnr
from pipeline.experiments.kit.model import Claim, Experiment, Run
from pipeline.experiments.kit.pages import (METRICS, as_ratio, claim_takeaways, difference_gallery, format_number,
                                            linked_table, speed_psnr_figure)
from pipeline.experiments.kit.planning import (UNTIMED, accepts, headline_view, listed, phantom, scene, timed_frames,
                                               truth_run)
from pipeline.experiments.kit.results import ok_rows, speed_points, tagged
from reports import blocks, takeaways

VTK_GPU, VTK_CPU = "vtk-gpu", "vtk-cpu"

PEER_SCENES = {
    # scene: (data set, preset, mode, shading)
    "skull": ("ct_skull", "bone", "dvr", "phong"),
    "cthead": ("cthead", "bone", "dvr", "phong"),
    "engine": ("engine_real", "semi", "dvr", "phong"),
    "engine-mip": ("engine_real", "semi", "mip", "none"),
    "skull-iso": ("ct_skull", "bone", "iso", "phong"),
}
"""The timed scenes: a phantom and real scans, compositing, maximum and isosurface modes."""

MATCHED_SCENES = {
    # scene: (data set, preset)
    "sphere": ("sphere", "opaque"),
    "engine": ("engine", "semi"),
    "skull": ("ct_skull", "bone"),
}
"""Unshaded DVR scenes on which VTK is matched to the reference (same step, no early termination)."""

MATCHED_PSNR = 60.0
"""dB the matched GPU mapper must reach against the reference (issue 8's target)."""

USABLE_PSNR = 40.0
"""dB below which an image is not the reference's (the take-aways' accuracy bar)."""


def _label(backend, options):
    """The technique's name: the backend and every option but the step it shares with the others."""
    return backend + "".join(f" ({k}={v})" for k, v in sorted(options.items()) if k != "step_factor")


def _matched(backend, floor):
    """The check that every matched scene of ``backend`` reaches ``floor`` dB against the reference."""
    return worst_psnr(f"{backend}'s worst matched scene", floor, part="matched", role="test", backend=backend)


class Peers(Experiment):
    """Every backend against VTK's GPU and CPU mappers: speed ratio and accuracy on one set of scenes."""

    name = "volbench-peers"
    title = "Peers: every backend against VTK's volume mappers"
    settings = frozenset({"scenes", "matched_scenes", "volume_size", "image_sizes", "step_factor",
                          "truth_step_factor", "repeat"})
    scales = {
        "smoke": {"scenes": ["skull"], "matched_scenes": ["sphere"], "image_sizes": [48]},
        "default": {"volume_size": 128, "image_sizes": [256]},
        "full": {"volume_size": 256, "image_sizes": [256, 512]},
    }
    description = (
        "A researcher reading our numbers asks first how they compare with VTK. Every registered backend renders the "
        "same scenes as VTK's GPU ray caster (vtkOpenGLGPUVolumeRayCastMapper) and its CPU ray caster "
        "(vtkFixedPointVolumeRayCastMapper): a phantom and real scans, orthographic, headline view, at two image "
        "sizes, in every mode each backend supports, all at one sampling distance where a backend has one (shear-warp "
        "and VolPack sample once per slice). Times are the median frame after warm-up with preparation (uploads, RLE "
        "builds) excluded; ratios to VTK are measured in the same run on the same machine. Images are compared with "
        "the reference at a finer step. VTK keeps its default early ray termination (what its users get). The matched "
        "runs beside them turn it off and render unshaded at the reference's own step, the conditions under which VTK "
        "should reproduce the reference."
    )

    def runs(self, profile):
        if not (accepts(VTK_GPU) or accepts(VTK_CPU)):
            return []
        size = profile.setting(self, "volume_size", profile.volume_size)
        image_sizes = [int(s) for s in profile.setting(self, "image_sizes", [256, 512])]
        step, truth_step = profile.setting(self, "step_factor", 0.5), profile.setting(self, "truth_step_factor", 0.25)
        frames, runs = timed_frames(profile, self), []
        for scene_name in listed(profile, self, "scenes", PEER_SCENES, PEER_SCENES):
            dataset, preset, mode, shading = PEER_SCENES[scene_name]
            views = (headline_view(dataset),)
            for image in image_sizes:
                spec = scene(scene_name, image, volumes=[phantom(dataset, size, preset=preset)], mode=mode,
                             shading=shading)
                tags = {"scene": scene_name, "dataset": dataset, "mode": mode, "image_size": image, "part": "timed"}
                truth = truth_run(self.name, f"{scene_name}.{image}", spec, views, truth_step, tags)
                runs.append(truth)
                for backend in renderers.names():
                    options = {"step_factor": step} if accepts(backend, "step_factor") else {}
                    runs.append(Run(self.name, f"{scene_name}.{image}.{backend}", backend, spec, views,
                                    options=options, reference=truth.id, **frames,
                                    tags={**tags, "role": "test", "technique": _label(backend, options)}))
        image = min(image_sizes)
        for scene_name in listed(profile, self, "matched_scenes", MATCHED_SCENES, MATCHED_SCENES):
            dataset, preset = MATCHED_SCENES[scene_name]
            spec = scene(f"matched-{scene_name}", image, volumes=[phantom(dataset, size, preset=preset)],
                         shading="none")
            views = (headline_view(dataset),)
            tags = {"scene": scene_name, "dataset": dataset, "image_size": image, "part": "matched"}
            truth = truth_run(self.name, f"matched.{scene_name}", spec, views, step, tags)
            runs += [truth] + [Run(self.name, f"matched.{scene_name}.{backend}", backend, spec, views,
                                   options={**options, "step_factor": step}, reference=truth.id, **UNTIMED,
                                   tags={**tags, "role": "test", "technique": backend})
                               for backend, options in ((VTK_GPU, {"early_termination": False}), (VTK_CPU, {}))
                               if accepts(backend, "step_factor", *options)]
        return runs

    claims = (
        Claim("vtk-gpu-matched", "Matched to the conventions, VTK's GPU ray caster renders the reference's image",
              f"PSNR ≥ {MATCHED_PSNR:g} dB against the reference at the same step, unshaded, early termination off "
              "(every matched scene)", _matched(VTK_GPU, MATCHED_PSNR)),
        Claim("vtk-cpu-matched", "VTK's fixed-point CPU ray caster is accurate despite its 15-bit arithmetic",
              f"PSNR ≥ {USABLE_PSNR:g} dB against the reference at the same step, unshaded (every matched scene)",
              _matched(VTK_CPU, USABLE_PSNR)),
    )

    def report(self, results, ctx):
        ok = ok_rows(results)
        timed = _timed(ok)
        out = [claim_takeaways(ctx, _peer_takeaways(timed))]
        if not timed.empty:
            out.append(linked_table("Every backend against VTK", timed,
                                    ["scene", "mode", "image_size", "technique", "time_ms", "time_ms_min",
                                     "time_ms_max", "over_vtk_gpu", "over_vtk_cpu", *METRICS], ctx,
                                    csv_name="peers.csv",
                                    names={"image_size": "image (px)", "over_vtk_gpu": "time / VTK GPU",
                                           "over_vtk_cpu": "time / VTK CPU"},
                                    caption="Median frame after warm-up, fastest and slowest timed frame; 'time / "
                                            "VTK' below 1: faster than VTK on the same scene and image size, measured "
                                            "in one run. Metrics against the reference at a finer step."))
            out += [speed_psnr_figure(ctx, f"peers-{int(image)}", group, group="scene", label="backend",
                                      heading=f"Speed against accuracy at {int(image)}²",
                                      caption="One series per scene, each point one backend (labelled); higher and "
                                              "further left is better.",
                                      title=_chart_title(group, int(image)),
                                      x_label="median frame time (ms, log scale)", log_x=True)
                    for image, group in timed.groupby("image_size")]
            largest = timed[timed.image_size == timed.image_size.max()]
            out += [difference_gallery(f"{scene_name} at {int(group.image_size.iloc[0])}²: every backend and its "
                                       "difference from the reference", group.sort_values("time_total"), ctx,
                                       against=results, label=lambda row: row.technique)
                    for scene_name, group in largest.groupby("scene")]
        matched = tagged(ok, part="matched", role="test")
        if not matched.empty:
            out.append(blocks.Table("Matched scenes: VTK against the reference at the same step", matched.sort_values(
                ["backend", "scene"])[["scene", "backend", *METRICS]].rename(columns=METRICS).reset_index(drop=True),
                csv_name="peers_matched.csv",
                caption="Unshaded DVR; VTK's GPU mapper with early termination off; both at the reference's step. "
                        "What remains: VTK samples at entry + kΔ and drops the last partial step where the reference "
                        "samples cell midpoints, and skips opacity correction for table entries ≤ 1e-4."))
        skipped = tagged(results, status="skipped")
        if not skipped.empty:
            out.append(blocks.Table("Not rendered, with the backend's reason", skipped[
                ["scene", "backend", "reason"]].drop_duplicates().reset_index(drop=True)))
        return out


def _timed(ok):
    """The timed test rows with milliseconds and each row's time over VTK's on its scene and size."""
    if "part" not in ok:
        return pd.DataFrame()
    rows = speed_points(ok[(ok.part == "timed") & (ok.role == "test")])
    for backend, column in ((VTK_GPU, "over_vtk_gpu"), (VTK_CPU, "over_vtk_cpu")):
        vtk = rows[rows.backend == backend].groupby(["scene", "image_size"]).time_total.median()
        keys = list(zip(rows.scene, rows.image_size))
        rows[column] = rows.time_total.to_numpy() / np.array([vtk.get(k, np.nan) for k in keys], float)
    return rows.sort_values(["scene", "image_size", "time_total"])


def _peer_takeaways(timed):
    """Per scene at the largest size the fastest accurate backend; each backend's time over VTK's."""
    if timed.empty:
        return []
    largest = timed[timed.image_size == timed.image_size.max()]
    sentences = takeaways.fastest_at_accuracy(largest.assign(
        scene=[f"{s} ({int(i)}²)" for s, i in zip(largest.scene, largest.image_size)]), psnr_min=USABLE_PSNR)
    for backend in [b for b in pd.unique(timed.backend) if b not in (VTK_GPU, VTK_CPU)]:
        mine = timed[timed.backend == backend]
        parts = []
        for column, peer in (("over_vtk_gpu", "VTK GPU"), ("over_vtk_cpu", "VTK CPU")):
            ratios = mine[column].dropna()
            if not ratios.empty:
                parts.append(f"{as_ratio(ratios.median())} the time of {peer} (median over {len(ratios)} scenes and "
                             f"image sizes, {as_ratio(ratios.min())}–{as_ratio(ratios.max())})")
        if parts:
            sentences.append(f"{backend} takes " + " and ".join(parts) + ".")
    return sentences


def _chart_title(group, image):
    accurate = group[group.psnr >= USABLE_PSNR]
    if accurate.empty:
        return f"{image}²: no backend reaches {USABLE_PSNR:g} dB"
    best = accurate.loc[accurate.time_ms.idxmin()]
    return (f"{image}²: fastest at ≥ {USABLE_PSNR:g} dB is {best.backend} on {best.scene} "
            f"({format_number(best.time_ms)} ms)")
