"""volbench's own studies: the phantom gallery, the reference's convergence, speed versus accuracy."""

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

import datasets
from core.errors import InputError
from datasets.stats import BOX_STATISTICS, in_box
import renderers
from pipeline.experiments.base import Claim, ClaimResult, Experiment, Run, format_number
from pipeline.experiments.kit.model import Paper
from pipeline.experiments.kit.pages import DIFF_SCALE, LINKS, METRICS, frames_note, links, ms  # noqa: F401
from pipeline.experiments.kit.planning import HEADLINE_VIEW, UPRIGHT, phantom, scene, voxels
from pipeline.experiments.kit.results import reference_exr
from reports import blocks, takeaways

REAL_UPRIGHT = {
    "cthead": {"rotate": {"axis": [0, 1, -1], "degrees": 180}},
    "mrihead": {"rotate": {"axis": [0, 1, 1], "degrees": 180}},
    "brainsmall": {"rotate": {"axis": [1, 0, -1], "degrees": 180}},
}
"""The gallery's turn of real scans stored otherwise than the phantoms (body axis z, face −y), so
that each stands as its phantom does: cthead's crown is slice 0, mrihead faces +y, brainsmall is
stacked in sagittal slices (x front → back, y crown → neck). Each is a half turn (mirroring x,
which no scan here labels)."""


@dataclass(frozen=True)
class StandIn:
    """The real scan a phantom stands in for, the presets both have, and the phantom request
    that matches the scan's voxel size (``size`` voxels along the longest axis, ``params``)."""

    real: str
    presets: tuple
    size: int | None = None
    params: dict = field(default_factory=dict)


STAND_INS = {
    "ct_skull": StandIn("cthead", ("bone", "skin")),
    "mri_head": StandIn("mrihead", ("skin",)),
    "engine": StandIn("engine_real", ("semi", "surfaces")),
    "bonsai_like": StandIn("bonsai", ("tree", "isbvr")),
    "folded_brain": StandIn("brainsmall", ("volpack",), size=128, params={"decimate": 2}),
}
"""Phantom → the real scan of the same kind it stands in for: the gallery shows them side by side
and the statistics claims compare them (see :func:`_target_claims`)."""

RELATIVE_BAND = 0.25
"""A phantom's statistic holds within ±25 % of its target ..."""

ABSOLUTE_FLOOR = {"nontransparent_fraction": 0.005, "nonzero_fraction": 0.005, "empty_block_fraction": 0.02,
                  "runs_per_scanline": 0.1, "mean_run_length": 0.5}
"""... or within this absolute distance where that is wider: a band around a target near 0 (the
no-cue control's empty blocks) still means something."""

# Kept under their old names while the papers move to their packages (issue 21).
_ms, _links, _frames_note, _voxels, _phantom, _reference_exr = ms, links, frames_note, voxels, phantom, reference_exr


def _scene(volume, profile, *, image_size=None, shading="phong", mode="dvr", name=None):
    return scene(name or volume.get("dataset", "scene"), image_size or profile.image_size, volumes=[volume],
                 mode=mode, shading=shading)


def _scene_and_truth(experiment, scene_name, scene_def, profile, truth_factor, tags):
    """The scene mapping of ``scene_def = (dataset, preset, shading)`` and its fine-step truth run."""
    dataset, preset, shading = scene_def
    size = profile.setting(experiment, "volume_size", profile.volume_size)
    image_size = profile.setting(experiment, "image_size", profile.image_size)
    volume = _phantom(dataset, size, **({"preset": preset} if preset else {}))
    scene = _scene(volume, profile, image_size=image_size, shading=shading, name=scene_name)
    truth = Run(experiment, f"{scene_name}.truth", "reference", scene, (HEADLINE_VIEW,),
                options={"step_factor": truth_factor}, warmup=0, repeat=1,
                tags={"scene": scene_name, "role": "truth", **tags})
    return scene, truth


# --------------------------------------------------------------------------------------------
class PhantomGallery(Experiment):
    """Every data set rendered by the reference with its default preset, with its statistics."""

    name = "volbench-phantoms"
    title = "Data sets: statistics and gallery"
    settings = frozenset({"datasets", "volume_size", "image_size", "step_factor", "statistics_size", "all_presets"})
    description = (
        "Every synthetic stand-in and every real scan, rendered by the reference renderer with its "
        "default preset (Blinn–Phong, headline view) so that a person can judge how CT-like the "
        "phantoms look, next to the statistics the papers use: the fraction of non-transparent "
        "voxels (α > 0.05, the thesis's threshold), the fraction of empty 8³ blocks and the mean "
        "number of non-transparent runs per scanline. Statistics are taken at the size of the "
        "original data set (256³ for most), where the reproduction notes' targets apply."
    )

    @property
    def claims(self):
        return _target_claims()

    def runs(self, profile):
        wanted = profile.setting(self.name, "datasets", "all")
        names = datasets.names() if wanted == "all" else wanted
        size = profile.setting(self.name, "volume_size", profile.volume_size)
        image_size = profile.setting(self.name, "image_size", profile.image_size)
        step_factor = profile.setting(self.name, "step_factor", 0.5)
        stats_size = profile.setting(self.name, "statistics_size", "paper")
        stood_in = {}
        for phantom, stand_in in STAND_INS.items():
            stood_in.setdefault(stand_in.real, []).extend(stand_in.presets)
        runs = []
        for name in names:
            spec = datasets.get(name)
            stand_in = STAND_INS.get(name)
            if profile.setting(self.name, "all_presets", False):
                presets = list(spec.presets)
            else:  # the default, every preset with targets and every one a stand-in is compared under
                presets = list(dict.fromkeys([spec.default_preset, *spec.targets_by_preset,
                                              *(stand_in.presets if stand_in else ()), *stood_in.get(name, ())]))
            for preset in presets:
                upright = REAL_UPRIGHT.get(name, UPRIGHT if spec.up_axis == "z" else None)
                volume = _phantom(name, size, preset=preset, **({"transform": upright} if upright else {}))
                # Statistics at the original data set's size, where the notes' targets apply; a
                # stand-in under a preset it shares with its real scan at the scan's voxel size.
                if stand_in and preset in stand_in.presets and stats_size == "paper":
                    extra = {"params": stand_in.params} if stand_in.params else {}
                    measured = _phantom(name, stand_in.size or spec.default_size, preset=preset, **extra)
                else:
                    measured = _phantom(name, spec.default_size if stats_size == "paper" else stats_size, preset=preset)
                runs.append(Run(
                    experiment=self.name, id=f"{name}.{preset}", backend="reference",
                    scene=_scene(volume, profile, image_size=image_size, name=name),
                    views=(HEADLINE_VIEW,), options={"step_factor": step_factor},
                    warmup=0, repeat=1, statistics=measured,
                    tags={"dataset": name, "preset": preset, "kind": spec.kind},
                ))
        return runs

    def report(self, results, ctx):
        ok = results[results.status == "ok"]
        stat_cols = [c for c in ok.columns if c.startswith("stat_")]
        table = ok[["dataset", "kind", "preset", *stat_cols]].rename(columns=lambda c: c.removeprefix("stat_"))
        shown = [c for c in ("dataset", "kind", "preset", "size", *BOX_STATISTICS, "megabytes", "generation_seconds")
                 if c in table]
        targets = []
        for name in table.dataset.unique():
            for preset, stats in datasets.get(name).targets_by_preset.items():
                targets.extend({"dataset": name, "preset": preset, "statistic": stat, "target": value}
                               for stat, value in stats.items())
        table.reset_index(drop=True).to_csv(ctx.report_dir / "csv" / "phantom_statistics_all.csv", index=False)
        linked = pd.concat([table[shown].rename(columns={"generation_seconds": "generation (s)"}),
                            _links(ok, ctx)], axis=1).reset_index(drop=True)
        out = [blocks.Takeaways(_gallery_takeaways(results)),
               blocks.Table("Statistics under each rendered preset", linked,
                            caption="Non-transparent: α > 0.05; empty block: an 8³ block with no voxel of α > 0; "
                                    "runs per scanline: runs of non-transparent voxels along x (VolPack's c_v); "
                                    "generation: the phantom generator's wall time when it was generated (it is "
                                    "cached after that). Every statistic is in csv/phantom_statistics_all.csv; "
                                    "each row links to its run's JSON record and EXR image.",
                            csv_name="phantom_statistics.csv", links=LINKS)]
        compared = _stand_in_comparison(ok)
        if not compared.empty:
            out.append(blocks.Table(
                "Stand-ins against their real scans, in the same box", compared,
                caption="Each real scan is placed, centred, in its phantom's box at the scan's voxel size "
                        "(datasets.stats.in_box: padding with transparent voxels scales the fractions by the "
                        "scan's share of the box and runs per scanline by its share of the scanlines; an "
                        "anisotropic scan such as cthead counts as resampled to its finest spacing). The claim "
                        f"holds within ±{RELATIVE_BAND:.0%} of the real value, or the absolute floor where wider.",
                csv_name="stand_in_statistics.csv"))
        if targets:
            out.append(blocks.Table("Targets from the reproduction notes", pd.DataFrame(targets),
                                    caption="What each stand-in was tuned towards where no real scan of its kind "
                                            "is at hand (the papers' data sets); a preset a stand-in shares with "
                                            "its real scan is compared with the scan instead."))
        paired = set()
        pairs = blocks.Gallery(
            "Phantoms beside the real scans they stand in for",
            caption="Same view (30° yaw, 20° pitch), same orientation (body axis up) and the same preset; "
                    "left the generated phantom, right the real scan, with both statistics rows (the real "
                    "scan's in the phantom's box). Click an image for full size.")
        for phantom, stand_in in STAND_INS.items():
            for preset in stand_in.presets:
                match = ok[(ok.dataset == phantom) & (ok.preset == preset)]
                real_rows = ok[(ok.dataset == stand_in.real) & (ok.preset == preset)]
                if match.empty or real_rows.empty:
                    continue
                row, real_row = next(match.itertuples()), next(real_rows.itertuples())
                paired.update({row.run, real_row.run})
                real_spec = datasets.get(stand_in.real)
                pairs.items.append(blocks.GalleryItem(
                    caption=f"{phantom} stands in for {stand_in.real} ({real_spec.modality}) — preset {preset}",
                    image=ctx.image(row.png), label=f"phantom {phantom}",
                    extra=((f"real scan {stand_in.real}", ctx.image(real_row.png)),),
                    note=f"{_statistics_rows(compared, phantom, preset)} {datasets.get(phantom).description} "
                         f"Real: {real_spec.description} Both: {_frames_note(row)}."))
        gallery = blocks.Gallery("Every reference render (headline view)",
                                 caption="Each a single untimed frame (no warm-up): pictures to judge, not timings. "
                                         "Click an image for full size.")
        for row in ok.itertuples():
            if row.run in paired:
                continue
            spec = datasets.get(row.dataset)
            what = (f"Phantom: {spec.description}" if spec.kind == "phantom"
                    else f"Real scan ({spec.modality}): {spec.description}")
            gallery.items.append(blocks.GalleryItem(
                caption=f"{row.dataset} — {row.preset}", image=ctx.image(row.png),
                note=f"{what} {_frames_note(row).capitalize()}."))
        if pairs.items:
            out.append(pairs)
        out.append(gallery)
        return out


def _statistics_row(df, name, preset):
    """``{statistic: value}`` measured for data set ``name`` under ``preset`` (``None`` if not run)."""
    rows = df[(df.dataset == name) & (df.preset == preset)] if "dataset" in df and "preset" in df else df.iloc[:0]
    if rows.empty:
        return None
    row = rows.iloc[0]
    return {k.removeprefix("stat_"): row[k] for k in rows.columns if k.startswith("stat_") and pd.notna(row[k])}


def _real_in_box(df, phantom, preset):
    """The real scan's :data:`BOX_STATISTICS` placed in ``phantom``'s box, with the phantom's own.

    Returns ``(phantom_stats, real_stats, real_in_box)``, or a string saying why they do not
    compare: a side not measured, or a phantom measured at another size than the scan's voxels
    (profiles that shrink ``statistics_size``).
    """
    stand_in = STAND_INS[phantom]
    mine, real = _statistics_row(df, phantom, preset), _statistics_row(df, stand_in.real, preset)
    if mine is None or real is None:
        return f"{phantom if mine is None else stand_in.real} ({preset}) not measured"
    expected = stand_in.size or datasets.get(phantom).default_size
    if int(mine.get("size", 0)) != expected:
        return f"{phantom} measured at size {mine.get('size')}, not at the real scan's voxel size ({expected})"
    return mine, real, in_box(real, (int(mine["nx"]), int(mine["ny"]), int(mine["nz"])))


REAL_IN_BOX = "real, phantom's box"
"""Column of the real scan's statistic placed in its phantom's box."""


def _band(stat, target):
    """Half-width of the band a statistic must fall in: relative, with an absolute floor."""
    return max(RELATIVE_BAND * abs(target), ABSOLUTE_FLOOR.get(stat, 0.0))


def _stand_in_comparison(ok):
    """One row per stand-in, shared preset and statistic: phantom, real scan, real scan in the phantom's box."""
    rows = []
    for phantom, stand_in in STAND_INS.items():
        for preset in stand_in.presets:
            measured = _real_in_box(ok, phantom, preset)
            if isinstance(measured, str):
                continue
            mine, real, boxed = measured
            for stat in BOX_STATISTICS:
                rows.append({"phantom": phantom, "real scan": stand_in.real, "preset": preset, "statistic": stat,
                             "phantom value": mine[stat], "real, own box": real[stat], REAL_IN_BOX: boxed[stat],
                             "difference": f"{mine[stat] / boxed[stat] - 1:+.0%}" if boxed[stat] else "n/a",
                             "within band": bool(abs(mine[stat] - boxed[stat]) <= _band(stat, boxed[stat]))})
    return pd.DataFrame(rows)


def _statistics_rows(compared, phantom, preset):
    """The phantom's and the real scan's statistics as two short rows for a gallery note."""
    if compared.empty:
        return ""
    rows = compared[(compared.phantom == phantom) & (compared.preset == preset)]
    if rows.empty:
        return ""
    names = {"nontransparent_fraction": "non-transparent", "empty_block_fraction": "empty 8³ blocks",
             "runs_per_scanline": "runs/scanline", "mean_run_length": "mean run"}
    records = rows.to_dict("records")
    mine = ", ".join(f"{names[r['statistic']]} {format_number(r['phantom value'])}" for r in records)
    real = ", ".join(f"{names[r['statistic']]} {format_number(r[REAL_IN_BOX])}" for r in records)
    return f"Phantom: {mine}. Real scan in the same box: {real}."


def _gallery_takeaways(results):
    """What the gallery shows, counted: how many phantoms and real scans, which pairs, which statistics miss."""
    per_run = results.drop_duplicates("run")
    ok = per_run[per_run.status == "ok"]
    sentences = []
    if "kind" in ok:
        phantoms, reals = int((ok.kind == "phantom").sum()), int((ok.kind == "real").sum())
        sentences.append(f"{ok.dataset.nunique()} data sets rendered under {len(ok)} presets: "
                         f"{phantoms} phantom renders and {reals} renders of real scans.")
        pairs = [f"{p} ↔ {s.real}" for p, s in STAND_INS.items() if {p, s.real} <= set(ok.dataset)]
        if pairs:
            sentences.append(f"{len(pairs)} phantom{'s are' if len(pairs) != 1 else ' is'} shown beside the real scan {'they stand' if len(pairs) != 1 else 'it stands'} in for "
                             f"({', '.join(pairs)}).")
        compared = _stand_in_comparison(ok)
        if not compared.empty:
            missed = compared[~compared["within band"].astype(bool)]
            held = len(compared) - len(missed)
            sentence = (f"{held} of {len(compared)} stand-in statistics fall within ±{RELATIVE_BAND:.0%} of the real "
                        f"scan's in the same box")
            if not missed.empty:
                sentence += "; outside: " + ", ".join(
                    f"{r['phantom']} {r['preset']} {r['statistic']} {format_number(r['phantom value'])} "
                    f"vs {format_number(r[REAL_IN_BOX])}" for r in missed.to_dict("records"))
            sentences.append(sentence + ".")
    return sentences


def _real_says(df, phantom, stat):
    """Why a stand-in may miss a notes' target: what its real scan shows under the presets they share."""
    if phantom not in STAND_INS:
        return ""
    seen = []
    for preset in STAND_INS[phantom].presets:
        measured = _real_in_box(df, phantom, preset)
        if not isinstance(measured, str) and stat in measured[2]:
            seen.append(f"{preset} {format_number(measured[2][stat])}")
    real = STAND_INS[phantom].real
    if not seen:
        return f"; the phantom follows the real {real} where the two disagree (see the stand-in claims)"
    return f"; the real {real} in the same box: {', '.join(seen)} (the phantom follows the real scan)"


def _target_claims():
    """The statistics claims, each within ±25 % of its target or an absolute floor where wider.

    A stand-in under a preset it shares with its real scan is compared with the scan placed in
    the phantom's box (:func:`datasets.stats.in_box`), for each of :data:`BOX_STATISTICS`; every
    other target a phantom declares comes from the reproduction notes.
    """
    claims = []
    for phantom, stand_in in STAND_INS.items():
        for preset in stand_in.presets:
            for stat in BOX_STATISTICS:
                def check(df, phantom=phantom, preset=preset, stat=stat, real=stand_in.real):
                    measured = _real_in_box(df, phantom, preset)
                    if isinstance(measured, str):
                        return ClaimResult("not measured", None, measured)
                    mine, _, boxed = measured
                    band = _band(stat, boxed[stat])
                    return ClaimResult(format_number(mine[stat]), bool(abs(mine[stat] - boxed[stat]) <= band),
                                       f"{real} in the same box {format_number(boxed[stat])} "
                                       f"± {format_number(band)}")
                claims.append(Claim(f"{phantom}.{preset}-{stat}-vs-{stand_in.real}",
                                    f"{phantom} ({preset}): {stat} like the real {stand_in.real}'s",
                                    f"{stand_in.real}'s value in the same box ± {RELATIVE_BAND:.0%}", check))
    for name in datasets.names(kind="phantom"):
        compared = STAND_INS[name].presets if name in STAND_INS else ()
        for preset, stats in datasets.get(name).targets_by_preset.items():
            for stat, target in stats.items():
                if preset in compared and stat in BOX_STATISTICS:
                    continue

                def check(df, name=name, preset=preset, stat=stat, target=target):
                    rows = df[(df.dataset == name) & (df.preset == preset)]
                    column = f"stat_{stat}"
                    if rows.empty or column not in rows:
                        return ClaimResult("not measured", None)
                    value = float(rows[column].iloc[0])
                    band = _band(stat, target)
                    return ClaimResult(format_number(value), bool(abs(value - target) <= band),
                                       f"target {format_number(target)} ± {format_number(band)}"
                                       f"{_real_says(df, name, stat)}")
                claims.append(Claim(f"{name}.{preset}-{stat}", f"{name} ({preset}): {stat} near the original's",
                                    f"{format_number(target)} ± {format_number(_band(stat, target))}", check))
    return tuple(claims)


# --------------------------------------------------------------------------------------------
CONVERGENCE_SCENES = {
    "skull-bone": ("ct_skull", "bone", "phong"),
    "engine-semi": ("engine", None, "none"),
    "fbm-haze": ("fbm_control", None, "none"),
}


def _observed_order(group):
    """Least-squares slope of log(rmse) against log(step): the observed order of convergence."""
    group = group[np.isfinite(group.rmse) & (group.rmse > 0)]
    if len(group) < 2:
        raise ValueError("fewer than two step sizes with a non-zero error")
    return float(np.polyfit(np.log(group.step_factor), np.log(group.rmse), 1)[0])


class ReferenceConvergence(Experiment):
    """The reference renderer's error against a much finer step, as the step shrinks."""

    name = "volbench-convergence"
    title = "Reference renderer: convergence with the step size"
    settings = frozenset({"volume_size", "image_size", "step_factors", "truth_step_factor"})
    description = (
        "The reference is ground truth only if its default step has converged. Each scene is "
        "rendered at step factors from 2 to 1/8 voxel and compared with a render at 1/32 voxel. "
        "The error must fall as the step shrinks (not flatten), and the default 1/4 voxel must "
        "be within 40 dB PSNR of the finest render."
    )
    STEP_FACTORS = (2.0, 1.0, 0.5, 0.25, 0.125)
    TRUTH_FACTOR = 1 / 32

    def runs(self, profile):
        factors = profile.setting(self.name, "step_factors", self.STEP_FACTORS)
        truth_factor = profile.setting(self.name, "truth_step_factor", self.TRUTH_FACTOR)
        runs = []
        for scene_name, scene_def in CONVERGENCE_SCENES.items():
            scene, truth = _scene_and_truth(self.name, scene_name, scene_def, profile, truth_factor,
                                            {"step_factor": truth_factor})
            runs.append(truth)
            for factor in factors:
                runs.append(Run(self.name, f"{scene_name}.step{factor:g}", "reference", scene,
                                (HEADLINE_VIEW,), options={"step_factor": factor}, reference=truth.id,
                                warmup=profile.warmup, repeat=profile.repeat,
                                tags={"scene": scene_name, "step_factor": factor, "role": "sweep"}))
        return runs

    claims = (
        Claim("monotone", "The error falls every time the step is halved (each scene)",
              "strictly decreasing RMSE",
              lambda df: _monotone(df)),
        Claim("order", "The error falls with the step at least linearly (observed order, worst scene)",
              "order ≥ 1", lambda df: _order(df)),
        Claim("default-step", "At the default step (1/4 voxel) the reference is within 40 dB of the finest render",
              "PSNR ≥ 40 dB (worst scene)", lambda df: _default_step(df)),
    )

    def report(self, results, ctx):
        ok = results[(results.status == "ok") & (results.role == "sweep")].copy()
        ok["step_factor"] = ok.step_factor.astype(float)
        from reports import plots

        orders = {}
        for scene, group in ok.groupby("scene"):
            try:
                orders[scene] = _observed_order(group)
            except ValueError:
                pass
        path, rel = ctx.plot_path("convergence")
        truth = _voxels(float(results[results.role == "truth"].step_factor.astype(float).min()))
        plots.convergence(ok, path, x_col="step_factor", y_col="rmse", group_col="scene",
                          title=_convergence_title(ok, orders),
                          y_label=f"RMSE against a {truth}-voxel render (intensity 0–1)")
        table = pd.concat([ok[["scene", "step_factor"]], _ms(ok), ok[list(METRICS)].rename(columns=METRICS),
                           _links(ok, ctx)], axis=1).sort_values(["scene", "step_factor"])
        table = table.rename(columns={"step_factor": "step (voxels)"})
        gallery = blocks.Gallery("Coarsest and default steps against the finest render", diff_scale=DIFF_SCALE,
                                 caption="Left each render, right its difference from the finest render.")
        for row in ok[ok.step_factor.isin([max(ok.step_factor), 0.25])].sort_values(["scene", "step_factor"]).itertuples():
            gallery.items.append(blocks.GalleryItem(
                caption=f"{row.scene}, step {row.step_factor:g} voxel", image=ctx.image(row.png),
                difference=ctx.difference(_reference_exr(results, row), row.exr, DIFF_SCALE),
                note=f"RMSE {format_number(row.rmse)}, PSNR {format_number(row.psnr)} dB, "
                     f"largest error {format_number(row.max_error)}"))
        return [blocks.Takeaways(_convergence_takeaways(ok, orders)),
                blocks.Figure("Error against step size (log–log)", rel,
                              f"RMSE against a {truth}-voxel render, one line per scene; grey guide lines of "
                              "slope 1 and 2 through the coarsest point. Parallel to a guide: that order."),
                blocks.Table("Errors and times", table.reset_index(drop=True), csv_name="convergence.csv",
                             caption="Time: median frame after warm-up, with the fastest and slowest timed frame. "
                                     "Each row links to its run's JSON record and EXR image.", links=LINKS),
                gallery]


def _convergence_title(ok, orders):
    """The finding of the convergence chart, from the numbers."""
    if not orders:
        return "Error against step size"
    flat = [scene for scene, g in ok.sort_values("step_factor", ascending=False).groupby("scene")
            if not (np.diff(g.rmse.to_numpy()) < 0).all()]
    low, high = min(orders.values()), max(orders.values())
    span = f"{low:.2g}" if f"{low:.2g}" == f"{high:.2g}" else f"{low:.2g}–{high:.2g}"
    title = f"Error falls at observed order {span} as the step shrinks"
    if flat:
        title += f"\nbut not monotonically on {', '.join(flat)}"
    return title


def _convergence_takeaways(ok, orders):
    sentences = takeaways.order_range(orders)
    default = ok[np.isclose(ok.step_factor, 0.25)]
    if not default.empty:
        worst = default.loc[default.psnr.idxmin()]
        sentences.append(f"At the default step of 1/4 voxel the worst scene is {worst.scene} at "
                         f"{format_number(worst.psnr)} dB PSNR (RMSE {format_number(worst.rmse)}).")
    coarse = ok[ok.step_factor == ok.step_factor.max()]
    if not coarse.empty:
        worst = coarse.loc[coarse.psnr.idxmin()]
        sentences.append(f"At the coarsest step ({worst.step_factor:g} voxel) the worst scene is {worst.scene} at "
                         f"{format_number(worst.psnr)} dB: where a coarse step visibly fails.")
    return sentences


def _sweep(df):
    rows = df[df.role == "sweep"].copy()
    rows["step_factor"] = rows.step_factor.astype(float)
    return rows.sort_values("step_factor", ascending=False)


def _monotone(df):
    failures = [scene for scene, g in _sweep(df).groupby("scene") if not (np.diff(g.rmse.to_numpy()) < 0).all()]
    scenes = _sweep(df).scene.nunique()
    return ClaimResult(f"{scenes - len(failures)}/{scenes} scenes monotone", not failures,
                       f"not monotone: {', '.join(failures)}" if failures else "")


def _order(df):
    orders = {scene: _observed_order(g) for scene, g in _sweep(df).groupby("scene")}
    worst = min(orders, key=orders.get)
    detail = ", ".join(f"{s}: {format_number(o)}" for s, o in orders.items())
    return ClaimResult(f"{format_number(orders[worst])} ({worst})", orders[worst] >= 1.0, detail)


def _default_step(df):
    rows = _sweep(df)
    rows = rows[np.isclose(rows.step_factor, 0.25)]
    if rows.empty:
        raise ValueError("no run at step factor 0.25")
    worst = rows.loc[rows.psnr.idxmin()]
    return ClaimResult(f"{format_number(worst.psnr)} dB ({worst.scene})", bool(worst.psnr >= 40.0),
                       ", ".join(f"{r.scene}: {format_number(r.psnr)} dB" for r in rows.itertuples()))


# --------------------------------------------------------------------------------------------
SPEED_ACCURACY_SCENES = {
    "skull-bone": ("ct_skull", "bone", "phong"),
    "engine-semi": ("engine", None, "phong"),
}


class SpeedAccuracy(Experiment):
    """Every registered backend over its quality settings: time against error."""

    name = "volbench-speed-accuracy"
    title = "Speed against accuracy, every backend"
    settings = frozenset({"scenes", "volume_size", "image_size"})
    description = (
        "Each registered backend renders the same scenes over its own quality settings (its "
        "``quality_sweep``: step size, and later slice count, thresholds, ...). Error is measured "
        "against the reference at 1/16 voxel, time is the median frame after warm-up. Backends "
        "that cannot run here are listed with the reason."
    )
    TRUTH_FACTOR = 1 / 16

    def runs(self, profile):
        wanted = profile.setting(self.name, "scenes", list(SPEED_ACCURACY_SCENES))
        unknown = [name for name in wanted if name not in SPEED_ACCURACY_SCENES]
        if unknown:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.scenes: unknown {unknown}; "
                             f"known: {list(SPEED_ACCURACY_SCENES)}")
        runs = []
        for scene_name in wanted:
            scene_def = SPEED_ACCURACY_SCENES[scene_name]
            scene, truth = _scene_and_truth(self.name, scene_name, scene_def, profile, self.TRUTH_FACTOR,
                                            {"setting": "truth"})
            runs.append(truth)
            for backend in renderers.names():
                for index, options in enumerate(renderers.backend_class(backend).quality_sweep):
                    setting = ",".join(f"{k}={v}" for k, v in sorted(options.items())) or "default"
                    runs.append(Run(self.name, f"{scene_name}.{backend}.{index}", backend, scene,
                                    (HEADLINE_VIEW,), options=dict(options), reference=truth.id,
                                    warmup=profile.warmup, repeat=profile.repeat,
                                    tags={"scene": scene_name, "setting": setting, "role": "sweep"}))
        return runs

    claims = (
        Claim("tradeoff", "For the reference, halving the step roughly doubles the time and lowers the error",
              "time ratio per halving in [1.5, 2.5]; error decreasing",
              lambda df: _tradeoff(df)),
    )

    overview = True
    """The index's techniques × data sets table is built from this experiment's runs."""

    def report(self, results, ctx):
        from reports import plots

        ok = results[(results.status == "ok") & (results.role == "sweep")].copy()
        ok["setting"] = ok.setting.fillna("default").astype(str)
        ok["technique"] = [f"{b} ({s})" if s != "default" else b for b, s in zip(ok.backend, ok.setting)]
        ok["time_ms"] = ok.time_total * 1e3
        ok["time_ms_min"] = ok.get("time_total_min", np.nan) * 1e3
        ok["time_ms_max"] = ok.get("time_total_max", np.nan) * 1e3
        out = [blocks.Takeaways(takeaways.fastest_at_accuracy(ok) + takeaways.accuracy_failures(ok)
                                + _stage_takeaways(ok))]
        for scene, group in ok.groupby("scene"):
            path, rel = ctx.plot_path(f"speed-accuracy-{scene}")
            plots.speed_accuracy(group, path, time_col="time_ms", error_col="psnr", group_col="backend",
                                 label_col="setting", title=_speed_title(scene, group), log_y=False,
                                 time_range_cols=("time_ms_min", "time_ms_max"), better="upper left",
                                 x_label="median frame time (ms); bars: fastest to slowest frame",
                                 y_label="PSNR against the reference (dB)")
            out.append(blocks.Figure(f"{scene}: median frame time against PSNR", rel,
                                     "Each point is one quality setting, labelled with it; higher and further "
                                     "left is better. Error bars span the fastest and slowest timed frame."))
        stages = [c for c in ok.columns if c.startswith("time_") and c not in ("time_total", "time_ms")
                  and not c.endswith(("_min", "_max"))]
        ok["backend_setting"] = ok.backend + " " + ok.setting
        if stages:
            path, rel = ctx.plot_path("stages")
            plots.stage_breakdown(ok, path, stage_cols=stages, group_col="backend_setting",
                                  title=_stage_title(ok, stages))
            out.append(blocks.Figure("Time per stage (median over scenes)", rel,
                                     "Each backend's own stages, as it reports them (CONVENTIONS, Results)."))
        columns = ["scene", "backend", "setting"]
        table = pd.concat([ok[columns], _ms(ok), ok[list(METRICS)].rename(columns=METRICS), _links(ok, ctx)], axis=1)
        out.append(blocks.Table("All settings", table.sort_values(["scene", "backend", "time (ms)"]).reset_index(drop=True),
                                csv_name="speed_accuracy.csv", links=LINKS,
                                caption="Time: median frame after warm-up, with the fastest and slowest timed frame. "
                                        "Each row links to its run's JSON record and EXR image."))
        for scene, group in ok.groupby("scene"):
            gallery = blocks.Gallery(f"{scene}: every setting against the reference", diff_scale=DIFF_SCALE)
            for row in group.sort_values("time_total").itertuples():
                gallery.items.append(blocks.GalleryItem(
                    caption=row.technique, image=ctx.image(row.png),
                    difference=ctx.difference(_reference_exr(results, row), row.exr, DIFF_SCALE),
                    note=f"{format_number(row.time_ms)} ms, PSNR {format_number(row.psnr)} dB, "
                         f"largest error {format_number(row.max_error)}"))
            out.append(gallery)
        unavailable = [{"backend": info.name, "reason": info.reason} for info in renderers.available() if not info.available]
        if unavailable:
            out.append(blocks.Table("Backends that cannot run here", pd.DataFrame(unavailable)))
        return out


def _speed_title(scene, group, psnr_min=takeaways.PSNR_GOOD):
    """The finding of a speed-accuracy chart: the fastest setting that reaches ``psnr_min``."""
    accurate = group[group.psnr >= psnr_min]
    if accurate.empty:
        return f"{scene}: no setting reaches {psnr_min:g} dB (best {format_number(group.psnr.max())} dB)"
    best = accurate.loc[accurate.time_ms.idxmin()]
    return f"{scene}: {psnr_min:g} dB at {format_number(best.time_ms)} ms with {best.technique}"


def _stage_shares(ok, stages):
    medians = ok[stages].median()
    total = medians.sum()
    return (medians / total).sort_values(ascending=False) if total > 0 else pd.Series(dtype=float)


def _stage_title(ok, stages):
    shares = _stage_shares(ok, stages)
    if shares.empty:
        return "Time per stage"
    return f"The {shares.index[0].removeprefix('time_')} stage takes {shares.iloc[0]:.0%} of the median frame"


def _stage_takeaways(ok):
    stages = [c for c in ok.columns if c.startswith("time_") and c not in ("time_total", "time_ms")
              and not c.endswith(("_min", "_max"))]
    shares = _stage_shares(ok, stages) if stages else pd.Series(dtype=float)
    if shares.empty:
        return []
    parts = ", ".join(f"{name.removeprefix('time_')} {share:.0%}" for name, share in shares.items())
    return [f"Where the time goes (median over every setting and scene): {parts}."]


def _tradeoff(df):
    rows = df[(df.backend == "reference") & (df.role == "sweep")].copy()
    rows["step_factor"] = rows.setting.str.extract(r"step_factor=([0-9.e-]+)")[0].astype(float)
    ratios, monotone = [], True
    for _, group in rows.groupby("scene"):
        group = group.sort_values("step_factor", ascending=False)
        times = group.time_total.to_numpy()
        ratios.extend(times[1:] / times[:-1])
        monotone &= bool((np.diff(group.rmse.to_numpy()) < 0).all())
    if not ratios:
        raise ValueError("no reference sweep")
    median_ratio = float(np.median(ratios))
    holds = 1.5 <= median_ratio <= 2.5 and monotone
    return ClaimResult(f"×{format_number(median_ratio)} per halving", holds,
                       f"ratios {', '.join(format_number(r) for r in ratios)}; error decreasing: {monotone}")


EXPERIMENTS = (PhantomGallery, ReferenceConvergence, SpeedAccuracy)

PAPER = Paper("volbench", None, experiments=EXPERIMENTS)
"""What this paper needs and which experiments reproduce it (the registry reads it)."""
