"""``kruger2003-passes`` (E4, E6, E7): fragments per main pass, the iso-surface caster against DVR, the sweep of M."""

import json
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, Run, scaled
from pipeline.experiments.kit.pages import (as_ratio, claim_takeaways, figure, format_number, linked_table,
                                            time_lines_figure, unless_missing)
from pipeline.experiments.kit.planning import (accepts, headline_view, is_registered, phantom, scene, timed_frames,
                                               truth_run)
from pipeline.experiments.kit.results import (file_exists, nonempty_or, numeric, ok_rows, rows_matching, speed_points,
                                              tagged)
from pipeline.experiments.kit.judging import (STRICTLY_ABOVE_ONE, all_of, config_rows, decision_words, median_count,
                                              median_time)
from pipeline.experiments.kruger2003.methods import (RAYCAST, SETTINGS, SIZE_SCALES, gl_not_measurable, method_name,
                                                     method_runs, sizes)
from pipeline.experiments.kruger2003.tables import PASSES
from reports import plots

M_VALUES = (1, 2, 4, 8, 16, 32, 64)
"""Samples per main pass of the M sweep (the paper's 8 among them)."""

PAPER_M = 8
"""The paper's samples per pass, forced by the shader limits of the ATI 9700."""


def _fragments_per_pass(record_path, view="headline"):
    """The fragments each main pass drew in ``view``, from a run's record (its occlusion-query counts)."""
    if not file_exists(record_path):
        raise ValueError(f"run record {record_path!r} is missing")
    for entry in json.loads(Path(record_path).read_text()).get("views", []):
        if entry.get("view") == view:
            counts = entry.get("info", {}).get("fragments_per_main_pass")
            if counts:
                return [float(c) for c in counts]
    raise ValueError(f"{record_path}: no fragments_per_main_pass for view {view!r}")


def _pass_curves(ok):
    """Each main pass's fragments per method, from the records (none from a run whose record has no counts)."""
    return pd.DataFrame([{"method": method_name(row.config), "main pass": i + 1, "fragments": c}
                         for row in tagged(ok, part="passes", role="test").itertuples()
                         for i, c in enumerate(unless_missing(_fragments_per_pass, row.record, empty=[]))])


def _pass_trend(df, config, flat):
    rows = nonempty_or(rows_matching(df, config, config=config, part="passes"), f"no successful {config} run")
    counts = _fragments_per_pass(rows.record.iloc[0])
    first = counts[0]
    if first <= 0:
        raise ValueError(f"{config}: the first main pass drew no fragment")
    last = counts[-1] / first
    holds = last >= 0.95 if flat else last <= 0.5
    return ClaimResult(f"last pass {format_number(100 * last)} % of the first", bool(holds),
                       f"{len(counts)} main passes, first {format_number(first)} fragments")


def _iso_faster(df):
    dvr, iso = config_rows(df, "rc-a", part="passes"), config_rows(df, "rc-a", part="iso")
    decision = intervals.ratio_decision(dvr, iso, at_least=STRICTLY_ABOVE_ONE)
    samples = median_count(dvr, "count_samples") / median_count(iso, "count_samples")
    return ClaimResult.decided(decision_words(decision), decision,
                               f"DVR {format_number(median_time(dvr, 'rc-a') * 1e3)} ms, iso "
                               f"{format_number(median_time(iso, 'rc-a') * 1e3)} ms (whole frames, interleaved)"
                               + (f"; samples DVR / iso {as_ratio(samples)}" if np.isfinite(samples) else ""))


COUNTS = (("count_passes_main", "main passes"), ("count_samples", "samples"))
"""The counts said beside each M's time: per-pass overhead grows with the passes, wasted work with the samples."""


def _m_words(rows, m):
    """``"M 8: 42.9 ms, 40 main passes, 5.54e+05 samples"`` (the counts where recorded)."""
    return ", ".join([f"M {m}: {format_number(median_time(rows, 'rc-b') * 1e3)} ms"]
                     + [f"{format_number(median_count(rows, column))} {name}" for column, name in COUNTS
                        if column in rows])


def _m_u_shape(df):
    """The fastest M inside the sweep against each end of the sweep: both ends must be slower."""
    sweep = rows_matching(df, "the M sweep", part="m-sweep")
    ms = numeric(sweep, "m")
    values = sorted(int(m) for m in ms.dropna().unique())
    if len(values) < 3:
        raise ValueError("fewer than three values of M")
    rows = {m: sweep[ms == m] for m in values}
    best = min(values[1:-1], key=lambda m: median_time(rows[m], "rc-b"))
    resampler = intervals.Resampler()
    decisions = {f"M {m}": intervals.ratio_decision(rows[m], rows[best], at_least=STRICTLY_ABOVE_ONE,
                                                    resampler=resampler) for m in (values[0], values[-1])}
    return all_of(decisions, what=f"fastest inside at M = {best}; end / M = {best} time ",
                 extra="; ".join(_m_words(rows[m], m) for m in values) + " (whole frames, interleaved)")


def _m_title(sweep):
    best = sweep.loc[sweep.time_ms.idxmin()]
    return f"Fastest at M = {int(best.M)} ({format_number(best.time_ms)} ms); the paper used {PAPER_M}"


class Passes(Experiment):
    """Per-pass work, the iso-surface caster and the samples per pass M."""

    name = "kruger2003-passes"
    paper = "kruger2003"
    title = "Work per pass, the iso-surface caster and the samples per pass M (E4, E6, E7)"
    settings = SETTINGS | {"m_values"}
    scales = scaled(base=SIZE_SCALES, smoke={"m_values": [2, 8, 32]})
    description = (
        "Occlusion queries count, for every main pass, the fragments that survive the early depth test: flat for RC "
        "(the whole footprint every pass), falling for RC-a as rays saturate or leave, and lower again for RC-b across "
        "empty segments; the intermediate pass is never culled. The iso-surface caster shades once per pass and ends a "
        "ray at its hit, so it should beat DVR with early termination on an opaque surface. M trades the per-pass "
        "overhead (small M: many passes) against samples wasted after a ray ends inside a pass (large M)."
    )
    claims = (
        Claim("rc-flat", "RC draws the whole footprint in every main pass", "fragments of the last main pass ≥ 95 % "
              "of the first", lambda df: _pass_trend(df, "rc", flat=True), kind="count"),
        Claim("rca-falls", "With early termination the fragments per main pass fall as rays end",
              "RC-a's last main pass ≤ 50 % of its first", lambda df: _pass_trend(df, "rc-a", flat=False),
              kind="count"),
        Claim("iso-faster", "The iso-surface caster beats DVR with early termination on an opaque surface (Sec. 2.2)",
              "time ratio DVR RC-a / iso RC-a > 1 (whole frames)", _iso_faster, kind="timing"),
        Claim("m-u-shape", "The cost over M is U-shaped: per-pass overhead at small M, wasted samples at large M "
              "(Sec. 3)", "the fastest M inside the swept range faster than both ends: time at each end / at it > 1 "
              "(whole frames)", _m_u_shape, kind="timing"),
    )

    def runs(self, profile):
        if not is_registered(RAYCAST):
            return []
        size, image, step = sizes(self, profile)
        frames = timed_frames(profile, self)
        view = (headline_view("foot"),)
        dvr = scene("foot", image, volumes=[phantom("foot", size, preset="bone")])
        tags = {"scene": "foot", "dataset": "foot", "part": "passes"}
        truth = truth_run(self.name, "foot", dvr, view, 0.25, tags)
        # DVR and the iso-surface caster with early termination are timed together, as is the M sweep.
        runs = [truth] + method_runs(self.name, "foot", dvr, view, ("rc", "rc-a", "rc-b"), step, truth.id, tags,
                                     frames, together=("rc-a",), group="iso")
        iso = scene("foot-iso", image, volumes=[phantom("foot", size, preset="iso")], mode="iso")
        iso_truth = truth_run(self.name, "foot-iso", iso, view, 0.25, {**tags, "part": "iso"})
        # The paper's iso-surface caster tests s < isovalue at its samples (gl-raycast's iso_hit="sampled").
        runs += [iso_truth] + method_runs(self.name, "foot-iso", iso, view, ("rc-a",), step, iso_truth.id,
                                          {**tags, "part": "iso", "mode": "iso"}, frames, together=("rc-a",),
                                          group="iso", extra={"iso_hit": "sampled"})
        if accepts(RAYCAST, "samples_per_pass"):
            runs += [Run(self.name, f"foot.m{int(m)}", RAYCAST, dvr, view,
                         options={"variant": "rc-b", "samples_per_pass": int(m), "step_factor": step},
                         reference=truth.id, **frames, interleave="m-sweep",
                         tags={**tags, "part": "m-sweep", "role": "test", "config": "rc-b", "m": int(m)})
                     for m in profile.setting(self, "m_values", list(M_VALUES))]
        return runs

    def paper_table(self):
        return pd.DataFrame(PASSES)

    def report(self, results, ctx):
        ok = ok_rows(results)
        out = [claim_takeaways(ctx)]
        curves = _pass_curves(ok)
        if not curves.empty:
            out.append(figure(ctx, "fragments-per-pass", plots.lines, curves,
                              heading="Work per main pass (foot, headline view)",
                              caption="From a samples-passed occlusion query around each main pass.",
                              x="main pass", y="fragments", group="method",
                              title="Fragments that survive the depth test, per main pass",
                              x_label="main pass (number)", y_label="fragments drawn (count)"))
        sweep = tagged(ok, part="m-sweep")
        if not sweep.empty:
            sweep = speed_points(sweep).assign(M=numeric(sweep, "m"), method=method_name("rc-b"))
            out.append(time_lines_figure(
                ctx, "m-sweep", sweep, heading="Frame time against M",
                caption=f"Bars from the fastest to the slowest frame; dotted: the paper's M = {PAPER_M}.",
                x="M", group="method", title=_m_title(sweep), x_label="samples per main pass M (count)",
                log_x=True, vlines=(PAPER_M,)))
            out.append(linked_table("M sweep", sweep, ["M", "time_ms", "time_ms_min", "time_ms_max", "psnr"], ctx,
                                    csv_name="m_sweep.csv"))
        return out + gl_not_measurable()
