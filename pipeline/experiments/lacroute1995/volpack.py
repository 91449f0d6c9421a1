"""``lacroute1995-volpack``: our shear-warp against VolPack 1.0, the thesis's own library, on the same input.

Both render VolPack's brainsmall example and the folded-brain phantom (the thesis's MR brain's
stand-in) with the same classification, shading and view, timed and compared image to image; VTK's
CPU ray caster runs beside them as the ray caster users already have.
"""

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, Run
from pipeline.experiments.kit.pages import (DIFF_SCALE, as_ratio, change_words, format_number, linked_table,
                                            not_measurable)
from pipeline.experiments.kit.planning import (accepts, headline_view, is_registered, listed, missing_options, phantom,
                                               scene, timed_frames, truth_run, unregistered)
from pipeline.experiments.kit.results import ok_rows, pair_metrics, rows_matching, speed_points, text_column
from pipeline.experiments.lacroute1995 import judging, tables
from pipeline.experiments.lacroute1995.planning import SW, VP
from reports import blocks, plots

VOLPACK_CONFIGS = {
    # config: (backend, options, label)
    "shearwarp-1": (SW, {"workers": 1}, "our shear-warp, 1 worker"),
    "shearwarp-all": (SW, {"workers": None}, "our shear-warp, all cores"),
    "volpack-rle": (VP, {"mode": "rle"}, "VolPack, classified RLE"),
    "volpack-octree": (VP, {"mode": "octree"}, "VolPack, min-max octree (fast classification)"),
    "vtk-cpu-1": ("vtk-cpu", {"threads": 1, "step_factor": 1.0}, "VTK CPU ray caster, 1 thread (peer)"),
    "vtk-cpu-all": ("vtk-cpu", {"step_factor": 1.0}, "VTK CPU ray caster, all cores (peer)"),
}
"""VTK's fixed-point ray caster is the CPU alternative users run; it samples once per voxel here, as
shear-warp samples once per slice."""


def _technique(config):
    return VOLPACK_CONFIGS.get(config, (None, None, config))[2]


class VolPackComparison(Experiment):
    """Our shear-warp against VolPack 1.0 on the same volumes, classification and view."""

    name = "lacroute1995-volpack"
    paper = "lacroute1995"
    title = "Our shear-warp against VolPack, the thesis's own library"
    settings = frozenset({"scenes", "image_size", "brain_size", "brain_image_size", "truth_step_factor", "repeat"})
    scales = {"smoke": {"scenes": ["brain"], "image_size": 48, "brain_size": 32, "brain_image_size": 48},
              "default": {"repeat": 15, "image_size": 256, "brain_size": 128, "brain_image_size": 256},
              "full": {"repeat": 15, "image_size": 256, "brain_size": 256, "brain_image_size": 512}}
    description = (
        "VolPack is the library the thesis describes (Ch. 8); its classified-RLE mode is the thesis's "
        "parallel-projection algorithm and its octree mode the fast-classification algorithm. Both "
        "backends render the same volume with the same classification (VolPack's brainsmall example: "
        "density ramp × gradient ramp), Blinn–Phong shading and the same oblique view: the real "
        "brainsmall.den (128×128×84) and the folded-brain phantom that stands in for the thesis's "
        "256×256×167 MR brain. Our shear-warp runs with one worker (VolPack is single-threaded) and "
        "with every core. Times are the median frame after warm-up, preprocessing (classification, "
        "RLE and octree builds) excluded as in the thesis. The speed claims compare the technique on both "
        "sides (our kernels: tables, compositing, warp; VolPack's library calls), every configuration of a "
        "scene timed together frame by frame, with 95 % intervals; images are compared with each other and "
        "with the reference ray caster. VTK's fixed-point CPU ray caster (one sample per voxel, like "
        "shear-warp's one per slice) runs beside them as the CPU alternative users already have."
    )
    SCENES = ("brainsmall", "brain")

    def _scenes(self, profile):
        wanted = listed(profile, self, "scenes", self.SCENES, known=self.SCENES)
        image = profile.setting(self, "image_size", 256)
        brain_size = profile.setting(self, "brain_size", profile.volume_size)
        brain_image = profile.setting(self, "brain_image_size", profile.image_size)
        defs = {"brainsmall": ("brainsmall", phantom("brainsmall", preset="volpack"), image),
                "brain": ("folded_brain", phantom("folded_brain", brain_size, preset="volpack"), brain_image)}
        return {name: defs[name] for name in self.SCENES if name in wanted}

    def runs(self, profile):
        if not (is_registered(SW) or is_registered(VP)):
            return []
        truth_factor = profile.setting(self, "truth_step_factor", 0.25)
        runs = []
        for scene_name, (dataset, volume, image) in self._scenes(profile).items():
            spec = scene(scene_name, image, volumes=[volume])
            views = (headline_view(dataset),)
            tags = {"scene": scene_name, "dataset": dataset, "image_size": image}
            truth = truth_run(self.name, scene_name, spec, views, truth_factor, tags, config="reference")
            runs.append(truth)
            for config, (backend, options, _label) in VOLPACK_CONFIGS.items():
                if not accepts(backend, *options):
                    continue
                # Every configuration of a scene timed together, frame by frame: the claims' ratios pair them.
                runs.append(Run(self.name, f"{scene_name}.{config}", backend, spec, views, options=dict(options),
                                reference=truth.id, **timed_frames(profile, self), interleave=scene_name,
                                tags={**tags, "role": "test", "config": config}))
        return runs

    claims = (
        Claim("speed-1-worker", "On one core our shear-warp's kernels render a frame no slower than VolPack's "
              "classified-RLE library call on the same input", "technique time ratio ours / VolPack ≤ 1 (every scene: "
              "our kernels against VolPack's vpShadeTable + vpRenderClassifiedVolume)",
              lambda df: _speed(df, "shearwarp-1")),
        Claim("speed-all-cores", "With every core our shear-warp's kernels render a frame no slower than VolPack's "
              "library call (single-threaded)", "technique time ratio ours / VolPack ≤ 1 (every scene)",
              lambda df: _speed(df, "shearwarp-all")),
        Claim("images-agree", "Our images agree with VolPack's (the same algorithm and classification)",
              "PSNR ≥ 30 dB between the two (every scene)", lambda df: _agree(df)),
        Claim("accuracy-parity", "Our images are as close to the reference ray caster as VolPack's",
              "our PSNR ≥ VolPack's − 1 dB (every scene)", lambda df: _parity(df)),
        Claim("beats-vtk-cpu", "Shear-warp outruns a ray caster: ours on one core is faster than VTK's CPU "
              "ray caster on one thread at one sample per voxel", "technique time ratio ours / VTK ≤ 1 (every scene: "
              "our kernels against vtkRenderWindow.Render)",
              lambda df: _speed(df, "shearwarp-1", against="vtk-cpu-1", peer="VTK")),
        Claim("octree-vs-rle", "VolPack's fast-classification (octree) mode renders about 2× slower than its "
              "classified-RLE mode (Table 5.3: 1.8–2.5×)", "technique time ratio octree / RLE in 1.4–3.2 (every scene: "
              "VolPack's library calls)", lambda df: _octree(df)),
    )

    def paper_table(self):
        return tables.volpack_times()

    def report(self, results, ctx):
        ok = ok_rows(results)
        tests = speed_points(ok[ok.role == "test"])
        out = [blocks.Takeaways(_takeaways(ok))]
        if not tests.empty:
            out.append(linked_table("Frame time and accuracy, ours against VolPack", _against_volpack(ok, tests),
                                    ["scene", "technique", "time_ms", "time_ms_min", "time_ms_max", "time / VolPack RLE",
                                     "psnr", "ssim", "PSNR vs VolPack RLE (dB)", "SSIM vs VolPack RLE"], ctx,
                                    names={"psnr": "PSNR vs reference (dB)", "ssim": "SSIM vs reference"},
                                    csv_name="volpack.csv",
                                    caption="Time: median frame after warm-up with the fastest and slowest timed "
                                            "frame, preprocessing excluded. 'time / VolPack RLE' below 1: ours is "
                                            "faster. PSNR/SSIM against the reference ray caster and against VolPack's "
                                            "classified-RLE image of the same view."))
        for scene_name, group in tests.groupby("scene"):
            group = group.assign(technique=[_technique(c) for c in group.config])
            path, rel = ctx.plot_path(f"speed-{scene_name}")
            plots.speed_accuracy(group, path, time_col="time_ms", error_col="psnr", group_col="technique",
                                 title=_chart_title(scene_name, group), log_x=True, log_y=False,
                                 time_range_cols=("time_ms_min", "time_ms_max"), better="upper left",
                                 x_label="median frame time (ms); bars: fastest to slowest frame",
                                 y_label="PSNR against the reference (dB)")
            out.append(blocks.Figure(f"{scene_name}: frame time against accuracy", rel,
                                     "One point per technique; further left is faster, higher is closer to the "
                                     "reference ray caster."))
        for scene_name, group in ok.groupby("scene"):
            out.append(_gallery(scene_name, group, ctx))
        return out + not_measurable(unregistered(SW, VP) + missing_options(VP, "mode")
                                    + missing_options(SW, "workers"))


def _against_volpack(ok, tests):
    """``tests`` with their technique, their time over VolPack RLE's and PSNR/SSIM against its image (same scene)."""
    tests = tests.assign(technique=[_technique(c) for c in tests.config])
    compared = []
    for row in tests.itertuples():
        vp = rows_matching(ok, "VolPack", scene=row.scene, config="volpack-rle")
        entry = {"time / VolPack RLE": np.nan, "PSNR vs VolPack RLE (dB)": np.nan, "SSIM vs VolPack RLE": np.nan}
        if not vp.empty:
            entry["time / VolPack RLE"] = row.time_total / float(vp.time_total.iloc[0])
            if row.config != "volpack-rle":
                try:
                    pair = pair_metrics(vp.exr.iloc[0], row.exr)
                    entry["PSNR vs VolPack RLE (dB)"], entry["SSIM vs VolPack RLE"] = pair["psnr"], pair["ssim"]
                except ValueError:
                    pass
        compared.append(entry)
    return pd.concat([tests.reset_index(drop=True), pd.DataFrame(compared)], axis=1)


def _gallery(scene_name, group, ctx):
    """The scene's images side by side, each with its difference from VolPack RLE's (VolPack's own: the reference's)."""
    gallery = blocks.Gallery(f"{scene_name}: the images side by side", diff_scale=DIFF_SCALE,
                             caption="Each image with its difference from VolPack's classified-RLE image "
                                     "(VolPack's own: from the reference), same view and scale.")
    vp = group[group.config == "volpack-rle"]
    truth = group[group.role == "truth"]
    for row in group.sort_values("role", ascending=False).itertuples():
        if row.role == "truth":
            gallery.items.append(blocks.GalleryItem("reference ray caster", ctx.image(row.png),
                                                    note="single untimed frame, the ground truth"))
            continue
        against = truth if row.config == "volpack-rle" or vp.empty else vp
        extra = ()
        if row.config != "volpack-rle" and not truth.empty:
            extra = (("difference from the reference", ctx.difference(truth.exr.iloc[0], row.exr, DIFF_SCALE)),)
        gallery.items.append(blocks.GalleryItem(
            _technique(row.config), ctx.image(row.png),
            difference=ctx.difference(against.exr.iloc[0], row.exr, DIFF_SCALE) if not against.empty else None,
            label="render", extra=extra,
            note=f"{format_number(row.time_total * 1e3)} ms; PSNR against the reference "
                 f"{format_number(getattr(row, 'psnr', np.nan))} dB; the difference is from "
                 f"{'the reference' if against is truth else 'VolPack RLE'}"))
    return gallery


def _pairs(df, config, against="volpack-rle"):
    """``{scene: (ours, the other's)}``: the rows of both configurations for every scene where both rendered."""
    pairs = {}
    for scene_name in pd.unique(text_column(df, "scene")):
        ours = rows_matching(df, "", scene=scene_name, config=config)
        other = rows_matching(df, "", scene=scene_name, config=against)
        if not ours.empty and not other.empty:
            pairs[scene_name] = (ours, other)
    if not pairs:
        raise ValueError(f"no scene with both a successful {config} run and a {against} run")
    return pairs


def _speed(df, config, against="volpack-rle", peer="VolPack"):
    """Our technique time over the other's, every scene; the whole frames (wrappers, conversions) in the detail."""
    resampler = intervals.Resampler()
    pairs = _pairs(df, config, against)
    decisions = {s: judging.ratio(ours, other, judging.TECHNIQUE, resampler, at_most=1.0) for s, (ours, other) in pairs.items()}
    detail = "; ".join(f"{s}: technique ours {judging.milliseconds(o)}, {peer} {judging.milliseconds(v)}; whole frame "
                       f"ours {judging.milliseconds(o, judging.TOTAL)}, {peer} {judging.milliseconds(v, judging.TOTAL)}"
                       for s, (o, v) in pairs.items())
    if peer == "VolPack":
        detail += ("; VolPack's whole frame adds our wrapper's uint8 quantisation and image conversion, ours adds "
                   "Python around the kernels")
    rows = pd.concat([ours for ours, _ in pairs.values()])
    result = judging.judged(decisions, "; ".join(filter(None, [detail, judging.busy(rows)])))
    return judging.unless_starved(result, rows, holding_survives=True)


def _agree(df):
    values = {s: pair_metrics(vp.exr.iloc[0], ours.exr.iloc[0]) for s, (ours, vp) in _pairs(df, "shearwarp-1").items()}
    worst = min(values, key=lambda s: values[s]["psnr"])
    return ClaimResult(f"{format_number(values[worst]['psnr'])} dB ({worst})", bool(values[worst]["psnr"] >= 30.0),
                       "; ".join(f"{s}: PSNR {format_number(v['psnr'])} dB, SSIM {format_number(v['ssim'])}"
                                 for s, v in values.items()))


def _parity(df):
    gaps = {}
    for s, (ours, vp) in _pairs(df, "shearwarp-1").items():
        ours_psnr, vp_psnr = float(ours.iloc[0].get("psnr", np.nan)), float(vp.iloc[0].get("psnr", np.nan))
        if not (np.isfinite(ours_psnr) and np.isfinite(vp_psnr)):
            raise ValueError(f"{s}: no PSNR against the reference")
        gaps[s] = (ours_psnr, vp_psnr)
    worst = min(gaps, key=lambda s: gaps[s][0] - gaps[s][1])
    return ClaimResult(f"{format_number(gaps[worst][0] - gaps[worst][1])} dB ({worst})",
                       bool(gaps[worst][0] >= gaps[worst][1] - 1.0),
                       "; ".join(f"{s}: ours {format_number(o)} dB, VolPack {format_number(v)} dB" for s, (o, v) in gaps.items()))


def _octree(df):
    resampler = intervals.Resampler()
    decisions = {s: judging.ratio(octree, rle, judging.TECHNIQUE, resampler, at_least=1.4, at_most=3.2)
                 for s, (octree, rle) in _pairs(df, "volpack-octree").items()}
    return judging.judged(decisions, "thesis: ×1.8 (brainsmall), ×2.3 (brain); both VolPack's library calls "
                                     "(vpShadeTable, then vpRenderRawVolume or vpRenderClassifiedVolume)")


def _chart_title(scene_name, group):
    ours = group[group.config == "shearwarp-1"]
    vp = group[group.config == "volpack-rle"]
    if ours.empty or vp.empty:
        return f"{scene_name}: frame time against PSNR"
    ratio = float(ours.time_total.iloc[0] / vp.time_total.iloc[0])
    return f"{scene_name}: our shear-warp on 1 core is {change_words(ratio)} than VolPack"


def _takeaways(ok):
    """Per scene: each of our configurations against VolPack RLE, and VTK against ours."""
    sentences = []
    for scene_name in pd.unique(ok.scene) if "scene" in ok else []:
        part = ok[ok.scene == scene_name]
        vp = part[part.get("config") == "volpack-rle"] if "config" in part else part.iloc[:0]
        if vp.empty:
            continue
        vp_time = float(vp.time_total.iloc[0])
        for config in ("shearwarp-1", "shearwarp-all"):
            ours = part[part.config == config]
            if ours.empty:
                continue
            ratio = float(ours.time_total.iloc[0]) / vp_time
            sentence = (f"{scene_name}: {_technique(config)} takes {format_number(ours.time_total.iloc[0] * 1e3)} ms "
                        f"per frame against VolPack's {format_number(vp_time * 1e3)} ms (ratio {format_number(ratio)})")
            if config == "shearwarp-1":
                try:
                    pair = pair_metrics(vp.exr.iloc[0], ours.exr.iloc[0])
                    sentence += f"; the two images differ by {format_number(pair['psnr'])} dB PSNR"
                except ValueError:
                    pass
            sentences.append(sentence + ".")
        for config, peer in (("shearwarp-1", "vtk-cpu-1"), ("shearwarp-all", "vtk-cpu-all")):
            ours, vtk = part[part.config == config], part[part.config == peer]
            if not (ours.empty or vtk.empty):
                sentences.append(f"{scene_name}: {_technique(peer)} takes {format_number(vtk.time_total.iloc[0] * 1e3)} "
                                 f"ms, {as_ratio(vtk.time_total.iloc[0] / ours.time_total.iloc[0])} the time of "
                                 f"{_technique(config)}.")
    return sentences
