"""``volbench-atlas``: every backend (and :data:`TECHNIQUES`) swept along every stress axis (:mod:`.atlas_axes`)."""

import dataclasses
import functools

import numpy as np
import pandas as pd

import renderers
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, Run
from pipeline.experiments.kit.pages import DIFF_SCALE, difference_gallery, format_number, linked_table
from pipeline.experiments.kit.planning import REFERENCE, UNTIMED, listed, truth_run, volume_and_image_size
from pipeline.experiments.kit.results import numeric, ok_rows, reference_exr, rows_matching, tagged
from pipeline.experiments.volbench.atlas_axes import AXES, AXIS_BY_KEY, axis_reason, backend_options, points, short
from reports import blocks
from reports.takeaways import PSNR_GOOD

PSNR_BREAKS = 30.0
"""Below this PSNR against the reference a technique "breaks" on a point (40 dB, PSNR_GOOD: accurate)."""

TRUTH_STEP = 1 / 8
"""The reference's step for every ground truth, in voxels."""

CONVERGENCE_STEPS = (1.0, 0.5, 0.25)
"""The reference's own steps on the step axis: its error must fall as the step shrinks."""


@dataclasses.dataclass(frozen=True)
class Technique:
    """A backend with ``options`` of its own (none an option its axes sweep), a row of the atlas on the axes keyed
    ``axes``; ``elsewhere`` says why not on the others, ``slug`` is its part of run ids and interleave groups."""

    backend: str
    options: dict
    axes: tuple
    elsewhere: str
    slug: str


PRE_CLASSIFIED = "reference, pre-classified"
"""The reference classifying voxels before interpolating them (shear-warp's and VolPack's order), as a technique of its
own: on the TF axis it separates what pre-classification costs from what the shear-warp factorization does."""

SAMPLED_ISO = "gl-raycast, sampled iso hit"
"""gl-raycast testing ``s < isovalue`` at samples a step apart (the paper's caster, refined by bisection) instead of
walking every lattice cell of a ray for its first crossing (its default, the reference's walk): on the iso axes,
beside the exact hit, where sampling steps over a surface."""

TECHNIQUES = {
    PRE_CLASSIFIED: Technique(REFERENCE, {"classification": "pre", "step_factor": TRUTH_STEP}, ("tf",),
                              "swept on the TF axis only, where the order of classification matters",
                              "reference-pre"),
    SAMPLED_ISO: Technique("gl-raycast", {"iso_hit": "sampled"}, ("iso-step", "thin"),
                           "on the iso axes only: the sampled hit changes iso-surfaces alone", "gl-raycast-sampled"),
}
"""The extra rows, by label: backends with other options, each on the axes where those options matter."""


def technique_rows():
    """The heat map's rows: each backend but the reference followed by its :data:`TECHNIQUES`, the reference's last."""
    rows = []
    for backend in renderers.names():
        if backend != REFERENCE:
            rows += [backend, *(label for label, technique in TECHNIQUES.items() if technique.backend == backend)]
    return rows + [label for label, technique in TECHNIQUES.items() if technique.backend == REFERENCE]


def techniques(frame):
    """Each row's technique: the :data:`TECHNIQUES` label of its backend and options (``option_*``), else backend."""
    labels = frame.backend.copy()
    for label, technique in TECHNIQUES.items():
        mine = frame.backend == technique.backend
        for name, value in technique.options.items():
            column = frame.get(f"option_{name}", pd.Series(np.nan, frame.index))
            mine &= (column.astype(str) if isinstance(value, str) else pd.to_numeric(column, errors="coerce")) == value
        labels[mine] = label
    return labels


def _values(frame):
    """Each row's swept value: its ``value`` tag, or (a view axis) the number in its view name ``at<v>``."""
    tagged = pd.to_numeric(frame["value"], errors="coerce") if "value" in frame else pd.Series(np.nan, frame.index)
    from_view = pd.to_numeric(frame["view"].astype(str).str.removeprefix("at"), errors="coerce")
    return tagged.fillna(from_view)


def atlas_rows(results):
    """The successful test rows, with numeric ``value``, ``psnr`` and ``flip``; ``backend`` names the technique."""
    ok = ok_rows(results)
    if ok.empty or "role" not in ok:
        return ok.iloc[:0].assign(value=[], psnr=[], flip=[])
    tests = ok[ok.role == "test"]
    tests = tests.assign(backend=techniques(tests), value=_values(tests),
                         psnr=numeric(tests, "psnr") if "psnr" in tests else np.nan,
                         flip=pd.to_numeric(tests["flip"], errors="coerce") if "flip" in tests else np.nan)
    return tests[tests.psnr.notna()]


def threshold(rows, axis, *, breaks=PSNR_BREAKS):
    """Where ``rows`` (one backend on ``axis``) fall below ``breaks`` dB, or ``None`` if never: ``{"words", "value",
    "psnr", "everywhere", "expected"}``, the threshold in words, where it lies, the worst PSNR, whether every point
    failed and whether the failures lie at the harsher end (the expected side).

    The failing points that run to the harsher end of the sweep give "words ≥ v" (``v`` the mildest of them); failing
    points that run to the milder end instead give the reverse ("≤ v"); failures in the middle are listed.
    """
    if not (rows.psnr < breaks).any():
        return None
    order = rows.sort_values("value", ascending=axis.harsher == "up").reset_index(drop=True)
    fails = (order.psnr < breaks).to_numpy()
    name, values = axis.words.split(" (")[0], order.value
    everywhere, expected = bool(fails.all()), bool(fails.all() or fails[-1])
    if everywhere:
        at = 0
        words = (f"any {name} tried ({axis.point(values.iloc[0])} to {axis.point(values.iloc[-1])})"
                 if len(order) > 1 else f"{name} {axis.point(values.iloc[0])}")
    elif fails[-1]:
        at = len(fails) - np.argmin(fails[::-1])  # the mildest of the failing tail
        words = axis.threshold(values.iloc[at])
    elif fails[0]:
        at = np.argmin(fails) - 1
        words = dataclasses.replace(axis, harsher="down" if axis.harsher == "up" else "up").threshold(values.iloc[at])
    else:
        at, words = np.argmax(fails), f"{name} at " + ", ".join(axis.point(v) for v in values[fails])
    return {"words": words, "value": float(values.iloc[at]), "psnr": float(order.psnr.min()), "everywhere": everywhere,
            "expected": expected}


OTHERS_NAMED = 2
"""Besides its first threshold, a technique's "fails when …" names this many more axes it breaks on."""


def failure_phrases(tests, backends, *, breaks=PSNR_BREAKS):
    """``{backend: phrase}`` completing "fails when …": the mildest value of an axis below ``breaks`` ("min opacity ≥
    0.01 on the semi-transparent engine (17.6 dB)"), preferring a threshold inside a sweep to an axis that fails at
    every value; a backend that never falls below gets its worst point ("no axis below 30 dB (worst …)")."""
    out = {}
    for backend in backends:
        mine = tests[tests.backend == backend]
        if mine.empty:
            continue
        hits = [(axis, threshold(mine[mine.axis == axis.key], axis, breaks=breaks)) for axis in AXES]
        # A threshold inside a sweep, on its harsher side, says more than an axis failing everywhere
        # (a default that breaks) or than failures at the milder end: it comes first, with its scene.
        found = sorted([((h["everywhere"], not h["expected"], h["psnr"]), axis, h) for axis, h in hits if h],
                       key=lambda f: f[0])
        if found:
            (_, axis, hit), others = found[0], found[1:]
            phrase = f"{hit['words']} on {axis.scene_words} ({format_number(hit['psnr'])} dB)"
            if others:
                shown = [f"{h['words']} ({format_number(h['psnr'])} dB)" for _, _, h in others[:OTHERS_NAMED]]
                more = len(others) - len(shown)
                phrase += "; also " + ", ".join(shown) + (f" and {more} more {'axis' if more == 1 else 'axes'}" if more else "")
            out[backend] = phrase
        else:
            worst = mine.loc[mine.psnr.idxmin()]
            axis = AXIS_BY_KEY[worst.axis]
            out[backend] = (f"no axis below {breaks:g} dB (worst {format_number(worst.psnr)} dB at "
                            f"{axis.words.split(' (')[0]} {axis.point(worst.value)})")
    return out


def heat_cells(tests, backends, reasons, *, unrendered=None, difference=None, axes=AXES):
    """The heat map's cells over ``axes``: ``{(backend, axis words): HeatCell}``; ``reasons`` and ``unrendered`` map
    ``(backend, axis key)`` to why it was left out of the axis or made no frame, ``difference(row)`` gives the worst
    point's difference image."""
    cells = {}
    for backend in backends:
        for axis in axes:
            why = reasons.get((backend, axis.key), "")
            rows = tests[(tests.backend == backend) & (tests.axis == axis.key)]
            if why or rows.empty:
                text = why or f"no frame here: {(unrendered or {}).get((backend, axis.key), 'not run')}"
                cells[(backend, axis.words)] = blocks.HeatCell(text=text, value=None)
                continue
            worst = rows.loc[rows.psnr.idxmin()]
            flip = f"FLIP {format_number(worst.flip)} at " if pd.notna(worst.flip) else "at "
            cells[(backend, axis.words)] = blocks.HeatCell(
                text=f"{worst.psnr:.1f} dB", value=float(worst.psnr), link=f"#atlas-{axis.key}",
                image=difference(worst) if difference else None,
                note=f"{flip}{axis.words.split(' (')[0]} {axis.point(worst.value)}")
    return cells


def _convergence(df):
    rows = rows_matching(df, "the reference's step sweep", role="convergence")
    if len(rows) < 2:
        raise ValueError("fewer than two steps of the reference's own sweep")
    rows = rows.assign(step=numeric(rows, "value"), psnr=numeric(rows, "psnr")).sort_values("step", ascending=False)
    measured = ", ".join(f"{format_number(p)} dB at {s:g}" for s, p in zip(rows.step, rows.psnr))
    return ClaimResult(measured, bool((np.diff(rows.psnr.to_numpy()) > 0).all()),
                       "PSNR against the reference at 1/8 voxel, largest step first")


def _shearwarp_45(df):
    rows = rows_matching(df, "shear-warp's angle sweep", backend="shearwarp", axis="angle")
    if len(rows) < 3:
        raise ValueError("fewer than three angles of shear-warp's sweep")
    rows = rows.assign(angle=_values(rows), psnr=numeric(rows, "psnr"))
    worst = rows.loc[rows.psnr.idxmin()]
    return ClaimResult(f"worst at {worst.angle:g}° ({format_number(worst.psnr)} dB)", bool(worst.angle >= 35.0),
                       f"PSNR spread over the sweep {format_number(rows.psnr.max() - rows.psnr.min())} dB")


class Atlas(Experiment):
    """Every backend along every stress axis it supports, against the reference: where each one breaks."""

    name = "volbench-atlas"
    title = "Stability atlas: where each technique breaks"
    page = "atlas"
    atlas = True
    """The index's decision panel reads :meth:`failures` from the experiment that sets this."""
    settings = frozenset({"volume_size", "image_size", "axes"})
    scales = {"smoke": {"volume_size": 24, "image_size": 32},
              "default": {"volume_size": 48, "image_size": 64},
              "full": {"volume_size": 128, "image_size": 256}}
    description = (
        "One sweep per stress axis, each on one scene shared by every backend (same data, camera and transfer "
        "function), every point one untimed frame compared with the reference at 1/8 voxel. A backend without an "
        f"axis's feature or option is not run on it; its cell says why. A point below {PSNR_BREAKS:g} dB PSNR breaks; "
        f"{PSNR_GOOD:g} dB is accurate. Shear-warp and VolPack skip voxels below their ``min_opacity`` (0.05 by "
        "default), which drops the semi-transparent engine's casing on every scene: the min-opacity axis shows that, "
        "with the default in its sweep; every other axis runs them at min opacity 0, so that its column shows its own "
        "stress. On the TF axis the reference also runs pre-classified (voxels classified, then interpolated: "
        "shear-warp's order) at the truth's step, a row of its own: what the order of classification costs, apart "
        "from the shear-warp factorization. Two axes render iso-surfaces, so only the backends with an iso mode run "
        "on them: the step sweep on the engine's casting (its binary preset's isovalue), and the thin-feature axis, "
        "parallel tubes whose radius falls from 4 voxels to 1/4 voxel (the trilinear surface has that radius however "
        "thin), where a hit tested at samples a step apart starts to step over a tube. There gl-raycast also runs "
        "with the paper's sampled iso hit, a row of its own beside its default exact hit (every lattice cell a ray "
        "crosses solved, as the reference does). A third iso axis overlaps 1 to 7 smoke clouds, each with its own "
        "surface: the nearest first crossing of any of them, which only the multi-volume casters render."
    )
    claims = (
        Claim("reference-converges", "The reference converges: its error falls as its step shrinks",
              "PSNR against the 1/8-voxel reference rises with every halving of the step (1, 1/2, 1/4 voxel)",
              _convergence, kind="accuracy"),
        Claim("shearwarp-45", "Shear-warp's worst view is near 45°, where its principal axis switches",
              "the lowest PSNR of shear-warp's angle sweep lies at 35° or more", _shearwarp_45, kind="accuracy"),
    )

    def plan(self, profile):
        """``{axis key: points}``: the ``(value, scene, views)`` at this profile's scale of each axis of its ``axes``
        setting (keys of :data:`AXIS_BY_KEY`; default all)."""
        size, image = (int(value) for value in volume_and_image_size(profile, self))
        return {key: points(AXIS_BY_KEY[key], AXIS_BY_KEY[key].values[profile.scale], size=size, image=image)
                for key in listed(profile, self, "axes", [axis.key for axis in AXES], known=AXIS_BY_KEY)}

    def runs(self, profile):
        runs = []
        reasons = left_out()
        for key, planned in self.plan(profile).items():
            axis = AXIS_BY_KEY[key]
            values = axis.values[profile.scale]
            for index, (value, spec, views) in enumerate(planned):
                tags = {"axis": key, "scene": spec["name"], **({"value": value} if value is not None else {})}
                prefix = f"{key}.{index}"
                truth = dataclasses.replace(truth_run(self.name, prefix, spec, views, TRUTH_STEP, tags),
                                            interleave=f"{key}.truth")
                runs.append(truth)
                sweep = [(v, {axis.option: v}) for v in values] if axis.option else [(value, {})]
                # (backend, fixed options, name in ids and interleave groups, numbered): every backend at its
                # defaults, then the extra techniques, numbered only along a swept option so that a technique's
                # one run per point keeps the id it always had.
                players = [(backend, backend_options(axis, backend), backend, True) for backend in renderers.names()
                           if backend != REFERENCE and (backend, key) not in reasons]
                players += [(t.backend, {**backend_options(axis, t.backend), **t.options}, t.slug, bool(axis.option))
                            for label, t in TECHNIQUES.items() if (label, key) not in reasons]
                for backend, fixed, name, numbered in players:
                    for number, (point, swept) in enumerate(sweep):
                        run_tags = {**tags, "role": "test", **({"value": point} if point is not None else {})}
                        runs.append(Run(self.name, f"{prefix}.{name}" + (f".{number}" if numbered else ""), backend,
                                        spec, views, options={**fixed, **swept}, reference=truth.id, **UNTIMED,
                                        interleave=f"{key}.{name}", tags=run_tags))
                if key == "step":
                    runs += [Run(self.name, f"{prefix}.reference.{number}", REFERENCE, spec, views,
                                 options={"step_factor": step}, reference=truth.id, **UNTIMED,
                                 interleave=f"{key}.truth", tags={**tags, "role": "convergence", "value": step})
                             for number, step in enumerate(CONVERGENCE_STEPS)]
        return runs

    def failures(self, results):
        """``{backend: phrase}`` completing "fails when …" on the index (:func:`failure_phrases`)."""
        tests = atlas_rows(results)
        return failure_phrases(tests, sorted(set(tests.backend)))

    def report(self, results, ctx):
        from reports import plots  # matplotlib: only when the report is built

        tests, reasons = atlas_rows(results), left_out()
        out = [blocks.Takeaways(_takeaways(tests))]
        caption = (f"Each cell: the lowest PSNR against the reference over that axis's sweep, with the worst FLIP and "
                   f"where; red below {PSNR_BREAKS:g} dB (breaks), amber to {PSNR_GOOD:g} dB, green above (accurate). "
                   "A cell links to its sweep chart and shows the worst point's difference image (absolute error, full "
                   f"colour at {DIFF_SCALE:g}). Grey: the technique lacks the axis, and why.")
        for title, axes, rows, more in _heat_maps(technique_rows(), reasons):
            cells = heat_cells(tests, rows, reasons, unrendered=_unrendered(results), axes=axes,
                               difference=lambda row: ctx.difference(reference_exr(results, row), row.exr, DIFF_SCALE))
            out.append(blocks.HeatMap(title, rows, [axis.words for axis in axes], cells, caption=caption + more,
                                      thresholds=(PSNR_BREAKS, PSNR_GOOD)))
        for axis in AXES:
            rows = tagged(tests, axis=axis.key)
            out += _axis_blocks(axis, rows, results, ctx, plots) if not rows.empty else []
        if not tests.empty:
            named = {"value": "swept value", "axis_words": "axis"}
            table = tests.assign(axis_words=[AXIS_BY_KEY[k].words for k in tests.axis])
            out.append(linked_table("Every point", table.sort_values(["axis", "backend", "value"]),
                                    ["backend", "axis_words", "value", "psnr", "flip"], ctx, names=named,
                                    csv_name="atlas.csv",
                                    caption="One untimed frame per point; each row links to its run record and EXR."))
        return out


def _heat_maps(backends, reasons):
    """``[(title, axes, rows, caption addition)]``: the volume-rendering axes with every technique, then the
    iso-surface axes with the techniques that render iso-surfaces (those without are named once)."""
    volume = [axis for axis in AXES if axis.mode != "iso"]
    iso = [axis for axis in AXES if axis.mode == "iso"]
    maps = [("Worst PSNR of each technique on each axis", volume, backends, "")]
    if iso:
        keys = {axis.key for axis in iso}
        lacking = [b for b in backends
                   if b not in TECHNIQUES and "iso" not in renderers.backend_class(b).capabilities.modes]
        elsewhere = [b for b in backends if b in TECHNIQUES and not keys & set(TECHNIQUES[b].axes)]
        rows = [b for b in backends if b not in lacking + elsewhere]
        more = "".join([f" Not on these axes, without an iso-surface mode: {', '.join(lacking)}." if lacking else "",
                        *(f" {b}: {TECHNIQUES[b].elsewhere}." for b in elsewhere)])
        maps.append(("Worst PSNR on the iso-surface axes", iso, rows, more))
    return maps


@functools.lru_cache(maxsize=1)
def left_out():
    """``{(technique, axis key): reason}`` for every backend or :data:`TECHNIQUES` row left out of an axis, judged on
    every value of every scale at once (a backend lacks a feature or an option, not a size), so that the plan and
    the report agree whatever profile made the results."""
    reasons = {}
    for axis in AXES:
        values = sorted({v for scale in axis.values.values() for v in scale})
        planned = points(axis, values, size=32, image=32)
        whys = {backend: axis_reason(axis, backend, planned) for backend in renderers.names() if backend != REFERENCE}
        whys.update({label: axis_reason(axis, t.backend, planned) if axis.key in t.axes else t.elsewhere
                     for label, t in TECHNIQUES.items()})
        reasons.update({(name, axis.key): why for name, why in whys.items() if why})
    return reasons


def _unrendered(results):
    """``{(technique, axis key): reason}`` of the first run of each that made no frame."""
    if "status" not in results or "axis" not in results:
        return {}
    missed = results[(results.status != "ok") & results.axis.notna()]
    return {(technique, row.axis): short(str(row.reason)) for technique, row in zip(techniques(missed),
                                                                                    missed.itertuples())}


def _takeaways(tests):
    """At most five sentences: the thresholds, the techniques that never break, the worst axis."""
    if tests.empty:
        return ["No atlas point rendered here; the table of skipped runs says why."]
    phrases = failure_phrases(tests, sorted(set(tests.backend)))
    failing = {b: p for b, p in phrases.items() if not p.startswith("no axis")}
    holding = [b for b in phrases if b not in failing]
    out = [f"A point breaks below {PSNR_BREAKS:g} dB PSNR against the reference and is accurate from {PSNR_GOOD:g} dB."]
    if failing:
        out.append("Below " + f"{PSNR_BREAKS:g} dB: " + "; ".join(f"{b} once {p}" for b, p in failing.items()) + ".")
    if holding:
        worst = tests[tests.backend.isin(holding)].groupby("backend").psnr.min()
        out.append(f"Never below {PSNR_BREAKS:g} dB on any axis: "
                   + ", ".join(f"{b} (worst {format_number(worst[b])} dB)" for b in holding) + ".")
    per_axis = tests.groupby(["axis", "backend"]).psnr.min().groupby("axis")
    broken = per_axis.apply(lambda s: int((s < PSNR_BREAKS).sum()))
    median = per_axis.median()
    worst_axis = max(broken.index, key=lambda k: (broken[k], -median[k]))
    out.append(f"The worst axis overall is {AXIS_BY_KEY[worst_axis].words.split(' (')[0]}: "
               f"{broken[worst_axis]} of {per_axis.size().get(worst_axis, 0)} techniques break on it "
               f"(median worst PSNR {format_number(median[worst_axis])} dB).")
    return out[:5]


def _breaking_points(axis, rows):
    """One sentence: where each technique on ``axis`` falls below 30 dB (its :func:`threshold`), or that none does."""
    found = {backend: threshold(mine, axis) for backend, mine in rows.groupby("backend")}
    broken = [f"{backend} once {hit['words']} ({format_number(hit['psnr'])} dB)"
              for backend, hit in found.items() if hit]
    held = [backend for backend, hit in found.items() if not hit]
    if not broken:
        return f"No technique falls below {PSNR_BREAKS:g} dB here."
    return (f"Below {PSNR_BREAKS:g} dB: " + "; ".join(broken) + "."
            + (f" Never below it: {'; '.join(held)}." if held else ""))


def _axis_blocks(axis, rows, results, ctx, plots):
    """One axis: its sweep chart (anchored for the heat map) and a gallery of each backend's worst point."""
    path, rel = ctx.plot_path(axis.key)
    low, high, name = float(rows.value.min()), float(rows.value.max()), axis.words.split(" (")[0].capitalize()
    guides = [(f"{PSNR_BREAKS:g} dB (breaks)", [low, high], [PSNR_BREAKS] * 2),
              (f"{PSNR_GOOD:g} dB (accurate)", [low, high], [PSNR_GOOD] * 2)]
    below = sorted(set(rows[rows.psnr < PSNR_BREAKS].backend))
    plots.lines(rows.sort_values("value"), path, x="value", y="psnr", group="backend",
                title=f"{name}: {len(below)} of {rows.backend.nunique()} techniques fall below {PSNR_BREAKS:g} dB",
                x_label=axis.words, y_label="PSNR against the reference (dB)", guides=guides,
                log_x=axis.log_x and low > 0)
    out = [blocks.Figure(f"{name} on {axis.scene_words}", rel,
                         f"PSNR against the reference at each point, one line per technique; grey lines at "
                         f"{PSNR_BREAKS:g} dB (breaks) and {PSNR_GOOD:g} dB (accurate). {_breaking_points(axis, rows)}",
                         anchor=f"atlas-{axis.key}")]
    worst = rows.loc[[mine.psnr.idxmin() for _, mine in rows.groupby("backend")]]
    return out + [difference_gallery(
        f"{name}: each technique's worst point", worst, ctx, against=results,
        label=lambda row: f"{row.backend} at {axis.point(row.value)}",
        note=lambda row: f"PSNR {format_number(row.psnr)} dB" + (f", FLIP {format_number(row.flip)}"
                                                                 if pd.notna(row.flip) else ""))]
