"""``ropinski2005-samples`` (E3): the lens leaves the samples where they were, and the regions split them.

The paper (§3): "The number of samples used during rendering of each region is determined based on the
length of the current section of the ray", so a ray takes as many samples with the lens as without; the runs
and what ``gl-raycast`` counts: :attr:`Samples.description`.
"""

import numpy as np
import pandas as pd

from pipeline.experiments.kit.model import Claim, ClaimResult
from pipeline.experiments.kit.pages import claim_takeaways, figure, format_number
from pipeline.experiments.kit.planning import UNTIMED, listed
from pipeline.experiments.kit.results import nonempty_or, numeric, rows_matching, text_column
from pipeline.experiments.ropinski2005.methods import (CONFIGS, LENS_SCALES, METHODS, OFF, PAPER_METHOD, REGIONS,
                                                       LensExperiment, lens_run, lens_settings, method_name,
                                                       raycast_not_measurable)
from pipeline.experiments.ropinski2005.pages import headline, run_table, tests_of
from pipeline.experiments.ropinski2005.scenes import (SETUPS, lens_scene, lens_views, outside_appearance, scene_tags,
                                                      without_lens)
from reports import blocks, plots

COUNTED = {"opaque_threshold": 1.0}
"""Early termination off: every sample of a ray's span is taken, whatever was composited before it."""

APPEARANCES = {"none": "no lens", "outside": "lens with the outside appearance", "lens": "lens with its own appearance"}
"""The ``appearance`` tag of each run, in words."""

REGION_COLUMNS = tuple(f"count_samples_{region}" for region in ("region0", "region1", "region2"))
REGION_WORDS = ("region₀", "region₁", "region₂")


def _pairs(df, appearance, control="none", by=("scene", "view"), *, missing=None):
    """``[(scene, view, config, row, control row)]``: every ``appearance`` run's view beside the ``control`` run's
    with the same tags ``by`` (the lens-off run's of its scene and view); ValueError saying ``missing`` if none."""
    controls = rows_matching(df, control, appearance=control)
    pairs = []
    for row in rows_matching(df, appearance, appearance=appearance).itertuples():
        match = rows_matching(controls, control, **{tag: getattr(row, tag) for tag in by})
        if not match.empty:
            pairs.append((row.scene, row.view, row.config, row, next(match.itertuples())))
    return nonempty_or(pairs, missing or f"no {APPEARANCES[appearance]} run beside a lens-off run of its scene")


def _worst(wrong, words, otherwise):
    """The largest ``(size, detail, config, scene, view)`` of ``wrong`` in ``words(size, detail)``, or ``otherwise``."""
    if not wrong:
        return otherwise
    size, detail, config, scene, view = max(wrong)
    return f"{words(size, detail)} ({config}, {scene}, {view})"


def _count(row, column):
    value = float(getattr(row, column, np.nan))
    if not np.isfinite(value):
        raise ValueError(f"run {row.run} counted no {column.removeprefix('count_')}")
    return value


def _invariant(df):
    unequal, detail = [], {}
    for scene, view, config, row, off in _pairs(df, "outside"):
        lens, none = _count(row, "count_samples"), _count(off, "count_samples")
        detail.setdefault(config, []).append(lens - none)
        if lens != none:
            unequal.append((abs(lens - none), lens - none, config, scene, view))
    words = "; ".join(f"{c}: {len(d)} views, " + ("equal" if not any(d) else
                                                 f"differences {', '.join(format_number(x, 4) for x in d if x)}")
                      for c, d in detail.items())
    measured = _worst(unequal, lambda _, difference: f"{format_number(difference, 4)} samples",
                      f"equal on {sum(map(len, detail.values()))} views")
    return ClaimResult(measured, not unequal, words + "; early termination off (opacity threshold 1)")


def _region_counts(row):
    """A row's samples per region, or ``None`` where its method does not count regions."""
    values = [float(getattr(row, column, np.nan)) for column in REGION_COLUMNS]
    return values if all(np.isfinite(values)) else None


def _partition(df):
    checked, wrong = [], []
    for scene, view, config, row, off in _pairs(df, "outside"):
        regions = _region_counts(row)
        if regions is None:
            continue
        difference = sum(regions) - _count(off, "count_samples")
        checked.append(config)
        if difference:
            wrong.append((abs(difference), difference, config, scene, view))
    if not checked:
        raise ValueError("no outside-appearance run counted samples per region (samples_region0–2)")
    measured = _worst(wrong, lambda _, difference: f"regions − no lens = {format_number(difference, 4)} samples",
                      f"equal on {len(checked)} views")
    return ClaimResult(measured, not wrong, f"methods counting regions: {', '.join(dict.fromkeys(checked))}")


def _outside_unchanged(df):
    missing = "no lens-appearance run beside an outside-appearance run, both counting regions"
    checked, wrong, inside = 0, [], []
    for scene, view, config, row, match in _pairs(df, "lens", "outside", ("scene", "view", "config"), missing=missing):
        own, control = _region_counts(row), _region_counts(match)
        if own is None or control is None:
            continue
        checked += 1
        inside.append(f"{scene} {config} region₁ {format_number(own[1], 4)} of {format_number(control[1], 4)}")
        for index in (0, 2):
            if own[index] != control[index]:
                wrong.append((abs(own[index] - control[index]), f"region{index}", config, scene, view))
    if not checked:
        raise ValueError(missing)
    measured = _worst(wrong, lambda difference, region: f"{region} differs by {format_number(difference, 4)} samples",
                      f"region₀ and region₂ equal on {checked} views")
    return ClaimResult(measured, not wrong, "; ".join(inside))


CLAIMS = (
    Claim("invariant", "The lens does not change the number of samples: each region takes the lattice points of "
          "its own section of the ray (§3)", "samples with a lens showing the outside appearance = samples without "
          "the lens, exactly, every method, scene and view (early termination off)", _invariant, kind="count"),
    Claim("regions-partition", "The three regions split a ray's samples between them, none counted twice or left "
          "out", "samples of region₀ + region₁ + region₂ = samples without the lens, exactly, every method that "
          "counts regions (outside appearance)", _partition, kind="count"),
    Claim("outside-unchanged", "The lens's appearance changes only the work inside it: region₀ and region₂ take "
          "the same samples whatever the lens shows", "region₀ and region₂ samples with the lens's own appearance "
          "= with the outside appearance, exactly, every method that counts regions, scene and view",
          _outside_unchanged, kind="count"),
)


def sample_table(tests):
    """Per scene and method: samples without the lens, with the outside appearance and with its own, by region."""
    rows = []
    shown = headline(tests)
    off = shown[text_column(shown, "appearance") == "none"]
    for (scene, config), part in shown[text_column(shown, "appearance") != "none"].groupby(["scene", "config"],
                                                                                         sort=False):
        row = {"scene": scene, "method": method_name(config),
               "no lens": numeric(off[off.scene == scene], "count_samples").median()}
        for appearance in ("outside", "lens"):
            chosen = part[part.appearance == appearance]
            row[APPEARANCES[appearance]] = numeric(chosen, "count_samples").median()
            row |= {f"{region}, {appearance}": numeric(chosen, column).median()
                    for column, region in zip(REGION_COLUMNS, REGION_WORDS) if column in chosen}
        rows.append(row)
    return pd.DataFrame(rows)


def _region_figure(tests, ctx):
    own = rows_matching(headline(tests), "the paper's method's lens", appearance="lens", config=PAPER_METHOD)
    if own.empty or not all(column in own for column in REGION_COLUMNS):
        return []
    regions = {REGIONS[c.removeprefix("count_samples_")]: numeric(own, c).to_numpy() / 1e6 for c in REGION_COLUMNS}
    bars = pd.DataFrame({"scene": own.scene.to_numpy(), **regions})
    return [figure(ctx, "samples-regions", plots.bar_compare, bars, heading="Samples per region",
                   caption="Counted by the caster (exact, machine-independent), the lens with its own appearance, "
                           "headline view, early termination off.",
                   category_col="scene", value_cols=list(REGIONS.values())[::-1],
                   value_label="samples per frame (millions)", title="Samples per region, the paper's method")]


class Samples(LensExperiment):
    name = "ropinski2005-samples"
    title = "Sample counts with and without the lens, region by region (E3)"
    settings = frozenset({"scenes", "methods", "volume_size", "image_size", "orbit", "step_factor"})
    scales = LENS_SCALES
    description = (
        "The paper's argument for cutting rays into regions instead of testing samples: each region takes the "
        "samples of its own section of the ray, so the lens costs no samples (§3). gl-raycast counts every "
        "sample it takes and, where the method knows each ray's lens segment, the samples of each region. "
        "Every lens method renders each lens scene three ways, once each from the headline view with early "
        "termination off: without the lens, with the lens showing the outside appearance (DVR with the "
        "volume's own transfer function: the lens then changes nothing but where each sample is composited) "
        "and with the lens's own appearance. Counts do not depend on the machine, so every claim is exact."
    )
    claims = CLAIMS

    def lens_runs(self, profile):
        wanted = listed(profile, self, "scenes", tuple(SETUPS), known=SETUPS)
        methods = listed(profile, self, "methods", CONFIGS, known=METHODS)
        size, image, orbit, step = lens_settings(profile, self)
        runs = []
        for scene_name in wanted:
            spec = lens_scene(scene_name, image, size=size, real_data=profile.real_data)
            views = lens_views(scene_name, orbit)
            tags = scene_tags(scene_name, role="test")
            # One job per scene (an interleave group of single untimed frames): a job's start costs more than
            # such a frame, and counts do not depend on what ran beside them.
            runs.append(lens_run(self.name, f"{scene_name}.{OFF}", without_lens(spec), views, OFF, UNTIMED,
                                 {**tags, "appearance": "none"}, step_factor=step, options=COUNTED, group=scene_name))
            for method in methods:
                for appearance, scene_spec in (("outside", outside_appearance(spec)), ("lens", spec)):
                    runs.append(lens_run(self.name, f"{scene_name}.{method}.{appearance}", scene_spec, views, method,
                                         UNTIMED, {**tags, "appearance": appearance}, step_factor=step,
                                         options=COUNTED, group=scene_name))
        return runs

    def report(self, results, ctx):
        tests = tests_of(results)
        out = [claim_takeaways(ctx)]
        if not tests.empty:
            out += _region_figure(tests, ctx)
            out.append(blocks.Table("Samples per frame (headline view)", sample_table(tests), csv_name="samples.csv",
                                    caption="Counted by the caster, early termination off: every sample of every "
                                            "ray's span. Region columns only for the methods that count regions."))
            out.append(run_table(tests, ["scene", "method", "appearance", "count_samples", *REGION_COLUMNS,
                                         "count_lens_rays"], ctx, timed=False, method=method_name,
                                 names=dict(zip(REGION_COLUMNS, REGION_WORDS)), csv_name="samples_runs.csv"))
        return out + raycast_not_measurable(sorted(set(text_column(tests, "config"))) if not tests.empty else CONFIGS)
