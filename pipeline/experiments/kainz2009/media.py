"""E9: the homogeneous-segment shortcut (``kainz2009-media``; Fig. 1 (4))."""

import numpy as np
import pandas as pd

from pipeline.experiments.kainz2009 import tables
from pipeline.experiments.kainz2009.methods import (IMAGE_SIZES, TILED, PaperExperiment, device_note, frames_caption,
                                                    run_settings, table)
from pipeline.experiments.kainz2009.scenes import volume
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import STRICTLY_ABOVE_ONE, counts, decision_words, ratio, timed
from pipeline.experiments.kit.model import Claim, ClaimResult, Run, scaled
from pipeline.experiments.kit.pages import as_ratio, claim_takeaways, difference_gallery, format_number
from pipeline.experiments.kit.planning import HEADLINE_VIEW, scene, truth_run
from pipeline.experiments.kit.results import nonempty_or, numeric, ok_rows, speed_points, text_column

ROD_COUNT = 35
RODS = "rods"
PIXEL = "time_pixel"
"""The pixel kernel, where segments are composited: the shortcut's stage."""
APPLE_OPTICAL_DEPTH = 1.5
"""Optical depth of the apple across its diameter (per voxel opacity follows the size)."""


def _apple_scene(size, image, rods):
    """Fig. 1 (4)'s stand-in: a translucent apple (the ``sphere`` phantom, radius 0.39 of the box)
    pierced by ``rods`` closed 20-gon prisms (76 triangles each) of translucent homogeneous media,
    randomly turned and coloured (note 002 §6)."""
    alpha = round(float(-np.expm1(-APPLE_OPTICAL_DEPTH / (0.78 * size))), 6)
    apple = volume("sphere", size, "opaque", "apple", transfer_function={"points": [
        [0.0, 0.8, 0.15, 0.1, 0.0], [0.3, 0.8, 0.15, 0.1, 0.0], [0.6, 0.85, 0.25, 0.12, alpha],
        [1.0, 0.9, 0.35, 0.15, alpha]]})
    rng = np.random.default_rng(2009)
    meshes = []
    for i in range(int(rods)):
        axis = rng.normal(size=3)
        meshes.append({"name": f"rod{i:02d}",
                       "transform": {"scale": float(size),
                                     "rotate": {"axis": [round(float(v), 4) for v in axis],
                                                "degrees": round(float(rng.uniform(0, 180)), 3)},
                                     "translate": [round(float(v), 4) for v in rng.uniform(-0.15, 0.15, 3) * size]},
                       "medium": {"colour": [round(float(v), 3) for v in rng.uniform(0.2, 1.0, 3)],
                                  "extinction": round(12.0 / size, 6)},
                       **({"generator": "rod", "params": {"sides": 20, "radius": 0.012, "length": 1.1}} if i == 0
                          else {"instance_of": "rod00"})})
    return scene("apple", image, volumes=[apple], meshes=meshes)


def _media_rows(ok):
    if "role" not in ok or "config" not in ok:
        return pd.DataFrame()
    rows = ok[(ok.role == "test") & text_column(ok, "config").isin(["analytic", "sampled"])]
    if rows.empty:
        return rows
    return speed_points(rows).assign(pixel_ms=numeric(rows, "time_pixel") * 1e3)


def rods_view(size):
    """The rods where they leave the apple: rays above its box (``y`` over half the size) meet media alone.

    The segments the shortcut composites analytically are there; in the whole picture they are a few
    in a thousand of the apple's samples, too few for any change in them to show in its time.
    """
    return {"view": RODS, "azimuth": 30.0, "elevation": 0.0, "target": [0.0, round(0.66 * size, 4), 0.0],
            "view_height": round(0.3 * size, 4)}


def _media_pairs(df, column):
    """``{view: (analytic, sampled)}`` values of ``column``."""
    rows = _media_rows(df)
    pairs = {}
    for view, part in (rows.groupby(text_column(rows, "view")) if not rows.empty else ()):
        values = dict(zip(part.config, numeric(part, column)))
        if {"analytic", "sampled"} <= set(values):
            pairs[view] = values["analytic"], values["sampled"]
    return nonempty_or(pairs, "no analytic and sampled run of one view")


def _gain(df, view, resampler, at_least=STRICTLY_ABOVE_ONE):
    """Sampled over analytic pixel kernel in ``view`` (a Decision, at least ``at_least``) and the rows compared."""
    rows = timed(df, f"the {view} view", PIXEL, role="test", view=view)
    analytic, sampled = (rows[text_column(rows, "config") == config] for config in ("analytic", "sampled"))
    if analytic.empty or sampled.empty:
        raise ValueError(f"no analytic and sampled run of the {view} view")
    return ratio(sampled, analytic, PIXEL, resampler, at_least=at_least), rows


def _media_gain(df, at_least=STRICTLY_ABOVE_ONE):
    """The pixel kernel's gain where segments hold media alone, at least ``at_least`` (by default: a gain at all);
    the whole apple's beside it."""
    resampler = intervals.Resampler()
    decision, rows = _gain(df, RODS, resampler, at_least)
    times = dict(zip(rows.config, numeric(rows, PIXEL) * 1e3))
    detail = (f"pixel kernel where only media are (view {RODS!r}) {format_number(times['analytic'])} ms analytic, "
              f"{format_number(times['sampled'])} ms sampled; "
              f"media steps {counts(rows, 'count_medium_steps', label='config')}")
    headline = HEADLINE_VIEW["view"]
    if (text_column(df, "view") == headline).any():
        whole, _ = _gain(df, headline, resampler)
        detail += f"; the whole apple (view {headline!r}): {decision_words(whole)}"
    return ClaimResult.decided(f"{decision_words(decision)}: "
                               f"{format_number(100 * (decision.value - 1))} % gain", decision, detail)


def _media_accuracy(df):
    pairs = _media_pairs(df, "psnr")
    if any(np.isnan(v) for pair in pairs.values() for v in pair):
        raise ValueError("no PSNR against the reference")
    holds = all(min(a, s) >= 40.0 and (a == s or abs(a - s) <= 0.5) for a, s in pairs.values())
    return ClaimResult("; ".join(f"{view}: {format_number(a)} dB analytic, {format_number(s)} dB sampled"
                                 for view, (a, s) in pairs.items()), bool(holds), "PSNR against the reference")


def _media_steps(df):
    pairs = _media_pairs(df, "count_medium_steps")
    return ClaimResult("; ".join(f"{view}: {int(a)} analytic, {int(s)} sampled" for view, (a, s) in pairs.items()),
                       all(a < s for a, s in pairs.values()), "media composited without a volume, one frame")


class Media(PaperExperiment):
    name = "kainz2009-media"
    needs = ("media",)
    paper_rows = tables.MEDIA
    title = "The homogeneous-segment shortcut: rods of translucent media in an apple (E9; Fig. 1 (4))"
    settings = frozenset({"volume_size", "image_size", "rods", "step_factor", "truth_step_factor", "repeat"})
    scales = scaled(base=IMAGE_SIZES, smoke={"volume_size": 32}, default={"volume_size": 128},
                    full={"volume_size": 512})
    description = (
        "A segment of a ray in which only homogeneous-material polyhedra contribute needs no texture sampling: its "
        "colour and opacity follow from its length (1 − exp(−σL)), and the paper reports up to 10 % more speed from "
        "skipping the sampling loop there. Fig. 1 (4) shows 35 translucent rods of 76 polygons each piercing a 512³ "
        "apple. Here a translucent sphere phantom stands in for the apple and 35 closed 20-gon prisms filled with "
        "coloured media, randomly turned, pierce it and stick out of it; where a rod is outside the apple (its tight "
        "hull) the segment holds media alone. cl-tiled composites those segments analytically and, as the ablation, "
        "cell by cell at the common step, timed together; both are checked against the reference. In the whole picture "
        "such segments are a few in a thousand of the apple's samples, so the gain is timed on the pixel kernel in a "
        "second view, of the rods above the apple's box, where every segment holds media alone."
    )

    def plan(self, profile):
        size = int(profile.setting(self, "volume_size", profile.volume_size))
        image, step, truth_step, frames = run_settings(self, profile)
        rods = int(profile.setting(self, "rods", ROD_COUNT))
        views = (dict(HEADLINE_VIEW), rods_view(size))
        spec = _apple_scene(size, image, rods)
        tags = {"scene": "apple", "size": size, "rods": rods}
        truth = truth_run(self.name, "apple", spec, views, truth_step, tags, config="reference")
        return [truth] + [Run(self.name, f"apple.{media}", TILED, spec, views,
                              options={"step_factor": step, "media": media}, reference=truth.id, **frames,
                              interleave="apple", tags={**tags, "role": "test", "config": media})
                          for media in ("analytic", "sampled")]

    claims = (
        *Claim("shortcut-gain-paper", "Compositing homogeneous segments analytically instead of sampling them makes "
               "frames up to 10 % faster (paper)", f"pixel-kernel time(sampled) / time(analytic) ≥ "
               f"{as_ratio(tables.MEDIA_GAIN)} where segments hold media alone (view {RODS!r})",
               lambda df: _media_gain(df, tables.MEDIA_GAIN), paper_value="up to 10 %", kind="timing").with_ours(
            "Compositing homogeneous segments analytically instead of sampling them makes frames faster (paper: up to "
            "10 %)", f"pixel-kernel time(sampled) / time(analytic) > ×1 where segments hold "
            f"media alone (view {RODS!r})", _media_gain, why="faster at all: the paper's 10 % is its best case, on its "
            "scenes and GPU"),
        Claim("shortcut-exact", "The shortcut costs no accuracy", "PSNR against the reference ≥ 40 dB for both, "
              "within 0.5 dB of each other, every view", _media_accuracy, kind="accuracy"),
        Claim("fewer-steps", "The shortcut replaces the sampling loop by one step per segment",
              "media steps (analytic) < media steps (sampled), every view", _media_steps, kind="count"),
    )

    def report(self, results, ctx):
        rows = _media_rows(ok_rows(results))
        out = [claim_takeaways(ctx, device_note(rows))]
        if not rows.empty:
            out.append(table("Analytic and sampled media", rows.sort_values(["view", "config"]),
                             ["view", "config", "time_ms", "time_ms_min", "time_ms_max", "pixel_ms", "psnr",
                              "ssim", "count_medium_steps", "count_samples", "count_triangles", "count_fragments_max"],
                             ctx, csv_name="media.csv",
                             caption="count_medium_steps: media composited without a volume (one per segment "
                                     "analytically, one per cell part sampled); PSNR against the reference. "
                                     + frames_caption(rows)))
            out.append(difference_gallery(
                "Both variants and their difference from the reference", rows.sort_values(["view", "config"]), ctx,
                against=results, label=lambda row: f"media {row.config}, view {row.view}",
                caption="Left the image, right |image − reference|, each view.",
                note=lambda row: f"PSNR {format_number(getattr(row, 'psnr', np.nan))} dB, "
                                 f"pixel kernel {format_number(row.pixel_ms)} ms"))
        return out
