"""E2, the headline: frame time against the number of overlapping 64³ volumes (``kainz2009-scaling``)."""

import dataclasses

import pandas as pd

from core.errors import InputError
from pipeline.experiments.kainz2009 import tables
from pipeline.experiments.kainz2009.methods import (METHOD_NAMES, PEEL, TILED, VTK_MAX_VOLUMES, PaperExperiment,
                                                    device_note, devices, frames_caption, method_runs, peeling_missing,
                                                    run_settings, table)
from pipeline.experiments.kainz2009.ratios import FRAMES, KERNELS
from pipeline.experiments.kainz2009.scenes import CLOUD_SIZES, blob, clouds, volume
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.checks import Measure, Ratio, worst_psnr
from pipeline.experiments.kit.judging import (STRICTLY_ABOVE_ONE, TECHNIQUE, TOTAL, decided, ratio_pair, statistic,
                                              timed, with_interval)
from pipeline.experiments.kit.model import Claim, ClaimResult, scaled
from pipeline.experiments.kit.pages import as_ratio, claim_takeaways, figure, format_number, time_lines_figure
from pipeline.experiments.kit.planning import HEADLINE_VIEW, listed, scene, truth_run
from pipeline.experiments.kit.results import fit_line, numeric, ok_rows, role_rows, rows_matching, speed_points
from reports import plots

COUNTS = (1, 2, 4, 8, 16, 20, 32, 50, 64)
SERIES = {"clouds": "N × 64³ clouds", "clouds+256": "N × 64³ clouds + one 256³ volume",
          "clouds+mesh": "N × 64³ clouds + a 30k-triangle mesh"}
"""Each series in the paper's words."""
TARGET_COUNT = 50
TARGET_RATIO = 4.0
"""The issue's target: 50 clouds and the 30k mesh at most 4× one cloud's frame time, same picture."""

VIEW_HEIGHT = 1.6
"""Picture height in cloud edges: one cloud already covers most of the picture (the paper zooms so),
and every count of clouds is seen through the same pixels."""


GROUP = "clouds"
"""The interleave group of the runs the timing claims compare: the clouds alone by cl-tiled and depth
peeling at every count, and cl-tiled's clouds with the mesh at :data:`TARGET_COUNT`."""


def _tiled_time(what, series, count):
    """cl-tiled's kernel time with ``count`` clouds of ``series``, selected by the run's ``scene`` tag.

    Not by ``count``: tags match as text, and ``runs.csv`` read back beside experiments without a
    count gives ``50.0``.
    """
    return Measure(what, match={"scene": f"{series}.n{count:02d}", "config": TILED, "role": "test"}, column=TECHNIQUE)


ONE_CLOUD = _tiled_time("time(1 cloud)", "clouds", 1)
FLAT_WITH_MESH = Ratio(_tiled_time(f"time({TARGET_COUNT} clouds + mesh)", "clouds+mesh", TARGET_COUNT), ONE_CLOUD,
                       at_most=TARGET_RATIO)
FLAT_VOLUMES = Ratio(_tiled_time(f"time({TARGET_COUNT} clouds)", "clouds", TARGET_COUNT), ONE_CLOUD,
                     at_most=TARGET_RATIO)
ACCURATE = worst_psnr("cl-tiled's worst PSNR against the reference over every checked count and series", 40.0,
                      config=TILED, checked="yes")


def _with_samples(ratio):
    """``ratio``'s check, its detail with the volume samples of both runs: the work that grew with the time.

    The clouds overlap heavily (note 002 §6), so a ray samples every cloud it is inside at each step
    and the samples grow about as the count; the time per sample says what the count itself cost.
    """
    def check(df):
        result = ratio(df)
        if "count_samples" not in df:
            return result
        samples = [numeric(rows_matching(df, m.what, **m.match), "count_samples").median()
                   for m in (ratio.numerator, ratio.denominator)]
        if not all(value > 0 for value in samples):
            return result
        times = ratio.numerator.value(df) / ratio.denominator.value(df)
        grew = samples[0] / samples[1]
        return dataclasses.replace(result, detail=f"{result.detail}; volume samples {int(samples[0])} and "
                                                  f"{int(samples[1])} ({as_ratio(grew)}), so the time per sample "
                                                  f"{as_ratio(times / grew)}")
    return check


def _peeling_growth(df):
    """Depth peeling's growth from one cloud to N over cl-tiled's, at the largest N both render (whole frames)."""
    rows = {config: timed(df, METHOD_NAMES[config], TOTAL, series="clouds", config=config, role="test")
            for config in (TILED, PEEL)}
    common = sorted(set(numeric(rows[TILED], "count")) & set(numeric(rows[PEEL], "count")))
    if len(common) < 2 or common[0] != 1:
        raise ValueError("depth peeling and cl-tiled share no count beyond one volume")
    n = common[-1]
    resampler = intervals.Resampler()
    # config -> (value, draws) of its time at N over its time at 1
    growth = {config: ratio_pair(*(statistic(part[numeric(part, "count") == count], TOTAL, resampler)
                                   for count in (n, 1))) for config, part in rows.items()}
    decision = decided(*ratio_pair(growth[PEEL], growth[TILED]), at_least=STRICTLY_ABOVE_ONE, frames=resampler.arms())
    measured = f"peeling {as_ratio(growth[PEEL][0])}, cl-tiled {as_ratio(growth[TILED][0])} at N = {int(n)}"
    return ClaimResult.decided(with_interval(f"{measured}: {as_ratio(decision.value)}", decision), decision,
                               f"time at N = {int(n)} over time at N = 1, clouds alone, {FRAMES}; peeling's growth "
                               f"over cl-tiled's; {devices(pd.concat(rows.values()))}")


class Scaling(PaperExperiment):
    name = "kainz2009-scaling"
    title = "Frame time against the number of overlapping volumes (E2; C5, C8)"
    settings = frozenset({"counts", "series", "small_size", "large_size", "image_size", "mesh_triangles",
                          "step_factor", "truth_step_factor", "truth_counts", "repeat"})
    scales = scaled(base=CLOUD_SIZES,
                    smoke={"counts": [1, 50], "series": ["clouds"], "mesh_triangles": 2000, "truth_counts": [50]},
                    default={"counts": [1, 4, 8, 16, 50, 64], "mesh_triangles": 30000, "truth_counts": [1, 8, 50]},
                    full={"mesh_triangles": 30000})
    description = (
        "The paper's central point: the tiled caster rasterizes every boundary once per frame and walks each ray's "
        "segments with the set of volumes present, so its cost grows gently with the number of overlapping volumes (it "
        "renders 50 × 64³ volumes with a 30k-polygon mesh at 8–16 fps, while depth peeling needs a pass per layer and "
        "the shader tools stop at 4 volumes). Here 1 to 64 smoke clouds of 64³ (stand-ins at the profile's size) "
        "overlap heavily around one point, randomly turned, alone, inside one 256³ volume, and with a 30k-triangle "
        "translucent mesh among them. The camera and the picture stay fixed, zoomed so that one cloud already covers "
        "most pixels, so only the volume count changes. VTK's GPU caster (vtkMultiVolume, up to 7 volumes) renders the "
        "clouds alone beside it. Selected counts are checked against the reference."
    )

    def plan(self, profile):
        counts = [int(n) for n in profile.setting(self, "counts", list(COUNTS))]
        if not counts or min(counts) < 1 or max(counts) > 64:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.counts: need counts from 1 to 64 "
                             f"(the active-object set is one 64-bit mask), got {counts}")
        series = listed(profile, self, "series", SERIES, SERIES)
        small = int(profile.setting(self, "small_size", 64))
        large = int(profile.setting(self, "large_size", 256))
        image, step, truth_step, frames = run_settings(self, profile)
        triangles = int(profile.setting(self, "mesh_triangles", 30000))
        truth_counts = {int(n) for n in profile.setting(self, "truth_counts", [1, 8, TARGET_COUNT])}
        views = (dict(HEADLINE_VIEW),)
        runs = []
        for kind in series:
            for count in counts:
                large_volume = [volume("ct_skull", large, "bone", "large")] if kind == "clouds+256" else []
                spec = scene(f"{kind}-{count}", image, volumes=large_volume + clouds(count, small),
                             meshes=(blob(small, triangles),) if kind == "clouds+mesh" else (),
                             camera={"view_height": round(VIEW_HEIGHT * (large if large_volume else small), 4)})
                prefix = f"{kind}.n{count:02d}"
                # "checked": whether the count has a reference run, so the accuracy claim reads those runs only.
                tags = {"series": kind, "count": count, "scene": prefix,
                        "checked": "yes" if count in truth_counts else "no"}
                truth = None
                if count in truth_counts:
                    truth = truth_run(self.name, prefix, spec, views, truth_step, tags, config="reference")
                    runs.append(truth)
                compared = kind == "clouds" or (kind == "clouds+mesh" and count == TARGET_COUNT)
                runs += method_runs(self.name, prefix, spec, views, tags, truth, step=step, frames=frames,
                                    groups=(GROUP if compared else None, GROUP if kind == "clouds" else None),
                                    vtk=kind == "clouds" and count <= VTK_MAX_VOLUMES)
        return runs

    claims = (
        Claim("flat-with-mesh", f"{TARGET_COUNT} overlapping 64³ volumes plus a 30k-triangle mesh cost little more "
              "than one volume (the bound is the issue's target; paper: C8 at 8–16 fps, no one-volume rate beside "
              "it)", f"{FLAT_WITH_MESH.expected} ({KERNELS})",
              _with_samples(FLAT_WITH_MESH), paper_value="8–16 fps (C8)", kind="timing"),
        Claim("flat-volumes", f"{TARGET_COUNT} overlapping 64³ volumes alone cost little more than one",
              f"{FLAT_VOLUMES.expected} ({KERNELS})", _with_samples(FLAT_VOLUMES), kind="timing"),
        Claim("accuracy", "Every count of overlapping volumes renders the reference's image", ACCURATE.expected,
              ACCURATE),
        Claim("peeling-grows-faster", "Depth peeling's cost grows faster with the volume count than the tiled "
              "caster's (a geometry pass per layer; Table 1: Roessler 24–38 → 5–9 fps from 2 to 4 volumes)",
              f"(time(N)/time(1) of depth peeling) / (that of cl-tiled) > ×1 at the largest N both render (clouds "
              f"alone, {FRAMES})", _peeling_growth, paper_value="24–38 → 5–9 fps", kind="timing"),
    )

    def paper_table(self):
        return pd.DataFrame(tables.SCALING).assign(device=tables.PAPER_DEVICE)

    def report(self, results, ctx):
        tests = role_rows(ok_rows(results))
        out = [claim_takeaways(ctx, device_note(tests), _scaling_takeaways(tests))]
        if not tests.empty:
            rows = speed_points(tests)
            rows["count"] = numeric(rows, "count")
            rows["method"] = [f"{SERIES[s]} ({METHOD_NAMES[c]})" for s, c in zip(rows.series, rows.config)]
            counts = {"x": "count", "group": "method", "x_label": "overlapping 64³ volumes N (count)",
                      "vlines": (TARGET_COUNT,)}
            out.append(time_lines_figure(ctx, "time", rows, heading="Frame time against the number of volumes",
                                         caption="Bars from the fastest to the slowest frame; dotted: N = 50 (C8). "
                                                 + frames_caption(rows),
                                         title=_scaling_title(rows), **counts))
            base = _one_cloud_ms(rows)
            for column in ("", "_min", "_max"):
                rows[f"relative{column}"] = rows[f"time_ms{column}"] / base
            out.append(figure(ctx, "relative", plots.lines, rows, heading="Growth relative to one volume",
                              caption="Each series over its own method's one-cloud run; bars from the fastest to "
                                      "the slowest frame.", y="relative", y_range=("relative_min", "relative_max"),
                              title=f"Frame time over one cloud's; target ≤ {TARGET_RATIO:g}× at N = {TARGET_COUNT}",
                              y_label="frame time / one cloud's frame time (ratio)",
                              guides=((f"target {TARGET_RATIO:g}×", [1, max(rows["count"].max(), 2)],
                                       [TARGET_RATIO, TARGET_RATIO]),), **counts))
            out.append(table("Every run", rows.sort_values(["series", "config", "count"]),
                             ["series", "config", "count", "time_ms", "time_ms_min", "time_ms_max", "psnr",
                              "count_triangles", "count_fragments_max", "count_fragments_mean",
                              "count_fragments_dropped", "count_samples"], ctx, csv_name="scaling.csv",
                             caption="Depth complexity: boundary fragments per pixel (capped at 63 in local "
                                     "memory; dropped ones counted). PSNR where the count has a reference run."))
        return out + peeling_missing()


def _one_cloud_ms(rows):
    """Per row, the one-cloud time its series is compared with: cl-tiled's clouds alone, VTK's for VTK."""
    one = rows[(rows.series == "clouds") & (rows["count"] == 1)]
    return rows.config.map(dict(zip(one.config, one.time_ms))).astype(float)


def _scaling_title(rows):
    tiled = rows[(rows.config == TILED) & (rows.series == "clouds")]
    if len(tiled) < 2:
        return "Frame time against the number of overlapping volumes"
    first, last = tiled.sort_values("count").iloc[[0, -1]].itertuples()
    return (f"cl-tiled: {format_number(first.time_ms)} ms at N = {int(first.count)}, "
            f"{format_number(last.time_ms)} ms at N = {int(last.count)}")


def _scaling_takeaways(tests):
    """The clouds-alone series as a line: fixed cost plus cost per added volume."""
    if "series" not in tests:
        return []
    tiled = tests[(tests.config == TILED) & (tests.series == "clouds")]
    if numeric(tiled, "count").nunique() < 3:
        return []
    slope, intercept, r2 = fit_line(numeric(tiled, "count"), numeric(tiled, "time_total") * 1e3)
    return [f"cl-tiled with clouds alone: {format_number(intercept)} ms + {format_number(slope)} ms per added volume "
            f"(least squares over {len(tiled)} counts, R² {format_number(r2)}): linear in the volumes a ray meets, "
            "with no per-layer pass."]
