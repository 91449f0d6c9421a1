"""E1/E5/E12/E13: Table 1's multi-volume scenes C1–C8 (``kainz2009-table1``)."""

import numpy as np
import pandas as pd

from pipeline.experiments.kainz2009.methods import (METHOD_NAMES, PEEL, TILED, VTK, VTK_MAX_VOLUMES, PaperExperiment,
                                                    frames_caption, method_runs, peeling_missing, run_settings, table)
from pipeline.experiments.kainz2009.ratios import FRAMES, PeelingRatio, paper_bands
from pipeline.experiments.kainz2009.scenes import CLOUD_SIZES, SURFACE, blob, clouds, mesh, volume
from pipeline.experiments.kainz2009.tables import (BAND, PAPER_DEVICE, POOL_BYTES, TABLE1, TRIANGLE_KERNEL_SHARE,
                                                   table1_rows)
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import TECHNIQUE, TOTAL, all_of, counts, decided, decision_words, timed
from pipeline.experiments.kit.model import Claim, ClaimResult, scaled
from pipeline.experiments.kit.pages import (as_percent, as_ratio, claim_takeaways, difference_gallery, figure,
                                            format_number, speed_psnr_figure, title_or)
from pipeline.experiments.kit.planning import HEADLINE_VIEW, listed, scene, truth_run
from pipeline.experiments.kit.results import (numeric, ok_rows, role_rows, rows_matching, speed_points, stage_time,
                                              text_column)
from reports import plots

ACCURACY_SCENES = ("C1", "C2", "C3")

GROUP = "scenes"
"""The interleave group of every scene's cl-tiled and depth-peeling runs: the band compares the scenes,
the peeling claims each scene's two methods."""


def _uncentred(size):
    """Object→world of a volume placed like a mesh in its object space shifted by ``−size/2``."""
    half = -0.5 * size
    return {"matrix": [[1, 0, 0, half], [0, 1, 0, half], [0, 0, 1, half], [0, 0, 0, 1]]}


def _table1_scene(name, small, large, scan, image, triangles, vessel_resolution):
    """The stand-in of Table 1 row ``name`` (note 002 §6) as a scene mapping."""
    anatomy = volume("ct_skull", large, "bone", "skull")
    torso = volume("torso", scan, "abdomen", "torso", transform=_uncentred(scan))
    brain = volume("folded_brain", large, "volpack", "brain",
                    transform={"scale": 0.8, "rotate": {"axis": [0, 0, 1], "degrees": 15}})
    meshes, volumes = (), []
    if name == "C1":
        volumes = [torso]
    elif name == "C2":
        volumes = [anatomy, brain]
    elif name == "C3":
        volumes = [anatomy, brain,
                   volume("aneurysm", large, "vessels", "pet",
                           transform={"translate": [0.2 * large, 0, 0], "scale": 0.7}),
                   volume("mri_head", large, "skin", "neck", transform={
                       "translate": [0, -0.3 * large, 0.1 * large], "rotate": {"axis": [1, 0, 0], "degrees": 30},
                       "scale": 0.9})]
    elif name in ("C4", "C5"):
        volumes = [anatomy] + clouds(8 if name == "C4" else 20, small, scale=large / (2.0 * small))
    elif name == "C6":
        volumes = [torso]
        meshes = (mesh("bone", "phantom_isosurface", {"dataset": "torso", "size": int(scan), "level": 0.65,
                                                      "triangles": int(triangles)},
                       transform={"translate": [-0.5 * scan] * 3}),)
    elif name == "C7":
        volumes = [torso]
        corner = {"scale": 0.5 * scan, "translate": [-0.25 * scan] * 3}
        meshes = (mesh("vessels", "vessel_tree", {"resolution": int(vessel_resolution), "triangles": int(triangles)},
                       transform=corner),
                  mesh("liver", "noisy_sphere", {"radius": round(0.18 * scan, 4), "subdivisions": 5,
                                                 "triangles": int(triangles) // 3},
                       transform={"translate": [0.1 * scan, 0.0, 0.0]},
                       surface={**SURFACE, "colour": [0.6, 0.25, 0.2]}),
                  mesh("tumour", "noisy_sphere", {"radius": round(0.06 * scan, 4), "subdivisions": 4, "seed": 1,
                                                  "triangles": int(triangles) // 6},
                       transform={"translate": [0.12 * scan, 0.02 * scan, 0.0]},
                       surface={**SURFACE, "colour": [0.9, 0.9, 0.3]}))
    elif name == "C8":
        volumes = clouds(50, small)
        meshes = (blob(small, triangles),)
    return scene(name, image, volumes=volumes, meshes=meshes)


def _accuracy_c1_c3(df):
    rows = rows_matching(df, "cl-tiled", config=TILED, role="test")
    rows = rows[text_column(rows, "scene").isin(ACCURACY_SCENES)]
    missing = sorted(set(ACCURACY_SCENES) - set(rows.scene))
    if missing:
        raise ValueError(f"no cl-tiled image of {', '.join(missing)} against the reference")
    psnr = numeric(rows, "psnr")
    if psnr.notna().sum() == 0:
        raise ValueError("no image of C1–C3 compared with its reference")
    return ClaimResult(f"{format_number(psnr.min())} dB ({rows.loc[psnr.idxmin()].scene})", bool(psnr.min() >= 40.0),
                       f"{int(psnr.notna().sum())} images, median {format_number(psnr.median())} dB")


def _band(df):
    """The slowest scene's whole-frame time over the fastest's (the paper states frame rates), every scene of one
    draw at once; the kernels' own band beside it."""
    rows = timed(df, "cl-tiled", TOTAL, config=TILED, role="test")
    if len(rows) < 2:
        raise ValueError("fewer than two scenes rendered by cl-tiled")
    times = dict(zip(rows.scene, numeric(rows, TOTAL)))
    slow, fast = max(times, key=times.get), min(times, key=times.get)
    scenes = intervals.row_draws(rows, TOTAL, intervals.Resampler())
    frames = {scene: intervals.frame_count(rows[rows.scene == scene], TOTAL) for scene in times}
    decision = intervals.timing_decision(times[slow] / times[fast],
                                         None if scenes is None else scenes.max(axis=1) / scenes.min(axis=1), frames,
                                         at_most=BAND)
    kernels = numeric(rows, TECHNIQUE) if TECHNIQUE in rows else pd.Series([np.nan])
    kernel_band = f"; kernels alone {as_ratio(kernels.max() / kernels.min())}" if kernels.notna().all() else ""
    return ClaimResult.decided(f"{decision_words(decision)}, {slow} over {fast}", decision,
                               f"{len(times)} scenes, whole frames {format_number(times[fast] * 1e3)}–"
                               f"{format_number(times[slow] * 1e3)} ms{kernel_band}; volume samples "
                               f"{counts(rows, 'count_samples')}")


def _shares(df):
    """The rows with ``binning_share``: the triangle kernel's share of triangle + pixel kernel (%)."""
    rows = rows_matching(df, "cl-tiled", config=TILED, role="test")
    binning, pixel = numeric(rows, "time_binning"), numeric(rows, "time_pixel")
    share = binning / (binning + pixel)
    if share.notna().sum() == 0:
        raise ValueError("no binning and pixel stage times")
    return rows.assign(binning_share=100 * share)[share.notna()]


def _binning_share(df, low=None, high=0.10):
    """Every scene's binning share within [``low``, ``high``] (by default at most 10 %), each with the interval of
    its frames."""
    rows = _shares(df)
    resampler = intervals.Resampler()
    binning, pixel = (intervals.row_draws(rows, column, resampler) for column in ("time_binning", "time_pixel"))
    decisions = {}
    for i, row in enumerate(rows.itertuples()):
        share_draws = None if binning is None or pixel is None else binning[:, i] / (binning[:, i] + pixel[:, i])
        decisions[row.scene] = decided(row.binning_share / 100, share_draws, at_least=low, at_most=high,
                                       frames=resampler.arms())
    return all_of(decisions, extra="binning / (binning + pixel kernel), OpenCL profiling; boundary triangles "
                                   + counts(rows, "count_triangles"), show=as_percent)


def _pool(df):
    rows = rows_matching(df, "cl-tiled", config=TILED, role="test")
    used = numeric(rows, "info_pool_bytes_used")
    if used.notna().sum() == 0:
        raise ValueError("no pool use recorded")
    worst = rows.loc[used.idxmax()]
    return ClaimResult(f"{format_number(used.max() / 2 ** 20)} MiB ({worst.scene})", bool(used.max() <= POOL_BYTES),
                       f"{len(rows)} scenes")


# Table 1's frame time of a shader caster (Roessler, column 2; Brecheisen, column 3), whom depth peeling stands in
# for, over the tiled caster's (column 4).
ONE_VOLUME = paper_bands(TABLE1, 2, 4, "C1")
"""Table 1's single volume, C1, where Roessler is the faster."""
MANY_VOLUMES = paper_bands(TABLE1, 2, 4, "C3", "C4")
"""Table 1's scenes of four volumes and more that Roessler ran (C3, C4; C5 and C8 it could not)."""
WITH_MESHES = paper_bands(TABLE1, 3, 4, "C6", "C7")
"""Table 1's scenes with meshes, which only Brecheisen ran (C7 from 0 fps: no upper bound)."""


PEEL_OVER_TILED = PeelingRatio(PEEL, TILED)
"""What the depth-peeling claims compare."""


class Table1(PaperExperiment):
    name = "kainz2009-table1"
    title = "Table 1: the multi-volume scenes C1–C8, images, workload split and memory (E1, E5, E12, E13)"
    settings = frozenset({"scenes", "small_size", "large_size", "scan_size", "image_size", "mesh_triangles",
                          "vessel_resolution", "step_factor", "truth_step_factor", "repeat"})
    scales = scaled(base=CLOUD_SIZES, smoke={"scenes": ["C2", "C6", "C8"], "scan_size": 32, "mesh_triangles": 2000,
                                             "vessel_resolution": 32},
                    default={"scan_size": 128, "mesh_triangles": 30000, "vessel_resolution": 96},
                    full={"scan_size": 512, "mesh_triangles": 30000, "vessel_resolution": 160})
    description = (
        "Table 1 times the tiled caster against two depth-peeling shader casters on eight scenes: one 512³ scan (C1), "
        "two and four overlapping 256³ volumes (C2, C3), a 256³ scan with 8 or 20 time steps of 64³ (C4, C5), a 512³ "
        "scan with a 30k iso-surface (C6) or with a 30k vessel tree, a 10k liver and a 5k tumour (C7), and 50 × 64³ "
        "volumes with a 30k mesh (C8). Here phantoms stand in (note 002 §6, at the profile's sizes) with translucent "
        "meshes, Blinn–Phong shading and the headline view. cl-tiled renders them with tight brick hulls; VTK's GPU "
        "caster (single-pass shaders, up to 7 volumes, no meshes) takes the shader casters' place where it can; the "
        "reference renders every image at a finer step. The stage times split each frame into the triangle kernel "
        "(binning) and the pixel kernel, and each run records the atlas, the tile lists and the chunk pool it used."
    )

    def plan(self, profile):
        scenes = listed(profile, self, "scenes", TABLE1, TABLE1)
        sizes = [int(profile.setting(self, key, default)) for key, default in
                 (("small_size", 64), ("large_size", 256), ("scan_size", 512))]
        image, step, truth_step, frames = run_settings(self, profile)
        triangles = int(profile.setting(self, "mesh_triangles", 30000))
        resolution = int(profile.setting(self, "vessel_resolution", 160))
        views = (dict(HEADLINE_VIEW),)
        runs = []
        for scene_name in scenes:
            spec = _table1_scene(scene_name, *sizes, image, triangles, resolution)
            tags = {"scene": scene_name, "image_size": image}
            truth = truth_run(self.name, scene_name, spec, views, truth_step, tags, config="reference")
            runs += [truth, *method_runs(self.name, scene_name, spec, views, tags, truth, step=step, frames=frames,
                                         groups=(GROUP, GROUP),
                                         vtk="meshes" not in spec and len(spec["volumes"]) <= VTK_MAX_VOLUMES)]
        return runs

    claims = (
        Claim("accuracy", "cl-tiled renders the reference's image on the volume scenes C1–C3",
              "PSNR ≥ 40 dB against the reference on C1, C2 and C3", _accuracy_c1_c3, kind="accuracy"),
        Claim("narrow-band", "The tiled caster's frame time stays in a narrow band across all eight scenes "
              "(paper: 7–25 fps)", f"slowest / fastest scene ≤ {as_ratio(BAND)} (every scene cl-tiled rendered; "
              f"{FRAMES}: the paper states frame rates)", _band, paper_value="7–25 fps", kind="timing"),
        *Claim("pixel-kernel-dominates-paper", "The triangle kernel takes 2–10 % of the computation, the pixel kernel "
               "the rest (paper)", f"binning within {format_number(100 * TRIANGLE_KERNEL_SHARE[0])}–"
               f"{as_percent(TRIANGLE_KERNEL_SHARE[1])} of binning + pixel kernel on every scene (OpenCL profiling: "
               "time_binning, time_pixel)", lambda df: _binning_share(df, *TRIANGLE_KERNEL_SHARE), paper_value="2–10 %",
               kind="timing").with_ours(
            "The pixel kernel takes most of the frame, the triangle kernel at most 10 % (paper: 2–10 %, §4.2)",
            "binning ≤ 10 % of binning + pixel kernel on every scene (OpenCL profiling: time_binning, time_pixel)",
            _binning_share, why="at most 10 %: how little the triangle kernel takes follows each stand-in's triangles "
            "per voxel"),
        Claim("pool-enough", "The paper's 6 MB chunk pool holds every scene's tile lists",
              "chunk pool used ≤ 6 MiB on every scene", _pool, paper_value="6 MB", kind="count"),
        *PEEL_OVER_TILED.claims(
            "peeling-wins-one-volume", ONE_VOLUME,
            ("On a single volume a shader caster beats the tiled caster by the paper's margin: Roessler 14–46 fps "
             "against 10–21 on C1 (paper)",
             "A shader caster beats the tiled caster on a single volume (C1: Roessler 14–46 fps against 10–21)"),
            above=False, paper_value="14–46 vs 10–21 fps"),
        *PEEL_OVER_TILED.claims(
            "tiled-wins-many-volumes", MANY_VOLUMES,
            ("From four volumes on, the tiled caster beats a shader caster by the paper's margins: 16–25 fps against "
             "Roessler's 5–9 on C3, 15–23 against 1.5–3 on C4 (paper)",
             "From four volumes on, the tiled caster beats depth peeling (C3: 16–25 fps against 5–9)"),
            above=True, scenes=("C3", "C4", "C5", "C8"), where="on every scene with ≥ 4 volumes both render",
            why="the direction, also on C5 and C8 (no shader caster ran them)",
            paper_value="C3 16–25 vs 5–9, C4 15–23 vs 1.5–3 fps"),
        *PEEL_OVER_TILED.claims(
            "peeling-collapses-with-meshes", WITH_MESHES,
            ("With meshes, a shader caster collapses by the paper's margins: Brecheisen 1–2 fps against the tiled "
             "caster's 7–15 on C6, 0–1 against 7–15 on C7 (paper)",
             "With meshes, depth peeling collapses (C6, C7: Brecheisen 0–2 fps against the tiled caster's 7–15): "
             "every surface layer costs a geometry pass"),
            above=True, where="on C6 and C7, whichever both render", paper_value="C6 1–2, C7 0–1 vs 7–15 fps"),
    )

    def paper_table(self):
        return pd.DataFrame(table1_rows(*TABLE1)).assign(device=PAPER_DEVICE)

    def report(self, results, ctx):
        tests = role_rows(ok_rows(results))
        out = [claim_takeaways(ctx, _peer_takeaways(tests))]
        if not tests.empty:
            rows = speed_points(tests)
            rows["method"] = rows.config.map(METHOD_NAMES)
            rows["fps"] = 1e3 / rows.time_ms
            out.append(speed_psnr_figure(ctx, "speed-accuracy", rows, heading="Speed against accuracy",
                                         caption="One point per scene (labelled) and method. " + frames_caption(rows),
                                         title="Median frame time against PSNR, every scene", group="method",
                                         label="scene", x_label="median frame time (ms, log scale)", log_x=True))
            merged = rows.assign(**{"paper fps (mid)": rows.scene.map({s: np.mean(r[4]) for s, r in TABLE1.items()})})
            out.append(table("Frame times and accuracy", merged.sort_values(["scene", "config"]),
                             ["scene", "method", "time_ms", "time_ms_min", "time_ms_max", "fps", "paper fps (mid)",
                              "psnr", "ssim", "count_triangles", "count_fragments_max"], ctx, csv_name="table1.csv",
                             caption="fps = 1000 / median frame time, beside the middle of the paper's range "
                                     "on a GTX 280 (compare the spread across scenes, not the values)."))
            tiled = rows[rows.config == TILED].copy()
            stages = [c for c in ("time_setup", "time_binning", "time_pixel", "time_readback") if c in tiled]
            if stages:
                out.append(figure(ctx, "stages", plots.stage_breakdown, tiled, heading="Workload split per scene (E5)",
                                  caption="Median time of each cl-tiled stage per frame, OpenCL profiling events; "
                                          "binning is the paper's triangle kernel, pixel its pixel kernel.",
                                  stage_cols=stages, group_col="scene",
                                  title=title_or(_stage_title, tiled, "Where the frame time goes")))
            out.append(_memory_table(tiled, ctx))
            out.append(difference_gallery("Each scene and method, and its difference from the reference (E13)",
                                          rows.sort_values(["scene", "config"]), ctx, against=results,
                                          label=lambda row: f"{row.scene}, {row.method}",
                                          caption="Left the method's image, right |method − reference|, headline "
                                                  "view."))
        return out + peeling_missing()


def _stage_title(tiled):
    shares = _shares(tiled).binning_share
    return (f"Binning {format_number(shares.min())}–{format_number(shares.max())} % of binning + pixel kernel "
            "(paper: 2–10 %)")


def _memory_table(tiled, ctx):
    """E12: atlas, fixed tile tables and the pool used per scene (bytes as MiB)."""
    tiles = np.ceil(numeric(tiled, "image_size") / 8) ** 2
    memory = tiled.assign(**{"atlas (MiB)": numeric(tiled, "info_atlas_bytes") / 2 ** 20,
                             "pool used (MiB)": numeric(tiled, "info_pool_bytes_used") / 2 ** 20,
                             "pool allocated (MiB)": numeric(tiled, "count_pool_chunks") * 64 * 12 / 2 ** 20,
                             "chunk-index table (MiB)": tiles * 64 * 4 / 2 ** 20})
    columns = ["scene", "atlas (MiB)", "chunk-index table (MiB)", "pool used (MiB)", "pool allocated (MiB)",
               "count_triangles", "count_records_per_tile_max"]
    return table("Memory per scene (E12)", memory.sort_values("scene"), columns, ctx, csv_name="table1_memory.csv",
                 caption="Paper: a 528³ atlas of 562 MB (gradients ×4), a 2.25 MB chunk-index table at 768², a "
                         "6 MB pool. Chunks hold 64 records of 12 B.")


def _peer_takeaways(tests):
    """One sentence: each scene's VTK and depth-peeling time over cl-tiled's."""
    if "config" not in tests:
        return []
    sentences = []
    for name in sorted(set(tests.scene)):
        here = tests[tests.scene == name]
        tiled = here[here.config == TILED]
        for peer in (VTK, PEEL):
            if not tiled.empty and (here.config == peer).any():
                ratio = stage_time(here[here.config == peer].iloc[0]) / stage_time(tiled.iloc[0])
                sentences.append(f"{name}: {METHOD_NAMES[peer]} takes {as_ratio(ratio)} cl-tiled's time")
    shape = " (different devices and APIs: read as the shape, not a speed-up)."
    return ["; ".join(sentences) + shape] if sentences else []
