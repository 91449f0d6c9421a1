"""Lacroute 1995 (the VolPack thesis): the shear-warp factorization's experiments (note 003, §4.2).

Ten experiments, each with the thesis's own numbers beside ours (:meth:`paper_table`) and the
thesis's statements as claims checked on the measured table:

``lacroute1995-volpack``
    our ``shearwarp`` against ``volpack`` (the thesis's own library) on the same input and mode.
``lacroute1995-quality``
    E7/E8: error against the reference at 0°, 22.5° and 45° for a smooth and a binary transfer
    function (the 45° aliasing of Fig. 5.10), and opacity correction on a low-opacity cube.
``lacroute1995-matrix``
    E11: the optimisation matrix of Fig. 5.17 (samples and time for brute force, early
    termination only, RLE only, RLE + early termination).
``lacroute1995-angles``
    E4: time over a full turn (Fig. 5.3): no jump where the principal axis switches.
``lacroute1995-scaling``
    E2/E3: time against the volume size (n², not n³), RLE memory, the 2D warp against the image
    size (Table 5.4).
``lacroute1995-throughput``
    E12–E14: constant-opacity cubes and checkerboards (Figs 5.19–5.21), brute force beside, and
    the cost model ``T = N_v/a + N_r·b`` fitted and used to predict two scenes.
``lacroute1995-parallel``
    E16/E17: workers, the four task schedules of Ch. 6 and the task size.
``lacroute1995-shading``
    E18 lookup-table against procedural shading, E15 union-find variants, E22 the mode switch
    (octree against RLE build and render), VolPack's and our backend's.
``lacroute1995-projection``
    E2, Table 5.3 complete: parallel, perspective and fast classification over a turn of views,
    mean/fastest/slowest view, and each mode's memory.
``lacroute1995-perspective``
    E21: perspective image quality against the reference as the field of view widens.

Every timed comparison renders at least one warm-up frame and three timed frames (more when
the profile asks); runs of the reference renderer that serve as ground truth render one untimed
frame. Runs whose backend is not registered are not planned, and each report says what could not
be measured and why; a run that cannot happen here (backend unavailable, feature or real scan
missing) is recorded as skipped by the runner, and its claims come out "not measured".

Data sets whose body axis is the scanner's z (the heads, the brains, the engine) are viewed with
the camera of the gallery's upright rendering (:func:`upright_view`), without an object
transform, so that the backends render them in their own voxel frame.
"""

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

import datasets
from core.errors import InputError
from pipeline.experiments.base import Claim, ClaimResult, Experiment, Run, format_number
from pipeline.experiments.kit.model import Paper
from pipeline.experiments.verdicts import depends_on_missing
from pipeline.experiments.common import (UNTIMED, accepts, as_percent, as_ratio, dataset_view, file_exists, fit_line,
                                         headline_view, is_registered, missing_options, not_measurable, numeric,
                                         ok_rows, one_row, pair_metrics, read_exr, rows_matching, speed_points,
                                         stage_time, text_column, timed_frames, unregistered, usable_cores)
from pipeline.experiments.volbench import HEADLINE_VIEW, LINKS, _links, _ms, _phantom, _reference_exr, _scene
from reports import blocks, plots

PAPER = "lacroute1995"
SW, VP, REF = "shearwarp", "volpack", "reference"
DIFF_SCALE = 0.1
"""Absolute error at the top of the colour map of every difference image in these reports."""

SCHEDULES = ("round-robin-steal", "round-robin", "contiguous-steal", "contiguous")
"""The thesis's Ch. 6 task assignments, in its order of load imbalance (Table 6.4)."""

DEFAULT_SCHEDULE, DEFAULT_TASK_SIZE = "round-robin-steal", 8
"""The shearwarp backend's defaults (the agreed interface)."""

THESIS = "150 MHz SGI Indigo2 (R4400), 256² grey images"


# ------------------------------------------------------------------------------------ helpers
def opacity_deficit(reference_exr, test_exr, *, low=0.05, high=0.95):
    """How much more transparent ``test`` is than ``reference``: ``1 − τ_test/τ_ref`` (median).

    ``τ = −ln(1 − A)`` is the optical depth of a pixel's accumulated opacity; the median ratio
    is taken over pixels whose reference opacity lies in ``[low, high]`` (neither empty nor
    saturated). A renderer that leaves opacity uncorrected at a sample spacing ``Δ`` instead of
    ``Δ0`` shows ``1 − Δ0/Δ``: 29 % at 45° about one axis, 42 % about two.
    """
    a = read_exr(reference_exr)[..., 3].astype(np.float64)
    b = read_exr(test_exr)[..., 3].astype(np.float64)
    if a.shape != b.shape:
        raise ValueError(f"{test_exr} and {reference_exr} differ in size")
    mask = (a >= low) & (a <= high)
    if mask.sum() < 10:
        raise ValueError(f"fewer than 10 pixels of {reference_exr} have an opacity in [{low}, {high}]")
    tau_ref = -np.log1p(-a[mask])
    tau_test = -np.log1p(-np.clip(b[mask], 0.0, 1.0 - 1e-7))
    return float(1.0 - np.median(tau_test / tau_ref))

def fit_cost_model(visible, runs, seconds):
    """Least squares ``T = N_v/a + N_r·b + c`` (numpy lstsq): ``(a voxels/s, b s/run, c s, R²)``.

    The thesis's model (§5.3.5) has no constant; ``c`` takes the per-frame costs that depend on
    neither count (the shading and opacity tables, clearing, the warp).
    """
    visible, runs, seconds = (np.asarray(v, float) for v in (visible, runs, seconds))
    if len(seconds) < 4:
        raise ValueError(f"need at least four runs to fit the cost model, got {len(seconds)}")
    design = np.column_stack([visible, runs, np.ones_like(visible)])
    (per_voxel, per_run, constant), *_ = np.linalg.lstsq(design, seconds, rcond=None)
    predicted = design @ np.array([per_voxel, per_run, constant])
    total = np.sum((seconds - seconds.mean()) ** 2)
    r2 = 1.0 - np.sum((seconds - predicted) ** 2) / total if total > 0 else 1.0
    if per_voxel <= 0:
        raise ValueError(f"the fitted time per visible voxel is not positive ({per_voxel:.3g} s)")
    return float(1.0 / per_voxel), float(per_run), float(constant), float(r2)


def _truth_run(experiment, prefix, scene, views, step_factor, tags, **extra_tags):
    """The ground-truth run ``<prefix>.truth``: the reference renderer, one untimed frame.

    Parameters
    ----------
    experiment, prefix : str
        The experiment's name and the run id's prefix.
    scene : dict
    views : tuple of dict
    step_factor : float
        The reference's step, as a fraction of a voxel.
    tags : dict
        The run's tags; ``role="truth"`` and then ``extra_tags`` are added.
    """
    return Run(experiment, f"{prefix}.truth", REF, scene, views, options={"step_factor": step_factor}, **UNTIMED,
               tags={**tags, "role": "truth", **extra_tags})


def _truth_and_shearwarp(experiment, prefix, scene, views, step_factor, tags, *, pre_classified=False):
    """``[<prefix>.truth, <prefix>.shearwarp]``: the reference and one untimed shear-warp frame checked against it.

    With ``pre_classified`` also ``<prefix>.truth-pre`` (the reference classifying voxels before
    interpolating, the thesis's comparison caster) and ``<prefix>.shearwarp-vs-pre`` checked
    against it; every run is then tagged ``truth`` = ``post`` or ``pre``.
    """
    pairs = [("", "post", {"step_factor": step_factor})]
    if pre_classified:
        pairs.append(("-pre", "pre", {"step_factor": step_factor, "classification": "pre"}))
    runs = []
    for suffix, truth_kind, options in pairs:
        extra = {"truth": truth_kind} if pre_classified else {}
        truth = Run(experiment, f"{prefix}.truth{suffix}", REF, scene, views, options=options, **UNTIMED,
                    tags={**tags, "role": "truth", **extra})
        test_id = f"{prefix}.shearwarp" + (f"-vs{suffix}" if suffix else "")
        runs += [truth, Run(experiment, test_id, SW, scene, views, reference=truth.id, **UNTIMED,
                            tags={**tags, "role": "test", **extra})]
    return runs


def _title_or(make, ok, fallback, errors=(KeyError, ValueError)):
    """``make(ok)``, a chart title built from a claim's result, or ``fallback`` when it cannot be measured."""
    try:
        return make(ok)
    except errors:
        return fallback


def _claim_sentences(results, checks, template="{what}: {measured} ({detail}).", errors=(KeyError, ValueError)):
    """Takeaway sentences from claim checks on the successful runs, skipping those the data cannot measure.

    Parameters
    ----------
    results : DataFrame
        Every row of the experiment: a check that would read a run that should have happened here
        and did not (:func:`pipeline.experiments.verdicts.depends_on_missing`) gets no sentence, rather
        than one stating what the remaining runs show.
    checks : iterable of (callable, str)
        A check returning a :class:`ClaimResult`, and the words that introduce its result.
    template : str
        The sentence, with ``{what}``, ``{measured}`` and ``{detail}`` fields.
    errors : tuple of exception types
        What a check raises when its data is missing.
    """
    ok = ok_rows(results)
    sentences = []
    for fn, what in checks:
        if depends_on_missing(fn, results):
            continue
        try:
            result = fn(ok)
        except errors:
            continue
        sentences.append(template.format(what=what, measured=result.measured, detail=result.detail))
    return sentences


# =========================================================================== 1. against VolPack
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


class VolPackComparison(Experiment):
    """Our shear-warp against VolPack 1.0 on the same volumes, classification and view."""

    name = "lacroute1995-volpack"
    paper = PAPER
    title = "Our shear-warp against VolPack, the thesis's own library"
    settings = frozenset({"scenes", "image_size", "brain_size", "brain_image_size", "truth_step_factor", "repeat"})
    description = (
        "VolPack is the library the thesis describes (Ch. 8); its classified-RLE mode is the thesis's "
        "parallel-projection algorithm and its octree mode the fast-classification algorithm. Both "
        "backends render the same volume with the same classification (VolPack's brainsmall example: "
        "density ramp × gradient ramp), Blinn–Phong shading and the same oblique view: the real "
        "brainsmall.den (128×128×84) and the folded-brain phantom that stands in for the thesis's "
        "256×256×167 MR brain. Our shear-warp runs with one worker (VolPack is single-threaded) and "
        "with every core. Times are the median frame after warm-up, preprocessing (classification, "
        "RLE and octree builds) excluded as in the thesis; images are compared with each other and "
        "with the reference ray caster. VTK's fixed-point CPU ray caster (one sample per voxel, like "
        "shear-warp's one per slice) runs beside them as the CPU alternative users already have."
    )
    SCENES = ("brainsmall", "brain")

    def _scenes(self, profile):
        wanted = profile.setting(self.name, "scenes", list(self.SCENES))
        unknown = [s for s in wanted if s not in self.SCENES]
        if unknown:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.scenes: unknown {unknown}; "
                             f"known: {list(self.SCENES)}")
        image = profile.setting(self.name, "image_size", 256)
        brain_size = profile.setting(self.name, "brain_size", profile.volume_size)
        brain_image = profile.setting(self.name, "brain_image_size", profile.image_size)
        defs = {"brainsmall": ("brainsmall", _phantom("brainsmall", preset="volpack"), image),
                "brain": ("folded_brain", _phantom("folded_brain", brain_size, preset="volpack"), brain_image)}
        return {name: defs[name] for name in self.SCENES if name in wanted}

    def runs(self, profile):
        if not (is_registered(SW) or is_registered(VP)):
            return []
        truth_factor = profile.setting(self.name, "truth_step_factor", 0.25)
        runs = []
        for scene_name, (dataset, volume, image) in self._scenes(profile).items():
            scene = _scene(volume, profile, image_size=image, name=scene_name)
            views = (headline_view(dataset),)
            tags = {"scene": scene_name, "dataset": dataset, "image_size": image}
            truth = _truth_run(self.name, scene_name, scene, views, truth_factor, tags, config="reference")
            runs.append(truth)
            for config, (backend, options, _label) in VOLPACK_CONFIGS.items():
                if not accepts(backend, *options):
                    continue
                runs.append(Run(self.name, f"{scene_name}.{config}", backend, scene, views, options=dict(options),
                                reference=truth.id, **timed_frames(profile, self.name),
                                tags={**tags, "role": "test", "config": config}))
        return runs

    @property
    def claims(self):
        return (
            Claim("speed-1-worker", "On one core our shear-warp renders a frame no slower than VolPack's classified-RLE "
                  "mode on the same input", "time ratio ours / VolPack ≤ 1 (every scene)",
                  lambda df: _volpack_speed(df, "shearwarp-1")),
            Claim("speed-all-cores", "With every core our shear-warp renders a frame no slower than VolPack "
                  "(single-threaded)", "time ratio ours / VolPack ≤ 1 (every scene)",
                  lambda df: _volpack_speed(df, "shearwarp-all")),
            Claim("images-agree", "Our images agree with VolPack's (the same algorithm and classification)",
                  "PSNR ≥ 30 dB between the two (every scene)", _volpack_agree),
            Claim("accuracy-parity", "Our images are as close to the reference ray caster as VolPack's",
                  "our PSNR ≥ VolPack's − 1 dB (every scene)", _volpack_parity),
            Claim("beats-vtk-cpu", "Shear-warp outruns a ray caster: ours on one core is faster than VTK's CPU "
                  "ray caster on one thread at one sample per voxel", "time ratio ours / VTK ≤ 1 (every scene)",
                  lambda df: _volpack_speed(df, "shearwarp-1", against="vtk-cpu-1", peer="VTK")),
            Claim("octree-vs-rle", "VolPack's fast-classification (octree) mode renders about 2× slower than its "
                  "classified-RLE mode (Table 5.3: 1.8–2.5×)", "time ratio octree / RLE in 1.4–3.2 (every scene)",
                  _volpack_octree),
        )

    def paper_table(self):
        rows = [
            ("brainsmall", "parallel projection, classified RLE", 0.22, "0.19–0.26", 4),
            ("brain", "parallel projection, classified RLE", 0.86, "0.69–1.06", 19),
            ("brainsmall", "fast classification (raw array + min-max octree)", 0.40, "0.35–0.47", 8),
            ("brain", "fast classification (raw array + min-max octree)", 1.94, "1.51–2.36", 46),
            ("brainsmall", "classified RLE, one view (Table 5.5)", 0.154, "", None),
            ("brain", "classified RLE, one view (Table 5.5)", 0.824, "", None),
        ]
        return pd.DataFrame(rows, columns=["data set", "VolPack algorithm (thesis Tables 5.3, 5.5)", "mean time (s)",
                                           "fastest–slowest view (s)", "memory (MB)"]).assign(machine=THESIS)

    def report(self, results, ctx):

        ok = ok_rows(results)
        tests = ok[ok.role == "test"].copy()
        out = [blocks.Takeaways(_volpack_takeaways(ok))]
        rows = []
        for row in tests.itertuples():
            vp = rows_matching(ok, "VolPack", scene=row.scene, config="volpack-rle")
            entry = {"scene": row.scene, "technique": VOLPACK_CONFIGS.get(row.config, (None, None, row.config))[2],
                     "time (ms)": row.time_total * 1e3,
                     "fastest (ms)": getattr(row, "time_total_min", np.nan) * 1e3,
                     "slowest (ms)": getattr(row, "time_total_max", np.nan) * 1e3,
                     "time / VolPack RLE": np.nan, "PSNR vs reference (dB)": getattr(row, "psnr", np.nan),
                     "SSIM vs reference": getattr(row, "ssim", np.nan),
                     "PSNR vs VolPack RLE (dB)": np.nan, "SSIM vs VolPack RLE": np.nan}
            if not vp.empty:
                entry["time / VolPack RLE"] = row.time_total / float(vp.time_total.iloc[0])
                if row.config != "volpack-rle":
                    try:
                        pair = pair_metrics(vp.exr.iloc[0], row.exr)
                        entry["PSNR vs VolPack RLE (dB)"], entry["SSIM vs VolPack RLE"] = pair["psnr"], pair["ssim"]
                    except ValueError:
                        pass
            rows.append(entry)
        if rows:
            table = pd.concat([pd.DataFrame(rows), _links(tests.reset_index(drop=True), ctx)], axis=1)
            out.append(blocks.Table("Frame time and accuracy, ours against VolPack", table, csv_name="volpack.csv",
                                    links=LINKS,
                                    caption="Time: median frame after warm-up with the fastest and slowest timed "
                                            "frame, preprocessing excluded. 'time / VolPack RLE' below 1: ours is "
                                            "faster. PSNR/SSIM against the reference ray caster and against VolPack's "
                                            "classified-RLE image of the same view."))
        for scene, group in speed_points(tests).groupby("scene"):
            group = group.assign(technique=[VOLPACK_CONFIGS.get(c, (None, None, c))[2] for c in group.config])
            path, rel = ctx.plot_path(f"speed-{scene}")
            plots.speed_accuracy(group, path, time_col="time_ms", error_col="psnr", group_col="technique",
                                 title=_volpack_chart_title(scene, group), log_x=True, log_y=False,
                                 time_range_cols=("time_ms_min", "time_ms_max"), better="upper left",
                                 x_label="median frame time (ms); bars: fastest to slowest frame",
                                 y_label="PSNR against the reference (dB)")
            out.append(blocks.Figure(f"{scene}: frame time against accuracy", rel,
                                     "One point per technique; further left is faster, higher is closer to the "
                                     "reference ray caster."))
        for scene, group in ok.groupby("scene"):
            gallery = blocks.Gallery(f"{scene}: the images side by side", diff_scale=DIFF_SCALE,
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
                    extra = (("difference from the reference",
                              ctx.difference(truth.exr.iloc[0], row.exr, DIFF_SCALE)),)
                gallery.items.append(blocks.GalleryItem(
                    VOLPACK_CONFIGS.get(row.config, (None, None, row.config))[2], ctx.image(row.png),
                    difference=ctx.difference(against.exr.iloc[0], row.exr, DIFF_SCALE) if not against.empty else None,
                    label="render", extra=extra,
                    note=f"{format_number(row.time_total * 1e3)} ms; PSNR against the reference "
                         f"{format_number(getattr(row, 'psnr', np.nan))} dB; the difference is from "
                         f"{'the reference' if against is truth else 'VolPack RLE'}"))
            out.append(gallery)
        return out + not_measurable(unregistered(SW, VP) + missing_options(VP, "mode")
                                           + missing_options(SW, "workers"))


def _volpack_pairs(df, config, against="volpack-rle"):
    """``[(scene, ours row, the other's row)]`` for every scene where both rendered (VolPack RLE by default)."""
    pairs = []
    for scene in pd.unique(text_column(df, "scene")):
        ours = rows_matching(df, "", scene=scene, config=config)
        other = rows_matching(df, "", scene=scene, config=against)
        if not ours.empty and not other.empty:
            pairs.append((scene, ours.iloc[0], other.iloc[0]))
    if not pairs:
        raise ValueError(f"no scene with both a successful {config} run and a {against} run")
    return pairs


def _volpack_speed(df, config, against="volpack-rle", peer="VolPack"):
    pairs = _volpack_pairs(df, config, against)
    ratios = {scene: stage_time(ours) / stage_time(other) for scene, ours, other in pairs}
    worst = max(ratios, key=ratios.get)
    detail = "; ".join(f"{s}: ours {format_number(stage_time(o) * 1e3)} ms, {peer} {format_number(stage_time(v) * 1e3)} ms"
                       for s, o, v in pairs)
    return ClaimResult(", ".join(f"{as_ratio(r)} ({s})" for s, r in ratios.items()), bool(ratios[worst] <= 1.0), detail)


def _volpack_agree(df):
    values = {scene: pair_metrics(vp.exr, ours.exr) for scene, ours, vp in _volpack_pairs(df, "shearwarp-1")}
    worst = min(values, key=lambda s: values[s]["psnr"])
    return ClaimResult(f"{format_number(values[worst]['psnr'])} dB ({worst})", bool(values[worst]["psnr"] >= 30.0),
                       "; ".join(f"{s}: PSNR {format_number(v['psnr'])} dB, SSIM {format_number(v['ssim'])}"
                                 for s, v in values.items()))


def _volpack_parity(df):
    gaps = {}
    for scene, ours, vp in _volpack_pairs(df, "shearwarp-1"):
        ours_psnr, vp_psnr = float(ours.get("psnr", np.nan)), float(vp.get("psnr", np.nan))
        if not (np.isfinite(ours_psnr) and np.isfinite(vp_psnr)):
            raise ValueError(f"{scene}: no PSNR against the reference")
        gaps[scene] = (ours_psnr, vp_psnr)
    worst = min(gaps, key=lambda s: gaps[s][0] - gaps[s][1])
    return ClaimResult(f"{format_number(gaps[worst][0] - gaps[worst][1])} dB ({worst})",
                       bool(gaps[worst][0] >= gaps[worst][1] - 1.0),
                       "; ".join(f"{s}: ours {format_number(o)} dB, VolPack {format_number(v)} dB" for s, (o, v) in gaps.items()))


def _volpack_octree(df):
    ratios = {scene: stage_time(octree) / stage_time(rle) for scene, octree, rle in _volpack_pairs(df, "volpack-octree")}
    if not ratios:
        raise ValueError("no octree run")
    return ClaimResult(", ".join(f"{as_ratio(r)} ({s})" for s, r in ratios.items()),
                       bool(all(1.4 <= r <= 3.2 for r in ratios.values())), "thesis: ×1.8 (brainsmall), ×2.3 (brain)")


def _volpack_chart_title(scene, group):
    ours = group[group.config == "shearwarp-1"]
    vp = group[group.config == "volpack-rle"]
    if ours.empty or vp.empty:
        return f"{scene}: frame time against PSNR"
    ratio = float(ours.time_total.iloc[0] / vp.time_total.iloc[0])
    word = "faster" if ratio < 1 else "slower"
    return (f"{scene}: our shear-warp on 1 core is {format_number(1 / ratio if ratio < 1 else ratio, 2)}× {word} "
            f"than VolPack")


def _volpack_takeaways(ok):
    sentences = []
    for scene in pd.unique(ok.scene) if "scene" in ok else []:
        part = ok[ok.scene == scene]
        vp = part[part.get("config") == "volpack-rle"] if "config" in part else part.iloc[:0]
        if vp.empty:
            continue
        vp_time = float(vp.time_total.iloc[0])
        for config in ("shearwarp-1", "shearwarp-all"):
            ours = part[part.config == config]
            if ours.empty:
                continue
            ratio = float(ours.time_total.iloc[0]) / vp_time
            sentence = (f"{scene}: {VOLPACK_CONFIGS[config][2]} takes {format_number(ours.time_total.iloc[0] * 1e3)} ms "
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
                sentences.append(f"{scene}: {VOLPACK_CONFIGS[peer][2]} takes {format_number(vtk.time_total.iloc[0] * 1e3)} "
                                 f"ms, {as_ratio(vtk.time_total.iloc[0] / ours.time_total.iloc[0])} the time of "
                                 f"{VOLPACK_CONFIGS[config][2]}.")
    return sentences


# ================================================================= 2. image quality (E7, E8)
QUALITY_TFS = {
    # data set: (smooth preset, binary preset or explicit binary points, colour)
    "engine": ("smooth", "binary"),
    "engine_real": ("smooth", "binary"),
    "sphere": ("opaque", "binary"),
    "ct_skull": ("bone", 180),
}
"""Per data set, the smooth preset and the binary classification (a preset, or a raw threshold at
which a one-entry step from α 0 to 1 is built as the scene's transfer function)."""


def _binary_points(threshold, color=(0.95, 0.92, 0.85)):
    """A step transfer function at raw value ``threshold`` (one table entry wide), as scene points."""
    r, g, b = color
    return {"points": [[0.0, r, g, b, 0.0], [(threshold - 1) / 255, r, g, b, 0.0], [threshold / 255, r, g, b, 1.0],
                       [1.0, r, g, b, 1.0]], "name": f"binary{threshold}"}


def cube_value(size):
    """The constant-cube value whose opacity keeps the longest ray (the diagonal) unsaturated.

    With the identity preset α = value/255 per voxel; the diagonal crosses ``size·√3`` voxel
    lengths, and an optical depth of 1.5 there leaves the accumulated opacity near 0.78.
    """
    return int(max(1, round(255 * (1 - math.exp(-1.5 / (size * math.sqrt(3)))))))


CUBE_VIEWS = (("az0", 0.0, 0.0, 1.0), ("az45", 45.0, 0.0, math.sqrt(2)), ("diagonal", 45.0, math.degrees(math.atan(1 / math.sqrt(2))), math.sqrt(3)))
"""Views of the opacity-correction cube: name, azimuth, elevation, sample spacing Δ/Δ0."""


class ImageQuality(Experiment):
    """Shear-warp against the reference at 0°, 22.5°, 45°: smooth and binary classification; opacity correction."""

    name = "lacroute1995-quality"
    paper = PAPER
    title = "Image quality: the 45° worst case, binary classification and opacity correction (E7, E8)"
    settings = frozenset({"datasets", "volume_size", "image_size", "angles", "truth_step_factor", "shading",
                          "cube_size"})
    description = (
        "Shear-warp resamples bilinearly inside each slice and never between slices, so it is exact "
        "only when rays meet the slices head-on; at 45° the sample spacing is largest and frequencies "
        "across the slices alias. The thesis (Figs 5.9, 5.10) shows that with a smooth transfer function "
        "the images are nearly identical to a trilinear ray caster's at every angle, and that a binary "
        "classification aliases visibly at 45°. Each data set is rendered at 0°, 22.5° and 45° about its "
        "body axis with both classifications and compared with the reference at a fine step twice: "
        "against the ground truth, which classifies the interpolated scalar (CONVENTIONS), and against "
        "the reference classifying and shading the voxels before interpolating, as the thesis's "
        "comparison caster (and shear-warp itself) does; the first is what a user gets, the second "
        "isolates shear-warp's resampling from the classification order. Opacity "
        "correction (§4.1.6) is checked on a uniform low-opacity cube at 0°, 45° about one axis and along "
        "the diagonal: without it the image is too transparent by 1 − Δ0/Δ (29 % and 42 %)."
    )
    DATASETS = ("engine", "engine_real", "ct_skull")
    ANGLES = (0.0, 22.5, 45.0)

    def runs(self, profile):
        if not is_registered(SW):
            return []
        wanted = profile.setting(self.name, "datasets", list(self.DATASETS))
        unknown = [d for d in wanted if d not in QUALITY_TFS]
        if unknown:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.datasets: no smooth/binary pair for "
                             f"{unknown}; known: {sorted(QUALITY_TFS)}")
        size = profile.setting(self.name, "volume_size", profile.volume_size)
        image = profile.setting(self.name, "image_size", profile.image_size)
        angles = [float(a) for a in profile.setting(self.name, "angles", list(self.ANGLES))]
        truth_factor = profile.setting(self.name, "truth_step_factor", 0.125)
        shading = profile.setting(self.name, "shading", "phong")
        runs = []
        for dataset in wanted:
            views = tuple(dataset_view(dataset, f"az{a:g}", a) for a in angles)
            for tf, choice in zip(("smooth", "binary"), QUALITY_TFS[dataset]):
                if isinstance(choice, str):
                    volume = _phantom(dataset, size, preset=choice)
                else:
                    volume = _phantom(dataset, size, transfer_function=_binary_points(choice))
                scene = _scene(volume, profile, image_size=image, shading=shading, name=f"{dataset}-{tf}")
                tags = {"part": "classification", "dataset": dataset, "tf": tf}
                runs += _truth_and_shearwarp(self.name, f"{dataset}.{tf}", scene, views, truth_factor, tags,
                                             pre_classified=True)
        if accepts(SW, "opacity_correction", "min_opacity"):
            cube = profile.setting(self.name, "cube_size", size)
            value = cube_value(cube)
            volume = _phantom("constant_cube", cube, preset="identity", params={"value": value})
            scene = _scene(volume, profile, image_size=image, shading="none", name="cube")
            views = tuple({"view": name, "azimuth": az, "elevation": el} for name, az, el, _ in CUBE_VIEWS)
            tags = {"part": "opacity", "dataset": "constant_cube", "alpha": value / 255}
            truth = _truth_run(self.name, "cube", scene, views, 0.25, tags, correction="reference")
            runs.append(truth)
            for correction in (True, False):
                runs.append(Run(self.name, f"cube.{'corrected' if correction else 'uncorrected'}", SW, scene, views,
                                options={"opacity_correction": correction, "min_opacity": round(value / 255 / 2, 6)},
                                reference=truth.id, **UNTIMED,
                                tags={**tags, "role": "test", "correction": "on" if correction else "off"}))
        return runs

    claims = (
        Claim("smooth-0deg", "With a smooth transfer function shear-warp matches the ground-truth ray caster "
              "(post-classified, CONVENTIONS) head-on", "PSNR ≥ 35 dB at 0° (worst data set)",
              lambda df: _quality_smooth_head_on(df, "post")),
        Claim("smooth-0deg-pre", "With a smooth transfer function shear-warp matches a trilinear ray caster that "
              "classifies and shades voxels before interpolating, as the thesis's comparison caster does (Fig. 5.9), "
              "head-on", "PSNR ≥ 35 dB at 0° (worst data set)", lambda df: _quality_smooth_head_on(df, "pre")),
        Claim("smooth-all-angles", "With a smooth transfer function the error against the thesis's kind of ray caster "
              "stays small at every angle (Fig. 5.9)", "PSNR falls by ≤ 3 dB from 0° to 45° (worst data set)",
              lambda df: _quality_drop(df, "smooth", False)),
        Claim("binary-45deg-aliasing", "A binary classification aliases at 45° (Fig. 5.10a) where a smooth one "
              "barely does (5.10c), both against the thesis's kind of trilinear ray caster", "binary's PSNR loss "
              "from 0° to 45° exceeds the smooth one's by ≥ 1 dB (every data set)",
              lambda df: _quality_drop(df, "binary", True)),
        Claim("uncorrected-too-transparent", "Without opacity correction a 45° view is about 30 % too transparent "
              "(§4.1.6; 42 % along the diagonal)", "optical-depth deficit 29 % ± 7 (45°), 42 % ± 7 (diagonal)",
              lambda df: _opacity_uncorrected(df)),
        Claim("corrected-agrees", "With opacity correction the cube agrees with the ray caster at every angle",
              "optical-depth deficit within ±5 % (every view)", lambda df: _opacity_corrected(df)),
    )

    def paper_table(self):
        rows = [
            ("Fig. 5.9", "CT head at 45°, smooth classification", "shear-warp and trilinear ray caster 'virtually identical'"),
            ("Fig. 5.10a", "engine crop at 45°, binary classification", "aliasing visible in shear-warp"),
            ("Fig. 5.10b", "same, trilinear ray caster", "virtually no aliasing"),
            ("Fig. 5.10c", "engine crop at 45°, smooth classification", "aliasing barely noticeable"),
            ("§4.1.6", "opacity without correction at 45°", "30 % more transparent (about one axis; 1 − 1/√2 = 29 %)"),
            ("derived (note 003)", "opacity without correction, 45° about two axes", "42 % (1 − 1/√3)"),
        ]
        return pd.DataFrame(rows, columns=["thesis", "test", "finding (qualitative in the thesis)"])

    def report(self, results, ctx):

        ok = ok_rows(results)
        out = [blocks.Takeaways(_quality_takeaways(results))]
        tests = ok[(ok.get("part") == "classification") & (ok.role == "test")].copy() if "part" in ok else ok.iloc[:0]
        if not tests.empty:
            tests["angle (°)"] = [_angle_of(v) for v in tests.view]
            tests["truth"] = tests.truth.fillna("post") if "truth" in tests else "post"
            tests["against"] = tests.truth.map(TRUTHS)
            tests["series"] = tests.dataset + " " + tests.tf + " vs " + tests.truth + "-classified"
            table = tests[["dataset", "tf", "against", "angle (°)", "psnr", "ssim", "rmse", "max_error"]].rename(
                columns={"tf": "classification", "psnr": "PSNR (dB)", "ssim": "SSIM", "rmse": "RMSE",
                         "max_error": "largest error"})
            table = pd.concat([table.reset_index(drop=True), _links(tests.reset_index(drop=True), ctx)], axis=1)
            out.append(blocks.Table("Error against the reference by angle", table, csv_name="quality.csv", links=LINKS,
                                    caption="Each a single untimed frame; the reference renders at a fine step "
                                            "(the truth run's step factor), once post-classified (the ground truth) "
                                            "and once pre-classified (voxels classified and shaded, then "
                                            "interpolated: the thesis's comparison caster, which shares shear-warp's "
                                            "classification order). Angles turn about the body axis."))
            path, rel = ctx.plot_path("psnr-angle")
            plots.lines(tests, path, x="angle (°)", y="psnr", group="series",
                        title=_quality_chart_title(tests[tests.truth == "pre"]),
                   x_label="view angle to the volume axes (degrees)", y_label="PSNR against the reference (dB)",
                   vlines=(45.0,))
            out.append(blocks.Figure("Accuracy against the view angle", rel,
                                     "One line per data set, classification and reference; 45° (dotted) is the "
                                     "thesis's worst case."))
            gallery = blocks.Gallery("Binary and smooth classification at 0° and 45°", diff_scale=DIFF_SCALE,
                                     caption="Left the shear-warp image, right its difference from the reference "
                                             "named in the title.")
            shown = tests[tests["angle (°)"].isin([0.0, 45.0])]
            for row in shown.sort_values(["dataset", "tf", "angle (°)", "truth"]).itertuples():
                gallery.items.append(blocks.GalleryItem(
                    f"{row.dataset}, {row.tf}, {_angle_of(row.view):g}°, vs {row.truth}-classified",
                    ctx.image(row.png), difference=ctx.difference(_reference_exr(results, row), row.exr, DIFF_SCALE),
                    note=f"PSNR {format_number(row.psnr)} dB, SSIM {format_number(row.ssim)}; single untimed frame"))
            out.append(gallery)
        cube = ok[(ok.get("part") == "opacity") & (ok.role == "test")] if "part" in ok else ok.iloc[:0]
        if not cube.empty:
            rows = []
            for row in cube.itertuples():
                spacing = dict((n, s) for n, _a, _e, s in CUBE_VIEWS).get(row.view, np.nan)
                try:
                    deficit = opacity_deficit(_reference_exr(results, row), row.exr)
                except ValueError:
                    deficit = np.nan
                rows.append({"view": row.view, "correction": row.correction, "Δ/Δ0": spacing,
                             "too transparent (measured)": deficit,
                             "expected": 0.0 if row.correction == "on" else 1 - 1 / spacing,
                             "PSNR (dB)": getattr(row, "psnr", np.nan)})
            out.append(blocks.Table("Opacity correction on a uniform cube", pd.DataFrame(rows).sort_values(["view", "correction"]),
                                    caption="'Too transparent' is 1 − τ/τ_ref, τ = −ln(1 − A) the optical depth of a "
                                            "pixel (median over pixels with reference opacity 0.05–0.95). Without "
                                            "correction the expected deficit is 1 − Δ0/Δ.", csv_name="opacity_correction.csv"))
            gallery = blocks.Gallery("The cube with and without opacity correction", diff_scale=DIFF_SCALE,
                                     caption="Alpha composited over black; right the difference from the reference.")
            for row in cube.sort_values(["view", "correction"]).itertuples():
                gallery.items.append(blocks.GalleryItem(
                    f"{row.view}, correction {row.correction}", ctx.image(row.png),
                    difference=ctx.difference(_reference_exr(results, row), row.exr, DIFF_SCALE),
                    note=f"PSNR {format_number(getattr(row, 'psnr', np.nan))} dB; single untimed frame"))
            out.append(gallery)
        return out + not_measurable(unregistered(SW) + missing_options(SW, "opacity_correction", "min_opacity"))


def _angle_of(view):
    """The angle in a view name (``az22.5`` → 22.5, ``deg090`` → 90)."""
    match = re.search(r"(-?\d+(?:\.\d+)?)$", str(view))
    if not match:
        raise ValueError(f"view {view!r} names no angle")
    return float(match.group(1))


TRUTHS = {"post": "the ground truth (post-classified)", "pre": "the pre-classified caster (the thesis's comparison)"}
"""The two references of the quality study, by the ``truth`` tag."""


def _quality_rows(df, tf, truth="post"):
    """Shear-warp rows of classification ``tf`` measured against the ``truth`` reference (see :data:`TRUTHS`)."""
    rows = df[(text_column(df, "part") == "classification") & (text_column(df, "role") == "test") & (text_column(df, "tf") == tf)
              & (text_column(df, "truth") == truth)].copy()
    if rows.empty:
        raise ValueError(f"no successful shear-warp run with the {tf} classification against {TRUTHS[truth]}")
    rows["angle"] = [_angle_of(v) for v in rows.view]
    rows["psnr"] = numeric(rows, "psnr")
    return rows


def _quality_smooth_head_on(df, truth):
    rows = _quality_rows(df, "smooth", truth)
    head_on = rows[np.isclose(rows.angle, 0.0)]
    if head_on.empty:
        raise ValueError("no view at 0°")
    worst = head_on.loc[head_on.psnr.idxmin()]
    return ClaimResult(f"{format_number(worst.psnr)} dB ({worst.dataset})", bool(worst.psnr >= 35.0),
                       ", ".join(f"{r.dataset}: {format_number(r.psnr)} dB" for r in head_on.itertuples()))


def _psnr_at(rows, dataset, angle):
    match = rows[(rows.dataset == dataset) & np.isclose(rows.angle, angle)]
    if match.empty:
        raise ValueError(f"{dataset}: no view at {angle:g}°")
    return float(match.psnr.iloc[0])


def _quality_drop(df, tf, aliasing, truth="pre"):
    rows = _quality_rows(df, tf, truth)
    drops, details, holds = {}, [], True
    smooth = _quality_rows(df, "smooth", truth) if aliasing else None
    for dataset in pd.unique(rows.dataset):
        head_on, oblique = _psnr_at(rows, dataset, 0.0), _psnr_at(rows, dataset, 45.0)
        drops[dataset] = head_on - oblique
        detail = f"{dataset}: {format_number(head_on)} dB at 0°, {format_number(oblique)} dB at 45°"
        if aliasing:
            smooth_drop = _psnr_at(smooth, dataset, 0.0) - _psnr_at(smooth, dataset, 45.0)
            detail += f" (smooth loses {format_number(smooth_drop)} dB)"
            drops[dataset] -= smooth_drop  # the loss beyond the smooth classification's
            holds &= drops[dataset] >= 1.0
        else:
            holds &= drops[dataset] <= 3.0
        details.append(detail)
    key = min(drops, key=drops.get) if aliasing else max(drops, key=drops.get)
    what = "more than the smooth one loses" if aliasing else "lower at 45°"
    return ClaimResult(f"{format_number(drops[key])} dB {what} ({key})", bool(holds), "; ".join(details))


def _cube_deficits(df, correction):
    rows = df[(text_column(df, "part") == "opacity") & (text_column(df, "role") == "test") & (text_column(df, "correction") == correction)]
    truth = df[(text_column(df, "part") == "opacity") & (text_column(df, "role") == "truth")]
    if rows.empty or truth.empty:
        raise ValueError(f"no successful cube run with correction {correction} and its reference")
    deficits = {}
    for row in rows.itertuples():
        reference = truth[truth.view == row.view]
        if reference.empty:
            continue
        deficits[row.view] = opacity_deficit(reference.exr.iloc[0], row.exr)
    if not deficits:
        raise ValueError("no cube view rendered by both")
    return deficits


def _opacity_uncorrected(df):
    deficits = _cube_deficits(df, "off")
    expected = {name: 1 - 1 / spacing for name, _a, _e, spacing in CUBE_VIEWS if spacing > 1}
    measured = {v: d for v, d in deficits.items() if v in expected}
    if not measured:
        raise ValueError("no oblique cube view")
    holds = all(abs(d - expected[v]) <= 0.07 for v, d in measured.items())
    return ClaimResult(", ".join(f"{as_percent(d)} ({v})" for v, d in measured.items()), bool(holds),
                       ", ".join(f"{v}: expected {as_percent(expected[v])}" for v in measured)
                       + (f"; head-on: {as_percent(deficits['az0'])}" if "az0" in deficits else ""))


def _opacity_corrected(df):
    deficits = _cube_deficits(df, "on")
    worst = max(deficits, key=lambda v: abs(deficits[v]))
    return ClaimResult(f"{as_percent(deficits[worst])} ({worst})", bool(abs(deficits[worst]) <= 0.05),
                       ", ".join(f"{v}: {as_percent(d)}" for v, d in deficits.items()))


def _quality_chart_title(tests):
    parts = []
    for tf in ("binary", "smooth"):
        rows = tests[tests.tf == tf]
        drops = []
        for dataset in pd.unique(rows.dataset):
            sub = rows[rows.dataset == dataset]
            a, b = sub[np.isclose(sub["angle (°)"], 0.0)], sub[np.isclose(sub["angle (°)"], 45.0)]
            if not a.empty and not b.empty:
                drops.append(float(a.psnr.iloc[0] - b.psnr.iloc[0]))
        if drops:
            parts.append(f"{tf} loses {format_number(max(drops), 2)} dB")
    return ("From 0° to 45° " + ", ".join(parts)) if parts else "PSNR against the view angle"


def _real_versus_phantom(ok):
    """The smooth head-on PSNR against the pre-classified caster on real scans and on phantoms, side by side."""
    try:
        rows = _quality_rows(ok, "smooth", "pre")
    except (KeyError, ValueError):
        return []
    head_on = rows[np.isclose(rows.angle, 0.0)]
    kinds = {name: datasets.get(name).kind for name in pd.unique(head_on.dataset)}
    real = head_on[[kinds[d] == "real" for d in head_on.dataset]]
    phantom = head_on[[kinds[d] == "phantom" for d in head_on.dataset]]
    if real.empty or phantom.empty:
        return []
    listing = lambda frame: ", ".join(f"{r.dataset} {format_number(r.psnr)} dB" for r in frame.itertuples())
    return [f"Against the pre-classified caster, head-on with a smooth classification, the real scans give "
            f"{listing(real)} and the phantoms {listing(phantom)}. The phantoms' edges are not antialiased "
            f"(no partial-volume blur), the case the thesis (§5.1.2) names as one where bilinear slices "
            f"produce artifacts; their difference images put the error on the silhouettes."]


def _quality_takeaways(results):
    ok = ok_rows(results)
    sentences = _claim_sentences(results, ((lambda d: _quality_smooth_head_on(d, "post"), TRUTHS["post"]),
                                      (lambda d: _quality_smooth_head_on(d, "pre"), TRUTHS["pre"])),
                                 "Head-on with a smooth classification, against {what}: {measured} at worst "
                                 "({detail}).")
    sentences += _real_versus_phantom(ok)
    sentences += _claim_sentences(results, ((lambda d: _quality_drop(d, "binary", True), "binary classification"),
                                       (lambda d: _quality_drop(d, "smooth", False), "smooth classification")),
                                  "With a {what}, against the pre-classified caster, the PSNR is {measured}: "
                                  "{detail}.")
    for correction, label in (("off", "without"), ("on", "with")):
        try:
            deficits = _cube_deficits(ok, correction)
        except (KeyError, ValueError):
            continue
        sentences.append(f"The uniform cube {label} opacity correction is too transparent by "
                         + ", ".join(f"{as_percent(d)} ({v})" for v, d in deficits.items()) + ".")
    return sentences


# ====================================================================== 3. optimisation matrix
MATRIX_CONFIGS = {
    # config: (options, label, thesis test of Fig. 5.17)
    "brute-force": ({"rle": False, "early_termination": False}, "none (brute force)", 1),
    "early-termination": ({"rle": False, "early_termination": True}, "early termination only", 2),
    "rle": ({"rle": True, "early_termination": False}, "RLE only", 3),
    "rle+early-termination": ({"rle": True, "early_termination": True}, "RLE + early termination", 4),
}
MATRIX_THESIS = {
    # data set: {config: (samples, seconds)}, Fig. 5.17
    "brainsmall": {"brute-force": (1_397_844, 1.1), "early-termination": (1_021_395, 1.0), "rle": (301_138, 0.38),
                   "rle+early-termination": (32_495, 0.15), "octree": (90_391, 0.33)},
    "brain": {"brute-force": (11_030_183, 8.2), "early-termination": (8_556_478, 8.4), "rle": (1_760_992, 2.0),
              "rle+early-termination": (305_127, 0.82), "octree": (629_080, 1.94)},
}
MATRIX_DATASETS = {"brainsmall": "volpack", "folded_brain": "volpack", "ct_skull": "bone", "mrihead": "volpack"}
"""Data sets of the matrix and their classification: the real brainsmall, the brain stand-in, the
CT head stand-in (bone) and the real MR head."""


class OptimisationMatrix(Experiment):
    """Fig. 5.17: samples and time with each coherence optimisation on and off."""

    name = "lacroute1995-matrix"
    paper = PAPER
    title = "Impact of each coherence optimisation: samples and time (E11, Fig. 5.17)"
    settings = frozenset({"datasets", "volume_size", "image_size", "repeat"})
    description = (
        "The thesis's Fig. 5.17 renders the brain with neither coherence structure (brute-force "
        "shear-warp), with early ray termination only, with the run-length-encoded volume only, and with "
        "both. The sample counts (voxels resampled and composited) do not depend on the machine and are "
        "the best target for a reproduction: 1 : 0.78 : 0.16 : 0.028 for the brain. Early termination "
        "alone barely helps (most transparent voxels are not occluded); RLE alone gives 3–4×; both "
        "together about an order of magnitude. VolPack's octree mode (the thesis's test 5) is in the "
        "lacroute1995-volpack experiment."
    )
    DATASETS = ("brainsmall", "folded_brain", "ct_skull")

    def runs(self, profile):
        if not accepts(SW, "rle", "early_termination"):
            return []
        wanted = profile.setting(self.name, "datasets", list(self.DATASETS))
        unknown = [d for d in wanted if d not in MATRIX_DATASETS]
        if unknown:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.datasets: unknown {unknown}; "
                             f"known: {sorted(MATRIX_DATASETS)}")
        size = profile.setting(self.name, "volume_size", profile.volume_size)
        image = profile.setting(self.name, "image_size", profile.image_size)
        runs = []
        for dataset in wanted:
            volume = _phantom(dataset, size, preset=MATRIX_DATASETS[dataset])
            scene = _scene(volume, profile, image_size=image, name=dataset)
            for config, (options, _label, _test) in MATRIX_CONFIGS.items():
                runs.append(Run(self.name, f"{dataset}.{config}", SW, scene, (headline_view(dataset),), options=dict(options),
                                **timed_frames(profile, self.name), tags={"dataset": dataset, "config": config}))
        return runs

    claims = (
        Claim("sample-ratios", "Sample counts relative to brute force fall as in Fig. 5.17 "
              "(brain 1 : 0.78 : 0.16 : 0.028)",
              "early termination 0.5–1, RLE 0.05–0.35, both 0.005–0.1 (every data set)", lambda df: _matrix_samples(df)),
        Claim("early-termination-alone", "Early termination alone barely helps (thesis ×0.97–1.1)",
              "speed-up over brute force ≤ 2 (every data set)", lambda df: _matrix_speedup(df, "early-termination", None, 2.0)),
        Claim("rle-alone", "The RLE volume alone gives 3–4× (thesis ×2.9–4.1)", "speed-up 2–6 (every data set)",
              lambda df: _matrix_speedup(df, "rle", 2.0, 6.0)),
        Claim("rle-and-early-termination", "RLE and early termination together give about an order of magnitude "
              "(thesis ×7.1–9.9)", "speed-up ≥ 5 (every data set)",
              lambda df: _matrix_speedup(df, "rle+early-termination", 5.0, None)),
    )

    def paper_table(self):
        rows = []
        for dataset, configs in MATRIX_THESIS.items():
            brute_samples, brute_time = configs["brute-force"]
            for config, (samples, seconds) in configs.items():
                label = MATRIX_CONFIGS[config][1] if config in MATRIX_CONFIGS else "min-max octree + early termination"
                rows.append({"data set": dataset, "optimisation": label, "samples": samples,
                             "samples / brute force": samples / brute_samples, "time (s)": seconds,
                             "speed-up": brute_time / seconds})
        return pd.DataFrame(rows).assign(machine=THESIS)

    def report(self, results, ctx):

        ok = ok_rows(results)
        table = _matrix_table(ok)
        out = [blocks.Takeaways(_matrix_takeaways(table))]
        if table.empty:
            return out
        linked = pd.concat([table.reset_index(drop=True), _links(ok.loc[table.index].reset_index(drop=True), ctx)], axis=1)
        out.append(blocks.Table("Samples and time per optimisation", linked.drop(columns=["index"], errors="ignore"),
                                csv_name="matrix.csv", links=LINKS,
                                caption="Samples: the backend's `samples` counter (voxels resampled and composited). "
                                        "Thesis columns: Fig. 5.17's brain (brainsmall for brainsmall). Time: median "
                                        "frame after warm-up with the fastest and slowest timed frame."))
        points = speed_points(ok.loc[table.index]).assign(samples=table["samples"].to_numpy(float),
                                                            optimisation=table["optimisation"].to_numpy())
        path, rel = ctx.plot_path("time-samples")
        plots.speed_accuracy(points, path, time_col="time_ms", error_col="samples", group_col="dataset",
                             label_col="optimisation", title=_matrix_title(table), log_x=True, log_y=True,
                             time_range_cols=("time_ms_min", "time_ms_max"),
                             x_label="median frame time (ms); bars: fastest to slowest frame",
                             y_label="voxels resampled and composited per frame")
        out.append(blocks.Figure("Frame time against samples", rel,
                                 "One point per optimisation and data set, log–log: time follows the sample count."))
        bars = table.pivot_table(index="optimisation", columns="dataset", values="samples / brute force", sort=False)
        thesis = {MATRIX_CONFIGS[c][1]: s / MATRIX_THESIS["brain"]["brute-force"][0]
                  for c, (s, _t) in MATRIX_THESIS["brain"].items() if c in MATRIX_CONFIGS}
        bars["thesis (brain)"] = [thesis.get(i, np.nan) for i in bars.index]
        bars = bars.reset_index()
        path, rel = ctx.plot_path("sample-ratios")
        plots.bar_compare(bars, path, category_col="optimisation", value_cols=[c for c in bars.columns if c != "optimisation"],
                          value_label="samples / brute-force samples", log_y=True,
                          title="Sample counts relative to brute force, ours against Fig. 5.17")
        out.append(blocks.Figure("Sample counts relative to brute force", rel,
                                 "Hardware-independent: the thesis's brain beside each of our data sets (log scale)."))
        gallery = blocks.Gallery("The images of each optimisation (they should be alike)",
                                 caption="Single frames from the timed runs; early termination and the RLE skip only "
                                         "what cannot contribute (α ≤ 0.05 voxels, pixels with α ≥ 0.95).")
        for row in ok.loc[table.index].itertuples():
            gallery.items.append(blocks.GalleryItem(f"{row.dataset}: {MATRIX_CONFIGS.get(row.config, (0, row.config))[1]}",
                                                    ctx.image(row.png), note=f"{format_number(row.time_total * 1e3)} ms"))
        out.append(gallery)
        return out + not_measurable(unregistered(SW) + missing_options(SW, "rle", "early_termination"))


def _matrix_table(ok):
    rows = []
    if ok.empty or "config" not in ok:
        return pd.DataFrame()
    for row in ok.itertuples():
        brute = ok[(ok.dataset == row.dataset) & (ok.config == "brute-force")]
        samples = float(getattr(row, "count_samples", np.nan))
        brute_samples = float(brute.count_samples.iloc[0]) if not brute.empty and "count_samples" in brute else np.nan
        brute_time = float(brute.time_total.iloc[0]) if not brute.empty else np.nan
        thesis = MATRIX_THESIS["brainsmall" if row.dataset == "brainsmall" else "brain"]
        t_samples, t_time = thesis.get(row.config, (np.nan, np.nan))
        rows.append({"index": row.Index, "dataset": row.dataset,
                     "optimisation": MATRIX_CONFIGS.get(row.config, (None, row.config))[1],
                     "samples": samples, "samples / brute force": samples / brute_samples,
                     "thesis samples / brute force": t_samples / thesis["brute-force"][0],
                     "time (ms)": row.time_total * 1e3,
                     "fastest (ms)": getattr(row, "time_total_min", np.nan) * 1e3,
                     "slowest (ms)": getattr(row, "time_total_max", np.nan) * 1e3,
                     "speed-up": brute_time / row.time_total, "thesis speed-up": thesis["brute-force"][1] / t_time})
    table = pd.DataFrame(rows).set_index("index")
    table["_order"] = [list(MATRIX_CONFIGS).index(c) if c in MATRIX_CONFIGS else 9 for c in ok.loc[table.index, "config"]]
    return table.sort_values(["dataset", "_order"]).drop(columns="_order")


def _matrix_groups(df):
    groups = {}
    for dataset in pd.unique(text_column(df, "dataset")):
        part = rows_matching(df, "", dataset=dataset)
        configs = {c: part[text_column(part, "config") == c] for c in MATRIX_CONFIGS}
        if any(rows.empty for rows in configs.values()):
            continue
        groups[dataset] = {c: rows.iloc[0] for c, rows in configs.items()}
    if not groups:
        raise ValueError("no data set with all four configurations rendered")
    return groups


def _matrix_samples(df):
    bands = {"early-termination": (0.5, 1.0), "rle": (0.05, 0.35), "rle+early-termination": (0.005, 0.1)}
    measured, holds = [], True
    for dataset, rows in _matrix_groups(df).items():
        brute = float(rows["brute-force"]["count_samples"])
        if not brute > 0:
            raise ValueError(f"{dataset}: brute force reported no samples")
        ratios = {c: float(rows[c]["count_samples"]) / brute for c in bands}
        holds &= all(lo <= ratios[c] <= hi for c, (lo, hi) in bands.items())
        measured.append(f"{dataset} 1 : " + " : ".join(format_number(ratios[c], 2) for c in bands))
    return ClaimResult("; ".join(measured), bool(holds), "thesis brain 1 : 0.78 : 0.16 : 0.028, brainsmall 1 : 0.73 : 0.22 : 0.023")


def _matrix_speedup(df, config, low, high):
    speedups = {d: stage_time(rows["brute-force"]) / stage_time(rows[config]) for d, rows in _matrix_groups(df).items()}
    holds = all((low is None or s >= low) and (high is None or s <= high) for s in speedups.values())
    return ClaimResult(", ".join(f"{as_ratio(s)} ({d})" for d, s in speedups.items()), bool(holds),
                       f"thesis: brainsmall {as_ratio(1.1 / MATRIX_THESIS['brainsmall'][config][1])}, "
                       f"brain {as_ratio(8.2 / MATRIX_THESIS['brain'][config][1])}")


def _matrix_title(table):
    both = table[table.optimisation == MATRIX_CONFIGS["rle+early-termination"][1]]
    if both.empty:
        return "Frame time against the number of samples"
    return (f"RLE + early termination: {format_number(1 / both['samples / brute force'].median(), 2)}× fewer samples, "
            f"{format_number(both['speed-up'].median(), 2)}× faster than brute force (median)")


def _matrix_takeaways(table):
    sentences = []
    for dataset, part in table.groupby("dataset", sort=False) if not table.empty else []:
        ratios = " : ".join(format_number(v, 2) for v in part["samples / brute force"])
        speedups = ", ".join(f"{o} ×{format_number(s, 2)}" for o, s in zip(part.optimisation, part["speed-up"]))
        sentences.append(f"{dataset}: samples relative to brute force {ratios}; speed-ups {speedups}.")
    return sentences


# ============================================================================ 4. view angles
ANGLE_DATASETS = {"sphere": "opaque", "ct_skull": "bone", "cthead": "bone"}


def principal_axis(angle):
    """The object axis most parallel to the view at ``angle`` of the turntable (0: first, 1: second).

    Both turntables (about y for the sphere, about the body axis for the z-up heads) switch their
    principal axis at 45° + k·90°; a view exactly at a switch counts with the following quadrant.
    Used where a run does not report the axis it chose (``info_principal_axis``).
    """
    return int(((float(angle) + 45.0) % 180.0) // 90.0)


class ViewAngles(Experiment):
    """Fig. 5.3: rendering time over a full turn, and the principal-axis switch at 45°."""

    name = "lacroute1995-angles"
    paper = PAPER
    title = "Rendering time against the view angle (E4, Fig. 5.3)"
    settings = frozenset({"datasets", "volume_size", "image_size", "angle_step", "repeat"})
    description = (
        "Shear-warp keeps three run-length encodings, one per principal axis, and switches between "
        "them where the view crosses 45°. The thesis's Fig. 5.3 turns a 256³ sphere and the CT head "
        "through 360°: the sphere's time varies by only 6 %, the head's by 13 %, and nothing jumps at "
        "the switch. Each data set is turned about its vertical axis in equal steps, every view timed."
    )
    DATASETS = ("sphere", "ct_skull")

    def runs(self, profile):
        if not is_registered(SW):
            return []
        wanted = profile.setting(self.name, "datasets", list(self.DATASETS))
        unknown = [d for d in wanted if d not in ANGLE_DATASETS]
        if unknown:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.datasets: unknown {unknown}; "
                             f"known: {sorted(ANGLE_DATASETS)}")
        step = float(profile.setting(self.name, "angle_step", 10))
        if not 0 < step <= 90:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.angle_step: expected degrees in (0, 90], got {step}")
        size = profile.setting(self.name, "volume_size", profile.volume_size)
        image = profile.setting(self.name, "image_size", profile.image_size)
        angles = np.arange(0.0, 360.0 - 1e-9, step)
        runs = []
        for dataset in wanted:
            volume = _phantom(dataset, size, preset=ANGLE_DATASETS[dataset])
            scene = _scene(volume, profile, image_size=image, name=dataset)
            views = tuple(dataset_view(dataset, f"deg{a:g}", a) for a in angles)
            runs.append(Run(self.name, f"{dataset}.turn", SW, scene, views, **timed_frames(profile, self.name),
                            tags={"dataset": dataset, "angle_step": step}))
        return runs

    claims = (
        Claim("no-axis-switch-jump", "Time does not jump where the principal axis switches (45° + k·90°)",
              "largest change across a switch ≤ 1.5 × the largest between other neighbouring angles (every data set)",
              lambda df: _angles_jump(df)),
        Claim("no-axis-switch-jump-samples", "The work (samples composited) does not jump where the principal axis "
              "switches either", "largest change across a switch ≤ 1.5 × the largest elsewhere (every data set)",
              lambda df: _angles_jump(df, "count_samples")),
        Claim("sphere-flat", "The sphere's time hardly depends on the view (thesis: 6 %)",
              "(max − min)/mean ≤ 12 %", lambda df: _angles_variation(df, "sphere", 0.12)),
        Claim("head-varies-more", "The head's time varies more with the view than the sphere's (thesis: 13 % against 6 %)",
              "head variation > sphere variation", lambda df: _angles_head(df)),
    )

    def paper_table(self):
        return pd.DataFrame([
            ("sphere 256³", "6 %", "none"),
            ("CT head 256×256×225 (bone)", "13 %", "none (provided all three RLE copies fit in memory)"),
        ], columns=["data set (Fig. 5.3)", "time variation over 360°", "jump at the 45° axis switch"]).assign(machine=THESIS)

    def report(self, results, ctx):
        ok = ok_rows(results)
        frame = _angle_frame(ok)
        out = [blocks.Takeaways(_angles_takeaways(ok))]
        if frame.empty:
            return out
        frame["time_ms"] = frame.time_total * 1e3
        frame["time_ms_min"] = pd.to_numeric(frame.get("time_total_min"), errors="coerce") * 1e3
        frame["time_ms_max"] = pd.to_numeric(frame.get("time_total_max"), errors="coerce") * 1e3
        for dataset, part in frame.groupby("dataset"):
            path, rel = ctx.plot_path(f"angle-{dataset}")
            plots.lines(part, path, x="angle", y="time_ms", group="dataset", y_range=("time_ms_min", "time_ms_max"),
                   title=_angles_title(part, dataset), x_label="view angle about the vertical axis (degrees)",
                   y_label="median frame time (ms)", vlines=(45.0, 135.0, 225.0, 315.0))
            out.append(blocks.Figure(f"{dataset}: time over a full turn", rel,
                                     "Dotted: the principal-axis switches. Bars: fastest to slowest timed frame."))
        summary = []
        for dataset, part in frame.groupby("dataset"):
            stats = _angle_stats(part)
            summary.append({"data set": dataset, "views": len(part), "mean (ms)": stats["mean"] * 1e3,
                            "fastest view (ms)": stats["min"] * 1e3, "slowest view (ms)": stats["max"] * 1e3,
                            "variation": as_percent(stats["variation"]),
                            "thesis variation": {"sphere": "6 %"}.get(dataset, "13 % (CT head)"),
                            "largest change at a switch": as_percent(stats["switch"]),
                            "largest change elsewhere": as_percent(stats["other"]),
                            **_sample_columns(part)})
        out.append(blocks.Table("Variation over the turn", pd.DataFrame(summary), csv_name="angles.csv",
                                caption="Variation: (slowest − fastest view) / mean. Changes are between neighbouring "
                                        "angles, relative to the mean time."))
        gallery = blocks.Gallery("Views at 0°, 45° and 90°")
        for row in frame[frame.angle.isin([0.0, 45.0, 90.0])].sort_values(["dataset", "angle"]).itertuples():
            gallery.items.append(blocks.GalleryItem(f"{row.dataset} at {row.angle:g}°", ctx.image(row.png),
                                                    note=f"{format_number(row.time_ms)} ms"))
        out.append(gallery)
        return out + not_measurable(unregistered(SW))


def _angle_frame(df):
    if df.empty or "dataset" not in df:
        return pd.DataFrame()
    frame = df.copy()
    frame["angle"] = [_angle_of(v) for v in frame.view]
    frame["time_total"] = numeric(frame, "time_total")
    return frame.sort_values(["dataset", "angle"])


def _angle_stats(part, column="time_total"):
    """Mean, extremes, variation and the largest neighbour-to-neighbour changes of ``column`` over a turn."""
    part = part.sort_values("angle")
    times, angles = numeric(part, column).to_numpy(float), part.angle.to_numpy(float)
    if not np.isfinite(times).all():
        raise ValueError(f"{part.dataset.iloc[0]}: some views have no {column}")
    if len(times) < 3:
        raise ValueError(f"{part.dataset.iloc[0]}: fewer than three views")
    mean = float(times.mean())
    nxt = np.roll(np.arange(len(times)), -1)  # neighbours, with the wrap from the last angle to 360°
    changes = np.abs(times[nxt] - times) / mean
    if "info_principal_axis" in part and part.info_principal_axis.notna().all():
        axes = part.info_principal_axis.astype(str).to_numpy()  # the axis the backend chose
    else:
        axes = np.array([principal_axis(a) for a in angles])
    switch = axes != axes[nxt]
    if not switch.any() or switch.all():
        raise ValueError("need neighbouring views both across and away from an axis switch")
    return {"mean": mean, "min": float(times.min()), "max": float(times.max()),
            "variation": float((times.max() - times.min()) / mean),
            "switch": float(changes[switch].max()), "other": float(changes[~switch].max())}


def _sample_columns(part):
    try:
        stats = _angle_stats(part, "count_samples")
    except (KeyError, ValueError):
        return {}
    return {"samples: variation": as_percent(stats["variation"]), "samples: largest change at a switch": as_percent(stats["switch"]),
            "samples: largest change elsewhere": as_percent(stats["other"])}


def _angles_jump(df, column="time_total"):
    frame = _angle_frame(df)
    if frame.empty:
        raise ValueError("no successful turn")
    stats = {d: _angle_stats(p, column) for d, p in frame.groupby("dataset")}
    holds = all(s["switch"] <= 1.5 * s["other"] for s in stats.values())
    what = "time; timings on a shared machine are noisy" if column == "time_total" else "sample count (machine-independent)"
    return ClaimResult(", ".join(f"{as_percent(s['switch'])} at a switch vs {as_percent(s['other'])} elsewhere ({d})"
                                 for d, s in stats.items()), bool(holds),
                       f"changes between neighbouring angles relative to the mean {what}")


def _angles_variation(df, dataset, bound):
    frame = _angle_frame(df)
    part = frame[frame.dataset == dataset] if not frame.empty else frame
    if part.empty:
        raise ValueError(f"no successful turn of {dataset}")
    variation = _angle_stats(part)["variation"]
    detail = "thesis: 6 %"
    try:
        detail += f"; samples vary {as_percent(_angle_stats(part, 'count_samples')['variation'])}"
    except (KeyError, ValueError):
        pass
    return ClaimResult(as_percent(variation), bool(variation <= bound), detail)


def _angles_head(df):
    frame = _angle_frame(df)
    if frame.empty:
        raise ValueError("no successful turn")
    sphere = frame[frame.dataset == "sphere"]
    heads = frame[frame.dataset.isin(["ct_skull", "cthead"])]
    if sphere.empty or heads.empty:
        raise ValueError("needs both the sphere and a head")
    s = _angle_stats(sphere)["variation"]
    h = {d: _angle_stats(p)["variation"] for d, p in heads.groupby("dataset")}
    return ClaimResult(", ".join(f"{as_percent(v)} ({d})" for d, v in h.items()) + f" vs sphere {as_percent(s)}",
                       bool(all(v > s for v in h.values())), "thesis: head 13 %, sphere 6 %")


def _angles_title(part, dataset):
    try:
        stats = _angle_stats(part)
    except ValueError:
        return f"{dataset}: frame time over a full turn"
    jump = "no jump" if stats["switch"] <= 1.5 * stats["other"] else "a jump"
    return (f"{dataset}: time varies {as_percent(stats['variation'])} over the turn, {jump} at the axis switches\n"
            f"(largest change there {as_percent(stats['switch'])}, elsewhere {as_percent(stats['other'])})")


def _angles_takeaways(ok):
    frame = _angle_frame(ok)
    sentences = []
    for dataset, part in frame.groupby("dataset") if not frame.empty else []:
        try:
            stats = _angle_stats(part)
        except ValueError:
            continue
        sentences.append(f"{dataset}: over {len(part)} views the frame time runs from {format_number(stats['min'] * 1e3)} "
                         f"to {format_number(stats['max'] * 1e3)} ms ({as_percent(stats['variation'])}); the largest change "
                         f"between neighbours across an axis switch is {as_percent(stats['switch'])}, elsewhere {as_percent(stats['other'])}.")
    return sentences


# ============================================================================ 5. size scaling
SCALING_DATASETS = {"folded_brain": "volpack", "ct_skull": "bone"}
TABLE_5_4 = {"warp (ms)": {64: 5.0, 128: 17.0, 256: 64.0},
             64: {64: 7, 128: 20, 256: 48}, 128: {128: 11, 256: 31}, 256: {256: 9}}


class SizeScaling(Experiment):
    """Table 5.3's n² growth, RLE memory, and Table 5.4's warp cost against the image size."""

    name = "lacroute1995-scaling"
    paper = PAPER
    title = "Time and memory against the volume and image size (E2, E3; Tables 5.3, 5.4)"
    settings = frozenset({"datasets", "volume_sizes", "image_sizes", "image_size", "repeat"})
    description = (
        "Shear-warp's work is proportional to the voxels it actually composites, which for surfaces "
        "grows with the square of the resolution: the thesis's 8× larger data sets took 3.5–3.9× as "
        "long (Table 5.3), not 8×. The three run-length encodings together stay well below an unencoded "
        "4-byte-per-voxel array and comparable to the 1-byte raw volume. The 2D warp costs time "
        "proportional to the image's pixels and matters only when the image is much larger than the "
        "volume (Table 5.4). Each data set is rendered at several sizes from the same view; the brain "
        "stand-in also at several image sizes."
    )
    DATASETS = ("folded_brain", "ct_skull")
    VOLUME_SIZES = (64, 128, 256)
    IMAGE_SIZES = (64, 128, 256)

    def runs(self, profile):
        if not is_registered(SW):
            return []
        wanted = profile.setting(self.name, "datasets", list(self.DATASETS))
        unknown = [d for d in wanted if d not in SCALING_DATASETS]
        if unknown:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.datasets: unknown {unknown}; "
                             f"known: {sorted(SCALING_DATASETS)}")
        sizes = [int(s) for s in profile.setting(self.name, "volume_sizes", list(self.VOLUME_SIZES))]
        images = [int(s) for s in profile.setting(self.name, "image_sizes", list(self.IMAGE_SIZES))]
        growth_image = int(profile.setting(self.name, "image_size", max(images)))
        wanted_pairs = {}
        for dataset in wanted:
            for n in sizes:
                wanted_pairs[(dataset, n, growth_image)] = "growth"
        if wanted:
            for n in sizes:
                for i in images:
                    if i >= n:
                        wanted_pairs.setdefault((wanted[0], n, i), "warp")
        runs = []
        for (dataset, n, i), study in wanted_pairs.items():
            volume = _phantom(dataset, n, preset=SCALING_DATASETS[dataset])
            scene = _scene(volume, profile, image_size=i, name=f"{dataset}-{n}")
            runs.append(Run(self.name, f"{dataset}.v{n}.i{i}", SW, scene, (headline_view(dataset),), **timed_frames(profile, self.name),
                            tags={"dataset": dataset, "volume_size": n, "image_size": i,
                                  "growth": int(i == growth_image)}))
        return runs

    claims = (
        Claim("n-squared-growth", "Doubling the volume's side multiplies the frame time by about 4 (n²), not 8 "
              "(Table 5.3: ×3.5–3.9 for 8× the voxels)", "time ratio per doubling 2.8–5.7 at the largest sizes "
              "(every data set)", lambda df: _growth(df)),
        Claim("rle-memory", "The three RLE copies take less memory than an unencoded 4-byte-per-voxel array "
              "(head: 9.8 MB of RLE against 61 MB)", "rle_bytes < 4 B × voxels (every run)", lambda df: _rle_memory(df)),
        Claim("warp-per-pixel", "The warp's time is proportional to the image's pixels (Table 5.4: 5, 17, 64 ms)",
              "warp time ratio per doubling of the image side 2.5–5.5 (largest pair)", lambda df: _warp_growth(df)),
        Claim("warp-share", "The warp matters only when the image is much larger than the volume (48 % of the "
              "time at 64³ → 256², 9 % at 256³ → 256²)", "warp share at the largest image falls as the volume grows",
              lambda df: _warp_share(df)),
    )

    def paper_table(self):
        rows = [("parallel RLE, brainsmall → brain (7.95× voxels)", "time ×3.9"),
                ("parallel RLE, headsmall → head", "time ×3.5"),
                ("memory, head: 3×RLE + images + tables", "13 MB (RLE alone 9.8 MB)"),
                ("memory, head: unencoded 4 B/voxel array (fast classification)", "61 MB"),
                ("memory, head: raw 1 B/voxel volume", "14 MB"),
                ("warp time at 64², 128², 256² images (Table 5.4)", "5.0, 17, 64 ms"),
                ("warp share, 64³ volume at 64², 128², 256²", "7 %, 20 %, 48 %"),
                ("warp share, 128³ volume at 128², 256²", "11 %, 31 %"),
                ("warp share, 256³ volume at 256²", "9 %")]
        return pd.DataFrame(rows, columns=["quantity (thesis)", "value"]).assign(machine=THESIS)

    def report(self, results, ctx):
        ok = ok_rows(results)
        out = [blocks.Takeaways(_scaling_takeaways(results))]
        if ok.empty:
            return out
        frame = speed_points(ok)
        frame["volume_size"] = numeric(frame, "volume_size")
        frame["image_size"] = numeric(frame, "image_size")
        growth = frame[numeric(frame, "growth") == 1]
        if not growth.empty:
            lo = float(growth.volume_size.min())
            hi = float(growth.volume_size.max())
            base = float(growth[growth.volume_size == lo].time_ms.median())
            xs = np.array([lo, hi])
            path, rel = ctx.plot_path("growth")
            plots.lines(growth, path, x="volume_size", y="time_ms", group="dataset", y_range=("time_ms_min", "time_ms_max"),
                   log_x=True, log_y=True, title=_growth_title(ok),
                   x_label="volume size (voxels along the longest side)", y_label="median frame time (ms)",
                   guides=(("∝ n² (thesis)", xs, base * (xs / lo) ** 2), ("∝ n³ (brute force)", xs, base * (xs / lo) ** 3)))
            out.append(blocks.Figure("Frame time against the volume size", rel,
                                     f"Fixed {int(growth.image_size.iloc[0])}² image; grey lines of slope 2 and 3 through "
                                     "the smallest size. Bars: fastest to slowest timed frame."))
        if "time_warp" in frame:
            frame["warp_ms"] = numeric(frame, "time_warp") * 1e3
            frame["warp_ms_min"] = pd.to_numeric(frame.get("time_warp_min"), errors="coerce") * 1e3
            frame["warp_ms_max"] = pd.to_numeric(frame.get("time_warp_max"), errors="coerce") * 1e3
            frame["volume"] = [f"{int(v)}³ {d}" for v, d in zip(frame.volume_size, frame.dataset)]
            path, rel = ctx.plot_path("warp")
            image_sizes = np.array(sorted(frame.image_size.unique()), float)
            warp = frame[frame.dataset == frame.dataset.iloc[0]]
            guide = ()
            if len(image_sizes) > 1:
                ref_time = float(warp[warp.image_size == image_sizes[0]].warp_ms.median())
                guide = (("∝ pixels (thesis)", image_sizes, ref_time * (image_sizes / image_sizes[0]) ** 2),)
            plots.lines(warp, path, x="image_size", y="warp_ms", group="volume", y_range=("warp_ms_min", "warp_ms_max"),
                   log_x=True, log_y=True, title=_warp_title(ok), x_label="image size (pixels along a side)",
                   y_label="median warp time per frame (ms)", guides=guide)
            out.append(blocks.Figure("Warp time against the image size", rel,
                                     "One line per volume size; the grey line grows with the pixel count."))
            rows = []
            for row in warp.sort_values(["volume_size", "image_size"]).itertuples():
                thesis = TABLE_5_4.get(int(row.volume_size), {}).get(int(row.image_size))
                rows.append({"volume": row.volume, "image": f"{int(row.image_size)}²", "warp (ms)": row.warp_ms,
                             "thesis warp (ms)": TABLE_5_4["warp (ms)"].get(int(row.image_size), np.nan),
                             "share of the frame": as_percent(row.warp_ms / row.time_ms),
                             "thesis share": f"{thesis} %" if thesis is not None else ""})
            out.append(blocks.Table("The warp's cost beside Table 5.4", pd.DataFrame(rows), csv_name="warp.csv",
                                    caption="Medians of the timed frames; thesis: MR brain prefiltered to each size."))
        memory = []
        for row in ok.drop_duplicates(["dataset", "volume_size"]).itertuples():
            rle, raw = float(getattr(row, "count_rle_bytes", np.nan)), float(getattr(row, "count_raw_bytes", np.nan))
            memory.append({"data set": row.dataset, "size": int(float(row.volume_size)), "3×RLE (MB)": rle / 1e6,
                           "raw volume (MB)": raw / 1e6, "4 B/voxel array (MB)": 4 * raw / 1e6,
                           "RLE / raw": rle / raw, "RLE / 4 B per voxel": rle / (4 * raw)})
        out.append(blocks.Table("Memory of the three run-length encodings", pd.DataFrame(memory), csv_name="memory.csv",
                                caption="Counters rle_bytes and raw_bytes of the backend (1 byte per raw voxel: "
                                        "uint8 volumes). Thesis head: 9.8 MB of RLE, 14 MB raw, 61 MB at 4 B/voxel."))
        table = pd.concat([ok[["dataset", "volume_size", "image_size"]].reset_index(drop=True),
                           _ms(ok).reset_index(drop=True), _links(ok.reset_index(drop=True), ctx)], axis=1)
        out.append(blocks.Table("Every run", table, csv_name="scaling.csv", links=LINKS))
        return out + not_measurable(unregistered(SW))


def _growth_ratios(df, stage="total"):
    rows = df[numeric(df, "growth") == 1]
    ratios = {}
    for dataset in pd.unique(text_column(rows, "dataset")):
        part = rows[text_column(rows, "dataset") == dataset].copy()
        part["n"] = numeric(part, "volume_size")
        part = part.sort_values("n")
        if len(part) < 2:
            continue
        a, b = part.iloc[-2], part.iloc[-1]
        doublings = math.log2(b.n / a.n)
        ratios[dataset] = ((stage_time(b, stage) / stage_time(a, stage)) ** (1 / doublings), int(a.n), int(b.n))
    if not ratios:
        raise ValueError("no data set rendered at two sizes")
    return ratios


def _growth(df):
    ratios = _growth_ratios(df)
    detail = "; ".join(f"{d}: {a}³ → {b}³" for d, (_r, a, b) in ratios.items())
    try:
        composite = _growth_ratios(df, "composite")
        detail += "; compositing alone " + ", ".join(f"{as_ratio(r)} ({d})" for d, (r, _a, _b) in composite.items())
    except (KeyError, ValueError):
        pass
    return ClaimResult(", ".join(f"{as_ratio(r)} per doubling ({d})" for d, (r, _a, _b) in ratios.items()),
                       bool(all(2.8 <= r <= 5.66 for r, _a, _b in ratios.values())), detail)


def _rle_memory(df):
    """At each data set's largest size (the thesis's statement is about 256³ scans; at a few
    voxels the per-scanline offsets dominate), the RLE copies against 4 bytes per voxel."""
    frame = df.assign(rle=numeric(df, "count_rle_bytes"), raw=numeric(df, "count_raw_bytes"), n=numeric(df, "volume_size"))
    frame = frame[np.isfinite(frame.rle) & np.isfinite(frame.raw) & (frame.raw > 0)]
    if frame.empty:
        raise ValueError("no run reported rle_bytes and raw_bytes")
    largest = frame[frame.n == frame.groupby("dataset").n.transform("max")].drop_duplicates("dataset")
    fraction = {f"{r.dataset} {int(r.n)}³": r.rle / (4 * r.raw) for r in largest.itertuples()}
    per_raw = {f"{r.dataset} {int(r.n)}³": r.rle / r.raw for r in largest.itertuples()}
    return ClaimResult(", ".join(f"{format_number(v)} of the 4 B/voxel array ({k})" for k, v in fraction.items()),
                       bool(max(fraction.values()) < 1.0),
                       "RLE / raw 1 B/voxel volume: " + ", ".join(f"{format_number(v)} ({k})" for k, v in per_raw.items())
                       + " (thesis head 0.7, brain 1.9, images and tables included)")


def _warp_rows(df):
    frame = df.copy()
    frame["n"], frame["i"], frame["warp"] = numeric(frame, "volume_size"), numeric(frame, "image_size"), numeric(frame, "time_warp")
    first = text_column(frame, "dataset").iloc[0]
    return frame[(text_column(frame, "dataset") == first) & np.isfinite(frame.warp)]


def _warp_growth(df):
    frame = _warp_rows(df)
    smallest = frame[frame.n == frame.n.min()].sort_values("i")
    if len(smallest) < 2:
        raise ValueError("fewer than two image sizes at the smallest volume")
    a, b = smallest.iloc[-2], smallest.iloc[-1]
    ratio = (b.warp / a.warp) ** (1 / math.log2(b.i / a.i))
    return ClaimResult(f"{as_ratio(ratio)} per doubling ({int(a.i)}² → {int(b.i)}²)", bool(2.5 <= ratio <= 5.5),
                       ", ".join(f"{int(r.i)}²: {format_number(r.warp * 1e3)} ms" for r in smallest.itertuples())
                       + "; thesis ×3.4, ×3.8")


def _warp_share(df):
    frame = _warp_rows(df)
    frame["total"] = numeric(frame, "time_total")
    largest = frame[frame.i == frame.i.max()].sort_values("n")
    if len(largest) < 2:
        raise ValueError("fewer than two volume sizes at the largest image")
    shares = (largest.warp / largest.total).to_numpy()
    return ClaimResult(", ".join(f"{as_percent(s)} ({int(n)}³)" for s, n in zip(shares, largest.n)),
                       bool(np.all(np.diff(shares) < 0)), f"at {int(largest.i.iloc[0])}² images; thesis 48 %, 31 %, 9 %")


def _growth_title(ok):
    try:
        ratios = _growth_ratios(ok)
    except (KeyError, ValueError):
        return "Frame time against the volume size"
    return ("Time grows " + ", ".join(f"×{format_number(r, 2)} ({d})" for d, (r, _a, _b) in ratios.items())
            + " per doubling of the side\n(n² would be ×4, n³ ×8)")


def _warp_title(ok):
    return _title_or(lambda d: f"The warp costs {_warp_growth(d).measured} of the image side (pixels: ×4)", ok,
                     "Warp time against the image size", (KeyError, ValueError, IndexError))


def _scaling_takeaways(results):
    return _claim_sentences(results, ((_growth, "Frame time per doubling of the volume side"),
                                 (_rle_memory, "The three RLE copies take"), (_warp_growth, "The warp time grows"),
                                 (_warp_share, "The warp's share of the frame at the largest image")),
                            errors=(KeyError, ValueError, IndexError))


# ==================================================================== 6. throughput (E12–E14)
PREDICT_DATASETS = {"ct_skull": "bone", "engine": "surfaces"}
"""The scenes the fitted cost model predicts (the thesis predicts the CT head and the engine)."""


def all_visible_alpha(size):
    """The largest 8-bit opacity at which every non-transparent voxel of a face-on checkerboard is visible.

    A ray crosses ``size/2`` non-transparent voxels; their accumulated opacity must stay below the
    0.95 termination threshold: ``(size/2)·(−ln(1 − α)) < −ln 0.05 ≈ 3``, with some margin.
    """
    return max(1, math.floor(255 * (1 - math.exp(-2.8 / (size / 2))))) / 255


class Throughput(Experiment):
    """Figs 5.19–5.21: constant-opacity cubes and checkerboards; the cost model of §5.3.5."""

    name = "lacroute1995-throughput"
    paper = PAPER
    title = "Voxel throughput, run overhead and the cost model (E12–E14, Figs 5.19–5.21)"
    settings = frozenset({"volume_size", "image_size", "cube_alphas", "checker_blocks", "checker_alphas",
                          "brute_force", "predict", "repeat"})
    description = (
        "Where coherence is low the data structures cost more than they save. Constant-opacity cubes "
        "(one non-transparent run per scanline) measure the time per visible voxel: the thesis finds it "
        "linear in the visible voxels, with brute force flat and the crossover near 80 % visible. 3-D "
        "checkerboards with halving block sizes double the runs per scanline at a constant visible "
        "count: time is linear in the runs (400 ns per run on the R4400), and only 1-voxel runs make the "
        "optimised renderer slower than brute force, by about 15 %. A least-squares fit of T = N_v/a + "
        "N_r·b + c over all of these predicts the CT head and engine stand-ins. All views are face-on; "
        "the minimum-opacity threshold is set below the smallest opacity tested."
    )
    CUBE_ALPHAS = (0.0, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0)
    CHECKER_ALPHAS = ("all-visible", 1.0)
    MIN_OPACITY = 0.002

    def runs(self, profile):
        if not accepts(SW, "rle", "early_termination", "min_opacity"):
            return []
        n = int(profile.setting(self.name, "volume_size", profile.volume_size))
        image = profile.setting(self.name, "image_size", profile.image_size)
        brute_mode = profile.setting(self.name, "brute_force", "all")
        if brute_mode not in ("all", "ends"):
            raise InputError(f"profile {profile.name!r} settings.{self.name}.brute_force: expected 'all' or 'ends', "
                             f"got {brute_mode!r}")
        cube_alphas = [float(a) for a in profile.setting(self.name, "cube_alphas", list(self.CUBE_ALPHAS))]
        blocks_ = [int(b) for b in profile.setting(self.name, "checker_blocks",
                                                   [n // 2 ** k for k in range(1, 20) if n // 2 ** k >= 1])]
        checker_alphas = profile.setting(self.name, "checker_alphas", list(self.CHECKER_ALPHAS))
        view = ({"view": "face-on", "azimuth": 0.0, "elevation": 0.0},)
        timed = timed_frames(profile, self.name)
        runs = []

        def add(run_id, volume, options, tags):
            scene = _scene(volume, profile, image_size=image, shading="none", name=run_id.split(".")[0])
            runs.append(Run(self.name, run_id, SW, scene, view, options=options, **timed, tags=tags))

        optimised = {"min_opacity": self.MIN_OPACITY}
        brute = {"rle": False, "early_termination": False, "min_opacity": self.MIN_OPACITY}
        for index, alpha in enumerate(cube_alphas):
            value = int(round(alpha * 255))
            volume = _phantom("constant_cube", n, preset="identity", params={"value": value})
            tags = {"series": "cube", "alpha": value / 255, "block": n, "volume_size": n}
            add(f"cube{value}.optimised", volume, optimised, {**tags, "config": "optimised"})
            if brute_mode == "all" or index in (0, len(cube_alphas) - 1):
                add(f"cube{value}.brute", volume, brute, {**tags, "config": "brute-force"})
        for alpha in checker_alphas:
            alpha = all_visible_alpha(n) if alpha == "all-visible" else float(alpha)
            value = int(round(alpha * 255))
            for index, block in enumerate(blocks_):
                volume = _phantom("checkerboard", n, preset="identity", params={"block": block, "value": value})
                tags = {"series": f"checker α {value / 255:.3g}", "alpha": value / 255, "block": block, "volume_size": n}
                add(f"checker{value}.b{block}.optimised", volume, optimised, {**tags, "config": "optimised"})
                if brute_mode == "all" or index in (0, len(blocks_) - 1):
                    add(f"checker{value}.b{block}.brute", volume, brute, {**tags, "config": "brute-force"})
        for dataset in profile.setting(self.name, "predict", list(PREDICT_DATASETS)):
            if dataset not in PREDICT_DATASETS:
                raise InputError(f"profile {profile.name!r} settings.{self.name}.predict: unknown {dataset!r}; "
                                 f"known: {sorted(PREDICT_DATASETS)}")
            volume = _phantom(dataset, n, preset=PREDICT_DATASETS[dataset])
            scene = _scene(volume, profile, image_size=image, name=dataset)
            runs.append(Run(self.name, f"predict.{dataset}", SW, scene, (headline_view(dataset),), **timed,
                            tags={"series": "predict", "dataset": dataset, "config": "optimised", "volume_size": n}))
        return runs

    claims = (
        Claim("linear-in-visible-voxels", "Time is linear in the number of visible voxels (Fig. 5.19)",
              "R² ≥ 0.95 of a line through the cubes' times against their samples", lambda df: _cube_linear(df)),
        Claim("brute-force-flat", "Brute force takes the same time whatever the opacity (Fig. 5.19)",
              "(max − min)/median ≤ 25 % over the cubes", lambda df: _brute_flat(df)),
        Claim("crossover", "The optimised renderer beats brute force unless most voxels are visible "
              "(crossover ≈ 80 % visible; ≈ 25 % slower at 100 %)", "faster than brute force on every cube with ≤ 50 % "
              "of its voxels visible", lambda df: _crossover(df)),
        Claim("linear-in-runs", "At a constant visible count, time is linear in the number of runs (Fig. 5.21; "
              "400 ns per run)", "R² ≥ 0.9 per checkerboard series (time against voxel_runs)", lambda df: _runs_linear(df)),
        Claim("one-voxel-runs", "Even 1-voxel runs with every voxel visible make the optimised renderer only "
              "about 15 % slower than brute force", "optimised / brute force ≤ 1.3 at the smallest block, all visible",
              lambda df: _worst_runs(df)),
        Claim("cost-model", "T = N_v/a + N_r·b predicts real scenes (thesis: head 0.6 s predicted vs 0.76–0.87 s, "
              "engine 0.9 vs 0.92 s)", "prediction within 25 % of the measured time (every predicted scene)",
              lambda df: _prediction(df)),
    )

    def paper_table(self):
        rows = [("voxel throughput (slope of Fig. 5.19)", "880 Kvoxels/s (800 K in the cost model)"),
                ("cost per run (slope of Fig. 5.21)", "400 ns"),
                ("brute force against the optimised renderer", "crossover at 80 % visible; optimised 25 % slower at 100 %"),
                ("checkerboards, ≤ 40 % visible", "optimised always faster"),
                ("checkerboards, 50 % visible", "crossover at 192 runs per scanline; 15 % slower at 256"),
                ("cost model, CT head (N_v 400 K, N_r 340 K)", "0.6 s predicted, 0.76–0.87 s measured"),
                ("cost model, engine (N_v ≈ 600 K, N_r 300 K)", "0.9 s predicted, 0.92 s measured")]
        return pd.DataFrame(rows, columns=["quantity (thesis §5.3)", "value"]).assign(machine=THESIS)

    def report(self, results, ctx):
        ok = ok_rows(results)
        if ok.empty:
            return []
        frame = speed_points(ok)
        frame["samples"] = numeric(frame, "count_samples")
        frame["runs"] = numeric(frame, "count_voxel_runs")
        out = [blocks.Takeaways(_throughput_takeaways(results))]
        cubes = frame[frame.series == "cube"].copy()
        if not cubes.empty:
            cubes["visible (millions)"] = cubes.samples / 1e6
            brute_level = cubes[cubes.config == "brute-force"]
            opt = cubes[cubes.config == "optimised"]
            path, rel = ctx.plot_path("cubes")
            guides = ()
            if not brute_level.empty and not opt.empty:
                xs = np.array([0.0, float(opt["visible (millions)"].max())])
                guides = (("brute force (median over its runs)", xs, np.full(2, float(brute_level.time_ms.median()))),)
            plots.lines(opt.assign(config="optimised (RLE + early termination)"), path, x="visible (millions)", y="time_ms",
                   group="config", y_range=("time_ms_min", "time_ms_max"), title=_cube_title(ok),
                   x_label="voxels composited per frame (millions)", y_label="median frame time (ms)", guides=guides)
            out.append(blocks.Figure("Constant-opacity cubes: time against visible voxels", rel,
                                     "Each point one opacity (visible voxels fall as the opacity rises and early "
                                     "termination cuts the rays short). Bars: fastest to slowest frame."))
        checkers = frame[frame.series.astype(str).str.startswith("checker")].copy()
        if not checkers.empty:
            checkers["line"] = checkers.series + ", " + checkers.config
            path, rel = ctx.plot_path("checkerboards")
            plots.lines(checkers, path, x="runs", y="time_ms", group="line", y_range=("time_ms_min", "time_ms_max"),
                   title=_runs_title(ok), x_label="voxel runs traversed per frame (the backend's voxel_runs)",
                   y_label="median frame time (ms)")
            out.append(blocks.Figure("Checkerboards: time against the number of runs", rel,
                                     "Block sizes halve from right to left... each halving doubles the runs per "
                                     "scanline at a constant visible count; brute force beside."))
        try:
            a, b, c, r2 = _cost_fit(ok)
            fit = pd.DataFrame([{"quantity": "throughput a", "ours": f"{format_number(a / 1e6)} Mvoxels/s",
                                 "thesis": "0.88 Mvoxels/s"},
                                {"quantity": "cost per run b", "ours": f"{format_number(b * 1e9)} ns", "thesis": "400 ns"},
                                {"quantity": "fixed cost per frame c", "ours": f"{format_number(c * 1e3)} ms",
                                 "thesis": "(not in the model)"},
                                {"quantity": "R² of the fit", "ours": format_number(r2), "thesis": ""}])
            out.append(blocks.Table("The cost model T = N_v/a + N_r·b + c, fitted", fit,
                                    caption="numpy lstsq over every optimised cube and checkerboard run; N_v: the "
                                            "samples counter, N_r: voxel_runs."))
        except (KeyError, ValueError):
            pass
        columns = [c for c in ("series", "config", "alpha", "block", "samples", "runs") if c in frame]
        table = pd.concat([frame[columns].reset_index(drop=True), _ms(ok).reset_index(drop=True),
                           _links(ok.reset_index(drop=True), ctx)], axis=1)
        out.append(blocks.Table("Every run", table, csv_name="throughput.csv", links=LINKS))
        return out + not_measurable(unregistered(SW) + missing_options(SW, "rle", "early_termination", "min_opacity"))


def _series(df, series, config):
    rows = df[(text_column(df, "series") == series) & (text_column(df, "config") == config)].copy()
    rows["samples"], rows["runs"] = numeric(rows, "count_samples"), numeric(rows, "count_voxel_runs")
    rows["time"] = numeric(rows, "time_total")
    return rows[np.isfinite(rows.time)]


def _cube_linear(df):
    rows = _series(df, "cube", "optimised")
    slope, intercept, r2 = fit_line(rows.samples, rows.time)
    return ClaimResult(f"R² {format_number(r2)}", bool(r2 >= 0.95),
                       f"{format_number(1 / slope / 1e6)} Mvoxels/s, {format_number(intercept * 1e3)} ms fixed; thesis 0.88 Mvoxels/s")


def _brute_flat(df):
    rows = _series(df, "cube", "brute-force")
    if len(rows) < 2:
        raise ValueError("fewer than two brute-force cubes")
    spread = float((rows.time.max() - rows.time.min()) / rows.time.median())
    return ClaimResult(as_percent(spread), bool(spread <= 0.25), f"{len(rows)} cubes, median {format_number(rows.time.median() * 1e3)} ms")


def _cube_visible(df):
    rows = _series(df, "cube", "optimised")
    brute = _series(df, "cube", "brute-force")
    if rows.empty or brute.empty:
        raise ValueError("needs optimised and brute-force cubes")
    total = float(brute.samples.max())
    if not total > 0:
        raise ValueError("brute force reported no samples")
    rows["visible"] = rows.samples / total
    return rows.sort_values("visible"), float(brute.time.median())


def _crossover(df):
    rows, level = _cube_visible(df)
    low = rows[rows.visible <= 0.5]
    if low.empty:
        raise ValueError("no cube with at most half of its voxels visible")
    holds = bool((low.time < level).all())
    slower = rows[rows.time >= level]
    crossing = "never (optimised always faster)" if slower.empty else f"{as_percent(float(slower.visible.min()))} visible"
    most = rows.iloc[-1]
    return ClaimResult(f"slower than brute force from {crossing}", holds,
                       f"at {as_percent(float(most.visible))} visible the optimised renderer takes {as_ratio(float(most.time / level))} "
                       "the brute-force time (thesis: ×1.25 at 100 %)")


def _runs_linear(df):
    series = [s for s in pd.unique(text_column(df, "series")) if s.startswith("checker")]
    fits = {}
    for s in series:
        rows = _series(df, s, "optimised")
        if len(rows) >= 3:
            fits[s] = fit_line(rows.runs, rows.time)
    if not fits:
        raise ValueError("no checkerboard series with three block sizes")
    return ClaimResult(", ".join(f"R² {format_number(r2)} ({s})" for s, (_a, _b, r2) in fits.items()),
                       bool(all(r2 >= 0.9 for _a, _b, r2 in fits.values())),
                       ", ".join(f"{format_number(slope * 1e9)} ns per run ({s})" for s, (slope, _b, _r) in fits.items())
                       + "; thesis 400 ns")


def _worst_runs(df):
    series = [s for s in pd.unique(text_column(df, "series")) if s.startswith("checker")]
    ratios = {}
    for s in series:
        opt, brute = _series(df, s, "optimised"), _series(df, s, "brute-force")
        if opt.empty or brute.empty:
            continue
        opt["block"], brute["block"] = numeric(opt, "block"), numeric(brute, "block")
        smallest = opt.block.min()
        match = brute[brute.block == smallest]
        if match.empty:
            continue
        ratios[s] = (float(opt[opt.block == smallest].time.iloc[0] / match.time.iloc[0]), int(smallest))
    if not ratios:
        raise ValueError("no checkerboard with both renderers at its smallest block")
    # The all-visible series is the thesis's worst case: the lowest opacity.
    key = min(ratios, key=lambda s: float(s.split("α")[-1]))
    ratio, block = ratios[key]
    return ClaimResult(f"{as_ratio(ratio)} ({key}, {block}-voxel blocks)", bool(ratio <= 1.3),
                       ", ".join(f"{s}: {as_ratio(r)}" for s, (r, _b) in ratios.items()) + "; thesis ×1.15")


def _cost_fit(df):
    rows = df[text_column(df, "config") == "optimised"]
    rows = rows[text_column(rows, "series") != "predict"]
    samples, runs, time = numeric(rows, "count_samples"), numeric(rows, "count_voxel_runs"), numeric(rows, "time_total")
    keep = np.isfinite(samples) & np.isfinite(runs) & np.isfinite(time)
    return fit_cost_model(samples[keep], runs[keep], time[keep])


def _prediction(df):
    a, b, c, _r2 = _cost_fit(df)
    rows = df[text_column(df, "series") == "predict"]
    if rows.empty:
        raise ValueError("no predicted scene rendered")
    errors = {}
    for row in rows.itertuples():
        predicted = float(row.count_samples) / a + float(row.count_voxel_runs) * b + c
        errors[row.dataset] = (predicted, float(row.time_total))
    holds = all(abs(p - m) / m <= 0.25 for p, m in errors.values())
    return ClaimResult(", ".join(f"{format_number((p - m) / m * 100)} % ({d})" for d, (p, m) in errors.items()), bool(holds),
                       "; ".join(f"{d}: predicted {format_number(p * 1e3)} ms, measured {format_number(m * 1e3)} ms"
                                 for d, (p, m) in errors.items())
                       + f"; a = {format_number(a / 1e6)} Mvoxels/s, b = {format_number(b * 1e9)} ns/run, c = {format_number(c * 1e3)} ms")


def _cube_title(ok):
    try:
        linear = _cube_linear(ok)
        cross = _crossover(ok)
    except (KeyError, ValueError):
        return "Constant-opacity cubes: frame time against visible voxels"
    return f"Time is linear in visible voxels ({linear.measured});\noptimised {cross.measured}"


def _runs_title(ok):
    return _title_or(lambda d: f"Time grows linearly with the runs: {_runs_linear(d).detail.split(';')[0]}", ok,
                     "Checkerboards: frame time against the number of runs")


def _throughput_takeaways(results):
    return _claim_sentences(results, ((_cube_linear, "Cubes, time against visible voxels"), (_crossover, "Against brute force"),
                                 (_runs_linear, "Checkerboards, time against runs"),
                                 (_worst_runs, "1-voxel runs against brute force"),
                                 (_prediction, "The fitted cost model's error on real scenes")))


# ======================================================================= 7. parallel (E16, E17)
TABLE_6_2 = {"CT head 128³": (2.5, 5.3, 9.9, 18, 31), "CT head 256×256×225": (1.1, 2.2, 4.3, 7.5, 13)}
TABLE_6_4 = {"round-robin-steal": (7, 149), "round-robin": (18, 160), "contiguous-steal": (32, 187), "contiguous": (169, 342)}


class Parallel(Experiment):
    """Ch. 6: speed-up with workers, the four task assignments and the task size."""

    name = "lacroute1995-parallel"
    paper = PAPER
    title = "Multiprocessor rendering: speed-up, load balancing and task size (E16, E17)"
    settings = frozenset({"volume_sizes", "image_size", "workers", "schedules", "task_sizes", "dataset", "preset",
                          "repeat"})
    description = (
        "The thesis partitions the intermediate image into groups of scanlines (tasks) and hands them "
        "to processors contiguously or round robin, with or without stealing (Ch. 6). On the 16-CPU SGI "
        "Challenge it reached 75 % efficiency; round robin with stealing balanced best (7 % imbalance) "
        "and contiguous blocks without stealing worst (169 %, 2.3× slower); small tasks cost memory "
        "locality and large ones idle time, so the total overhead is U-shaped in the task size. Here the "
        "CT head stand-in is rendered with 1, 2, … workers (as many as this machine has), each "
        "schedule at the most workers, and a sweep of task sizes. With few cores the differences the "
        "thesis saw at 16–32 processors may not show; the claims say so when they cannot."
    )
    TASK_SIZES = (1, 2, 4, 8, 16, 32, 64)

    def runs(self, profile):
        if not accepts(SW, "workers", "schedule", "task_size"):
            return []
        cores = usable_cores()
        workers = [int(w) for w in profile.setting(self.name, "workers",
                                                   sorted({1, *[2 ** k for k in range(1, 8) if 2 ** k <= cores], cores}))]
        schedules = profile.setting(self.name, "schedules", list(SCHEDULES))
        unknown = [s for s in schedules if s not in SCHEDULES]
        if unknown:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.schedules: unknown {unknown}; known: {list(SCHEDULES)}")
        task_sizes = [int(t) for t in profile.setting(self.name, "task_sizes", list(self.TASK_SIZES))]
        sizes = [int(s) for s in profile.setting(self.name, "volume_sizes", [profile.volume_size])]
        image = profile.setting(self.name, "image_size", profile.image_size)
        dataset = profile.setting(self.name, "dataset", "ct_skull")
        preset = profile.setting(self.name, "preset", datasets.get(dataset).default_preset)
        most = max(workers)
        runs = []
        for n in sizes:
            volume = _phantom(dataset, n, preset=preset)
            scene = _scene(volume, profile, image_size=image, name=f"{dataset}-{n}")
            configs = {}
            for w in workers:
                configs[(w, DEFAULT_SCHEDULE, DEFAULT_TASK_SIZE)] = "workers"
            for s in schedules:
                configs.setdefault((most, s, DEFAULT_TASK_SIZE), "schedule")
            for t in task_sizes:
                configs.setdefault((most, DEFAULT_SCHEDULE, t), "task_size")
            for (w, s, t), study in configs.items():
                runs.append(Run(self.name, f"{dataset}{n}.w{w}.{s}.t{t}", SW, scene, (headline_view(dataset),),
                                options={"workers": w, "schedule": s, "task_size": t}, **timed_frames(profile, self.name),
                                tags={"dataset": dataset, "volume_size": n, "workers": w, "schedule": s,
                                      "task_size": t, "study": study}))
        return runs

    claims = (
        Claim("speed-up", "Rendering speeds up nearly linearly with processors (thesis: ×2.0–2.1 on 2, 75 % "
              "efficiency on 16)", "efficiency T1 / (p·Tp) ≥ 70 % at the most workers (every size)",
              lambda df: _speedup(df)),
        Claim("schedule-order", "Round robin with stealing balances best and contiguous blocks without stealing worst "
              "(Table 6.4: 149 < 160 < 187 < 342 ms)", "contiguous slowest; round-robin-steal within 5 % of the fastest",
              lambda df: _schedule_order(df)),
        Claim("task-size-u", "The task size has an interior optimum: small tasks lose locality, large ones balance",
              "fastest task size neither the smallest nor the largest swept", lambda df: _task_u(df)),
        Claim("load-imbalance", "Round robin with stealing keeps the load imbalance low (7 % in Table 6.4)",
              "imbalance (largest − mean)/mean of the samples per worker ≤ 20 %", lambda df: _imbalance(df)),
        Claim("imbalance-order", "Contiguous blocks without stealing are the worst balanced (169 % against 7 % for "
              "round robin with stealing)", "sample imbalance of contiguous > round-robin-steal",
              lambda df: _imbalance_order(df)),
    )

    def paper_table(self):
        rows = []
        for data, rates in TABLE_6_2.items():
            for p, rate in zip((1, 2, 4, 8, 16), rates):
                rows.append({"table": "6.2 (SGI Challenge)", "data set / assignment": data, "processors": p,
                             "frame rate (Hz)": rate, "speed-up": rate / rates[0], "load imbalance": ""})
        for schedule, (imbalance, ms) in TABLE_6_4.items():
            rows.append({"table": "6.4 (DASH, 32 CPUs, 256³ head)", "data set / assignment": schedule, "processors": 32,
                         "frame rate (Hz)": 1000 / ms, "speed-up": np.nan, "load imbalance": f"{imbalance} %"})
        return pd.DataFrame(rows)

    def report(self, results, ctx):
        ok = ok_rows(results)
        if ok.empty:
            return []
        frame = speed_points(ok)
        for column in ("workers", "task_size", "volume_size"):
            frame[column] = numeric(frame, column)
        out = [blocks.Takeaways(_parallel_takeaways(results))]
        speed = frame[(frame.schedule == DEFAULT_SCHEDULE) & (frame.task_size == DEFAULT_TASK_SIZE)].copy()
        if speed.workers.nunique() > 1:
            speed["speed-up"] = np.nan
            for n, part in speed.groupby("volume_size"):
                one = part[part.workers == 1]
                if one.empty:
                    continue
                t1 = float(one.time_ms.iloc[0])
                speed.loc[part.index, "speed-up"] = t1 / part.time_ms
                speed.loc[part.index, "speed-up low"] = t1 / part.time_ms_max
                speed.loc[part.index, "speed-up high"] = t1 / part.time_ms_min
            speed["volume"] = [f"{int(n)}³" for n in speed.volume_size]
            ps = np.array(sorted(speed.workers.unique()), float)
            path, rel = ctx.plot_path("speedup")
            plots.lines(speed, path, x="workers", y="speed-up", group="volume", y_range=("speed-up low", "speed-up high"),
                   title=_speedup_title(ok), x_label="workers (threads)", y_label="speed-up over one worker (×)",
                   guides=(("linear", ps, ps),))
            out.append(blocks.Figure("Speed-up against workers", rel,
                                     "Bars from the fastest and slowest timed frames; grey: linear speed-up."))
        sched = frame[frame.task_size == DEFAULT_TASK_SIZE]
        sched = sched[sched.workers == frame.workers.max()]
        if sched.schedule.nunique() > 1:
            rows = []
            for row in sched.sort_values("time_ms").itertuples():
                imbalance, ms = TABLE_6_4.get(row.schedule, (np.nan, np.nan))
                rows.append({"volume": f"{int(row.volume_size)}³", "schedule": row.schedule, "time (ms)": row.time_ms,
                             "fastest (ms)": row.time_ms_min, "slowest (ms)": row.time_ms_max,
                             "imbalance (samples)": _imbalance_text(row._asdict()),
                             "thesis time (ms, DASH 32 CPUs)": ms, "thesis imbalance": f"{imbalance} %"})
            out.append(blocks.Table(f"Task assignments at {int(frame.workers.max())} workers", pd.DataFrame(rows),
                                    csv_name="schedules.csv"))
        tasks = frame[(frame.schedule == DEFAULT_SCHEDULE) & (frame.workers == frame.workers.max())]
        if tasks.task_size.nunique() > 2:
            tasks = tasks.assign(volume=[f"{int(n)}³" for n in tasks.volume_size])
            path, rel = ctx.plot_path("task-size")
            plots.lines(tasks, path, x="task_size", y="time_ms", group="volume", y_range=("time_ms_min", "time_ms_max"),
                   log_x=True, title=_task_title(ok), x_label="task size (intermediate-image scanlines per task)",
                   y_label="median frame time (ms)")
            out.append(blocks.Figure("Frame time against the task size", rel,
                                     f"{int(frame.workers.max())} workers, round robin with stealing."))
        table = pd.concat([ok[["volume_size", "workers", "schedule", "task_size", "study"]].reset_index(drop=True),
                           _ms(ok).reset_index(drop=True), _links(ok.reset_index(drop=True), ctx)], axis=1)
        out.append(blocks.Table("Every run", table, csv_name="parallel.csv", links=LINKS))
        missing = unregistered(SW) + missing_options(SW, "workers", "schedule", "task_size")
        missing.append(("load imbalance in busy time (Table 6.4)", "the backend does not time inside its kernel; "
                        "the imbalance here is of the samples each worker composited"))
        if usable_cores() < 4:
            missing.append(("speed-up beyond 2 workers and the thesis's 16–32-processor effects",
                            f"this machine has {usable_cores()} cores"))
        return out + not_measurable(missing)


def worker_imbalance(record_path, view):
    """Load imbalance of one rendered view: (largest − mean)/mean of the samples each worker composited.

    The thesis's Table 6.4 measures busy *time* per processor; the ``shearwarp`` backend does not
    time inside its kernel but records each worker's composited samples (``info.worker_samples``
    of the run record), the work that time is proportional to (E14's cost model).
    """
    import json

    if not file_exists(record_path):
        raise ValueError(f"run record {record_path!r} is missing")
    record = json.loads(Path(record_path).read_text())
    for entry in record.get("views", []):
        if entry.get("view") == view:
            samples = np.asarray(entry.get("info", {}).get("worker_samples") or [], float)
            if len(samples) < 2 or samples.mean() <= 0:
                raise ValueError(f"{record_path}: no per-worker samples for view {view!r}")
            return float(samples.max() / samples.mean() - 1.0)
    raise ValueError(f"{record_path}: no view {view!r}")


def _row_imbalance(row):
    return worker_imbalance(row.get("record"), row.get("view"))


def _speedup(df):
    rows = df[(text_column(df, "schedule") == DEFAULT_SCHEDULE) & (numeric(df, "task_size") == DEFAULT_TASK_SIZE)].copy()
    rows["w"], rows["n"] = numeric(rows, "workers"), numeric(rows, "volume_size")
    results = {}
    for n, part in rows.groupby("n"):
        one, most = part[part.w == 1], part[part.w == part.w.max()]
        if one.empty or part.w.max() <= 1:
            continue
        p = float(most.w.iloc[0])
        speedup = stage_time(one.iloc[0]) / stage_time(most.iloc[0])
        results[int(n)] = (speedup, speedup / p, int(p))
    if not results:
        raise ValueError("no size rendered with one worker and with more")
    return ClaimResult(", ".join(f"{as_ratio(s)} on {p} workers ({as_percent(e)}, {n}³)" for n, (s, e, p) in results.items()),
                       bool(all(e >= 0.7 for _s, e, _p in results.values())),
                       f"this machine: {usable_cores()} cores; timings on a shared machine are noisy")


def _schedule_order(df):
    rows = df[numeric(df, "task_size") == DEFAULT_TASK_SIZE]
    rows = rows[numeric(rows, "workers") == numeric(rows, "workers").max()]
    outcomes = {}
    for n, part in rows.groupby(numeric(rows, "volume_size")):
        times = {s: stage_time(part[text_column(part, "schedule") == s].iloc[0]) for s in SCHEDULES
                 if (text_column(part, "schedule") == s).any()}
        if len(times) < 4:
            continue
        fastest = min(times.values())
        holds = max(times, key=times.get) == "contiguous" and times["round-robin-steal"] <= 1.05 * fastest
        outcomes[int(n)] = (holds, times)
    if not outcomes:
        raise ValueError("not all four schedules rendered at the most workers")
    workers = int(numeric(rows, "workers").max())
    measured = "; ".join(f"{n}³: " + " < ".join(f"{s} {format_number(t * 1e3)} ms" for s, t in sorted(times.items(), key=lambda kv: kv[1]))
                         for n, (_h, times) in outcomes.items())
    detail = f"{workers} workers" + ("; with 2 workers a contiguous split has only two blocks, so the thesis's "
                                     "32-processor imbalance cannot show fully" if workers <= 2 else "")
    return ClaimResult(measured, bool(all(h for h, _t in outcomes.values())), detail)


def _task_u(df):
    rows = df[text_column(df, "schedule") == DEFAULT_SCHEDULE]
    rows = rows[numeric(rows, "workers") == numeric(rows, "workers").max()].copy()
    rows["t"] = numeric(rows, "task_size")
    outcomes = {}
    for n, part in rows.groupby(numeric(rows, "volume_size")):
        if part.t.nunique() < 3:
            continue
        part = part.sort_values("t")
        best = part.loc[numeric(part, "time_total").idxmin()]
        outcomes[int(n)] = (int(best.t), part.t.min() < best.t < part.t.max())
    if not outcomes:
        raise ValueError("fewer than three task sizes swept")
    return ClaimResult(", ".join(f"fastest at {t} scanlines ({n}³)" for n, (t, _i) in outcomes.items()),
                       bool(all(i for _t, i in outcomes.values())), "thesis optimum: 8–20 scanlines on the Challenge")


def _imbalance_text(row):
    try:
        return as_percent(_row_imbalance(row))
    except ValueError:
        return "not reported"


def _schedule_imbalance(df, schedule):
    rows = df[(text_column(df, "schedule") == schedule) & (numeric(df, "task_size") == DEFAULT_TASK_SIZE)]
    rows = rows[numeric(rows, "workers") == numeric(df, "workers").max()]
    if rows.empty or float(numeric(rows, "workers").max()) < 2:
        raise ValueError(f"no {schedule} run with two or more workers")
    return {int(float(row["volume_size"])): _row_imbalance(row) for _i, row in rows.iterrows()}


def _imbalance(df):
    values = _schedule_imbalance(df, "round-robin-steal")
    return ClaimResult(", ".join(f"{as_percent(v)} ({n}³)" for n, v in values.items()), bool(max(values.values()) <= 0.2),
                       "samples composited per worker; thesis 7 % in busy time (DASH, 32 processors)")


def _imbalance_order(df):
    good, bad = _schedule_imbalance(df, "round-robin-steal"), _schedule_imbalance(df, "contiguous")
    sizes = sorted(set(good) & set(bad))
    if not sizes:
        raise ValueError("no size rendered with both schedules")
    return ClaimResult(", ".join(f"contiguous {as_percent(bad[n])} vs round-robin-steal {as_percent(good[n])} ({n}³)" for n in sizes),
                       bool(all(bad[n] > good[n] for n in sizes)), "samples composited per worker; thesis 169 % vs 7 %")


def _speedup_title(ok):
    return _title_or(lambda d: f"Speed-up: {_speedup(d).measured}", ok, "Speed-up against the number of workers")


def _task_title(ok):
    return _title_or(lambda d: f"Task size: {_task_u(d).measured}", ok, "Frame time against the task size")


def _parallel_takeaways(results):
    return _claim_sentences(results, ((_speedup, "Speed-up"), (_schedule_order, "Schedules"), (_task_u, "Task size")),
                            "{what}: {measured}.")


# ============================================================ 8. shading, union-find, mode switch
class Variants(Experiment):
    """Table 7.1 (LUT against procedural shading), §4.1.3 (union by rank), §4.4 (VolPack's mode switch)."""

    name = "lacroute1995-shading"
    paper = PAPER
    title = "Shading tables, union-find variants and the mode switch (E18, E15, E22)"
    settings = frozenset({"volume_size", "image_size", "dataset", "preset", "repeat"})
    description = (
        "Three implementation choices of the thesis. Shading by lookup table (8192 entries over 13-bit "
        "quantised normals, rebuilt every frame) against Phong computed per voxel: Table 7.1 finds the "
        "table about 4–5× faster. Path compression alone against path compression with union by rank "
        "in the early-termination links: rank made the thesis's renderer 5–15 % slower (§4.1.3). "
        "VolPack's mode switch (§4.4): after a classification edit the octree (fast-classification) "
        "mode renders at once, while the RLE mode must classify and encode the volume again; the cold "
        "runs here time each preprocessing stage in the frame where it is built. Both VolPack's modes and "
        "our backend's: the octree (once per volume), the summed-area table (once per classification), "
        "the three RLE copies built from the octree against the brute-force classify-and-encode, and "
        "the frame with fast classification against the RLE frame."
    )

    def runs(self, profile):
        size = profile.setting(self.name, "volume_size", profile.volume_size)
        image = profile.setting(self.name, "image_size", profile.image_size)
        dataset = profile.setting(self.name, "dataset", "ct_skull")
        preset = profile.setting(self.name, "preset", "skin")
        volume = _phantom(dataset, size, preset=preset)
        scene = _scene(volume, profile, image_size=image, name=f"{dataset}-{preset}")
        view = (headline_view(dataset),)
        timed = timed_frames(profile, self.name)
        # Cold runs: the first frame builds (and times) the per-volume structures; with three frames
        # the median total is a warm frame.
        cold = {"warmup": 0, "repeat": timed["repeat"]}
        tags = {"dataset": dataset, "preset": preset}
        runs = []
        if accepts(SW, "shading", "union"):
            # The baseline (lookup-table shading, path compression) serves both comparisons; its
            # reference is the procedural image, so the evaluation measures the table's error.
            procedural = accepts(SW, "shading")
            runs.append(Run(self.name, "baseline", SW, scene, view, options={"shading": "lut", "union": "path-compression"},
                            reference="shading.procedural" if procedural else None, **timed,
                            tags={**tags, "part": "baseline", "config": "lut, path-compression"}))
            runs.append(Run(self.name, "shading.procedural", SW, scene, view, options={"shading": "procedural"}, **timed,
                            tags={**tags, "part": "shading", "config": "procedural"}))
            runs.append(Run(self.name, "union.rank", SW, scene, view, options={"union": "rank"}, **timed,
                            tags={**tags, "part": "union", "config": "rank"}))
        if is_registered(SW):
            runs.append(Run(self.name, "mode.shearwarp-cold", SW, scene, view, **cold,
                            tags={**tags, "part": "mode", "config": "shearwarp"}))
        if accepts(SW, "classification", "octree_rle_build"):
            # E22 with our backend: the three RLE copies built from the min-max octree, and rendering
            # with fast classification (octree + summed-area table, classified on the fly).
            for config, options in SW_MODE_CONFIGS.items():
                runs.append(Run(self.name, f"mode.{config}-cold", SW, scene, view, options=dict(options), **cold,
                                tags={**tags, "part": "mode", "config": config}))
        if accepts(VP, "mode"):
            for mode in ("rle", "octree"):
                runs.append(Run(self.name, f"mode.volpack-{mode}-cold", VP, scene, view, options={"mode": mode}, **cold,
                                tags={**tags, "part": "mode", "config": f"volpack-{mode}"}))
        return runs

    claims = (
        Claim("lut-faster", "Lookup-table shading is several times faster than per-voxel Phong (Table 7.1: ×4.3 "
              "total)", "procedural / LUT frame time ≥ 2", lambda df: _lut_speed(df)),
        Claim("lut-accurate", "13-bit normals are enough: the table's image matches per-voxel Phong",
              "PSNR ≥ 35 dB between them", lambda df: _lut_accuracy(df)),
        Claim("union-by-rank", "Union by rank does not make the renderer faster (thesis: 5–15 % slower)",
              "rank / path-compression frame time ≥ 0.97", lambda df: _union(df)),
        Claim("mode-switch", "After a classification edit the octree mode shows an image sooner than re-encoding "
              "the RLE volume (§4.4)", "octree render < RLE classify + RLE render (VolPack)", lambda df: _mode_switch(df)),
        Claim("octree-rle-build", "Building the three RLE copies from the min-max octree is faster than the brute-force "
              "build (§4.4, E22)", "ours: sat_build + rle_build (octree) < classify + rle_build (brute force)",
              lambda df: _octree_rle_build(df)),
        Claim("fast-classification-render", "Rendering with fast classification takes about twice the classified-RLE "
              "render (Table 5.3: ×1.8–2.5)", "ours: warm frame octree / RLE in 1.4–3.2", lambda df: _octree_render(df)),
        Claim("mode-switch-ours", "With our backend too, after a classification edit fast classification shows an "
              "image sooner than re-encoding (§4.4)", "ours: sat_build + octree frame < classify + rle_build + RLE frame",
              lambda df: _mode_switch_ours(df)),
    )

    def paper_table(self):
        rows = [("Table 7.1", "procedural per-voxel shading", "13.3 s shading, 14.5 s total (×5.2)"),
                ("Table 7.1", "lookup tables", "2.3 s shading, 3.4 s total (×1.2)"),
                ("Table 7.1", "lookup tables, inlined", "1.6 s shading, 2.8 s total (×1.0)"),
                ("§4.1.3", "union by rank in addition to path compression", "renderer 5–15 % slower"),
                ("§4.4, Fig. 5.4", "mode switch (brain): preprocess, fast classification, switch, fast render",
                 "stage times in a plot only"),
                ("Ch. 6", "preprocessing of the 256³ head on one processor", "65 s"),
                ("Table 5.3", "fast classification against RLE rendering", "×1.8–2.5"),
                ("§4.4, E22", "octree-accelerated against brute-force RLE build", "faster (no number given)")]
        return pd.DataFrame(rows, columns=["thesis", "variant", "value"]).assign(machine=THESIS)

    def report(self, results, ctx):

        ok = ok_rows(results)
        if ok.empty:
            return []
        out = [blocks.Takeaways(_variant_takeaways(results))]
        frame = speed_points(ok)
        stages = [c for c in frame.columns if c.startswith("time_") and not c.endswith(("_min", "_max"))
                  and c not in ("time_total", "time_ms")]
        warm = frame[frame.part != "mode"]
        per_frame = [s for s in stages if warm[s].notna().any() and s not in PREPROCESSING_STAGES]
        if per_frame and not warm.empty:
            path, rel = ctx.plot_path("stages")
            plots.stage_breakdown(warm.assign(variant=warm.part + ": " + warm.config), path, stage_cols=per_frame,
                                  group_col="variant", title=_lut_title(ok))
            out.append(blocks.Figure("Per-frame time by stage", rel, "Median timed frame of each variant, by the backend's stages."))
        rows = []
        for row in frame.itertuples():
            d = row._asdict()
            entry = {"part": row.part, "variant": row.config, "time (ms)": row.time_ms, "fastest (ms)": row.time_ms_min,
                     "slowest (ms)": row.time_ms_max}
            for stage in ("classify", "rle_build", "octree", "octree_build", "sat_build", "octree_classify",
                          "shade_table", "composite", "render"):
                if f"time_{stage}" in d and pd.notna(d[f"time_{stage}"]):
                    entry[f"{stage} (ms)"] = float(d[f"time_{stage}"]) * 1e3
            rows.append(entry)
        table = pd.concat([pd.DataFrame(rows), _links(ok.reset_index(drop=True), ctx)], axis=1)
        try:
            out.append(blocks.Table("The mode switch with our backend (E22)", mode_switch_table(ok),
                                    csv_name="mode_switch.csv",
                                    caption="Cold runs: preprocessing stages of the first frame; 'frame' is the median "
                                            "(warm) frame. 'after an edit': what a classification change costs before "
                                            "the next image (the octree survives an edit; octree_build is per volume)."))
        except (KeyError, ValueError):
            pass
        out.append(blocks.Table("Every variant", table, csv_name="variants.csv", links=LINKS,
                                caption="Mode rows are cold runs (no warm-up): classify / rle_build / octree are the "
                                        "preprocessing stages of their first frame; 'time' is the median of three "
                                        "frames, the slowest being the cold one."))
        shading = ok[ok.part.isin(["baseline", "shading"])] if "part" in ok else ok.iloc[:0]
        if not shading.empty:
            gallery = blocks.Gallery("Lookup-table against procedural shading", diff_scale=DIFF_SCALE,
                                     caption="The lookup-table image with its difference from the procedural one.")
            for row in shading.sort_values("config").itertuples():
                diff = ctx.difference(_reference_exr(results, row), row.exr, DIFF_SCALE) if row.part == "baseline" else None
                gallery.items.append(blocks.GalleryItem(
                    row.config, ctx.image(row.png), difference=diff,
                    note=f"{format_number(row.time_total * 1e3)} ms" + (f"; PSNR against procedural "
                                                                        f"{format_number(getattr(row, 'psnr', np.nan))} dB"
                                                                        if diff else "")))
            out.append(gallery)
        return out + not_measurable(unregistered(SW, VP) + missing_options(SW, "shading", "union")
                                           + missing_options(VP, "mode"))


SW_MODE_CONFIGS = {
    # config: shearwarp options of the E22 cold runs ("shearwarp": the defaults, brute-force RLE build)
    "shearwarp-octree-rle": {"octree_rle_build": True},
    "shearwarp-octree": {"classification": "octree"},
}
PREPROCESSING_STAGES = ("time_classify", "time_rle_build", "time_octree", "time_octree_build", "time_sat_build")
"""Stages timed only in the frame that builds a per-volume structure."""


def _stage(row, stage):
    """``row``'s ``time_<stage>`` in seconds; ValueError if the run did not report it."""
    value = float(row.get(f"time_{stage}", np.nan))
    if not np.isfinite(value):
        raise ValueError(f"run {row.get('run')} ({row.get('config')}) reported no {stage!r} stage")
    return value


def mode_switch_table(df):
    """Preprocessing stages, warm frame and time to an image after an edit of our backend's three modes."""
    rows = []
    for config, label, edit in (("shearwarp", "RLE, brute-force build", ("classify", "rle_build")),
                                ("shearwarp-octree-rle", "RLE built from the octree", ("sat_build", "rle_build")),
                                ("shearwarp-octree", "fast classification", ("sat_build",))):
        match = rows_matching(df, config, part="mode", config=config)
        if match.empty:
            continue
        row = match.iloc[0]
        entry = {"mode": label}
        for stage in ("octree_build", "classify", "sat_build", "rle_build", "octree_classify"):
            value = float(row.get(f"time_{stage}", np.nan))
            entry[f"{stage} (ms)"] = value * 1e3 if np.isfinite(value) else np.nan
        entry["frame (ms)"] = stage_time(row) * 1e3
        entry["after an edit (ms)"] = (sum(_stage(row, s) for s in edit) + stage_time(row)) * 1e3
        for counter in ("rle_bytes", "octree_bytes", "classified_on_the_fly"):
            entry[counter] = float(row.get(f"count_{counter}", np.nan))
        rows.append(entry)
    if not rows:
        raise ValueError("no cold shearwarp mode run")
    return pd.DataFrame(rows)


def _octree_rle_build(df):
    brute, octree = _config_row(df, "mode", "shearwarp"), _config_row(df, "mode", "shearwarp-octree-rle")
    plain = _stage(brute, "classify") + _stage(brute, "rle_build")
    fast = _stage(octree, "sat_build") + _stage(octree, "rle_build")
    return ClaimResult(f"{format_number(fast * 1e3)} ms vs {format_number(plain * 1e3)} ms ({as_ratio(plain / fast)} faster)",
                       bool(fast < plain),
                       f"octree: SAT {format_number(_stage(octree, 'sat_build') * 1e3)} ms + RLE "
                       f"{format_number(_stage(octree, 'rle_build') * 1e3)} ms (octree itself, once per volume: "
                       f"{format_number(float(octree.get('time_octree_build', np.nan)) * 1e3)} ms); brute force: classify "
                       f"{format_number(_stage(brute, 'classify') * 1e3)} ms + RLE {format_number(_stage(brute, 'rle_build') * 1e3)} ms; "
                       "single cold frames, noisy")


def _octree_render(df):
    rle, octree = _config_row(df, "mode", "shearwarp"), _config_row(df, "mode", "shearwarp-octree")
    ratio = stage_time(octree) / stage_time(rle)
    return ClaimResult(as_ratio(ratio), bool(1.4 <= ratio <= 3.2),
                       f"octree {format_number(stage_time(octree) * 1e3)} ms (of which octree_classify "
                       f"{format_number(float(octree.get('time_octree_classify', np.nan)) * 1e3)} ms), RLE "
                       f"{format_number(stage_time(rle) * 1e3)} ms; median warm frames; thesis ×1.8–2.5")


def _mode_switch_ours(df):
    rle, octree = _config_row(df, "mode", "shearwarp"), _config_row(df, "mode", "shearwarp-octree")
    edit_rle = _stage(rle, "classify") + _stage(rle, "rle_build") + stage_time(rle)
    edit_octree = _stage(octree, "sat_build") + stage_time(octree)
    return ClaimResult(f"fast classification {format_number(edit_octree * 1e3)} ms vs RLE {format_number(edit_rle * 1e3)} ms",
                       bool(edit_octree < edit_rle),
                       f"octree: SAT {format_number(_stage(octree, 'sat_build') * 1e3)} ms + frame "
                       f"{format_number(stage_time(octree) * 1e3)} ms; RLE: classify {format_number(_stage(rle, 'classify') * 1e3)} ms "
                       f"+ build {format_number(_stage(rle, 'rle_build') * 1e3)} ms + frame {format_number(stage_time(rle) * 1e3)} ms")


def _config_row(df, part, config):
    return one_row(df, f"{part} {config}", part=part, config=config)


def _baseline(df):
    return one_row(df, "the baseline (lookup table, path compression)", part="baseline")


def _lut_speed(df):
    lut, procedural = _baseline(df), _config_row(df, "shading", "procedural")
    ratio = stage_time(procedural) / stage_time(lut)
    return ClaimResult(as_ratio(ratio), bool(ratio >= 2.0),
                       f"LUT {format_number(stage_time(lut) * 1e3)} ms, procedural {format_number(stage_time(procedural) * 1e3)} ms; thesis ×4.3")


def _lut_accuracy(df):
    lut, procedural = _baseline(df), _config_row(df, "shading", "procedural")
    value = float(lut.get("psnr", np.nan))
    if not np.isfinite(value):
        value = pair_metrics(procedural.exr, lut.exr)["psnr"]
    return ClaimResult(f"{format_number(value)} dB", bool(value >= 35.0), "LUT image against the procedural one")


def _union(df):
    rank, path = _config_row(df, "union", "rank"), _baseline(df)
    ratio = stage_time(rank) / stage_time(path)
    return ClaimResult(as_ratio(ratio), bool(ratio >= 0.97),
                       f"rank {format_number(stage_time(rank) * 1e3)} ms, path compression {format_number(stage_time(path) * 1e3)} ms; "
                       "thesis ×1.05–1.15; timings on a shared machine are noisy")


def _mode_switch(df):
    rle, octree = _config_row(df, "mode", "volpack-rle"), _config_row(df, "mode", "volpack-octree")
    classify = float(rle.get("time_classify", np.nan))
    if not np.isfinite(classify):
        raise ValueError("VolPack's RLE run reported no classify stage")
    render_rle = float(rle.get("time_render", rle.get("time_total")))
    render_octree = float(octree.get("time_render", octree.get("time_total")))
    edit_rle = classify + render_rle
    return ClaimResult(f"octree {format_number(render_octree * 1e3)} ms vs RLE {format_number(edit_rle * 1e3)} ms",
                       bool(render_octree < edit_rle),
                       f"RLE: classify {format_number(classify * 1e3)} ms + render {format_number(render_rle * 1e3)} ms; "
                       f"octree build (once per volume) {format_number(float(octree.get('time_octree', np.nan)) * 1e3)} ms")


def _lut_title(ok):
    return _title_or(lambda d: f"Lookup-table shading is {_lut_speed(d).measured} faster than per-voxel Phong", ok,
                     "Per-frame time by stage")


def _variant_takeaways(results):
    return _claim_sentences(results, ((_lut_speed, "Procedural / lookup-table shading time"),
                                 (_lut_accuracy, "Lookup-table against procedural image"),
                                 (_union, "Union by rank / path compression"),
                                 (_mode_switch, "Time to an image after a classification edit"),
                                 (_octree_rle_build, "Our RLE build from the octree against brute force"),
                                 (_octree_render, "Our fast-classification / RLE frame time"),
                                 (_mode_switch_ours, "Our time to an image after a classification edit")))


# =================================================== 9. projections and fast classification (E2)
TABLE_5_3 = {
    # thesis data set: {config: (mean s, fastest s, slowest s, memory MB)}
    "brainsmall": {"parallel": (0.22, 0.19, 0.26, 4), "perspective": (0.48, 0.42, 0.54, 4),
                   "fast-classification": (0.40, 0.35, 0.47, 8)},
    "headsmall": {"parallel": (0.25, 0.23, 0.28, 2), "perspective": (0.57, 0.53, 0.62, 2),
                  "fast-classification": (0.54, 0.49, 0.61, 8)},
    "brain": {"parallel": (0.86, 0.69, 1.06, 19), "perspective": (2.04, 1.67, 2.46, 19),
              "fast-classification": (1.94, 1.51, 2.36, 46)},
    "head": {"parallel": (0.87, 0.77, 0.98, 13), "perspective": (2.35, 2.12, 2.55, 13),
             "fast-classification": (2.19, 1.92, 2.39, 61)},
}
"""Table 5.3 (360 views per data set, 256² images, R4400): mean, fastest and slowest view, memory."""

PROJECTION_DATASETS = {
    # data set: (classification preset, the thesis's data set it stands for)
    "brainsmall": ("volpack", "brainsmall"),
    "folded_brain": ("volpack", "brain"),
    "ct_skull": ("bone", "head"),
    "mrihead": ("volpack", "brain"),
    "cthead": ("bone", "head"),
}

PROJECTION_CONFIGS = {
    # config: (camera projection, shearwarp options, label)
    "parallel": ("orthographic", {}, "parallel projection, classified RLE"),
    "perspective": ("perspective", {}, "perspective projection, classified RLE"),
    "fast-classification": ("orthographic", {"classification": "octree"},
                            "fast classification (min-max octree + summed-area table), parallel"),
}
OCTREE_MEMORY_LIMIT = 4.0
"""Fast-classification structures per voxel of an 8-bit volume: the thesis's 4-byte raw array."""


class Projections(Experiment):
    """Table 5.3 complete: parallel, perspective and fast classification over a set of views, and memory."""

    name = "lacroute1995-projection"
    paper = PAPER
    title = "Parallel, perspective and fast classification over many views (E2, Table 5.3)"
    settings = frozenset({"datasets", "volume_size", "image_size", "angle_step", "elevation", "fov", "workers",
                          "repeat"})
    description = (
        "Table 5.3 renders each data set from 360 views with the three algorithms of the thesis: "
        "parallel projection over the classified RLE volume, perspective projection over the same "
        "volume (Ch. 4.2: per-slice scaling, area-averaging filter, projective warp), and fast "
        "classification (§4.3: a min-max octree and a summed-area table find each frame's non-transparent "
        "runs, whose voxels are classified on the fly; for interactive transfer-function edits). "
        "Perspective took 2.2–2.7× and fast classification 1.8–2.5× the parallel time; fast "
        "classification's memory (a 4-byte-per-voxel raw array, the octree, the table) was 2–5× the "
        "RLE's. Here every data set turns about its body axis at a fixed elevation in equal azimuth "
        "steps; each view is timed (median frame after warm-up), and the table gives the mean, fastest "
        "and slowest view, on one worker by default (the thesis's Table 5.3 ran on one processor; one "
        "thread is also the least disturbed by other work on a shared machine). Memory is the backend's own "
        "count of each mode's structures: the three RLE copies (rle_bytes), the octree (octree_bytes) and the raw scalars (raw_bytes)."
    )
    DATASETS = ("brainsmall", "folded_brain", "ct_skull")

    def runs(self, profile):
        if not accepts(SW, "classification"):
            return []
        wanted = profile.setting(self.name, "datasets", list(self.DATASETS))
        unknown = [d for d in wanted if d not in PROJECTION_DATASETS]
        if unknown:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.datasets: unknown {unknown}; "
                             f"known: {sorted(PROJECTION_DATASETS)}")
        step = float(profile.setting(self.name, "angle_step", 30))
        if not 0 < step <= 360:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.angle_step: expected degrees in (0, 360], "
                             f"got {step}")
        fov = float(profile.setting(self.name, "fov", 30.0))
        if not 0 < fov < 120:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.fov: expected degrees in (0, 120), got {fov}")
        elevation = float(profile.setting(self.name, "elevation", HEADLINE_VIEW["elevation"]))
        workers = profile.setting(self.name, "workers", 1)
        if workers is not None and (not isinstance(workers, int) or workers < 1):
            raise InputError(f"profile {profile.name!r} settings.{self.name}.workers: expected an integer ≥ 1 or null "
                             f"(all cores), got {workers!r}")
        size = profile.setting(self.name, "volume_size", profile.volume_size)
        image = profile.setting(self.name, "image_size", profile.image_size)
        angles = np.arange(0.0, 360.0 - 1e-9, step)
        runs = []
        for dataset in wanted:
            preset, thesis = PROJECTION_DATASETS[dataset]
            volume = _phantom(dataset, size, preset=preset)
            views = tuple(dataset_view(dataset, f"deg{a:g}", a, elevation) for a in angles)
            for config, (projection, options, _label) in PROJECTION_CONFIGS.items():
                scene = _scene(volume, profile, image_size=image, name=f"{dataset}-{projection}")
                if projection == "perspective":
                    scene["camera"] = {"projection": "perspective", "fov_y": fov}
                runs.append(Run(self.name, f"{dataset}.{config}", SW, scene, views,
                                options={**options, "workers": workers}, **timed_frames(profile, self.name),
                                tags={"dataset": dataset, "config": config, "thesis_dataset": thesis,
                                      "projection": projection, "fov": fov if projection == "perspective" else 0.0}))
        return runs

    claims = (
        Claim("perspective-cost", "Perspective rendering costs 2.2–2.7× the parallel projection (Table 5.3)",
              "mean-view time ratio perspective / parallel in 1.6–3.5 (every data set)",
              lambda df: _projection_ratio(df, "perspective", 1.6, 3.5)),
        Claim("fast-classification-cost", "Fast classification (octree, raw volume) costs 1.8–2.5× the classified-RLE "
              "rendering (Table 5.3)", "mean-view time ratio fast classification / parallel in 1.4–3.2 (every data set)",
              lambda df: _projection_ratio(df, "fast-classification", 1.4, 3.2)),
        Claim("fast-classification-memory", "Fast classification needs about 4 bytes per voxel (the raw array, the "
              "octree and the table; head: 61 MB for 14.7 M voxels)",
              f"(raw_bytes + octree_bytes) / raw_bytes ≤ {OCTREE_MEMORY_LIMIT:g}, i.e. ≤ 4 B per voxel of an 8-bit "
              "volume (every data set)", lambda df: _octree_memory(df)),
    )

    def paper_table(self):
        rows = []
        for dataset, configs in TABLE_5_3.items():
            for config, (mean, low, high, mb) in configs.items():
                rows.append({"data set": dataset, "algorithm": PROJECTION_CONFIGS[config][2], "mean time (s)": mean,
                             "fastest–slowest view (s)": f"{low}–{high}", "memory (MB)": mb,
                             "time / parallel": mean / configs["parallel"][0]})
        return pd.DataFrame(rows).assign(machine=THESIS)

    def report(self, results, ctx):
        ok = ok_rows(results)
        out = [blocks.Takeaways(_projection_takeaways(results))]
        try:
            summary = projection_summary(ok)
        except (KeyError, ValueError):
            return out + not_measurable(unregistered(SW) + missing_options(SW, "classification"))
        table = summary.copy()
        for column in ("mean", "fastest", "slowest"):
            table[f"{column} (ms)"] = table.pop(column) * 1e3
        for column in ("rle_bytes", "octree_bytes", "raw_bytes"):
            table[f"{column} (MB)"] = table.pop(column) / 1e6
        out.append(blocks.Table("Table 5.3, ours beside the thesis's", table, csv_name="projection.csv",
                                caption="Mean, fastest and slowest view of the median frame times over the turn "
                                        "(warm-up excluded, preprocessing excluded). Thesis columns: Table 5.3 for the "
                                        "data set each one stands for (R4400, 256² images, 360 views). Memory: the "
                                        "backend's counters (rle_bytes in fast classification is the one per-frame "
                                        "encoding); the thesis's memory adds images and tables."))
        bars = summary.assign(ours=summary["time / parallel"]).rename(columns={"thesis time / parallel": "thesis"})
        bars["category"] = bars.dataset + ": " + bars.config
        path, rel = ctx.plot_path("ratios")
        plots.bar_compare(bars[bars.config != "parallel"], path, category_col="category", value_cols=["ours", "thesis"],
                          value_label="mean time / parallel mean time", title=_projection_title(ok))
        out.append(blocks.Figure("Cost relative to parallel projection", rel,
                                 "Mean-view time of each algorithm over the parallel projection's, ours beside "
                                 "Table 5.3's data set of the same kind."))
        frame = speed_points(ok)
        frame["angle"] = [_angle_of(v) for v in frame.view]
        for dataset, part in frame.groupby("dataset"):
            path, rel = ctx.plot_path(f"turn-{dataset}")
            plots.lines(part.sort_values("angle"), path, x="angle", y="time_ms", group="config",
                        y_range=("time_ms_min", "time_ms_max"), title=f"{dataset}: frame time over the turn",
                        x_label="azimuth about the body axis (degrees)", y_label="median frame time (ms)")
            out.append(blocks.Figure(f"{dataset}: time per view", rel,
                                     "One line per algorithm; bars: fastest to slowest timed frame of each view."))
        first = frame[frame.angle == frame.angle.min()]
        gallery = blocks.Gallery("The first view of each algorithm",
                                 caption="Parallel and fast classification render the same image (up to the "
                                         "classification of voxels at the transfer function's edges); perspective "
                                         "sees the volume from a finite eye.")
        for row in first.sort_values(["dataset", "config"]).itertuples():
            gallery.items.append(blocks.GalleryItem(f"{row.dataset}: {PROJECTION_CONFIGS.get(row.config, ('', {}, row.config))[2]}",
                                                    ctx.image(row.png), note=f"{format_number(row.time_ms)} ms"))
        out.append(gallery)
        return out + not_measurable(unregistered(SW) + missing_options(SW, "classification"))


def projection_summary(df):
    """Per data set and algorithm: views, mean/fastest/slowest view time (s), memory and the thesis's numbers."""
    rows = []
    for (dataset, config), part in df.groupby([text_column(df, "dataset"), text_column(df, "config")], sort=False):
        times = numeric(part, "time_total")
        times = times[np.isfinite(times)]
        if times.empty:
            continue
        thesis_set = str(part["thesis_dataset"].iloc[0]) if "thesis_dataset" in part else ""
        thesis = TABLE_5_3.get(thesis_set, {})
        mean, low, high, mb = thesis.get(config, (np.nan,) * 4)
        memory = {c: float(pd.to_numeric(part[f"count_{c}"], errors="coerce").max()) if f"count_{c}" in part else np.nan
                  for c in ("rle_bytes", "octree_bytes", "raw_bytes")}
        rows.append({"dataset": dataset, "config": config, "views": int(len(times)), "mean": float(times.mean()),
                     "fastest": float(times.min()), "slowest": float(times.max()), **memory,
                     "thesis data set": thesis_set, "thesis mean (s)": mean, "thesis fastest–slowest (s)":
                     f"{low}–{high}" if np.isfinite(low) else "", "thesis memory (MB)": mb,
                     "thesis time / parallel": mean / thesis["parallel"][0] if thesis else np.nan})
    if not rows:
        raise ValueError("no successful run with a frame time")
    summary = pd.DataFrame(rows)
    summary["time / parallel"] = np.nan
    for dataset, part in summary.groupby("dataset"):
        parallel = part[part.config == "parallel"]
        if not parallel.empty:
            summary.loc[part.index, "time / parallel"] = part["mean"] / float(parallel["mean"].iloc[0])
    order = {c: i for i, c in enumerate(PROJECTION_CONFIGS)}
    summary["_order"] = [order.get(c, 9) for c in summary.config]
    return summary.sort_values(["dataset", "_order"]).drop(columns="_order").reset_index(drop=True)


def _projection_ratio(df, config, low, high):
    summary = projection_summary(df)
    rows = summary[(summary.config == config) & summary["time / parallel"].notna()]
    if rows.empty:
        raise ValueError(f"no data set rendered both {config} and parallel")
    ratios = dict(zip(rows.dataset, rows["time / parallel"]))
    detail = "; ".join(f"{r['dataset']}: {format_number(r['mean'] * 1e3)} ms mean over {r['views']} views "
                       f"({format_number(r['fastest'] * 1e3)}–{format_number(r['slowest'] * 1e3)} ms), thesis "
                       f"{r['thesis data set']} {as_ratio(r['thesis time / parallel'])}" for _i, r in rows.iterrows())
    return ClaimResult(", ".join(f"{as_ratio(r)} ({d})" for d, r in ratios.items()),
                       bool(all(low <= r <= high for r in ratios.values())),
                       detail + "; timings on a shared machine are noisy")


def _octree_memory(df):
    summary = projection_summary(df)
    rows = summary[(summary.config == "fast-classification") & np.isfinite(summary.octree_bytes)
                   & np.isfinite(summary.raw_bytes)]
    if rows.empty:
        raise ValueError("no fast-classification run reported octree_bytes and raw_bytes")
    per_raw = {r.dataset: (r.raw_bytes + r.octree_bytes) / r.raw_bytes for r in rows.itertuples()}
    rle = dict(zip(summary[summary.config == "parallel"].dataset, summary[summary.config == "parallel"].rle_bytes))
    detail = "; ".join(f"{r.dataset}: raw {format_number(r.raw_bytes / 1e6)} MB + octree "
                       f"{format_number(r.octree_bytes / 1e6)} MB"
                       + (f" against 3×RLE {format_number(rle[r.dataset] / 1e6)} MB" if r.dataset in rle else "")
                       for r in rows.itertuples())
    return ClaimResult(", ".join(f"{format_number(v)}× the raw volume ({d})" for d, v in per_raw.items()),
                       bool(all(v <= OCTREE_MEMORY_LIMIT for v in per_raw.values())),
                       detail + "; the summed-area table is not counted (the backend reports no size for it); "
                                "thesis: head 61 MB = 4.1 B/voxel, brainsmall 8 MB = 5.8 B/voxel, images included")


def _projection_title(ok):
    parts = []
    for config, word in (("perspective", "perspective"), ("fast-classification", "fast classification")):
        try:
            parts.append(f"{word} {_projection_ratio(ok, config, 0, np.inf).measured}")
        except (KeyError, ValueError):
            continue
    return ("Time over parallel: " + "; ".join(parts) + "\n(thesis: perspective ×2.2–2.7, fast classification ×1.8–2.5)"
            if parts else "Time relative to parallel projection")


def _projection_takeaways(results):
    return _claim_sentences(results, ((lambda d: _projection_ratio(d, "perspective", 0, np.inf),
                                  "Perspective / parallel mean time"),
                                 (lambda d: _projection_ratio(d, "fast-classification", 0, np.inf),
                                  "Fast classification / parallel mean time"),
                                 (_octree_memory, "Fast-classification memory")))


# ========================================================== 10. perspective quality (E21)
class PerspectiveQuality(Experiment):
    """§4.2.5: image quality against the reference as the field of view widens."""

    name = "lacroute1995-perspective"
    paper = PAPER
    title = "Perspective artifacts: quality against the field of view (E21, §4.2.5)"
    settings = frozenset({"dataset", "preset", "volume_size", "image_size", "fovs", "truth_step_factor"})
    description = (
        "Perspective shear-warp keeps one principal axis for every ray and filters each slice over the "
        "pixel's footprint before compositing. The thesis admits two limits (§4.2.5): rays that meet the "
        "slices at more than 45° degrade the image, severely as they approach 90° (wide fields of view, "
        "fly-throughs), and averaging thin opaque structures with empty space before compositing lets what "
        "lies behind them show through. The thesis's test of the second (two thin opaque plates before a "
        "plane) needs a scene no registered data set provides; here the first is measured: the same data "
        "set from the same direction at fields of view of 15° to 90° (the camera framing the volume, so "
        "the eye comes closer as the field widens), each image against the reference ray caster with the "
        "same camera at a fine step, beside the parallel projection of the same view. The skull's thin "
        "bone shell is the kind of structure the visibility error affects."
    )
    FOVS = (15.0, 30.0, 60.0, 90.0)

    def runs(self, profile):
        if not is_registered(SW):
            return []
        dataset = profile.setting(self.name, "dataset", "ct_skull")
        preset = profile.setting(self.name, "preset", datasets.get(dataset).default_preset)
        fovs = [float(f) for f in profile.setting(self.name, "fovs", list(self.FOVS))]
        bad = [f for f in fovs if not 0 < f < 120]
        if bad or len(fovs) < 2:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.fovs: expected two or more fields of "
                             f"view in (0, 120) degrees, got {fovs}")
        size = profile.setting(self.name, "volume_size", profile.volume_size)
        image = profile.setting(self.name, "image_size", profile.image_size)
        truth_factor = profile.setting(self.name, "truth_step_factor", 0.25)
        volume = _phantom(dataset, size, preset=preset)
        views = (headline_view(dataset),)
        runs = []
        for fov in [0.0, *sorted(fovs)]:
            label = "parallel" if fov == 0 else f"fov{fov:g}"
            scene = _scene(volume, profile, image_size=image, name=f"{dataset}-{label}")
            if fov:
                scene["camera"] = {"projection": "perspective", "fov_y": fov}
            tags = {"dataset": dataset, "preset": preset, "fov": fov,
                    "projection": "perspective" if fov else "orthographic"}
            runs += _truth_and_shearwarp(self.name, label, scene, views, truth_factor, tags)
        return runs

    claims = (
        Claim("quality-falls-with-fov", "Quality degrades as the field of view widens and rays meet the slices at "
              "larger angles (§4.2.5)", "PSNR at the widest field ≥ 1 dB below the narrowest, and never more than "
              "0.5 dB above the next narrower one", lambda df: _fov_falls(df)),
        Claim("narrow-fov-like-parallel", "A narrow field of view is as accurate as the parallel projection",
              "|PSNR(narrowest field) − PSNR(parallel)| ≤ 2 dB", lambda df: _fov_parallel(df)),
    )

    def paper_table(self):
        return pd.DataFrame([
            ("§4.2.5 (1)", "wide field of view (≥ ~90°, fly-throughs)", "rays beyond 45° to the slices degrade quality, "
             "severely near 90°; the fix (≤ 6 pyramidal sub-volumes) not implemented"),
            ("§4.2.5 (2), Fig. 4.12", "thin opaque plates A, B before a plane C, strong perspective",
             "C shows through A and B (filtering before compositing); small except under severe perspective"),
            ("§4.2.5 (3)", "specular highlights", "central ray's view direction; wrong near or inside the volume"),
        ], columns=["thesis", "case", "finding (qualitative in the thesis)"])

    def report(self, results, ctx):
        ok = ok_rows(results)
        out = [blocks.Takeaways(_fov_takeaways(results))]
        try:
            rows = fov_rows(ok)
        except (KeyError, ValueError):
            return out + not_measurable(unregistered(SW))
        columns = {"fov": "field of view (°, 0: parallel)", "psnr": "PSNR (dB)", "ssim": "SSIM", "rmse": "RMSE",
                   "max_ray_angle": "largest ray-to-axis angle (°)"}
        table = rows.reindex(columns=list(columns)).rename(columns=columns)
        table = pd.concat([table.reset_index(drop=True), _links(rows.reset_index(drop=True), ctx)], axis=1)
        out.append(blocks.Table("Error against the reference by field of view", table, csv_name="perspective.csv",
                                links=LINKS, caption="Single untimed frames; each against the reference ray caster "
                                                     "with the same camera at a fine step. The largest ray angle is "
                                                     "the backend's info.max_ray_angle."))
        perspective = rows[rows.fov > 0].assign(series=rows.dataset.astype(str))
        path, rel = ctx.plot_path("psnr-fov")
        guides = ()
        parallel = rows[rows.fov == 0]
        if not parallel.empty:
            xs = np.array([perspective.fov.min(), perspective.fov.max()])
            guides = (("parallel projection", xs, np.full(2, float(parallel.psnr.iloc[0]))),)
        plots.lines(perspective, path, x="fov", y="psnr", group="series", title=_fov_title(ok),
                    x_label="vertical field of view (degrees)", y_label="PSNR against the reference (dB)", guides=guides)
        out.append(blocks.Figure("Accuracy against the field of view", rel,
                                 "The eye comes closer as the field widens (the camera frames the volume)."))
        gallery = blocks.Gallery("Each field of view and its difference from the reference", diff_scale=DIFF_SCALE,
                                 caption=f"One colour scale for every difference image (absolute error "
                                         f"{DIFF_SCALE:g} at the top).")
        for row in rows.itertuples():
            gallery.items.append(blocks.GalleryItem(
                "parallel" if row.fov == 0 else f"field of view {row.fov:g}°", ctx.image(row.png),
                difference=ctx.difference(_reference_exr(results, row), row.exr, DIFF_SCALE),
                note=f"PSNR {format_number(row.psnr)} dB, SSIM {format_number(getattr(row, 'ssim', np.nan))}"
                     + (f"; largest ray angle {format_number(row.max_ray_angle)}°" if np.isfinite(row.max_ray_angle) else "")))
        out.append(gallery)
        return out + not_measurable(unregistered(SW) + [
            ("the visibility error of Fig. 4.12 (plates A, B before C)", "no registered data set holds thin plates "
             "before a plane, and scenes take volumes from the registry only")])


def fov_rows(df):
    """The shear-warp rows with their field of view (0: parallel), PSNR and largest ray angle, by field."""
    rows = df[text_column(df, "role") == "test"].copy()
    rows["fov"], rows["psnr"] = numeric(rows, "fov"), numeric(rows, "psnr")
    rows["max_ray_angle"] = pd.to_numeric(rows.get("info_max_ray_angle", np.nan), errors="coerce")
    rows = rows[np.isfinite(rows.psnr)]
    if rows.empty:
        raise ValueError("no shear-warp image compared with its reference")
    return rows.sort_values("fov")


def _fov_falls(df):
    rows = fov_rows(df)
    perspective = rows[rows.fov > 0]
    if len(perspective) < 2:
        raise ValueError("fewer than two fields of view")
    psnr = perspective.psnr.to_numpy(float)
    drop = psnr[0] - psnr[-1]
    rise = float(np.max(np.diff(psnr))) if len(psnr) > 1 else 0.0
    return ClaimResult(f"{format_number(drop)} dB lower at {perspective.fov.iloc[-1]:g}° than at {perspective.fov.iloc[0]:g}°",
                       bool(drop >= 1.0 and rise <= 0.5),
                       ", ".join(f"{f:g}°: {format_number(p)} dB" for f, p in zip(perspective.fov, psnr))
                       + f"; largest rise to a wider field {format_number(max(rise, 0.0))} dB")


def _fov_parallel(df):
    rows = fov_rows(df)
    parallel, perspective = rows[rows.fov == 0], rows[rows.fov > 0]
    if parallel.empty or perspective.empty:
        raise ValueError("needs the parallel projection and a perspective view")
    narrow = perspective.iloc[0]
    gap = float(narrow.psnr - parallel.psnr.iloc[0])
    return ClaimResult(f"{format_number(gap)} dB ({narrow.fov:g}° against parallel)", bool(abs(gap) <= 2.0),
                       f"parallel {format_number(parallel.psnr.iloc[0])} dB, {narrow.fov:g}° {format_number(narrow.psnr)} dB")


def _fov_title(ok):
    return _title_or(lambda d: f"PSNR {_fov_falls(d).measured}", ok, "PSNR against the field of view")


def _fov_takeaways(results):
    return _claim_sentences(results, ((_fov_falls, "As the field of view widens the PSNR is"),
                                 (_fov_parallel, "The narrowest field against the parallel projection")),
                            "{what} {measured} ({detail}).")


EXPERIMENTS = (VolPackComparison, ImageQuality, OptimisationMatrix, ViewAngles, SizeScaling, Throughput, Parallel, Variants,
               Projections, PerspectiveQuality)

PAPER = Paper("lacroute1995", "shearwarp", baselines=("volpack",), experiments=EXPERIMENTS,
              needs="the CPU shear-warp factorization (Numba) and VolPack itself as the baseline")
"""What this paper needs and which experiments reproduce it (the registry reads it)."""
