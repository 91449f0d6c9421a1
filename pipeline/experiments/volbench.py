"""volbench's own studies: the phantom gallery, the reference's convergence, speed versus accuracy."""

import numpy as np
import pandas as pd

import datasets
import renderers
from pipeline.experiments.base import Claim, ClaimResult, Experiment, Run, format_number
from reports import blocks

HEADLINE_VIEW = {"view": "headline", "azimuth": 30.0, "elevation": 20.0}
"""The oblique view note 000 recommends for headline numbers (30° yaw, 20° pitch)."""

UPRIGHT = {"rotate": {"axis": [1, 0, 0], "degrees": -90}}
"""Scanner z (the body axis of the phantoms and CT stacks) to world y (up), the face to +z."""


def _scene(volume, profile, *, image_size=None, shading="phong", mode="dvr", name=None):
    size = image_size or profile.image_size
    return {"name": name or volume.get("dataset", "scene"), "width": size, "height": size,
            "mode": mode, "shading": {"model": shading}, "volumes": [volume]}


def _phantom(name, size=None, **extra):
    spec = {"dataset": name, **extra}
    if size is not None and datasets.get(name).kind == "phantom":
        spec["size"] = size
    return spec


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
        runs = []
        for name in names:
            spec = datasets.get(name)
            if profile.setting(self.name, "all_presets", False):
                presets = list(spec.presets)
            else:  # the default, and every preset the notes give target statistics for
                presets = list(dict.fromkeys([spec.default_preset, *spec.targets_by_preset]))
            for preset in presets:
                volume = _phantom(name, size, preset=preset, **({"transform": UPRIGHT} if spec.up_axis == "z" else {}))
                # Statistics at the original data set's size, where the notes' targets apply.
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
        shown = [c for c in ("dataset", "kind", "preset", "size", "nontransparent_fraction", "empty_block_fraction",
                             "runs_per_scanline", "mean_run_length", "megabytes") if c in table]
        targets = []
        for name in table.dataset.unique():
            for preset, stats in datasets.get(name).targets_by_preset.items():
                targets.extend({"dataset": name, "preset": preset, "statistic": stat, "target": value}
                               for stat, value in stats.items())
        table.reset_index(drop=True).to_csv(ctx.report_dir / "csv" / "phantom_statistics_all.csv", index=False)
        out = [blocks.Table("Statistics under each rendered preset", table[shown].reset_index(drop=True),
                            caption="Non-transparent: α > 0.05; empty block: an 8³ block with no voxel of α > 0; "
                                    "runs per scanline: runs of non-transparent voxels along x (VolPack's c_v). "
                                    "Every statistic is in csv/phantom_statistics_all.csv.",
                            csv_name="phantom_statistics.csv")]
        if targets:
            out.append(blocks.Table("Targets from the reproduction notes", pd.DataFrame(targets),
                                    caption="What each stand-in was tuned towards (the papers' data sets)."))
        gallery = blocks.Gallery("Reference renders (headline view, default preset)")
        for row in ok.itertuples():
            gallery.items.append(blocks.GalleryItem(
                caption=f"{row.dataset} — {row.preset}", image=ctx.image(row.png),
                note=f"{row.kind}; {format_number(row.time_total)} s"))
        out.append(gallery)
        return out


def _target_claims():
    """One claim per target statistic a phantom declares: measured within ±50 % of the target."""
    claims = []
    for name in datasets.names(kind="phantom"):
        for preset, stats in datasets.get(name).targets_by_preset.items():
            for stat, target in stats.items():
                def check(df, name=name, preset=preset, stat=stat, target=target):
                    rows = df[(df.dataset == name) & (df.preset == preset)]
                    column = f"stat_{stat}"
                    if rows.empty or column not in rows:
                        return ClaimResult("not measured", None)
                    value = float(rows[column].iloc[0])
                    return ClaimResult(format_number(value), abs(value - target) <= 0.5 * abs(target),
                                       f"target {format_number(target)}")
                claims.append(Claim(f"{name}.{preset}-{stat}", f"{name} ({preset}): {stat} near the original's",
                                    f"{format_number(target)} ± 50 %", check))
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

        path, rel = ctx.plot_path("convergence")
        plots.convergence(ok, path, x_col="step_factor", y_col="rmse", group_col="scene")
        table = ok[["scene", "step_factor", "rmse", "psnr", "ssim", "flip", "time_total"]].sort_values(["scene", "step_factor"])
        gallery = blocks.Gallery("Coarsest and default steps against the finest render")
        for row in ok[ok.step_factor.isin([max(ok.step_factor), 0.25])].itertuples():
            gallery.items.append(blocks.GalleryItem(
                caption=f"{row.scene}, step {row.step_factor:g} voxel", image=ctx.image(row.png),
                difference=ctx.image(row.diff_png), note=f"RMSE {format_number(row.rmse)}, PSNR {format_number(row.psnr)} dB"))
        return [blocks.Figure("Error against step size (log–log)", rel,
                              "RMSE against a 1/32-voxel render; guide lines of slope 1 and 2."),
                blocks.Table("Errors and times", table.reset_index(drop=True), csv_name="convergence.csv"),
                gallery]


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
    settings = frozenset({"volume_size", "image_size"})
    description = (
        "Each registered backend renders the same scenes over its own quality settings (its "
        "``quality_sweep``: step size, and later slice count, thresholds, ...). Error is measured "
        "against the reference at 1/16 voxel, time is the median frame after warm-up. Backends "
        "that cannot run here are listed with the reason."
    )
    TRUTH_FACTOR = 1 / 16

    def runs(self, profile):
        runs = []
        for scene_name, scene_def in SPEED_ACCURACY_SCENES.items():
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

    def report(self, results, ctx):
        from reports import plots

        ok = results[(results.status == "ok") & (results.role == "sweep")].copy()
        out = []
        for scene, group in ok.groupby("scene"):
            path, rel = ctx.plot_path(f"speed-accuracy-{scene}")
            plots.speed_accuracy(group, path, time_col="time_total", error_col="rmse",
                                 group_col="backend", label_col="setting", title=f"{scene}: time vs RMSE")
            out.append(blocks.Figure(f"{scene}: median frame time against RMSE", rel,
                                     "Each point is one quality setting; lower left is better."))
        stages = [c for c in ok.columns if c.startswith("time_") and c != "time_total" and not c.endswith(("_min", "_max"))]
        ok["backend_setting"] = ok.backend + " " + ok.setting
        path, rel = ctx.plot_path("stages")
        plots.stage_breakdown(ok, path, stage_cols=stages, group_col="backend_setting")
        out.append(blocks.Figure("Time per stage (median over scenes)", rel,
                                 "Each backend's own stages, as it reports them (CONVENTIONS, Results)."))
        columns = ["scene", "backend", "setting", "time_total", "rmse", "psnr", "ssim", "flip"]
        out.append(blocks.Table("All settings", ok[columns].sort_values(["scene", "backend", "time_total"]).reset_index(drop=True),
                                csv_name="speed_accuracy.csv"))
        unavailable = [{"backend": info.name, "reason": info.reason} for info in renderers.available() if not info.available]
        if unavailable:
            out.append(blocks.Table("Backends that cannot run here", pd.DataFrame(unavailable)))
        return out


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
