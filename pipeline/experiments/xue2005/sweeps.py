"""``xue2005-tf`` (E10): the speed-up of ESS+ERT over Basic as the transfer function's iso-values move, and the
transfer functions with nothing to cull, where the paper claims no overhead.

Every transfer function is given explicitly in the scene (``transfer_function`` of the volume entry) with the
colours of the data set's ``isbvr`` preset.

Also the helpers :mod:`.fuzziness` shares: speed-ups with bootstrap draws, ratios of speed-ups from different
groups, a mode's counts.
"""

from dataclasses import replace

import numpy as np
import pandas as pd

import datasets
from core.errors import InputError
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import all_of, config_rows, median_count, ratio_of_draws, speedup
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, scaled
from pipeline.experiments.kit.pages import as_percent, as_ratio, claim_takeaways, figure, format_number, linked_table
from pipeline.experiments.kit.planning import (headline_view, listed, orbit_views, phantom, scene, timed_frames,
                                               volume_and_image_size)
from pipeline.experiments.kit.results import interleave_groups, nonempty, numeric, ok_rows, text_column
from pipeline.experiments.xue2005.methods import culled_fraction, isbvr_not_measurable, mode_runs
from pipeline.experiments.xue2005.tables import PAPER_DEVICE, STATEMENTS, TABLE1, paper_speedup
from reports import plots

SCENES = ("head", "aneurysm")

PAPER_ISO = {"head": (50, 170), "aneurysm": (50, 150)}
"""The ``isbvr`` presets' (iso_t, iso_p) in grey levels (note 001 §5): where each one-sided sweep crosses."""

ISO_T = (10, 30, 50, 80, 120)
"""iso_t (grey levels) swept at the paper's iso_p: from the background noise to inside the skin."""

ISO_P = (100, 130, 150, 170, 200, 240)
"""iso_p (grey levels) swept at the paper's iso_t: from soft tissue to where almost no voxel is opaque."""

FLOOR = 0.002
"""Opacity of the "neither" control below iso_t: above 0 everywhere, faint enough to see through."""

TOP = 0.9
"""The opacity the "neither" and "never opaque" controls stop at, short of 1."""

DENSE = ("dense", "fbm_control", "no_cue")
"""The dense-block control (note 001 §5): scene, data set (smooth fBm filling the box, values 50–200) and
preset (uniform opacity 0.003: never 0, never 1)."""

CONTROLS = {"neither": ("basic", "ess+ert"), "never-opaque": ("basic", "ess", "ess+ert")}
"""The controls run on each swept scene beside the ramps, with the modes each group times: "neither" has no
zero-opacity and no opaque region, "never-opaque" no opaque region."""

NO_OVERHEAD = (0.95, 1.05)
"""ESS+ERT / Basic time where nothing can be culled (the paper: "no overhead", §3): a 5 % band either side,
the issue's; the depth passes over the box (two footprints of a trivial shader) against the hundreds of shaded
slices are well inside it if the paper is right."""

STRONG = 1.5
"""The best iso pair's ESS+ERT speed-up over the worst's that "depends strongly on the iso choice" asks for:
half again, as much as the paper's Table 1 spread over data sets with their own TFs (×1.71, golden lady to
bonsai) nearly; fixed before any measurement."""

SCOPE = "whole frames (time_total), median over the views"


def ramp_points(dataset, iso_t, iso_p, *, floor=0.0, top=1.0):
    """A ``transfer_function`` entry (scene format): opacity ``floor`` up to ``iso_t``, linear to ``top`` at ``iso_p``
    (grey levels, 0 <= ``iso_t`` < ``iso_p`` <= 255), in the colours of ``dataset``'s ``isbvr`` preset at the four
    points; ``floor`` 0 and ``top`` 1 are the paper's Fig. 9e ramp."""
    if not 0 <= iso_t < iso_p <= 255:
        raise InputError(f"xue2005-tf: iso values need 0 <= iso_t < iso_p <= 255 grey levels, got {iso_t} and {iso_p}")
    table = datasets.preset(dataset, "isbvr").transfer_function.table
    grid = np.linspace(0.0, 1.0, len(table))

    def colour(value):
        return [round(float(np.interp(value, grid, table[:, k])), 6) for k in range(3)]

    values = (0.0, iso_t / 255, iso_p / 255, 1.0)
    alphas = (floor, floor, top, top)
    name = _tf_label(iso_t, iso_p) + (f"-floor{floor:g}" if floor else "") + (f"-top{top:g}" if top < 1 else "")
    return {"points": [[v, *colour(v), float(a)] for v, a in zip(values, alphas)], "name": name}


def _tf_label(iso_t, iso_p):
    return f"t{iso_t:g}-p{iso_p:g}"


def sweep_pairs(scene_name, iso_t, iso_p):
    """The (iso_t, iso_p) pairs of ``scene_name``: each iso_t at the paper's iso_p, each iso_p at the paper's
    iso_t, the paper's pair always; pairs with iso_t >= iso_p are left out."""
    paper_t, paper_p = PAPER_ISO[scene_name]
    pairs = [(paper_t, paper_p)] + [(t, paper_p) for t in iso_t] + [(paper_t, p) for p in iso_p]
    return list(dict.fromkeys((float(t), float(p)) for t, p in pairs if t < p))


def interval_columns(name, pair, *, value=None):
    """``{value: v, "<name> low": low, "<name> high": high}`` of a ``(v, draws)`` pair
    (:func:`~pipeline.experiments.kit.intervals.interval_or_nan`); ``value`` defaults to ``"<name> δ"``."""
    low, high = intervals.interval_or_nan(pair[1])
    return {value or f"{name} δ": pair[0], f"{name} low": low, f"{name} high": high}


def mode_counts(tested):
    """One mode's counts, medians over its views (occlusion queries): α', φ = (F_t + F_p) / F, F, F'_c and the cube
    sets' cubes; and its worst PSNR against Basic."""
    generated = median_count(tested, "count_fragments_generated")
    surfaces = median_count(tested, "count_surface_fragments_t") + median_count(tested, "count_surface_fragments_p")
    return {"alpha": culled_fraction(tested), "phi": surfaces / generated, "F": generated,
            "F_c": median_count(tested, "count_fragments"), "cubes_t": median_count(tested, "count_cubes_t"),
            "cubes_p": median_count(tested, "count_cubes_p"),
            "psnr": float(numeric(tested, "psnr").min()) if "psnr" in tested else np.nan}


def _iso_dependence(df):
    """Per scene: the best ramp's ESS+ERT speed-up over the worst's, at least :data:`STRONG` (with its interval)."""
    resampler = intervals.Resampler()
    scenes = nonempty([s for s in SCENES if s in set(text_column(df, "scene"))], what="a swept scene")
    decisions, notes = {}, []
    for scene_name in scenes:
        groups = interleave_groups(df, scene=scene_name, kind="ramp")
        if len(groups) < 2:
            raise ValueError(f"fewer than two iso pairs of {scene_name}")
        speeds = {name: speedup(rows, "basic", "ess+ert", resampler=resampler) for name, rows in groups.items()}
        best = max(speeds, key=lambda name: speeds[name][0])
        worst = min(speeds, key=lambda name: speeds[name][0])
        decisions[scene_name] = ratio_of_draws(speeds[best], speeds[worst], at_least=STRONG)
        ends = [f"{end} {groups[name].tf.iloc[0]} {as_ratio(speeds[name][0])} "
                f"(α' {as_percent(culled_fraction(config_rows(groups[name], 'ess+ert')))})"
                for end, name in (("best", best), ("worst", worst))]
        notes.append(f"{scene_name}: {', '.join(ends)} of {len(speeds)} pairs")
    return all_of(decisions, what="best / worst pair's speed-up ", extra="; ".join(notes) + f" ({SCOPE})")


def _nothing_to_cull(df):
    """The groups of the "neither" controls and the dense block: ``{label: rows}``."""
    found = {}
    for kind in ("neither", "dense"):
        for rows in interleave_groups(df, kind=kind).values():
            found[f"{rows.scene.iloc[0]} {kind}" if kind != "dense" else str(rows.scene.iloc[0])] = rows
    return nonempty(found, what="a control with nothing to cull")


def _no_overhead(df):
    resampler = intervals.Resampler()
    low, high = NO_OVERHEAD
    decisions = {label: intervals.ratio_decision(config_rows(rows, "ess+ert", what=label),
                                                 config_rows(rows, "basic", what=label), at_least=low, at_most=high,
                                                 resampler=resampler)
                 for label, rows in _nothing_to_cull(df).items()}
    return all_of(decisions, what="ESS+ERT / Basic time ", extra=SCOPE)


def _nothing_culled(df):
    counts = {}
    for label, rows in _nothing_to_cull(df).items():
        tested = config_rows(rows, "ess+ert", what=label)
        generated, shaded = median_count(tested, "count_fragments_generated"), median_count(tested, "count_fragments")
        counts[label] = (generated, shaded, median_count(tested, "count_init_fragments"))
    worst = max(counts, key=lambda label: counts[label][0] - counts[label][1])
    generated, shaded, _ = counts[worst]
    detail = "; ".join(f"{label}: F {format_number(f)}, F'_c {format_number(c)}, init passes {format_number(i)} "
                       f"fragments" for label, (f, c, i) in counts.items())
    return ClaimResult(f"F − F'_c = {generated - shaded:g} ({worst}, α' {as_percent(1 - shaded / generated)})",
                       all(f == c for f, c, _ in counts.values()), detail)


def _ert_free(df):
    """The "never opaque" controls: ESS+ERT / ESS time in :data:`NO_OVERHEAD`, and no Φ_p to draw or cull with."""
    resampler = intervals.Resampler()
    low, high = NO_OVERHEAD
    groups = nonempty({str(rows.scene.iloc[0]): rows for rows in interleave_groups(df, kind="never-opaque").values()},
                      what="the never-opaque control")
    decisions, broken = {}, []
    for scene_name, rows in groups.items():
        both, ess = config_rows(rows, "ess+ert", what=scene_name), config_rows(rows, "ess", what=scene_name)
        decisions[scene_name] = intervals.ratio_decision(both, ess, at_least=low, at_most=high, resampler=resampler)
        cubes, fragments = median_count(both, "count_cubes_p"), median_count(both, "count_surface_fragments_p")
        extra_culled = median_count(ess, "count_fragments") - median_count(both, "count_fragments")
        if cubes or fragments or extra_culled:
            broken.append(f"{scene_name}: {cubes:g} Φ_p cubes, F_p {fragments:g}, {extra_culled:g} more fragments "
                          f"culled than ESS")
    result = all_of(decisions, what="ESS+ERT / ESS time ", extra=SCOPE + "; " + (
        "; ".join(broken) if broken else "no Φ_p cube, no Φ_p fragment, the same F'_c as ESS on every scene"))
    if broken:  # a Φ_p where the TF has no opaque value fails whatever the frames say
        return replace(result, holds=False, inconclusive=False)
    return result


CLAIMS = (
    Claim("iso-dependence", "The speed-up depends strongly on the transfer function's iso-values (§3: \"data set and "
          "transfer function dependent\")",
          f"best iso pair's ESS+ERT speed-up over the worst pair's ≥ ×{STRONG:g} on each scene ({SCOPE}; the ramps "
          "of the iso_t and iso_p sweeps)", _iso_dependence, kind="timing"),
    Claim("no-overhead", "Where the TF has neither a zero-opacity nor an opaque region iSBVR costs nothing (§3: \"no "
          "overhead\")", f"ESS+ERT / Basic time within [{NO_OVERHEAD[0]:g}, {NO_OVERHEAD[1]:g}] on each control "
          f"(head and aneurysm with the lifted ramp, the dense block; {SCOPE})", _no_overhead, kind="timing"),
    Claim("nothing-culled", "With nothing to cull, the depth passes cull nothing",
          "F'_c = F (fragments shaded = slice fragments generated, occlusion queries) on every ESS+ERT run of those "
          "controls", _nothing_culled, kind="count"),
    Claim("ert-free-without-opaque", "Where the TF never reaches opacity 1, pseudo ERT has nothing to draw and costs "
          "nothing (§3)", f"ESS+ERT / ESS time within [{NO_OVERHEAD[0]:g}, {NO_OVERHEAD[1]:g}] ({SCOPE}), no Φ_p "
          "cube and the same F'_c, on each scene's never-opaque ramp", _ert_free, kind="timing"))


def speedups(groups, configs):
    """``(key, config, rows, row)`` for each ``(key, rows)`` of ``groups`` (interleave groups) and each mode of
    ``configs`` that ran there with Basic: ``row`` its speed-up over Basic with its interval, :func:`mode_counts` and
    its first run's record and image (one resampler for all)."""
    resampler = intervals.Resampler()
    for key, group in groups:
        for config in configs:
            try:
                value, draws = speedup(group, "basic", config, resampler=resampler)
                tested = config_rows(group, config)
            except (KeyError, ValueError):
                continue
            low, high = intervals.interval_or_nan(draws)
            yield key, config, tested, {"speedup": value, "low": low, "high": high, **mode_counts(tested),
                                        "record": tested.iloc[0].get("record"), "exr": tested.iloc[0].get("exr")}


def summary(ok):
    """One row per transfer function: its tags, the ESS+ERT speed-up with its interval, α', cubes and fragments
    (:func:`speedups`), and its cube sets' triangles."""
    return pd.DataFrame([{**{k: tested.iloc[0].get(k) for k in ("scene", "kind", "tf", "iso_t", "iso_p")},
                          "group": name, **row, "triangles_t": median_count(tested, "count_surface_triangles_t"),
                          "triangles_p": median_count(tested, "count_surface_triangles_p")}
                         for name, _config, tested, row in speedups(interleave_groups(ok).items(), ("ess+ert",))])


COLUMNS = {"scene": "scene", "kind": "transfer function", "tf": "label", "iso_t": "iso_t (grey level)",
           "iso_p": "iso_p (grey level)", "speedup": "Basic / ESS+ERT time (×)", "low": "95 % CI low",
           "high": "95 % CI high", "alpha": "α' culled", "phi": "φ = (F_t + F_p) / F", "cubes_t": "Φ_t cubes",
           "cubes_p": "Φ_p cubes", "triangles_t": "Φ_t triangles", "triangles_p": "Φ_p triangles",
           "F": "F (slice fragments)", "F_c": "F'_c (shaded)", "psnr": "PSNR vs Basic (dB)", "paper": "paper (Table 1)"}


def _sweep_figures(table, ctx):
    out = []
    ramps = table[table.kind == "ramp"]
    for axis, fixed, index in (("iso_t", "iso_p", 1), ("iso_p", "iso_t", 0)):
        at_paper = ramps[[row[fixed] == PAPER_ISO[row.scene][index] for _, row in ramps.iterrows()]].copy()
        if at_paper.empty:
            continue
        at_paper[axis] = at_paper[axis].astype(float)
        marks = sorted({PAPER_ISO[s][1 - index] for s in at_paper.scene})
        out.append(figure(ctx, f"speedup-{axis.replace('_', '')}", plots.lines, at_paper,
                          heading=f"Speed-up against {axis}",
                          caption=f"Each point: Basic over ESS+ERT whole-frame time, the two timed interleaved; bars: "
                                  f"95 % bootstrap interval from the frames. {fixed} at the paper's "
                                  f"({', '.join(f'{s} {PAPER_ISO[s][index]}' for s in PAPER_ISO)}); dotted: the "
                                  f"paper's {axis}.",
                          x=axis, y="speedup", group="scene", y_range=("low", "high"),
                          title=f"Speed-up vs {axis}: " + ", ".join(
                              f"{scene_name} {as_ratio(part.speedup.min())}–{format_number(part.speedup.max())}"
                              for scene_name, part in at_paper.groupby("scene", sort=False)),
                          x_label=f"{axis} (grey level, 0–255; {fixed} at the paper's)",
                          y_label="speed-up, Basic / ESS+ERT time (×)", vlines=marks))
    return out


class TransferSweep(Experiment):
    """E10: iso-values swept on the head and the aneurysm, and the transfer functions with nothing to cull."""

    name = "xue2005-tf"
    paper = "xue2005"
    title = "Transfer functions and iso-values: where iSBVR gains and where it costs nothing (E10)"
    settings = frozenset({"scenes", "iso_t", "iso_p", "volume_size", "image_size", "orbit", "repeat"})
    scales = scaled(smoke={"iso_t": [10, 50], "iso_p": [100], "orbit": 0}, default={"orbit": 0}, full={"orbit": 3})
    description = (
        "The paper's gains are \"data set and transfer function dependent\" (§3): space leaping needs a "
        "zero-opacity region, pseudo early termination an opaque one, and a TF with neither should cost nothing, "
        "since there is nothing to draw. Here the paper's ramp (opacity 0 below iso_t, linear to 1 at iso_p) "
        "moves on the head stand-in and the aneurysm: iso_t at the paper's iso_p, iso_p at the paper's iso_t. "
        "The controls: the same ramp lifted to opacity 0.002 everywhere and stopped at 0.9 (neither property), "
        "the ramp stopped at 0.9 (no opaque region), and the dense block of note 001 §5 (fBm filling the box, "
        "uniform opacity 0.003). Basic and ESS+ERT (and ESS for the never-opaque ramp) of one TF are timed "
        "interleaved, frame against frame; the occlusion queries count the slice fragments (F) and those "
        "shaded (F'_c), so the culled fraction α' = (F − F'_c)/F is the same on every machine.")
    claims = CLAIMS

    def runs(self, profile):
        wanted = listed(profile, self, "scenes", SCENES, known=SCENES)
        iso_t = [float(v) for v in profile.setting(self, "iso_t", list(ISO_T))]
        iso_p = [float(v) for v in profile.setting(self, "iso_p", list(ISO_P))]
        if not all(0 <= v <= 255 for v in iso_t + iso_p):
            raise InputError(f"profile {profile.name!r} settings.{self.name}: iso_t and iso_p are grey levels in "
                             f"[0, 255], got {iso_t} and {iso_p}")
        size, image = volume_and_image_size(profile, self)
        orbit = int(profile.setting(self, "orbit", 0))
        frames = timed_frames(profile, self)
        runs = []
        for scene_name in wanted:
            dataset = TABLE1[scene_name][0]
            views = orbit_views(dataset, orbit)
            paper_t, paper_p = (float(v) for v in PAPER_ISO[scene_name])
            tfs = [(_tf_label(t, p), "ramp", t, p, ramp_points(dataset, t, p), ("basic", "ess+ert"))
                   for t, p in sweep_pairs(scene_name, iso_t, iso_p)]
            tfs.append(("neither", "neither", paper_t, paper_p,
                        ramp_points(dataset, paper_t, paper_p, floor=FLOOR, top=TOP), CONTROLS["neither"]))
            tfs.append(("never-opaque", "never-opaque", paper_t, paper_p,
                        ramp_points(dataset, paper_t, paper_p, top=TOP), CONTROLS["never-opaque"]))
            for label, kind, t, p, tf, configs in tfs:
                spec = scene(scene_name, image, volumes=[phantom(dataset, size, transfer_function=tf)])
                tags = {"scene": scene_name, "dataset": dataset, "tf": label, "kind": kind, "iso_t": t, "iso_p": p}
                runs += self._group(f"{scene_name}.{label}", spec, views, configs, frames, tags)
        dense, dataset, preset = DENSE
        spec = scene(dense, image, volumes=[phantom(dataset, size, preset=preset)])
        runs += self._group(f"{dense}.{preset}", spec, (headline_view(dataset),), ("basic", "ess+ert"), frames,
                            {"scene": dense, "dataset": dataset, "tf": preset, "kind": "dense"})
        return runs

    def _group(self, prefix, spec, views, configs, frames, tags):
        """Basic and ``configs`` on one scene, one interleave group, each image compared with Basic's."""
        basic = mode_runs(self.name, prefix, spec, views, ("basic",), frames, tags, group=prefix)
        return basic + mode_runs(self.name, prefix, spec, views, [c for c in configs if c != "basic"], frames, tags,
                                 group=prefix, reference=f"{prefix}.basic")

    def paper_table(self):
        rows = [{"what": f"ESS+ERT / Basic, {TABLE1[s][2]} with its TF", "paper": as_ratio(paper_speedup(s, "ess+ert")),
                 "source": f"Table 1 ({PAPER_DEVICE})"} for s in SCENES]
        rows += [{"what": s["claim"], "paper": s["paper's own table"], "source": s["source"]} for s in STATEMENTS
                 if "overhead" in s["claim"]]
        return pd.DataFrame(rows)

    def report(self, results, ctx):
        ok = ok_rows(results)
        out = [claim_takeaways(ctx)]
        table = summary(ok) if {"interleave", "config", "kind"} <= set(ok.columns) else pd.DataFrame()
        if not table.empty:
            out += _sweep_figures(table, ctx)
            table["paper"] = [as_ratio(paper_speedup(r.scene, "ess+ert"))
                              if r.kind == "ramp" and (r.iso_t, r.iso_p) == PAPER_ISO.get(r.scene) else ""
                              for r in table.itertuples()]
            out.append(linked_table("Every transfer function: speed-up, culled fraction and cube sets", table,
                                    list(COLUMNS), ctx, names=COLUMNS, csv_name="tf_sweep.csv",
                                    caption="Speed-up: Basic over ESS+ERT whole-frame time (median over the views), "
                                            "its 95 % bootstrap interval from the interleaved frames. α' = "
                                            "(F − F'_c)/F and φ from ESS+ERT's occlusion queries; cubes of Φ_t at 8³ "
                                            "and Φ_p at 2³ voxels. Links: the ESS+ERT run. Paper: its Table 1 ratio "
                                            "(its TF unstated, its 256³ data), beside our paper-pair row."))
        return out + isbvr_not_measurable()
