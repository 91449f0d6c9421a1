"""E7: the sorting worst case (``kainz2009-sorting``)."""

import numpy as np
import pandas as pd

from pipeline.experiments.kainz2009 import tables
from pipeline.experiments.kainz2009.methods import (IMAGE_SIZES, TILED, PaperExperiment, device_note, frames_caption,
                                                    run_settings, scenes_of, table)
from pipeline.experiments.kainz2009.scenes import AXIS_VIEW, clouds, mesh
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import all_of, counts, decided, statistic, timed
from pipeline.experiments.kit.model import Claim, ClaimResult, Run, scaled
from pipeline.experiments.kit.pages import as_ratio, claim_takeaways, figure, format_number
from pipeline.experiments.kit.planning import listed, scene
from pipeline.experiments.kit.results import (nonempty_or, numeric, ok_rows, read_exr, rows_matching, speed_points,
                                              text_column)
from reports import plots

ORDERS = ("scene", "front-to-back", "back-to-front")
SCENES = ("boxes", "coil+clouds")

PIXEL = "time_pixel"
"""The pixel kernel, where the fragments are gathered and sorted and the rays traversed."""


def _sorting_scene(name, image, small, count, triangles):
    """E7's geometry-heavy scenes, seen along the row's or the coil's axis.

    ``boxes``: Table 2's 20 boxes in a row (depth complexity 40, 240 triangles). ``coil+clouds``:
    Fig. 1 (left)'s stand-in, the S1 coil (depth ≈ 21) of ``triangles`` among ``count`` clouds.
    """
    if name == "boxes":
        return scene(name, image, meshes=(mesh("boxes", "boxes_in_a_row", {"count": 20}),),
                     camera={"azimuth": 0.0, "elevation": 0.0, "view_height": 1.6})
    # 48 sides × 24 rows per turn: 23k triangles before decimation, so the coil can have 20k.
    coil = mesh("coil", "helical_screw", {"turns": 10, "pitch": 0.1, "sides": 48, "rows_per_turn": 24,
                                          "triangles": int(triangles)},
                transform={"scale": float(small), "translate": [0.0, 0.0, -0.5 * small]})
    return scene(name, image, volumes=clouds(count, small), meshes=(coil,),
                 camera={"azimuth": 0.0, "elevation": 0.0, "view_height": 1.2 * small})


def _sorting_rows(ok):
    """Full runs with their gather + sort time (the ablation of the same scene and order) and the rest."""
    if "part" not in ok:
        return pd.DataFrame()
    rows = ok[text_column(ok, "part").isin(["full", "gather+sort"])].copy()
    if rows.empty:
        return rows
    rows["pixel kernel (ms)"] = numeric(rows, "time_pixel") * 1e3
    sort_ms = rows[rows.part == "gather+sort"].set_index(["scene", "order"])["pixel kernel (ms)"]
    rows = speed_points(rows) if "time_total" in rows else rows
    rows["gather+sort (ms)"] = [sort_ms.get((s, o), np.nan) if p == "full" else np.nan
                                for s, o, p in zip(rows.scene, rows.order, rows.part)]
    rows["traversal (ms)"] = rows["pixel kernel (ms)"] - rows["gather+sort (ms)"]
    rows["gather+sort share (%)"] = 100 * rows["gather+sort (ms)"] / rows["pixel kernel (ms)"]
    return rows


def _sort_decision(df, name, resampler):
    """Worst-case sort over traversal on scene ``name``, judged below 1, and its sort moves."""
    rows = timed(df, f"runs on {name}", PIXEL, scene=name)
    parts = {(order, part): rows[(text_column(rows, "order") == order) & (text_column(rows, "part") == part)]
             for order in ("front-to-back", "back-to-front") for part in ("full", "gather+sort")}
    missing = sorted({order for (order, _), part in parts.items() if part.empty})
    if missing:
        raise ValueError(f"no full and gather + sort runs {', '.join(missing)} on {name}")

    def split(times):
        """(worst-case sort, traversal): the sorting reversed input adds, and the rest of the kernel."""
        sort = times["back-to-front", "gather+sort"] - times["front-to-back", "gather+sort"]
        return sort, times["back-to-front", "full"] - times["back-to-front", "gather+sort"]

    measured = {key: statistic(part, PIXEL, resampler) for key, part in parts.items()}
    sort, traversal = split({key: value for key, (value, _) in measured.items()})
    part_draws = {key: draws for key, (_, draws) in measured.items()}
    complete = not any(d is None for d in part_draws.values())
    decision = decided(sort / traversal, np.divide(*split(part_draws)) if complete else None, at_most=1.0,
                       frames=resampler.arms())
    full = pd.concat([parts["front-to-back", "full"], parts["back-to-front", "full"]])
    return decision, (f"{name}: worst-case sort {format_number(sort * 1e3)} ms, traversal "
                      f"{format_number(traversal * 1e3)} ms, sort moves "
                      + counts(full, "count_sort_moves", label="order"))


def _sort_small(df):
    resampler = intervals.Resampler()
    judged = {name: _sort_decision(df, name, resampler) for name in scenes_of(df, "full run", part="full")}
    return all_of({name: decision for name, (decision, _) in judged.items()},
                  extra="sort / traversal on the pixel kernel (OpenCL profiling); "
                        + "; ".join(detail for _, detail in judged.values()))


def _order_invariant(df):
    rows = rows_matching(df, "full runs", part="full")
    differences = {}
    for name, part in rows.groupby("scene"):
        images = [read_exr(path) for path in part.exr]
        if len(images) < 2:
            raise ValueError(f"fewer than two orders rendered on {name}")
        differences[name] = max(float(np.abs(image - images[0]).max()) for image in images[1:])
    worst = max(nonempty_or(differences, "no full run"), key=differences.get)
    return ClaimResult(f"max |difference| {format_number(differences[worst])} ({worst})",
                       max(differences.values()) == 0.0,
                       ", ".join(f"{s}: {format_number(d)}" for s, d in differences.items()))


class Sorting(PaperExperiment):
    name = "kainz2009-sorting"
    needs = ("triangle_order", "stop_after")
    paper_rows = tables.SORTING
    title = "The sorting worst case: triangles submitted front to back and back to front (E7)"
    settings = frozenset({"scenes", "orders", "image_size", "small_size", "count", "triangles", "step_factor",
                          "repeat"})
    scales = scaled(base=IMAGE_SIZES, smoke={"scenes": ["boxes"], "orders": ["front-to-back", "back-to-front"]},
                    default={"small_size": 32}, full={"small_size": 64})
    description = (
        "Each pixel inserts its fragments into a depth-sorted list in local memory in the order the triangle kernel "
        "appended them to the tile. Insertion sort costs nothing for fragments that arrive front to back and n(n − "
        "1)/2 shifts for n fragments that arrive back to front; the paper built such a worst case and found the sort "
        "still small next to ray traversal (§3.2, no number given). Here cl-tiled submits the triangles to binning in "
        "scene order or sorted by the view depth of their centroids, nearest or farthest first (the image does not "
        "change: fragments are ordered by depth and triangle id whatever their arrival), on Table 2's 20 boxes in a "
        "row (depth complexity 40) and on a 20k-triangle coil among smoke clouds (Fig. 1, left; the coil stands in for "
        "the dragon and no brain volume is added). An ablation of the pixel kernel that stops after gathering and "
        "sorting times that part alone; the rest of the kernel is the ray traversal (segment walk, sampling, shading)."
    )

    def plan(self, profile):
        image, step, _truth_step, frames = run_settings(self, profile)
        small = int(profile.setting(self, "small_size", 64))
        count = int(profile.setting(self, "count", 9))
        triangles = int(profile.setting(self, "triangles", 20000))
        orders = listed(profile, self, "orders", ORDERS, ORDERS)
        views = (dict(AXIS_VIEW),)
        runs = []
        for scene_name in listed(profile, self, "scenes", SCENES, SCENES):
            spec = _sorting_scene(scene_name, image, small, count, triangles)
            for order in orders:
                tags = {"scene": scene_name, "order": order, "config": TILED}
                group = scene_name.replace("+", "-")  # every order and its ablation timed together
                runs.append(Run(self.name, f"{group}.{order}", TILED, spec, views,
                                options={"step_factor": step, "triangle_order": order}, **frames, interleave=group,
                                tags={**tags, "role": "test", "part": "full"}))
                if order != "scene":  # the sort's best and worst case alone: the kernel stops after sorting
                    runs.append(Run(self.name, f"{group}.{order}.sort", TILED, spec, views,
                                    options={"step_factor": step, "triangle_order": order, "stop_after": "sort"},
                                    **frames, interleave=group,
                                    tags={**tags, "role": "ablation", "part": "gather+sort"}))
        return runs

    claims = (
        Claim("sort-small", "Sorting time stays small next to ray traversal, even when every list must be "
              "reversed (§3.2)", "worst-case sort time (gather + sort back to front − front to back) / ray "
              "traversal time (pixel kernel − gather + sort, back to front) ≤ ×1 on every scene (pixel kernel, "
              "time_pixel)", _sort_small, kind="timing"),
        Claim("order-invariant", "The submission order changes the work, not the image",
              "images of every order identical (max |difference| = 0) on every scene", _order_invariant,
              kind="accuracy"),
    )

    def report(self, results, ctx):
        rows = _sorting_rows(ok_rows(results))
        extra = [] if rows.empty else device_note(rows) + _sorting_takeaways(rows)
        out = [claim_takeaways(ctx, extra)]
        if not rows.empty:
            full = rows[rows.part == "full"].assign(label=lambda full: full.scene + ", " + full.order)
            split = full[full["gather+sort (ms)"].notna()].assign(
                time_gather_and_sort=full["gather+sort (ms)"] / 1e3, time_traversal=full["traversal (ms)"] / 1e3)
            if not split.empty:
                out.append(figure(ctx, "split", plots.stage_breakdown, split,
                                  heading="Where the pixel kernel's time goes, sorted and reversed input",
                                  caption="Gather + sort: the pixel kernel stopped after sorting (same order); "
                                          "traversal: the full pixel kernel minus that. " + frames_caption(full),
                                  stage_cols=["time_binning", "time_gather_and_sort", "time_traversal"],
                                  group_col="label", title="Binning, gather + sort and traversal per order"))
            out.append(table("Every order", full.sort_values(["scene", "order"]),
                             ["scene", "order", "pixel kernel (ms)", "gather+sort (ms)", "traversal (ms)",
                              "gather+sort share (%)", "count_sort_moves", "count_fragments_max",
                              "count_fragments_mean", "count_triangles", "time_ms"], ctx, csv_name="sorting.csv",
                             caption="Pixel kernel: OpenCL profiling, median frame. count_sort_moves: list entries "
                                     "the insertion sorts shifted in the frame (0 for input in depth order)."))
        return out


def _sorting_takeaways(rows):
    sentences = []
    full = rows[rows.part == "full"]
    for name, part in full.groupby("scene"):
        times = part.set_index("order")["pixel kernel (ms)"].dropna()
        if len(times) >= 2:
            sentences.append(f"{name}: the pixel kernel takes {format_number(times.min())} ms with "
                             f"{times.idxmin()} input and {format_number(times.max())} ms with {times.idxmax()} "
                             f"(worst / best {as_ratio(times.max() / times.min())}).")
        shares = part.set_index("order")["gather+sort share (%)"].dropna()
        if not shares.empty:
            sentences.append(f"{name}: gathering and sorting take "
                             + ", ".join(f"{format_number(v)} % ({o})" for o, v in shares.items())
                             + " of the pixel kernel (paper, geometry-heavy scene: up to 50 %).")
    return sentences
