"""``volbench-convergence``: the reference renderer's error against a much finer step, as the step shrinks."""

import numpy as np

from pipeline.experiments.kit.checks import worst_psnr
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, Run
from pipeline.experiments.kit.pages import (difference_gallery, figure, format_number, timed_metrics_table,
                                            unless_missing)
from pipeline.experiments.kit.planning import HEADLINE_VIEW, REFERENCE, voxels
from pipeline.experiments.volbench.scenes import scene_and_truth
from reports import blocks, takeaways

CONVERGENCE_SCENES = {
    "skull-bone": ("ct_skull", "bone", "phong"),
    "engine-semi": ("engine", None, "none"),
    "fbm-haze": ("fbm_control", None, "none"),
}
"""Scene → (data set, preset or None for its default, shading): a surface, a semi-transparent volume, haze."""


def _observed_order(group):
    """Least-squares slope of log(rmse) against log(step): the observed order of convergence."""
    group = group[np.isfinite(group.rmse) & (group.rmse > 0)]
    if len(group) < 2:
        raise ValueError("fewer than two step sizes with a non-zero error")
    return float(np.polyfit(np.log(group.step_factor), np.log(group.rmse), 1)[0])


def _sweep(df):
    rows = df[df.role == "sweep"]
    return rows.assign(step_factor=rows.step_factor.astype(float)).sort_values("step_factor", ascending=False)


def _not_monotone(sweep):
    """The scenes of ``sweep`` (largest step first) whose error does not fall at every halving of the step."""
    return [scene for scene, g in sweep.groupby("scene") if not (np.diff(g.rmse.to_numpy()) < 0).all()]


def _monotone(df):
    failures, scenes = _not_monotone(_sweep(df)), _sweep(df).scene.nunique()
    return ClaimResult(f"{scenes - len(failures)}/{scenes} scenes monotone", not failures,
                       f"not monotone: {', '.join(failures)}" if failures else "")


def _order(df):
    orders = {scene: _observed_order(g) for scene, g in _sweep(df).groupby("scene")}
    worst = min(orders, key=orders.get)
    detail = ", ".join(f"{s}: {format_number(o)}" for s, o in orders.items())
    return ClaimResult(f"{format_number(orders[worst])} ({worst})", orders[worst] >= 1.0, detail)


DEFAULT_STEP = worst_psnr("PSNR of the worst scene at 1/4 voxel", 40.0, role="sweep", step_factor=0.25)
"""The default step's check: every scene within 40 dB of the finest render."""


class ReferenceConvergence(Experiment):
    """The reference renderer's error against a much finer step, as the step shrinks."""

    name = "volbench-convergence"
    title = "Reference renderer: convergence with the step size"
    settings = frozenset({"volume_size", "image_size", "step_factors", "truth_step_factor"})
    scales = {
        "smoke": {"step_factors": [2.0, 1.0, 0.5, 0.25], "truth_step_factor": 0.0625},
        "default": {"volume_size": 96, "image_size": 160},
        "full": {"volume_size": 128, "image_size": 256, "step_factors": [2.0, 1.0, 0.5, 0.25, 0.125, 0.0625]},
    }
    description = (
        "The reference is ground truth only if its default step has converged. Each scene is rendered at step factors "
        "from 2 to 1/8 voxel and compared with a render at 1/32 voxel. The error must fall as the step shrinks (not "
        "flatten), and the default 1/4 voxel must be within 40 dB PSNR of the finest render."
    )
    STEP_FACTORS = (2.0, 1.0, 0.5, 0.25, 0.125)
    TRUTH_FACTOR = 1 / 32

    def runs(self, profile):
        factors = profile.setting(self, "step_factors", self.STEP_FACTORS)
        truth_factor = profile.setting(self, "truth_step_factor", self.TRUTH_FACTOR)
        runs = []
        for scene_name, scene_def in CONVERGENCE_SCENES.items():
            scene, truth = scene_and_truth(self, profile, scene_name, scene_def, truth_factor,
                                           {"step_factor": truth_factor})
            runs += [truth] + [Run(self.name, f"{scene_name}.step{factor:g}", REFERENCE, scene, (HEADLINE_VIEW,),
                                   options={"step_factor": factor}, reference=truth.id, warmup=profile.warmup,
                                   repeat=profile.repeat, tags={"scene": scene_name, "step_factor": factor,
                                                                "role": "sweep"})
                               for factor in factors]
        return runs

    claims = (
        Claim("monotone", "The error falls every time the step is halved (each scene)",
              "strictly decreasing RMSE", _monotone, kind="accuracy"),
        Claim("order", "The error falls with the step at least linearly (observed order, worst scene)",
              "order ≥ 1", _order, kind="accuracy"),
        Claim("default-step", "At the default step (1/4 voxel) the reference is within 40 dB of the finest render",
              DEFAULT_STEP.expected, DEFAULT_STEP),
    )

    def report(self, results, ctx):
        from reports import plots  # matplotlib: only when the report is built

        ok = results[(results.status == "ok") & (results.role == "sweep")].copy()
        ok["step_factor"] = ok.step_factor.astype(float)
        orders = {scene: unless_missing(_observed_order, group, empty=None) for scene, group in ok.groupby("scene")}
        orders = {scene: order for scene, order in orders.items() if order is not None}  # a scene without two errors
        truth = voxels(float(results[results.role == "truth"].step_factor.astype(float).min()))
        chart = figure(ctx, "convergence", plots.convergence, ok, heading="Error against step size (log–log)",
                       caption=f"RMSE against a {truth}-voxel render, one line per scene; grey guide lines of "
                               "slope 1 and 2 through the coarsest point. Parallel to a guide: that order.",
                       x_col="step_factor", y_col="rmse", group_col="scene", title=_convergence_title(ok, orders),
                       y_label=f"RMSE against a {truth}-voxel render (intensity 0–1)")
        shown = ok[ok.step_factor.isin([max(ok.step_factor), 0.25])].sort_values(["scene", "step_factor"])
        gallery = difference_gallery("Coarsest and default steps against the finest render", shown, ctx,
                                     against=results, label=lambda row: f"{row.scene}, step {row.step_factor:g} voxel",
                                     caption="Left each render, right its difference from the finest render.",
                                     note=lambda row: f"RMSE {format_number(row.rmse)}, PSNR {format_number(row.psnr)} "
                                                      f"dB, largest error {format_number(row.max_error)}")
        return [blocks.Takeaways(_convergence_takeaways(ok, orders)), chart,
                timed_metrics_table("Errors and times", ok, ["scene", "step_factor"], ctx, by=["scene", "step_factor"],
                                    names={"step_factor": "step (voxels)"}, csv_name="convergence.csv"),
                gallery]


def _convergence_title(ok, orders):
    """The finding of the convergence chart, from the numbers."""
    if not orders:
        return "Error against step size"
    flat = _not_monotone(ok.sort_values("step_factor", ascending=False))
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
