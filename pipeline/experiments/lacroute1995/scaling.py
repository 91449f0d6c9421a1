"""``lacroute1995-scaling`` (E2, E3; Tables 5.3, 5.4): time and memory against the volume and image size."""

import math

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals, judging
from pipeline.experiments.kit.judging import all_of, decision_words
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, Run
from pipeline.experiments.kit.pages import (as_percent, as_ratio, claim_takeaways, figure, format_number, linked_table,
                                            time_lines_figure, title_or)
from pipeline.experiments.kit.planning import headline_view, is_registered, listed, phantom, scene, timed_frames
from pipeline.experiments.kit.results import nonempty_or, numeric, ok_rows, speed_points, stage_points, text_column
from pipeline.experiments.lacroute1995 import tables
from pipeline.experiments.lacroute1995.planning import SW, shearwarp_missing
from reports import blocks, plots

SCALING_DATASETS = {"folded_brain": "volpack", "ct_skull": "bone"}

WARP_STEPS = tables.warp_steps()
"""Table 5.4's warp time per doubling of the image side, ``(least, most)`` over its two steps."""


class SizeScaling(Experiment):
    name = "lacroute1995-scaling"
    paper = "lacroute1995"
    title = "Time and memory against the volume and image size (E2, E3; Tables 5.3, 5.4)"
    settings = frozenset({"datasets", "volume_sizes", "image_sizes", "image_size", "repeat"})
    scales = {"smoke": {"datasets": ["folded_brain"], "volume_sizes": [16, 32], "image_sizes": [24, 48],
                        "image_size": 48},
              "default": {"repeat": 15, "volume_sizes": [64, 128, 256], "image_sizes": [64, 128, 256],
                          "image_size": 256},
              "full": {"repeat": 15, "volume_sizes": [64, 128, 256], "image_sizes": [64, 128, 256, 512],
                       "image_size": 256}}
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
        wanted = listed(profile, self, "datasets", self.DATASETS, known=SCALING_DATASETS)
        sizes = [int(s) for s in profile.setting(self, "volume_sizes", list(self.VOLUME_SIZES))]
        images = [int(s) for s in profile.setting(self, "image_sizes", list(self.IMAGE_SIZES))]
        growth_image = int(profile.setting(self, "image_size", max(images)))
        # Every data set at every size on the growth image; the first also on every image at least its size.
        pairs = [(dataset, n, growth_image) for dataset in wanted for n in sizes]
        if wanted:
            pairs += [(wanted[0], n, i) for n in sizes for i in images if i >= n]
        runs = []
        for dataset, n, i in dict.fromkeys(pairs):  # in order, each once
            volume = phantom(dataset, n, preset=SCALING_DATASETS[dataset])
            spec = scene(f"{dataset}-{n}", i, volumes=[volume])
            # A data set's sizes timed together, frame by frame: the growth and warp ratios pair them.
            runs.append(Run(self.name, f"{dataset}.v{n}.i{i}", SW, spec, (headline_view(dataset),),
                            **timed_frames(profile, self), interleave=dataset,
                            tags={"dataset": dataset, "volume_size": n, "image_size": i,
                                  "growth": int(i == growth_image)}))
        return runs

    claims = (
        *Claim("n-squared-growth-paper", "Doubling the volume's side at most quadruples the compositing time: 8× the "
               "voxels, \"only a four-fold increase\" (thesis, §5.2.1)", f"composite-stage time ratio per doubling ≤ "
               f"{as_ratio(tables.COMPOSITE_GROWTH)} at the largest sizes (every data set)",
               lambda df: _growth(df, None, tables.COMPOSITE_GROWTH), paper_value="×4 compositing, ×3.5–3.9 total",
               kind="timing").with_ours(
            "Doubling the volume's side multiplies the compositing time by about 4 (n²), not 8 (§5.2.1: 8× the voxels, "
            "about 4× the compositing time; Table 5.3: ×3.5–3.9 in total)", "composite-stage time ratio per doubling "
            "2.8–5.7 at the largest sizes (every data set)", lambda df: _growth(df), why="n² within half a power of "
            "two: how fast our stand-ins' visible surfaces grow with the side is their own"),
        Claim("rle-memory", "The three RLE copies take less memory than an unencoded 4-byte-per-voxel array "
              "(the thesis's head: 9.8 MB of RLE against 61 MB)", "rle_bytes < 4 B × voxels (every run)",
              lambda df: _rle_memory(df),
              paper_value="9.8 MB vs 61 MB (head)", kind="count"),
        *Claim("warp-per-pixel-paper", f"The warp's time grows ×{format_number(WARP_STEPS[0], 2)}–"
               f"{format_number(WARP_STEPS[1], 2)} per doubling of the image side: 5.0, 17, 64 ms (thesis, Table 5.4)",
               f"warp-stage time ratio per doubling of the image side within {as_ratio(WARP_STEPS[0])}–"
               f"{as_ratio(WARP_STEPS[1])}, Table 5.4's steps (largest pair)", lambda df: _warp_growth(df, *WARP_STEPS),
               paper_value="5.0, 17, 64 ms", kind="timing").with_ours(
            "The warp's time is proportional to the image's pixels (Table 5.4: 5, 17, 64 ms)",
            "warp-stage time ratio per doubling of the image side 2.5–5.5 (largest pair)", lambda df: _warp_growth(df),
            why="about ×4 per doubling: a modern CPU's caches and per-frame costs weigh small warps otherwise than the "
            "R4400's"),
        *Claim("warp-share-paper", "The warp takes at least 48 % of the time at 64³ → 256² and at most 9 % at 256³ → "
               "256² (thesis, Table 5.4)", "warp share of the technique time at the largest image: ≥ Table 5.4's at "
               "the smallest volume, ≤ its share at the largest (not measurable at sizes the table lacks)",
               lambda df: _warp_share(df, paper=True), paper_value="48 % (64³) → 9 % (256³)", kind="timing").with_ours(
            "The warp matters only when the image is much larger than the volume (48 % of the time at 64³ → 256², 9 % "
            "at 256³ → 256²)", "warp share of the technique time at the largest image falls as the volume grows (its "
            "largest rise ≤ 0)", lambda df: _warp_share(df), why="that the share falls at all: a modern CPU's warp and "
            "compositing stand in another ratio than the R4400's"),
    )

    def paper_table(self):
        return tables.size_scaling()

    def report(self, results, ctx):
        ok = ok_rows(results)
        out = [claim_takeaways(ctx)]
        if ok.empty:
            return out
        frame = speed_points(ok.assign(volume_size=numeric(ok, "volume_size"), image_size=numeric(ok, "image_size")))
        growth = frame[numeric(frame, "growth") == 1]
        if not growth.empty:
            out.append(_growth_figure(growth, ok, ctx))
        if "time_warp" in frame:
            out += _warp_blocks(frame, ok, ctx)
        memory = []
        for row in ok.drop_duplicates(["dataset", "volume_size"]).itertuples():
            rle, raw = float(getattr(row, "count_rle_bytes", np.nan)), float(getattr(row, "count_raw_bytes", np.nan))
            memory.append({"data set": row.dataset, "size": int(float(row.volume_size)), "3×RLE (MB)": rle / 1e6,
                           "raw volume (MB)": raw / 1e6, "4 B/voxel array (MB)": 4 * raw / 1e6,
                           "RLE / raw": rle / raw, "RLE / 4 B per voxel": rle / (4 * raw)})
        out.append(blocks.Table("Memory of the three run-length encodings", pd.DataFrame(memory), csv_name="memory.csv",
                                caption="Counters rle_bytes and raw_bytes of the backend (1 byte per raw voxel: "
                                        "uint8 volumes). Thesis head: 9.8 MB of RLE, 14 MB raw, 61 MB at 4 B/voxel."))
        out.append(linked_table("Every run", speed_points(ok),
                                ["dataset", "volume_size", "image_size", "time_ms", "time_ms_min", "time_ms_max"], ctx,
                                csv_name="scaling.csv"))
        return out + shearwarp_missing()


def _growth_figure(growth, ok, ctx):
    """Frame time against the volume size on log–log axes, with n² and n³ guides through the smallest size."""
    lo, hi = float(growth.volume_size.min()), float(growth.volume_size.max())
    base = float(growth[growth.volume_size == lo].time_ms.median())
    xs = np.array([lo, hi])
    title = title_or(lambda d: "Compositing time grows " + ", ".join(
        f"×{format_number(_per_doubling(a, b, k, judging.COMPOSITE, intervals.Resampler())[0], 2)} ({dataset})"
        for dataset, (a, b, k, _n, _m) in _growth_pairs(d).items())
        + " per doubling of the side\n(n² would be ×4, n³ ×8)", ok, "Frame time against the volume size")
    return time_lines_figure(ctx, "growth", growth, heading="Frame time against the volume size",
                             caption=f"Fixed {int(growth.image_size.iloc[0])}² image; grey lines of slope 2 and 3 "
                                     "through the smallest size. Bars: fastest to slowest timed frame.",
                             x="volume_size", group="dataset", log_x=True, log_y=True, title=title,
                             x_label="volume size (voxels along the longest side)",
                             guides=(("∝ n² (thesis)", xs, base * (xs / lo) ** 2),
                                     ("∝ n³ (brute force)", xs, base * (xs / lo) ** 3)))


def _warp_blocks(frame, ok, ctx):
    """The warp's time against the image size (the first data set), as a chart and beside Table 5.4."""
    frame = stage_points(frame, "time_warp", name="warp_ms")
    frame["volume"] = [f"{int(v)}³ {d}" for v, d in zip(frame.volume_size, frame.dataset)]
    image_sizes = np.array(sorted(frame.image_size.unique()), float)
    warp = frame[frame.dataset == frame.dataset.iloc[0]]
    guide = ()
    if len(image_sizes) > 1:
        ref_time = float(warp[warp.image_size == image_sizes[0]].warp_ms.median())
        guide = (("∝ pixels (thesis)", image_sizes, ref_time * (image_sizes / image_sizes[0]) ** 2),)
    rows = []
    for row in warp.sort_values(["volume_size", "image_size"]).itertuples():
        thesis = tables.TABLE_5_4.get(int(row.volume_size), {}).get(int(row.image_size))
        rows.append({"volume": row.volume, "image": f"{int(row.image_size)}²", "warp (ms)": row.warp_ms,
                     "thesis warp (ms)": tables.TABLE_5_4["warp (ms)"].get(int(row.image_size), np.nan),
                     "share of the frame": as_percent(row.warp_ms / row.time_ms),
                     "thesis share": f"{thesis} %" if thesis is not None else ""})
    return [figure(ctx, "warp", plots.lines, warp, heading="Warp time against the image size",
                   caption="One line per volume size; the grey line grows with the pixel count.",
                   x="image_size", y="warp_ms", group="volume", y_range=("warp_ms_min", "warp_ms_max"), log_x=True,
                   log_y=True, x_label="image size (pixels along a side)",
                   title=title_or(lambda d: f"The warp grows {_warp_growth(d).measured} per doubling of the image side "
                                  "(pixels: ×4)", ok, "Warp time against the image size",
                                  errors=(KeyError, ValueError, IndexError)),
                   y_label="median warp time per frame (ms)", guides=guide),
            blocks.Table("The warp's cost beside Table 5.4", pd.DataFrame(rows), csv_name="warp.csv",
                         caption="Medians of the timed frames; thesis: MR brain prefiltered to each size.")]


def _growth_pairs(df):
    """``{data set: (rows at the second-largest size, rows at the largest, doublings)}`` of the growth runs."""
    rows = df[numeric(df, "growth") == 1]
    pairs = {}
    for dataset in pd.unique(text_column(rows, "dataset")):
        part = rows[text_column(rows, "dataset") == dataset]
        sizes = sorted(numeric(part, "volume_size").dropna().unique())
        if len(sizes) < 2:
            continue
        a, b = (part[numeric(part, "volume_size") == n] for n in sizes[-2:])
        pairs[dataset] = (a, b, math.log2(sizes[-1] / sizes[-2]), int(sizes[-2]), int(sizes[-1]))
    return nonempty_or(pairs, "no data set rendered at two sizes")


def _per_doubling(rows_a, rows_b, doublings, column, resampler):
    """``(ratio per doubling, its draws)`` of ``column`` from rows ``a`` to rows ``b``."""
    a = judging.statistic(rows_a, column, resampler)
    value, draws = judging.ratio_pair(judging.statistic(rows_b, column, resampler), a)
    return value ** (1 / doublings), None if draws is None else draws ** (1 / doublings)


def _growth(df, at_least=2.8, at_most=5.66):
    resampler = intervals.Resampler()
    decisions, details = {}, []
    for dataset, (a, b, doublings, n, m) in _growth_pairs(df).items():
        value, draws = _per_doubling(a, b, doublings, judging.COMPOSITE, resampler)
        decisions[dataset] = judging.decided(value, draws, at_least=at_least, at_most=at_most, frames=resampler.arms())
        words = f"{dataset} {n}³ → {m}³: samples {as_ratio(_ratio_of(a, b, 'count_samples', doublings))}"
        for column, name in ((judging.TECHNIQUE, "technique"), (judging.TOTAL, "whole frame")):
            try:
                words += f", {name} {as_ratio(_ratio_of(a, b, column, doublings))}"
            except (KeyError, ValueError):
                pass
        details.append(words)
    return all_of(decisions, extra="per doubling: " + "; ".join(details) + " (the samples do not depend on the "
                                   "machine; n² is ×4)")


def _ratio_of(a, b, column, doublings):
    return (float(numeric(b, column).median()) / float(numeric(a, column).median())) ** (1 / doublings)


def _rle_memory(df):
    """At each data set's largest size (the thesis's statement is about 256³ scans; at a few
    voxels the per-scanline offsets dominate), the RLE copies against 4 bytes per voxel."""
    frame = df.assign(rle=numeric(df, "count_rle_bytes"), raw=numeric(df, "count_raw_bytes"), n=numeric(df, "volume_size"))
    frame = nonempty_or(frame[np.isfinite(frame.rle) & np.isfinite(frame.raw) & (frame.raw > 0)],
                        "no run reported rle_bytes and raw_bytes")
    largest = frame[frame.n == frame.groupby("dataset").n.transform("max")].drop_duplicates("dataset")
    fraction = {f"{r.dataset} {int(r.n)}³": r.rle / (4 * r.raw) for r in largest.itertuples()}
    per_raw = {f"{r.dataset} {int(r.n)}³": r.rle / r.raw for r in largest.itertuples()}
    return ClaimResult(", ".join(f"{format_number(v)} of the 4 B/voxel array ({k})" for k, v in fraction.items()),
                       bool(max(fraction.values()) < 1.0),
                       "RLE / raw 1 B/voxel volume: " + ", ".join(f"{format_number(v)} ({k})" for k, v in per_raw.items())
                       + " (thesis head 0.7, brain 1.9, images and tables included)")


def _warp_rows(df):
    frame = df.assign(n=numeric(df, "volume_size"), i=numeric(df, "image_size"), warp=numeric(df, "time_warp"))
    first = text_column(frame, "dataset").iloc[0]
    return frame[(text_column(frame, "dataset") == first) & np.isfinite(frame.warp)]


def _warp_growth(df, at_least=2.5, at_most=5.5):
    frame = _warp_rows(df)
    smallest = frame[frame.n == frame.n.min()].sort_values("i")
    if len(smallest) < 2:
        raise ValueError("fewer than two image sizes at the smallest volume")
    a, b = smallest.iloc[[-2]], smallest.iloc[[-1]]
    resampler = intervals.Resampler()
    value, draws = _per_doubling(a, b, math.log2(b.i.iloc[0] / a.i.iloc[0]), "time_warp", resampler)
    decision = judging.decided(value, draws, at_least=at_least, at_most=at_most, frames=resampler.arms())
    return ClaimResult.decided(judging.labelled({f"{int(a.i.iloc[0])}² → {int(b.i.iloc[0])}²": decision}), decision,
                               ", ".join(f"{int(r.i)}²: {format_number(r.warp * 1e3)} ms" for r in smallest.itertuples())
                               + " warp stage per frame; thesis ×3.4, ×3.8")


def _warp_share(df, paper=False):
    """The warp's share of the technique time at the largest image falls as the volume grows; or (``paper``) is
    at least Table 5.4's at the smallest volume and at most its share at the largest."""
    frame = _warp_rows(df)
    largest = frame[frame.i == frame.i.max()].sort_values("n")
    if len(largest) < 2:
        raise ValueError("fewer than two volume sizes at the largest image")
    resampler = intervals.Resampler()
    warp = judging.values(largest, "time_warp", resampler)
    shares, draws = judging.ratio_pair(warp, judging.values(largest, judging.TECHNIQUE, resampler))
    if paper:
        return _warp_share_paper(largest, shares, draws, resampler)
    decision = judging.decided(np.diff(shares).max(), None if draws is None else np.diff(draws, axis=1).max(axis=1),
                               at_most=0.0, centred=True, frames=resampler.arms())
    return ClaimResult.decided(", ".join(f"{as_percent(s)} ({int(n)}³)" for s, n in zip(shares, largest.n))
                               + f"; largest rise {decision_words(decision, as_percent)}", decision,
                               f"warp stage over the technique at {int(largest.i.iloc[0])}² images; thesis 48 %, 31 %, 9 %")


def _warp_share_paper(largest, shares, draws, resampler):
    """Table 5.4's shares at the ends of our volume sizes (at our largest image) as bounds: the first at least, the
    last at most."""
    image = int(largest.i.iloc[0])
    decisions = {}
    for end, bound in ((0, "at_least"), (-1, "at_most")):
        n = int(largest.n.iloc[end])
        thesis = tables.TABLE_5_4.get(n, {}).get(image)
        if thesis is None:
            raise ValueError(f"Table 5.4 gives no warp share for a {n}³ volume at {image}² images")
        decisions[f"{n}³, thesis {'≥' if end == 0 else '≤'} {thesis} %"] = judging.decided(
            shares[end], None if draws is None else draws[:, end], frames=resampler.arms(), **{bound: thesis / 100})
    return all_of(decisions, show=as_percent, extra=f"warp stage over the technique at {image}² images; every size: "
                  + ", ".join(f"{as_percent(s)} ({int(n)}³)" for s, n in zip(shares, largest.n)))
