"""``lacroute1995-perspective`` (E21, §4.2.5): perspective image quality as the field of view widens."""

import numpy as np
import pandas as pd

import datasets
from core.errors import InputError
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment
from pipeline.experiments.kit.pages import (DIFF_SCALE, as_percent, claim_takeaways, db_words, difference_gallery,
                                            figure, format_number, linked_table, title_or)
from pipeline.experiments.kit.planning import headline_view, is_registered, phantom, scene, volume_and_image_size
from pipeline.experiments.kit.results import (FOOTPRINT_ALPHA, footprint_psnr, nonempty_or, numeric, ok_rows, read_exr,
                                              text_column)
from pipeline.experiments.lacroute1995 import tables
from pipeline.experiments.lacroute1995.planning import SW, shearwarp_missing, truth_and_shearwarp
from reports import plots


class PerspectiveQuality(Experiment):
    name = "lacroute1995-perspective"
    paper = "lacroute1995"
    title = "Perspective artifacts: quality against the field of view (E21, §4.2.5)"
    settings = frozenset({"dataset", "preset", "volume_size", "image_size", "fovs", "truth_step_factor"})
    scales = {"smoke": {"fovs": [15, 90]}, "default": {"fovs": [15, 30, 60, 90]},
              "full": {"fovs": [15, 30, 45, 60, 75, 90]}}
    description = (
        "Perspective shear-warp keeps one principal axis for every ray and filters each slice over the "
        "pixel's footprint before compositing. The thesis admits two limits (§4.2.5): rays that meet the "
        "slices at more than 45° degrade the image, severely as they approach 90° (wide fields of view, "
        "fly-throughs), and averaging thin opaque structures with empty space before compositing lets what "
        "lies behind them show through. The thesis's test of the second (two thin opaque plates before a "
        "plane) needs a scene no registered data set provides; here the first is measured: the same data "
        "set from the same direction at fields of view of 15° to 90° (the camera framing the volume, so "
        "the eye comes closer as the field widens), each image against the reference ray caster with the "
        "same camera at a fine step, beside the parallel projection of the same view. The error is measured "
        "over the object's footprint: as the eye comes closer the object covers less of the frame, and "
        "the whole frame's PSNR would count more empty background as perfect. The skull's thin "
        "bone shell is the kind of structure the visibility error affects."
    )
    FOVS = (15.0, 30.0, 60.0, 90.0)

    def runs(self, profile):
        if not is_registered(SW):
            return []
        dataset = profile.setting(self, "dataset", "ct_skull")
        preset = profile.setting(self, "preset", datasets.get(dataset).default_preset)
        fovs = [float(f) for f in profile.setting(self, "fovs", list(self.FOVS))]
        bad = [f for f in fovs if not 0 < f < 120]
        if bad or len(fovs) < 2:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.fovs: expected two or more fields of "
                             f"view in (0, 120) degrees, got {fovs}")
        size, image = volume_and_image_size(profile, self)
        truth_factor = profile.setting(self, "truth_step_factor", 0.25)
        volume = phantom(dataset, size, preset=preset)
        views = (headline_view(dataset),)
        runs = []
        for fov in [0.0, *sorted(fovs)]:
            label = "parallel" if fov == 0 else f"fov{fov:g}"
            camera = {"projection": "perspective", "fov_y": fov} if fov else None
            spec = scene(f"{dataset}-{label}", image, volumes=[volume], camera=camera)
            tags = {"dataset": dataset, "preset": preset, "fov": fov,
                    "projection": "perspective" if fov else "orthographic"}
            runs += truth_and_shearwarp(self.name, label, spec, views, truth_factor, tags)
        return runs

    claims = (
        Claim("quality-falls-with-fov", "Quality degrades as the field of view widens and rays meet the slices at "
              "larger angles (§4.2.5)", "PSNR over the object's footprint at the widest field ≥ 1 dB below the "
              "narrowest, and never more than 0.5 dB above the next narrower one", lambda df: _falls(df),
              kind="accuracy"),
        Claim("narrow-fov-like-parallel", "A narrow field of view is as accurate as the parallel projection",
              "|PSNR(narrowest field) − PSNR(parallel)| ≤ 2 dB over the object's footprint", lambda df: _like_parallel(df),
              kind="accuracy"),
    )

    def paper_table(self):
        return tables.perspective_limits()

    def report(self, results, ctx):
        ok = ok_rows(results)
        out = [claim_takeaways(ctx)]
        try:
            rows = fov_rows(ok)
        except (KeyError, ValueError):
            return out + shearwarp_missing()
        out.append(linked_table("Error against the reference by field of view", rows,
                                ["fov", "footprint_psnr", "coverage", "psnr", "ssim", "rmse", "max_ray_angle"], ctx,
                                names={"fov": "field of view (°, 0: parallel)",
                                       "footprint_psnr": "PSNR over the footprint (dB)",
                                       "coverage": "share of the frame covered",
                                       "max_ray_angle": "largest ray-to-axis angle (°)"},
                                csv_name="perspective.csv",
                                caption="Single untimed frames; each against the reference ray caster "
                                        "with the same camera at a fine step, over the pixels the object covers "
                                        "(the claims) and over the whole frame. The largest ray angle is "
                                        "the backend's info.max_ray_angle."))
        perspective = rows[rows.fov > 0].assign(series=rows.dataset.astype(str))
        guides = ()
        parallel = rows[rows.fov == 0]
        if not parallel.empty:
            xs = np.array([perspective.fov.min(), perspective.fov.max()])
            guides = (("parallel projection", xs, np.full(2, float(parallel.footprint_psnr.iloc[0]))),)
        out.append(figure(ctx, "psnr-fov", plots.lines, perspective, heading="Accuracy against the field of view",
                          caption="The eye comes closer as the field widens (the camera frames the volume).",
                          x="fov", y="footprint_psnr", group="series", x_label="vertical field of view (degrees)",
                          title=title_or(lambda d: f"PSNR {_falls(d).measured}", ok, "PSNR against the field of view"),
                          y_label="PSNR against the reference over the object's footprint (dB)", guides=guides))
        out.append(difference_gallery(
            "Each field of view and its difference from the reference", rows, ctx, against=results,
            label=lambda row: "parallel" if row.fov == 0 else f"field of view {row.fov:g}°",
            caption=f"One colour scale for every difference image (absolute error {DIFF_SCALE:g} at the top).",
            note=lambda row: f"PSNR {format_number(row.psnr)} dB, SSIM {format_number(getattr(row, 'ssim', np.nan))}"
                             + (f"; largest ray angle {format_number(row.max_ray_angle)}°"
                                if np.isfinite(row.max_ray_angle) else "")))
        return out + shearwarp_missing(more=[
            ("the visibility error of Fig. 4.12 (plates A, B before C)", "no registered data set holds thin plates "
             "before a plane, and scenes take volumes from the registry only")])


def fov_rows(df):
    """The shear-warp rows with their field of view (0: parallel), PSNR over the footprint and largest ray angle."""
    rows = df[text_column(df, "role") == "test"]
    rows = nonempty_or(rows.assign(fov=numeric(rows, "fov"), max_ray_angle=pd.to_numeric(
        rows.get("info_max_ray_angle", np.nan), errors="coerce")), "no shear-warp image rendered")
    footprint, coverage = [], []
    for row in rows.itertuples():
        truth = df[(text_column(df, "run") == str(row.reference)) & (text_column(df, "view") == str(row.view))]
        if truth.empty:
            raise ValueError(f"run {row.run}: its reference {row.reference} did not render view {row.view}")
        footprint.append(footprint_psnr(truth.exr.iloc[0], row.exr))
        coverage.append(float((read_exr(truth.exr.iloc[0])[..., 3] > FOOTPRINT_ALPHA).mean()))
    rows["footprint_psnr"], rows["coverage"] = footprint, coverage
    return rows.sort_values("fov")


def _falls(df):
    rows = fov_rows(df)
    perspective = rows[rows.fov > 0]
    if len(perspective) < 2:
        raise ValueError("fewer than two fields of view")
    psnr_ = perspective.footprint_psnr.to_numpy(float)
    drop = psnr_[0] - psnr_[-1]
    rise = float(np.max(np.diff(psnr_)))
    return ClaimResult(f"{db_words(-drop, more='higher', less='lower')} at {perspective.fov.iloc[-1]:g}° than at "
                       f"{perspective.fov.iloc[0]:g}°", bool(drop >= 1.0 and rise <= 0.5),
                       ", ".join(f"{r.fov:g}°: {format_number(r.footprint_psnr)} dB over {as_percent(r.coverage)} of the "
                                 f"frame (whole frame {format_number(float(getattr(r, 'psnr', np.nan)))} dB)"
                                 for r in perspective.itertuples())
                       + f"; largest rise to a wider field {format_number(max(rise, 0.0))} dB")


def _like_parallel(df):
    rows = fov_rows(df)
    parallel, perspective = rows[rows.fov == 0], rows[rows.fov > 0]
    if parallel.empty or perspective.empty:
        raise ValueError("needs the parallel projection and a perspective view")
    narrow = perspective.iloc[0]
    gap = float(narrow.footprint_psnr - parallel.footprint_psnr.iloc[0])
    return ClaimResult(f"{format_number(gap)} dB ({narrow.fov:g}° against parallel)", bool(abs(gap) <= 2.0),
                       f"over the footprint: parallel {format_number(parallel.footprint_psnr.iloc[0])} dB, "
                       f"{narrow.fov:g}° {format_number(narrow.footprint_psnr)} dB")
