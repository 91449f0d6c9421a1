"""``lacroute1995-shading`` (E18, E15, E22): shading tables, union-find variants and the mode switch.

Lookup-table against per-voxel Phong shading (Table 7.1), path compression with and without union by
rank (§4.1.3), and what a classification edit costs before the next image in VolPack's and our
backend's modes (§4.4): cold runs time each preprocessing stage in the frame that builds it.
"""

import numpy as np
import pandas as pd

from pipeline.experiments.kit.checks import Measure, Ratio
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, Run
from pipeline.experiments.kit.pages import (DIFF_SCALE, as_ratio, claim_takeaways, format_number, linked_table,
                                            not_measurable)
from pipeline.experiments.kit.planning import (accepts, headline_view, is_registered, missing_options, phantom, scene,
                                               timed_frames, unregistered)
from pipeline.experiments.kit.results import (ok_rows, one_row, pair_metrics, reference_exr, rows_matching,
                                              speed_points, stage_time)
from pipeline.experiments.lacroute1995 import tables
from pipeline.experiments.lacroute1995.planning import SW, VP
from pipeline.experiments.lacroute1995.reading import title_or
from reports import blocks, plots

SW_MODE_CONFIGS = {
    # config: shearwarp options of the E22 cold runs ("shearwarp": the defaults, brute-force RLE build)
    "shearwarp-octree-rle": {"octree_rle_build": True},
    "shearwarp-octree": {"classification": "octree"},
}
PREPROCESSING_STAGES = ("time_classify", "time_rle_build", "time_octree", "time_octree_build", "time_sat_build")
"""Stages timed only in the frame that builds a per-volume structure."""

LUT_SPEED = Ratio(Measure("per-voxel Phong", match={"part": "shading", "config": "procedural"}),
                  Measure("lookup-table shading", match={"part": "baseline"}), at_least=2.0)
UNION_BY_RANK = Ratio(Measure("union by rank", match={"part": "union", "config": "rank"}),
                      Measure("path compression alone", match={"part": "baseline"}), at_least=0.97)
"""The baseline run (lookup-table shading, path compression alone) serves both comparisons."""
OCTREE_RENDER = Ratio(Measure("fast classification", match={"part": "mode", "config": "shearwarp-octree"}),
                      Measure("classified RLE", match={"part": "mode", "config": "shearwarp"}), at_least=1.4, at_most=3.2)
"""Our backend's warm frames (the median of a cold run's frames)."""


class Variants(Experiment):
    """Table 7.1 (LUT against procedural shading), §4.1.3 (union by rank), §4.4 (VolPack's mode switch)."""

    name = "lacroute1995-shading"
    paper = "lacroute1995"
    title = "Shading tables, union-find variants and the mode switch (E18, E15, E22)"
    settings = frozenset({"volume_size", "image_size", "dataset", "preset", "repeat"})
    scales = {"default": {"repeat": 15}, "full": {"repeat": 15}}
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
        size = profile.setting(self, "volume_size", profile.volume_size)
        image = profile.setting(self, "image_size", profile.image_size)
        dataset = profile.setting(self, "dataset", "ct_skull")
        preset = profile.setting(self, "preset", "skin")
        volume = phantom(dataset, size, preset=preset)
        spec = scene(f"{dataset}-{preset}", image, volumes=[volume])
        view = (headline_view(dataset),)
        timed = timed_frames(profile, self)
        # Cold runs: the first frame builds (and times) the per-volume structures; with three frames
        # the median total is a warm frame.
        cold = {"warmup": 0, "repeat": timed["repeat"]}
        tags = {"dataset": dataset, "preset": preset}
        runs = []
        if accepts(SW, "shading", "union"):
            # The baseline (lookup-table shading, path compression) serves both comparisons; its
            # reference is the procedural image, so the evaluation measures the table's error.
            procedural = accepts(SW, "shading")
            runs.append(Run(self.name, "baseline", SW, spec, view, options={"shading": "lut", "union": "path-compression"},
                            reference="shading.procedural" if procedural else None, **timed,
                            tags={**tags, "part": "baseline", "config": "lut, path-compression"}))
            runs.append(Run(self.name, "shading.procedural", SW, spec, view, options={"shading": "procedural"}, **timed,
                            tags={**tags, "part": "shading", "config": "procedural"}))
            runs.append(Run(self.name, "union.rank", SW, spec, view, options={"union": "rank"}, **timed,
                            tags={**tags, "part": "union", "config": "rank"}))
        if is_registered(SW):
            runs.append(Run(self.name, "mode.shearwarp-cold", SW, spec, view, **cold,
                            tags={**tags, "part": "mode", "config": "shearwarp"}))
        if accepts(SW, "classification", "octree_rle_build"):
            # E22 with our backend: the three RLE copies built from the min-max octree, and rendering
            # with fast classification (octree + summed-area table, classified on the fly).
            for config, options in SW_MODE_CONFIGS.items():
                runs.append(Run(self.name, f"mode.{config}-cold", SW, spec, view, options=dict(options), **cold,
                                tags={**tags, "part": "mode", "config": config}))
        if accepts(VP, "mode"):
            for mode in ("rle", "octree"):
                runs.append(Run(self.name, f"mode.volpack-{mode}-cold", VP, spec, view, options={"mode": mode}, **cold,
                                tags={**tags, "part": "mode", "config": f"volpack-{mode}"}))
        return runs

    claims = (
        Claim("lut-faster", "Lookup-table shading is several times faster than per-voxel Phong (Table 7.1: ×4.3 "
              "total)", LUT_SPEED.expected, LUT_SPEED),
        Claim("lut-accurate", "13-bit normals are enough: the table's image matches per-voxel Phong",
              "PSNR ≥ 35 dB between them", lambda df: _lut_accuracy(df)),
        Claim("union-by-rank", "Union by rank does not make the renderer faster (thesis: 5–15 % slower)",
              UNION_BY_RANK.expected, UNION_BY_RANK),
        Claim("mode-switch", "After a classification edit the octree mode shows an image sooner than re-encoding "
              "the RLE volume (§4.4)", "octree render < RLE classify + RLE render (VolPack)", lambda df: _mode_switch(df)),
        Claim("octree-rle-build", "Building the three RLE copies from the min-max octree is faster than the brute-force "
              "build (§4.4, E22)", "ours: sat_build + rle_build (octree) < classify + rle_build (brute force)",
              lambda df: _octree_rle_build(df)),
        Claim("fast-classification-render", "Rendering with fast classification takes about twice the classified-RLE "
              "render (Table 5.3: ×1.8–2.5)", OCTREE_RENDER.expected, OCTREE_RENDER),
        Claim("mode-switch-ours", "With our backend too, after a classification edit fast classification shows an "
              "image sooner than re-encoding (§4.4)", "ours: sat_build + octree frame < classify + rle_build + RLE frame",
              lambda df: _mode_switch_ours(df)),
    )

    def paper_table(self):
        return tables.variants()

    def report(self, results, ctx):
        ok = ok_rows(results)
        if ok.empty:
            return []
        out = [claim_takeaways(self.claims, results)]
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
        try:
            out.append(blocks.Table("The mode switch with our backend (E22)", mode_switch_table(ok),
                                    csv_name="mode_switch.csv",
                                    caption="Cold runs: preprocessing stages of the first frame; 'frame' is the median "
                                            "(warm) frame. 'after an edit': what a classification change costs before "
                                            "the next image (the octree survives an edit; octree_build is per volume)."))
        except (KeyError, ValueError):
            pass
        out.append(_variants_table(frame, ctx))
        shading = ok[ok.part.isin(["baseline", "shading"])] if "part" in ok else ok.iloc[:0]
        if not shading.empty:
            out.append(_shading_gallery(shading, results, ctx))
        return out + not_measurable(unregistered(SW, VP) + missing_options(SW, "shading", "union")
                                    + missing_options(VP, "mode"))


STAGE_COLUMNS = ("classify", "rle_build", "octree", "octree_build", "sat_build", "octree_classify", "shade_table",
                 "composite", "render")
"""The stages the table of every variant shows, where a run reported them."""


def _variants_table(frame, ctx):
    """Every variant's frame time and the stages it reported, in milliseconds."""
    stages = {f"{stage} (ms)": pd.to_numeric(frame[f"time_{stage}"], errors="coerce") * 1e3
              for stage in STAGE_COLUMNS if f"time_{stage}" in frame}
    reported = {name: values for name, values in stages.items() if values.notna().any()}
    return linked_table("Every variant", frame.assign(**reported),
                        ["part", "config", "time_ms", "time_ms_min", "time_ms_max", *reported], ctx,
                        names={"config": "variant"}, csv_name="variants.csv",
                        caption="Mode rows are cold runs (no warm-up): classify / rle_build / octree are the "
                                "preprocessing stages of their first frame; their median frame is the middle of "
                                "three, the slowest being the cold one.")


def _shading_gallery(shading, results, ctx):
    """The lookup-table image with its difference from the procedural one, and the procedural image."""
    gallery = blocks.Gallery("Lookup-table against procedural shading", diff_scale=DIFF_SCALE,
                             caption="The lookup-table image with its difference from the procedural one.")
    for row in shading.sort_values("config").itertuples():
        diff = ctx.difference(reference_exr(results, row), row.exr, DIFF_SCALE) if row.part == "baseline" else None
        gallery.items.append(blocks.GalleryItem(
            row.config, ctx.image(row.png), difference=diff,
            note=f"{format_number(row.time_total * 1e3)} ms" + (f"; PSNR against procedural "
                                                                f"{format_number(getattr(row, 'psnr', np.nan))} dB"
                                                                if diff else "")))
    return gallery


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
        entry["after an edit (ms)"] = (sum(stage_time(row, s) for s in edit) + stage_time(row)) * 1e3
        for counter in ("rle_bytes", "octree_bytes", "classified_on_the_fly"):
            entry[counter] = float(row.get(f"count_{counter}", np.nan))
        rows.append(entry)
    if not rows:
        raise ValueError("no cold shearwarp mode run")
    return pd.DataFrame(rows)


def _config_row(df, part, config):
    return one_row(df, f"{part} {config}", part=part, config=config)


def _octree_rle_build(df):
    brute, octree = _config_row(df, "mode", "shearwarp"), _config_row(df, "mode", "shearwarp-octree-rle")
    plain = stage_time(brute, "classify") + stage_time(brute, "rle_build")
    fast = stage_time(octree, "sat_build") + stage_time(octree, "rle_build")
    return ClaimResult(f"{format_number(fast * 1e3)} ms vs {format_number(plain * 1e3)} ms ({as_ratio(plain / fast)} faster)",
                       bool(fast < plain),
                       f"octree: SAT {format_number(stage_time(octree, 'sat_build') * 1e3)} ms + RLE "
                       f"{format_number(stage_time(octree, 'rle_build') * 1e3)} ms (octree itself, once per volume: "
                       f"{format_number(float(octree.get('time_octree_build', np.nan)) * 1e3)} ms); brute force: classify "
                       f"{format_number(stage_time(brute, 'classify') * 1e3)} ms + RLE "
                       f"{format_number(stage_time(brute, 'rle_build') * 1e3)} ms; single cold frames, noisy")


def _mode_switch_ours(df):
    rle, octree = _config_row(df, "mode", "shearwarp"), _config_row(df, "mode", "shearwarp-octree")
    edit_rle = stage_time(rle, "classify") + stage_time(rle, "rle_build") + stage_time(rle)
    edit_octree = stage_time(octree, "sat_build") + stage_time(octree)
    return ClaimResult(f"fast classification {format_number(edit_octree * 1e3)} ms vs RLE {format_number(edit_rle * 1e3)} ms",
                       bool(edit_octree < edit_rle),
                       f"octree: SAT {format_number(stage_time(octree, 'sat_build') * 1e3)} ms + frame "
                       f"{format_number(stage_time(octree) * 1e3)} ms; RLE: classify "
                       f"{format_number(stage_time(rle, 'classify') * 1e3)} ms + build "
                       f"{format_number(stage_time(rle, 'rle_build') * 1e3)} ms + frame {format_number(stage_time(rle) * 1e3)} ms")


def _lut_accuracy(df):
    lut = one_row(df, "the baseline (lookup table, path compression)", part="baseline")
    procedural = _config_row(df, "shading", "procedural")
    value = float(lut.get("psnr", np.nan))
    if not np.isfinite(value):
        value = pair_metrics(procedural.exr, lut.exr)["psnr"]
    return ClaimResult(f"{format_number(value)} dB", bool(value >= 35.0), "LUT image against the procedural one")


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
    return title_or(lambda d: f"Lookup-table shading is {LUT_SPEED(d).measured} faster than per-voxel Phong", ok,
                    "Per-frame time by stage")
