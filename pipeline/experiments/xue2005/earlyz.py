"""``xue2005-earlyz`` (E2): the early-z micro-benchmark: T_s, T_z and T_c per fragment, γ against the shader."""

import numpy as np
import pandas as pd

from core.errors import InputError
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import STRICTLY_BELOW_ONE, all_of, ratio_of_draws, ratio_pair, with_interval
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, Run, scaled
from pipeline.experiments.kit.pages import claim_takeaways, figure, format_number, unless_missing
from pipeline.experiments.kit.planning import accepts, phantom, scene, timed_frames, volume_and_image_size
from pipeline.experiments.kit.results import nonempty_or, numeric, ok_rows, rows_matching
from pipeline.experiments.kit.words import short_duration
from pipeline.experiments.xue2005 import costmodel
from pipeline.experiments.xue2005.methods import ISBVR, OPTIONS, STEP, isbvr_not_measurable, runs_table
from pipeline.experiments.xue2005.tables import EARLYZ_STATEMENTS
from reports import blocks, plots

DATASET, PRESET = "fbm_control", "no_cue"
"""The micro-benchmark's phantom: smooth noise filling the cube with a small opacity everywhere, so that every
fragment of the volume shader classifies, shades and blends (no empty or opaque region to branch around)."""

FILL = 0.95
"""Picture height as a share of the cube's edge: seen straight at a face, the cube covers every pixel."""

FRONT_VIEW = {"view": "front", "azimuth": 0.0, "elevation": 0.0}
"""Straight at a face, orthographic: every ray crosses every slice, so F = slices × pixels."""

EXTRA_TAPS = (0, 4, 16)
"""Extra volume-texture fetches per fragment in the volume shader: the complexity sweep of γ."""

CONFIGS = {
    # config: (gl-isbvr options, what its volume pass times)
    "simple": ({"zinit": "none", "shader": "simple"}, "T_s: the trivial shader, no depth test"),
    "culled": ({"zinit": "cull-all", "shader": "volume"},
               "T_z: the volume shader, every fragment culled by the early depth test"),
    "volume": ({"zinit": "none", "shader": "volume"}, "T_c: the volume shader, no depth test"),
}
"""The micro-benchmark's configurations; ``volume`` is run once per value of :data:`EXTRA_TAPS`."""

SCOPE = "the volume pass's draw time over the slices' fragments F, summed over the views"


def isbvr_run(experiment, run_id, scene_spec, views, options, frames, tags, *, group, reference=None):
    """A timed ``gl-isbvr`` run of ``options`` with slices one voxel apart and fragments counted, in ``group``."""
    return Run(experiment, run_id, ISBVR, scene_spec, tuple(views),
               options={**options, "step_factor": STEP, "count_fragments": True}, reference=reference, **frames,
               tags=tags, interleave=group)


def can_plan(*options):
    """Whether ``gl-isbvr`` is here with every option these experiments set, and ``options``."""
    return accepts(ISBVR, *OPTIONS, "count_fragments", *options)


def per_fragment(rows, resampler):
    """``(value, draws)``: seconds per fragment of ``rows``' volume pass, Σ draw time / Σ F over the rows (views).

    ``draws`` are the bootstrap draws from the timed frames (``None`` without frames); rows of one
    interleave group are resampled round by round, so ratios of two configurations pair their frames.
    """
    rows = nonempty_or(rows, "no successful run to time per fragment")
    fragments = numeric(rows, "count_fragments_generated")
    if not (fragments > 0).all():
        raise ValueError(f"run {rows.run.iloc[0]} counted no slice fragments (count_fragments_generated)")
    total = float(fragments.sum())
    value = float(numeric(rows, "time_draw").sum()) / total
    draws = intervals.row_draws(rows, "time_draw", resampler)
    return value, None if draws is None else draws.sum(axis=1) / total


def select(df, config, taps=None, **match):
    """The rows of ``config`` matching the tags ``match`` and, unless ``None``, ``taps`` extra taps (as numbers)."""
    rows = rows_matching(df, config, config=config, **match)
    return rows if taps is None else rows[numeric(rows, "extra_taps") == taps]


def _config_rows(df, config, taps=None):
    return nonempty_or(select(df, config, taps),
                       f"no successful {config} run" + ("" if taps is None else f" with {taps} extra taps"))


def _taps(df):
    """The extra taps of the volume-shader runs, ascending (at least two)."""
    taps = numeric(rows_matching(df, "volume", config="volume"), "extra_taps")
    values = sorted(int(t) for t in taps.dropna().unique())
    if len(values) < 2:
        raise ValueError(f"fewer than two shader complexities (extra taps {values})")
    return values


def _culled_at_most_simple(df):
    resampler = intervals.Resampler()
    culled = per_fragment(_config_rows(df, "culled"), resampler)
    simple = per_fragment(_config_rows(df, "simple"), resampler)
    decision = ratio_of_draws(culled, simple, at_most=1.0)
    return ClaimResult.decided(with_interval(f"T_z / T_s {format_number(decision.value)}", decision, format_number),
                               decision, f"T_z {short_duration(culled[0])}, T_s {short_duration(simple[0])} per "
                                         f"fragment ({SCOPE}; interleaved)")


def _gamma_falls(df):
    resampler = intervals.Resampler()
    simple = per_fragment(_config_rows(df, "simple"), resampler)
    taps = _taps(df)
    complex_ = {k: per_fragment(_config_rows(df, "volume", k), resampler) for k in taps}
    gammas = {k: ratio_pair(simple, t) for k, t in complex_.items()}
    decisions = {f"{a} → {b} taps": ratio_of_draws(gammas[b], gammas[a], at_most=STRICTLY_BELOW_ONE)
                 for a, b in zip(taps, taps[1:])}
    steps = ", ".join(f"{k} taps: γ {format_number(gammas[k][0])}, T_c {short_duration(complex_[k][0])}" for k in taps)
    return all_of(decisions, what="γ ", extra=steps + f"; T_s {short_duration(simple[0])} ({SCOPE}; interleaved)")


def _culls_everything(df):
    rows = _config_rows(df, "culled")
    shaded, generated = numeric(rows, "count_fragments"), numeric(rows, "count_fragments_generated")
    holds = bool((shaded == 0).all() and (generated > 0).all())
    return ClaimResult(f"{format_number(shaded.sum())} of {format_number(generated.sum())} fragments shaded", holds,
                       "occlusion query around the volume pass (F'_c) and around the slices without a depth test (F)")


CLAIMS = (
    Claim("tz-at-most-ts", "A fragment the early depth test discards costs no more than one through the simple "
          "shader (T_z ≈ T_s, assumed by Eqs. 3, 4 and 8)",
          f"T_z / T_s ≤ 1 (T_z: the volume shader with depth cleared to 0, T_s: the trivial shader; each {SCOPE})",
          _culled_at_most_simple, kind="timing"),
    Claim("gamma-falls", "γ = T_s / T_c falls as the volume shader grows more complex (T_s is fixed for a device, "
          "T_c depends on the shader; §2)", "γ at more extra taps / γ at fewer < 1 for each step of the sweep "
          f"({SCOPE})", _gamma_falls, kind="timing"),
    Claim("cull-all-culls", "Depth cleared to 0 culls every slice fragment, so the T_z configuration shades none",
          "F'_c = 0 with F > 0 (occlusion queries)", _culls_everything, kind="count"))


def _extreme(rows, end):
    """Seconds per fragment of the fastest (``end`` "min") or slowest ("max") frame of each view, summed."""
    column = f"time_draw_{end}"
    if column not in rows:
        return np.nan
    return float(numeric(rows, column).sum() / numeric(rows, "count_fragments_generated").sum())


def _quantities(ok):
    """One row per configuration: time per fragment (ns) with its interval and extremes, F, F'_c, and γ for T_c."""
    resampler = intervals.Resampler()
    simple = per_fragment(_config_rows(ok, "simple"), resampler)
    entries = [("T_s", "simple", None), ("T_z", "culled", None)] + [("T_c", "volume", k) for k in _taps(ok)]
    out = []
    for symbol, config, taps in entries:
        rows = _config_rows(ok, config, taps)
        value = per_fragment(rows, resampler)
        low, high = intervals.interval_or_nan(value[1])
        gamma = ratio_of_draws(simple, value) if symbol == "T_c" else None
        gamma_low, gamma_high = (gamma and gamma.interval) or (np.nan, np.nan)
        out.append({"quantity": symbol, "configuration": CONFIGS[config][1], "extra taps": taps or 0,
                    "ns per fragment": 1e9 * value[0], "CI low (ns)": 1e9 * low, "CI high (ns)": 1e9 * high,
                    "fastest frame (ns)": 1e9 * _extreme(rows, "min"),
                    "slowest frame (ns)": 1e9 * _extreme(rows, "max"),
                    "F": float(numeric(rows, "count_fragments_generated").sum()),
                    "F'_c": float(numeric(rows, "count_fragments").sum()),
                    "γ = T_s / T_c": gamma.value if gamma else np.nan, "γ CI low": gamma_low, "γ CI high": gamma_high})
    return pd.DataFrame(out)


def _model_takeaways(table):
    """What the measured γ means for the cost model: the break-even culling rate and the two ceilings."""
    complex_ = table[table.quantity == "T_c"]
    ts, tz = (float(table.loc[table.quantity == q, "ns per fragment"].iloc[0]) for q in ("T_s", "T_z"))
    times, gammas, taps = complex_["ns per fragment"], complex_["γ = T_s / T_c"], complex_["extra taps"]
    gamma = float(gammas.iloc[0])
    return [f"Per fragment on this device: T_s {format_number(ts)} ns, T_z {format_number(tz)} ns, T_c "
            f"{format_number(times.min())}–{format_number(times.max())} ns ({int(taps.min())}–{int(taps.max())} "
            f"extra taps), so γ is {format_number(gammas.min())}–{format_number(gammas.max())}.",
            f"With the volume shader as it is (γ = {format_number(gamma)}), per-slice two-pass rendering pays off "
            f"above a culling rate of {format_number(100 * costmodel.break_even_culling(gamma))} % and gains at most "
            f"×{format_number(costmodel.per_slice_ceiling(gamma))}, iSBVR at most "
            f"×{format_number(costmodel.isbvr_ceiling(gamma))} (the paper's example γ = 0.2: 25 %, ×2.5 and ×5)."]


def _figures(table, ctx):
    complex_ = table[table.quantity == "T_c"].assign(series="T_c: the volume shader", gamma="γ = T_s / T_c")
    span = (float(complex_["extra taps"].min()), float(complex_["extra taps"].max()))
    flat = table[table.quantity != "T_c"]
    guides = [(f"{q}: {format_number(v)} ns", span, (v, v)) for q, v in zip(flat.quantity, flat["ns per fragment"])]
    shaded, simple, culled = (float(rows["ns per fragment"].iloc[0])
                              for rows in (complex_, flat[flat.quantity == "T_s"], flat[flat.quantity == "T_z"]))
    return [figure(ctx, "per-fragment", plots.lines, complex_,
                   heading="Time per fragment against the shader's complexity",
                   caption=f"Points: T_c; bars from the fastest to the slowest frame; grey lines: T_s and T_z. Each is "
                           f"{SCOPE}.",
                   x="extra taps", y="ns per fragment", group="series",
                   y_range=("fastest frame (ns)", "slowest frame (ns)"), log_y=True, guides=guides,
                   title=f"A shaded fragment costs {format_number(shaded / simple)} simple or "
                         f"{format_number(shaded / culled)} culled ones",
                   x_label="extra texture taps in the volume shader (count)",
                   y_label="volume-pass time per fragment (ns)"),
            figure(ctx, "gamma", plots.lines, complex_, heading="γ against the shader's complexity",
                   caption="Bars: the 95 % bootstrap interval of γ (T_s and T_c timed interleaved, resampled round by "
                           "round).",
                   x="extra taps", y="γ = T_s / T_c", group="gamma", y_range=("γ CI low", "γ CI high"),
                   title=f"γ from {format_number(complex_['γ = T_s / T_c'].iloc[0])} to "
                         f"{format_number(complex_['γ = T_s / T_c'].iloc[-1])} as the volume shader grows",
                   x_label="extra texture taps in the volume shader (count)", y_label="γ = T_s / T_c (ratio)")]


Z_ONLY = ("the z-only pass against the same pass with colour on (the paper: up to twice as fast with colour writes "
          "off)", "gl-isbvr's volume pass always writes colour and blends, and its colour-off passes draw the "
                  "surfaces, not the slices, so no configuration times the same fragments with colour writes on "
                  "and off")
"""What the backend offers no configuration for (the paper's double-speed z)."""

RUN_COLUMNS = {"config": "config", "extra_taps": "extra taps", "view": "view", "draw_ms": "volume pass (ms)",
               "count_fragments_generated": "F", "count_fragments": "F'_c"}


class EarlyZ(Experiment):
    """The early-z micro-benchmark: T_s, T_z and T_c per fragment, and γ against the shader's complexity."""

    name = "xue2005-earlyz"
    paper = "xue2005"
    title = "The early-z micro-benchmark: T_s, T_z and T_c per fragment (E2)"
    settings = frozenset({"volume_size", "image_size", "extra_taps", "repeat"})
    scales = scaled(default={"repeat": 5}, full={"repeat": 5})
    description = (
        "The cost model (Eqs. 1–9) prices a fragment three ways: through the simple z-setup shader (T_s), "
        "discarded by the early depth test before any shader runs (T_z) and through the volume shader (T_c); "
        "their ratio γ = T_s / T_c decides when culling pays. The paper assumes T_z ≈ T_s, says T_s is fixed "
        "for a GPU while T_c depends on the shader, and that a z-only pass with colour writes off can run "
        "twice as fast on newer hardware; it gives no measured value. Here gl-isbvr's volume pass times each "
        "on a phantom of smooth noise with a small opacity everywhere (every fragment classifies, shades and "
        "blends), seen straight at a face with the cube filling the picture and slices one voxel apart: the "
        "trivial shader (T_s), the volume shader against a depth buffer cleared to 0 (every fragment culled: "
        "T_z) and the volume shader with 0, 4 and 16 extra texture taps (T_c). All configurations are timed "
        "interleaved in one job; a time per fragment is the pass's draw time over the slices' fragments "
        "counted by an occlusion query.")
    claims = CLAIMS

    def runs(self, profile):
        if not can_plan():
            return []
        size, image = map(int, volume_and_image_size(profile, self))
        taps = [int(k) for k in profile.setting(self, "extra_taps", list(EXTRA_TAPS))]
        if len(set(taps)) < 2 or min(taps) < 0:
            raise InputError(f"profile {profile.name!r} settings.{self.name}.extra_taps: need at least two different "
                             f"counts >= 0 for γ to fall over, got {taps}")
        frames = timed_frames(profile, self)
        spec = scene(DATASET, image, volumes=[phantom(DATASET, size, preset=PRESET)],
                     camera={"projection": "orthographic", "view_height": FILL * size})
        tags = {"scene": DATASET, "dataset": DATASET, "preset": PRESET}
        runs = [isbvr_run(self.name, f"micro.{config}", spec, (FRONT_VIEW,), CONFIGS[config][0], frames,
                          {**tags, "config": config, "extra_taps": 0}, group="micro")
                for config in ("simple", "culled")]
        runs += [isbvr_run(self.name, f"micro.volume.t{k}", spec, (FRONT_VIEW,),
                           {**CONFIGS["volume"][0], "extra_taps": k}, frames,
                           {**tags, "config": "volume", "extra_taps": k}, group="micro")
                 for k in sorted(set(taps))]
        return runs

    def paper_table(self):
        return pd.DataFrame(EARLYZ_STATEMENTS)

    def report(self, results, ctx):
        ok = ok_rows(results)
        table = unless_missing(_quantities, ok, empty=pd.DataFrame())
        out = [claim_takeaways(ctx, [] if table.empty else _model_takeaways(table))]
        if not table.empty:
            out.append(blocks.Table("T_s, T_z and T_c per fragment", table, csv_name="earlyz.csv",
                                    caption=f"Each time per fragment is {SCOPE}, interval from the frames "
                                            "(every configuration timed interleaved, resampled round by round); "
                                            "fastest and slowest: the fastest and slowest frame."))
            out += _figures(table, ctx)
        if not ok.empty:
            out.append(runs_table(ok, ctx, RUN_COLUMNS))
        return out + isbvr_not_measurable("count_fragments", also=[Z_ONLY])
