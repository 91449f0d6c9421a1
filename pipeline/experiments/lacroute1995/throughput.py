"""``lacroute1995-throughput`` (E12–E14, Figs 5.19–5.21): voxel throughput, run overhead and the cost model."""

import math

import numpy as np
import pandas as pd

from core.errors import InputError
from pipeline.experiments.kit import intervals, judging
from pipeline.experiments.kit.judging import STRICTLY_BELOW_ONE, all_of, decision_words
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, Run
from pipeline.experiments.kit.pages import (as_percent, as_ratio, claim_takeaways, format_number, linked_table,
                                            time_lines_figure, title_or)
from pipeline.experiments.kit.planning import accepts, listed, phantom, scene, timed_frames
from pipeline.experiments.kit.results import nonempty_or, numeric, ok_rows, rows_matching, speed_points, text_column
from pipeline.experiments.lacroute1995 import tables
from pipeline.experiments.lacroute1995.planning import SW, TIME, shearwarp_missing
from reports import blocks

PREDICT_DATASETS = {"ct_skull": "bone", "engine": "surfaces"}
"""The scenes the fitted cost model predicts (the thesis predicts the CT head and the engine)."""


def all_visible_alpha(size):
    """The largest 8-bit opacity at which every non-transparent voxel of a face-on checkerboard is visible.

    A ray crosses ``size/2`` non-transparent voxels; their accumulated opacity must stay below the
    0.95 termination threshold: ``(size/2)·(−ln(1 − α)) < −ln 0.05 ≈ 3``, with some margin.
    """
    return max(1, math.floor(255 * (1 - math.exp(-2.8 / (size / 2))))) / 255


def fit_cost_model(visible, runs, seconds):
    """Least squares ``T = N_v/a + N_r·b + c`` (numpy lstsq): ``(a voxels/s, b s/run, c s, R²)``.

    The thesis's model (§5.3.5) has no constant; ``c`` takes the per-frame costs that depend on
    neither count (the shading and opacity tables, clearing, the warp).
    """
    visible, runs, seconds = (np.asarray(v, float) for v in (visible, runs, seconds))
    if len(seconds) < 4:
        raise ValueError(f"need at least four runs to fit the cost model, got {len(seconds)}")
    design = np.column_stack([visible, runs, np.ones_like(visible)])
    (per_voxel, per_run, constant), *_ = np.linalg.lstsq(design, seconds, rcond=None)
    predicted = design @ np.array([per_voxel, per_run, constant])
    total = np.sum((seconds - seconds.mean()) ** 2)
    r2 = 1.0 - np.sum((seconds - predicted) ** 2) / total if total > 0 else 1.0
    if per_voxel <= 0:
        raise ValueError(f"the fitted time per visible voxel is not positive ({per_voxel:.3g} s)")
    return float(1.0 / per_voxel), float(per_run), float(constant), float(r2)


GROUP = "cost-model"
"""The one interleave group of every run: the fit and its predictions compare them all."""


class Throughput(Experiment):
    name = "lacroute1995-throughput"
    paper = "lacroute1995"
    title = "Voxel throughput, run overhead and the cost model (E12–E14, Figs 5.19–5.21)"
    settings = frozenset({"volume_size", "image_size", "cube_alphas", "checker_blocks", "checker_alphas",
                          "brute_force", "predict", "repeat"})
    scales = {"smoke": {"cube_alphas": [0.05, 0.2, 1.0], "checker_blocks": [4, 1], "checker_alphas": ["all-visible"],
                        "brute_force": "ends", "predict": []},
              "default": {"repeat": 15, "cube_alphas": [0.0, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0],
                          "checker_blocks": [64, 16, 4, 2, 1], "checker_alphas": ["all-visible", 1.0],
                          "brute_force": "ends"},
              "full": {"repeat": 15}}
    description = (
        "Where coherence is low the data structures cost more than they save. Constant-opacity cubes "
        "(one non-transparent run per scanline) measure the time per visible voxel: the thesis finds it "
        "linear in the visible voxels, with brute force flat and the crossover near 80 % visible. 3-D "
        "checkerboards with halving block sizes double the runs per scanline at a constant visible "
        "count: time is linear in the runs (400 ns per run on the R4400), and only 1-voxel runs make the "
        "optimised renderer slower than brute force, by about 15 %. A least-squares fit of T = N_v/a + "
        "N_r·b + c over all of these predicts the CT head and engine stand-ins. All views are face-on; "
        "the minimum-opacity threshold is set below the smallest opacity tested."
    )
    CUBE_ALPHAS = (0.0, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0)
    CHECKER_ALPHAS = ("all-visible", 1.0)
    MIN_OPACITY = 0.002

    def runs(self, profile):
        if not accepts(SW, "rle", "early_termination", "min_opacity"):
            return []
        n = int(profile.setting(self, "volume_size", profile.volume_size))
        image = profile.setting(self, "image_size", profile.image_size)
        brute_mode = profile.setting(self, "brute_force", "all")
        if brute_mode not in ("all", "ends"):
            raise InputError(f"profile {profile.name!r} settings.{self.name}.brute_force: expected 'all' or 'ends', "
                             f"got {brute_mode!r}")
        cube_alphas = [float(a) for a in profile.setting(self, "cube_alphas", list(self.CUBE_ALPHAS))]
        block_sizes = [int(b) for b in profile.setting(self, "checker_blocks",
                                                       [n // 2 ** k for k in range(1, 20) if n // 2 ** k >= 1])]
        checker_alphas = profile.setting(self, "checker_alphas", list(self.CHECKER_ALPHAS))
        predicted = listed(profile, self, "predict", PREDICT_DATASETS, known=PREDICT_DATASETS)
        view = ({"view": "face-on", "azimuth": 0.0, "elevation": 0.0},)
        timed = timed_frames(profile, self)
        runs = []

        # Every run is one interleave group: the cost model is fitted over the cubes and checkerboards together and
        # predicts the real scenes, so all of them are timed round by round in the same processes.
        def add(run_id, volume, options, tags):
            spec = scene(run_id.split(".")[0], image, volumes=[volume], shading="none")
            runs.append(Run(self.name, run_id, SW, spec, view, options=options, **timed, interleave=GROUP, tags=tags))

        optimised = {"min_opacity": self.MIN_OPACITY}
        brute = {"rle": False, "early_termination": False, "min_opacity": self.MIN_OPACITY}
        # Brute force where it composites: at α at or below the threshold it only resamples (Fig. 5.19's flat line
        # is of compositing every voxel).
        values = [int(round(alpha * 255)) for alpha in cube_alphas]
        compositing = [v for v in values if v / 255 > self.MIN_OPACITY]
        brute_values = compositing if brute_mode == "all" else compositing[:1] + compositing[-1:]
        for value in values:
            volume = phantom("constant_cube", n, preset="identity", params={"value": value})
            tags = {"series": "cube", "alpha": value / 255, "block": n, "volume_size": n}
            add(f"cube{value}.optimised", volume, optimised, {**tags, "config": "optimised"})
            if value in brute_values:
                add(f"cube{value}.brute", volume, brute, {**tags, "config": "brute-force"})
        for alpha in checker_alphas:
            alpha = all_visible_alpha(n) if alpha == "all-visible" else float(alpha)
            value = int(round(alpha * 255))
            for index, block in enumerate(block_sizes):
                volume = phantom("checkerboard", n, preset="identity", params={"block": block, "value": value})
                tags = {"series": f"checker α {value / 255:.3g}", "alpha": value / 255, "block": block, "volume_size": n}
                add(f"checker{value}.b{block}.optimised", volume, optimised, {**tags, "config": "optimised"})
                if brute_mode == "all" or index in (0, len(block_sizes) - 1):
                    add(f"checker{value}.b{block}.brute", volume, brute, {**tags, "config": "brute-force"})
        for dataset in predicted:
            volume = phantom(dataset, n, preset=PREDICT_DATASETS[dataset])
            # Face-on too: the runs of one group are timed view by view (the model predicts from the counts).
            runs.append(Run(self.name, f"predict.{dataset}", SW, scene(dataset, image, volumes=[volume]),
                            view, **timed, interleave=GROUP,
                            tags={"series": "predict", "dataset": dataset, "config": "optimised", "volume_size": n}))
        return runs

    claims = (
        Claim("linear-in-visible-voxels", "Time is linear in the number of visible voxels (Fig. 5.19)",
              "R² ≥ 0.95 of a line through the cubes' technique times against their samples", lambda df: _cube_linear(df),
              kind="cost model"),
        Claim("brute-force-flat", "Brute force takes the same time whatever the opacity (Fig. 5.19)",
              "(max − min)/median ≤ 25 % of the technique time over the cubes where brute force composites (α above "
              "the minimum opacity)", lambda df: _brute_flat(df), kind="timing"),
        *Claim("crossover-paper", "The optimised renderer beats brute force up to 80 % of the voxels visible and is at "
               "most 25 % slower with all of them visible (thesis, §5.3.2, Fig. 5.19)",
               "technique time ratio optimised / brute force < 1 on every cube with ≤ "
               f"{as_percent(tables.CROSSOVER_VISIBLE)} of its voxels visible, ≤ "
               f"{as_ratio(1 + tables.FULLY_VISIBLE_SLOWER)} on every cube with more",
               lambda df: _crossover(df, tables.CROSSOVER_VISIBLE, 1 + tables.FULLY_VISIBLE_SLOWER),
               paper_value="80 % visible; 25 % slower at 100 %", kind="timing").with_ours(
            "The optimised renderer beats brute force unless most voxels are visible (crossover ≈ 80 % visible; ≈ 25 % "
            "slower at 100 %)", "technique time ratio optimised / brute force < 1 on every cube with ≤ 50 % of its "
            "voxels visible", lambda df: _crossover(df), why="faster while at most half the voxels are visible, the "
            "thesis's crossover in kind: where it falls follows a modern CPU's costs"),
        Claim("linear-in-runs", "At a constant visible count, time is linear in the number of runs (Fig. 5.21; the "
              "thesis's 400 ns per run is its R4400's)", "R² ≥ 0.9 per checkerboard series (technique time against "
              "voxel_runs)", lambda df: _runs_linear(df), paper_value="400 ns/run", kind="cost model"),
        *Claim("one-voxel-runs-paper", "1-voxel runs with half of the voxels visible make the optimised renderer at "
               "most 15 % slower than brute force (thesis, §5.3.3)", "technique time ratio optimised / brute force ≤ "
               f"{as_ratio(1 + tables.ONE_VOXEL_RUNS_SLOWER)} at the smallest block, every non-transparent voxel "
               "visible", lambda df: _worst_runs(df, 1 + tables.ONE_VOXEL_RUNS_SLOWER), paper_value="15 %",
               kind="timing").with_ours(
            "Even 1-voxel runs with half of the voxels visible (every non-transparent one) make the optimised renderer "
            "only about 15 % slower than brute force", "technique time ratio optimised / brute force ≤ 1.3 at the "
            "smallest block, every non-transparent voxel visible", lambda df: _worst_runs(df),
            why="about the thesis's worst case: a modern CPU weighs a run's overhead against a sample otherwise than "
            "the R4400"),
        *Claim("cost-model-paper", "T = N_v/a + N_r·b predicts real scenes as well as the thesis's own predictions "
               f"did: within {as_percent(tables.cost_model_error())} (head 0.6 s predicted vs 0.76–0.87 s measured; "
               "thesis, §5.3.3)", f"technique time predicted within {as_percent(tables.cost_model_error())} of the "
               "measured (every predicted scene)", lambda df: _prediction(df, tables.cost_model_error()),
               paper_value="0.6 vs 0.76–0.87 s; 0.9 vs 0.92 s", kind="cost model").with_ours(
            "T = N_v/a + N_r·b predicts real scenes (thesis: head 0.6 s predicted vs 0.76–0.87 s, engine 0.9 vs 0.92 "
            "s)", "technique time predicted within 25 % of the measured (every predicted scene)",
            lambda df: _prediction(df), why="closer than the thesis's own head prediction: our model fits a constant "
            "for the per-frame costs the thesis's leaves out"),
    )

    def paper_table(self):
        return tables.throughput()

    def report(self, results, ctx):
        ok = ok_rows(results)
        if ok.empty:
            return []
        frame = speed_points(ok)
        frame["samples"] = numeric(frame, "count_samples")
        frame["runs"] = numeric(frame, "count_voxel_runs")
        out = [claim_takeaways(ctx)]
        cubes = frame[frame.series == "cube"].copy()
        if not cubes.empty:
            out.append(_cube_figure(cubes, ok, ctx))
        checkers = frame[frame.series.astype(str).str.startswith("checker")].copy()
        if not checkers.empty:
            checkers["line"] = checkers.series + ", " + checkers.config
            out.append(time_lines_figure(
                ctx, "checkerboards", checkers, heading="Checkerboards: time against the number of runs",
                caption="Block sizes halve from right to left... each halving doubles the runs per scanline at a "
                        "constant visible count; brute force beside.", x="runs", group="line",
                title=title_or(lambda d: f"Time grows linearly with the runs: {_runs_linear(d).detail.split(';')[0]}",
                               ok, "Checkerboards: frame time against the number of runs"),
                x_label="voxel runs traversed per frame (the backend's voxel_runs)"))
        try:
            a, b, c, r2 = _cost_fit(ok)
            fit = pd.DataFrame([("throughput a", f"{format_number(a / 1e6)} Mvoxels/s", "0.88 Mvoxels/s"),
                                ("cost per run b", f"{format_number(b * 1e9)} ns", "400 ns"),
                                ("fixed cost per frame c", f"{format_number(c * 1e3)} ms", "(not in the model)"),
                                ("R² of the fit", format_number(r2), "")], columns=["quantity", "ours", "thesis"])
            out.append(blocks.Table("The cost model T = N_v/a + N_r·b + c, fitted", fit,
                                    caption="numpy lstsq over every optimised cube and checkerboard run's technique time "
                                            "(the claims' scope); N_v: the samples counter, N_r: voxel_runs."))
        except (KeyError, ValueError):
            pass
        out.append(linked_table("Every run", frame, ["series", "config", "alpha", "block", "samples", "runs", "time_ms",
                                                     "time_ms_min", "time_ms_max"], ctx, csv_name="throughput.csv"))
        return out + shearwarp_missing("rle", "early_termination", "min_opacity")


def _cube_figure(cubes, ok, ctx):
    """The optimised cubes' time against their visible voxels, with brute force's median as a guide."""
    cubes["visible (millions)"] = cubes.samples / 1e6
    brute_level, opt = (cubes[cubes.config == config] for config in ("brute-force", "optimised"))
    guides = ()
    if not brute_level.empty and not opt.empty:
        xs = np.array([0.0, float(opt["visible (millions)"].max())])
        guides = (("brute force (median over its runs)", xs, np.full(2, float(brute_level.time_ms.median()))),)
    return time_lines_figure(
        ctx, "cubes", opt.assign(config="optimised (RLE + early termination)"),
        heading="Constant-opacity cubes: time against visible voxels",
        caption="Each point one opacity (visible voxels fall as the opacity rises and early termination cuts the rays "
                "short). Bars: fastest to slowest frame.",
        x="visible (millions)", group="config", x_label="voxels composited per frame (millions)", guides=guides,
        title=title_or(lambda d: f"Time is linear in visible voxels ({_cube_linear(d).measured});\nthe optimised "
                       f"renderer is {_crossover(d).measured.split(';')[0]}", ok,
                       "Constant-opacity cubes: frame time against visible voxels"))


def _series(df, series, config):
    rows = rows_matching(df, "", series=series, config=config).copy()
    rows["samples"], rows["runs"] = numeric(rows, "count_samples"), numeric(rows, "count_voxel_runs")
    rows["time"] = numeric(rows, TIME)
    return rows[np.isfinite(rows.time)]


def _cube_linear(df):
    slope, intercept, decision = judging.line(_series(df, "cube", "optimised"), "samples", TIME, intervals.Resampler(),
                                              at_least=0.95)
    return ClaimResult.decided(judging.labelled({"cubes": decision}, judging.r2_words), decision,
                               f"{format_number(1 / slope / 1e6)} Mvoxels/s, {format_number(intercept * 1e3)} ms fixed; "
                               "thesis 0.88 Mvoxels/s")


def _brute(df):
    """Brute-force cubes where brute force composites (α above the minimum opacity)."""
    rows = _series(df, "cube", "brute-force")
    return rows[numeric(rows, "alpha") > Throughput.MIN_OPACITY]


def _brute_flat(df):
    rows = _brute(df)
    if len(rows) < 2:
        raise ValueError("fewer than two brute-force cubes that composite")
    resampler = intervals.Resampler()
    times, draws = judging.values(rows, TIME, resampler)
    spread = lambda t, axis=None: (t.max(axis=axis) - t.min(axis=axis)) / np.median(t, axis=axis)  # noqa: E731
    decision = judging.decided(spread(times), None if draws is None else spread(draws, axis=1), at_most=0.25,
                               centred=True, frames=resampler.arms())
    return ClaimResult.decided(decision_words(decision, as_percent), decision,
                               f"{len(rows)} cubes at α " + ", ".join(format_number(a) for a in rows.alpha)
                               + f", median {judging.milliseconds(rows)} technique; samples "
                               + ", ".join(format_number(v) for v in rows.samples))


def _crossover(df, up_to=0.5, beyond=None):
    """Optimised / brute force < 1 on every cube with at most ``up_to`` of its voxels visible; with ``beyond``,
    also ≤ ``beyond`` on every cube with more."""
    rows, brute = _series(df, "cube", "optimised"), _brute(df)
    if rows.empty or brute.empty:
        raise ValueError("needs optimised and brute-force cubes")
    total = float(brute.samples.max())
    if not total > 0:
        raise ValueError("brute force reported no samples")
    rows = rows.assign(visible=rows.samples / total).sort_values("visible")
    resampler = intervals.Resampler()
    level, level_draws = judging.statistic(brute, TIME, resampler)
    times, draws = judging.values(rows, TIME, resampler)
    decisions = {f"{as_percent(v)} visible": judging.decided(
        t / level, None if draws is None or level_draws is None else draws[:, i] / level_draws, at_most=STRICTLY_BELOW_ONE,
        frames=resampler.arms())
        for i, (v, t) in enumerate(zip(rows.visible, times))}
    low = nonempty_or([d for (label, d), v in zip(decisions.items(), rows.visible) if v <= up_to],
                      f"no cube with at most {as_percent(up_to)} of its voxels visible")
    slower = rows[times >= level]
    crossing = ("never slower than brute force" if slower.empty
                else f"slower than brute force from {as_percent(float(slower.visible.min()))} visible")
    worst = intervals.combine(low)
    measured = f"{crossing}; at ≤ {as_percent(up_to)} visible at most " + judging.labelled({"worst": worst})
    if beyond is not None:
        high = [judging.decided(t / level, None if draws is None or level_draws is None else draws[:, i] / level_draws,
                                at_most=beyond, frames=resampler.arms())
                for i, (v, t) in enumerate(zip(rows.visible, times)) if v > up_to]
        if high:
            measured += ", above it at most " + judging.labelled({"worst": intervals.combine(high)})
        worst = intervals.combine(low + high)
    return ClaimResult.decided(measured, worst,
                               judging.labelled(decisions) + " (optimised / brute force; thesis: ×1.25 at 100 %)")


def _checker_series(df):
    return [s for s in pd.unique(text_column(df, "series")) if s.startswith("checker")]


def _runs_linear(df):
    resampler = intervals.Resampler()
    fits, samples = {}, {}
    for s in _checker_series(df):
        rows = _series(df, s, "optimised")
        if len(rows) >= 3:
            fits[s] = judging.line(rows, "runs", TIME, resampler, at_least=0.9)
            samples[s] = (rows.samples.min(), rows.samples.max())
    if not fits:
        raise ValueError("no checkerboard series with three block sizes")
    slopes = ", ".join(f"{format_number(slope * 1e9)} ns per run ({s}; samples {format_number(lo)}–"
                       f"{format_number(hi)})" for (s, (slope, _b, _d)), (lo, hi) in zip(fits.items(), samples.values()))
    return all_of({s: d for s, (_a, _b, d) in fits.items()}, show=judging.r2_words,
                  extra=f"{slopes}; thesis 400 ns. Where the samples vary, the visible count is not constant: "
                        "bilinear footprints of small blocks reach both colours")


def _worst_runs(df, at_most=1.3):
    resampler = intervals.Resampler()
    ratios = {}
    for s in _checker_series(df):
        opt, brute = _series(df, s, "optimised"), _series(df, s, "brute-force")
        smallest = numeric(opt, "block").min()
        match = brute[numeric(brute, "block") == smallest]
        if opt.empty or match.empty:
            continue
        ratios[s] = judging.ratio(opt[numeric(opt, "block") == smallest], match, TIME, resampler, at_most=at_most)
    # The all-visible series is the thesis's worst case: the lowest opacity.
    key = min(nonempty_or(ratios, "no checkerboard with both renderers at its smallest block"),
              key=lambda s: float(s.split("α")[-1]))
    return ClaimResult.decided(judging.labelled({key: ratios[key]}), ratios[key],
                               judging.labelled(ratios) + "; thesis ×1.15")


def _fit_rows(df):
    rows = df[text_column(df, "config") == "optimised"]
    rows = rows[text_column(rows, "series") != "predict"]
    rows = rows.assign(samples=numeric(rows, "count_samples"), runs=numeric(rows, "count_voxel_runs"),
                       time=numeric(rows, TIME))
    return rows[np.isfinite(rows.samples) & np.isfinite(rows.runs) & np.isfinite(rows.time)]


def _cost_fit(df):
    rows = _fit_rows(df)
    return fit_cost_model(rows.samples, rows.runs, rows.time)


def _prediction(df, bound=0.25):
    """Every predicted scene's technique time predicted within ``bound`` (relative) of the measured."""
    a, b, c, _r2 = _cost_fit(df)
    rows = nonempty_or(df[text_column(df, "series") == "predict"], "no predicted scene rendered")
    resampler = intervals.Resampler()
    fit = _fit_rows(df)
    _, fit_draws = judging.values(fit, TIME, resampler)
    coefficients = None  # (3, draws): the model refitted to every draw
    if fit_draws is not None:
        design = np.column_stack([fit.samples, fit.runs, np.ones(len(fit))])
        coefficients = np.linalg.lstsq(design, fit_draws.T, rcond=None)[0]
    decisions, words = {}, []
    for index, row in rows.iterrows():
        samples, runs = float(row["count_samples"]), float(row["count_voxel_runs"])
        predicted = samples / a + runs * b + c
        (measured,), draws = judging.values(rows.loc[[index]], TIME, resampler)
        error_draws = (None if coefficients is None or draws is None
                       else (samples * coefficients[0] + runs * coefficients[1] + coefficients[2]) / draws[:, 0] - 1)
        decisions[row["dataset"]] = judging.decided(predicted / measured - 1, error_draws, at_least=-bound,
                                                    at_most=bound, frames=resampler.arms())
        words.append(f"{row['dataset']}: predicted {format_number(predicted * 1e3)} ms, measured "
                     f"{format_number(measured * 1e3)} ms ({format_number(samples)} samples, {format_number(runs)} runs)")
    return all_of(decisions, extra="; ".join(words) + f"; a = {format_number(a / 1e6)} Mvoxels/s, b = "
                                   f"{format_number(b * 1e9)} ns/run, c = {format_number(c * 1e3)} ms", show=as_percent)
