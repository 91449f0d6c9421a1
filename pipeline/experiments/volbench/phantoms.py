"""``volbench-phantoms``: every data set rendered by the reference, with the statistics the papers use, each phantom
beside the real scan it stands in for (:data:`STAND_INS`)."""

from dataclasses import dataclass, field, replace

import pandas as pd

import datasets
from datasets.stats import BOX_STATISTICS, in_box
from pipeline.experiments.kit.checks import Band, Measure
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, Run
from pipeline.experiments.kit.pages import difference_gallery, format_number, frames_note, linked_table
from pipeline.experiments.kit import planning
from pipeline.experiments.kit.planning import HEADLINE_VIEW, REFERENCE, UNTIMED, UPRIGHT, scene
from pipeline.experiments.kit.results import tagged
from reports import blocks

REAL_UPRIGHT = {
    "cthead": {"rotate": {"axis": [0, 1, -1], "degrees": 180}},
    "mrihead": {"rotate": {"axis": [0, 1, 1], "degrees": 180}},
    "brainsmall": {"rotate": {"axis": [1, 0, -1], "degrees": 180}},
}
"""The gallery's turn of real scans stored otherwise than the phantoms (body axis z, face −y), so that each stands as
its phantom does: cthead's crown is slice 0, mrihead faces +y, brainsmall is stacked in sagittal slices (x front → back,
y crown → neck). Each is a half turn (mirroring x, which no scan here labels)."""


@dataclass(frozen=True)
class StandIn:
    """The real scan a phantom stands in for, the presets both have, and the phantom request
    that matches the scan's voxel size (``size`` voxels along the longest axis, ``params``)."""

    real: str
    presets: tuple
    size: int | None = None
    params: dict = field(default_factory=dict)


STAND_INS = {
    "ct_skull": StandIn("cthead", ("bone", "skin")),
    "mri_head": StandIn("mrihead", ("skin",)),
    "engine": StandIn("engine_real", ("semi", "surfaces")),
    "bonsai_like": StandIn("bonsai", ("tree", "isbvr")),
    "folded_brain": StandIn("brainsmall", ("volpack",), size=128, params={"decimate": 2}),
}
"""Phantom → the real scan of its kind it stands in for: shown side by side, compared by :func:`_target_claims`."""

RELATIVE_BAND = 0.25
"""A phantom's statistic holds within ±25 % of its target ..."""

ABSOLUTE_FLOOR = {"nontransparent_fraction": 0.005, "nonzero_fraction": 0.005, "empty_block_fraction": 0.02,
                  "runs_per_scanline": 0.1, "mean_run_length": 0.5}
"""... or within this absolute distance where wider, so that a band around a target near 0 still means something."""


class PhantomGallery(Experiment):
    """Every data set rendered by the reference with its default preset, with its statistics."""

    name = "volbench-phantoms"
    title = "Data sets: statistics and gallery"
    settings = frozenset({"datasets", "volume_size", "image_size", "step_factor", "statistics_size", "all_presets"})
    scales = {
        "smoke": {"datasets": ["ct_skull", "cthead", "engine", "sphere", "checkerboard", "nucleon", "brainsmall"],
                  "step_factor": 1.0, "statistics_size": 32},
        "default": {"volume_size": 256, "image_size": 256, "step_factor": 0.5},
        "full": {"all_presets": True, "step_factor": 0.25},
    }
    description = (
        "Every synthetic stand-in and every real scan, rendered by the reference renderer with its default preset "
        "(Blinn–Phong, headline view) so that a person can judge how CT-like the phantoms look, next to the statistics "
        "the papers use: the fraction of non-transparent voxels (α > 0.05, the thesis's threshold), the fraction of "
        "empty 8³ blocks and the mean number of non-transparent runs per scanline. Statistics are taken at the size of "
        "the original data set (256³ for most), where the reproduction notes' targets apply."
    )

    @property
    def claims(self):
        return _target_claims()

    def runs(self, profile):
        wanted = profile.setting(self, "datasets", "all")
        names = datasets.names() if wanted == "all" else wanted
        size, image_size = planning.volume_and_image_size(profile, self)
        step_factor = profile.setting(self, "step_factor", 0.5)
        stats_size = profile.setting(self, "statistics_size", "paper")
        stood_in = {}
        for stand_in in STAND_INS.values():
            stood_in.setdefault(stand_in.real, []).extend(stand_in.presets)
        runs = []
        for name in names:
            spec = datasets.get(name)
            stand_in = STAND_INS.get(name)
            if profile.setting(self, "all_presets", False):
                presets = list(spec.presets)
            else:  # the default, every preset with targets and every one a stand-in is compared under
                presets = list(dict.fromkeys([spec.default_preset, *spec.targets_by_preset,
                                              *(stand_in.presets if stand_in else ()), *stood_in.get(name, ())]))
            for preset in presets:
                upright = REAL_UPRIGHT.get(name, UPRIGHT if spec.up_axis == "z" else None)
                volume = planning.phantom(name, size, preset=preset, **({"transform": upright} if upright else {}))
                # Statistics at the original data set's size, where the notes' targets apply; a
                # stand-in under a preset it shares with its real scan at the scan's voxel size.
                if stand_in and preset in stand_in.presets and stats_size == "paper":
                    extra = {"params": stand_in.params} if stand_in.params else {}
                    measured = planning.phantom(name, stand_in.size or spec.default_size, preset=preset, **extra)
                else:
                    measured = planning.phantom(name, spec.default_size if stats_size == "paper" else stats_size,
                                                preset=preset)
                runs.append(Run(self.name, f"{name}.{preset}", REFERENCE, scene(name, image_size, volumes=[volume]),
                                (HEADLINE_VIEW,), options={"step_factor": step_factor}, **UNTIMED, statistics=measured,
                                tags={"dataset": name, "preset": preset, "kind": spec.kind}))
        return runs

    def report(self, results, ctx):
        ok = results[results.status == "ok"]
        stat_cols = [c for c in ok.columns if c.startswith("stat_")]
        table = ok[["dataset", "kind", "preset", *stat_cols]].rename(columns=lambda c: c.removeprefix("stat_"))
        shown = [c for c in ("dataset", "kind", "preset", "size", *BOX_STATISTICS, "megabytes", "generation_seconds")
                 if c in table]
        targets = [{"dataset": name, "preset": preset, "statistic": stat, "target": value}
                   for name in table.dataset.unique() for preset, stats in datasets.get(name).targets_by_preset.items()
                   for stat, value in stats.items()]
        table.reset_index(drop=True).to_csv(ctx.report_dir / "csv" / "phantom_statistics_all.csv", index=False)
        out = [blocks.Takeaways(_gallery_takeaways(results)),
               linked_table("Statistics under each rendered preset",
                            pd.concat([table, ok.reindex(columns=["record", "exr"])], axis=1), shown, ctx,
                            names={"generation_seconds": "generation (s)"},
                            caption="Non-transparent: α > 0.05; empty block: an 8³ block with no voxel of α > 0; "
                                    "runs per scanline: runs of non-transparent voxels along x (VolPack's c_v); "
                                    "generation: the phantom generator's wall time when it was generated (it is "
                                    "cached after that). Every statistic is in csv/phantom_statistics_all.csv; "
                                    "each row links to its run's JSON record and EXR image.",
                            csv_name="phantom_statistics.csv")]
        compared = _stand_in_comparison(ok)
        if not compared.empty:
            out.append(blocks.Table(
                "Stand-ins against their real scans, in the same box", compared,
                caption="Each real scan is placed, centred, in its phantom's box at the scan's voxel size "
                        "(datasets.stats.in_box: padding with transparent voxels scales the fractions by the "
                        "scan's share of the box and runs per scanline by its share of the scanlines; an "
                        "anisotropic scan such as cthead counts as resampled to its finest spacing). The claim "
                        f"holds within ±{RELATIVE_BAND:.0%} of the real value, or the absolute floor where wider.",
                csv_name="stand_in_statistics.csv"))
        if targets:
            out.append(blocks.Table("Targets from the reproduction notes", pd.DataFrame(targets),
                                    caption="What each stand-in was tuned towards where no real scan of its kind "
                                            "is at hand (the papers' data sets); a preset a stand-in shares with "
                                            "its real scan is compared with the scan instead."))
        paired = set()
        pairs = blocks.Gallery(
            "Phantoms beside the real scans they stand in for",
            caption="Same view (30° yaw, 20° pitch), same orientation (body axis up) and the same preset; "
                    "left the generated phantom, right the real scan, with both statistics rows (the real "
                    "scan's in the phantom's box). Click an image for full size.")
        for phantom, stand_in in STAND_INS.items():
            for preset in stand_in.presets:
                match = ok[(ok.dataset == phantom) & (ok.preset == preset)]
                real_rows = ok[(ok.dataset == stand_in.real) & (ok.preset == preset)]
                if match.empty or real_rows.empty:
                    continue
                row, real_row = next(match.itertuples()), next(real_rows.itertuples())
                paired.update({row.run, real_row.run})
                real_spec = datasets.get(stand_in.real)
                pairs.items.append(blocks.GalleryItem(
                    caption=f"{phantom} stands in for {stand_in.real} ({real_spec.modality}) — preset {preset}",
                    image=ctx.image(row.png), label=f"phantom {phantom}",
                    extra=((f"real scan {stand_in.real}", ctx.image(real_row.png)),),
                    note=f"{_statistics_rows(compared, phantom, preset)} {datasets.get(phantom).description} "
                         f"Real: {real_spec.description} Both: {frames_note(row)}."))
        if pairs.items:
            out.append(pairs)
        return out + [difference_gallery("Every reference render (headline view)", ok[~ok.run.isin(paired)], ctx,
                                         label=lambda row: f"{row.dataset} — {row.preset}", note=_render_note,
                                         caption="Each a single untimed frame (no warm-up): pictures to judge, not "
                                                 "timings. Click an image for full size.")]


def _render_note(row):
    """What a reference render shows, in words: the data set (a phantom or a real scan) and how it was timed."""
    spec = datasets.get(row.dataset)
    what = (f"Phantom: {spec.description}" if spec.kind == "phantom"
            else f"Real scan ({spec.modality}): {spec.description}")
    return f"{what} {frames_note(row).capitalize()}."


def _statistics_row(df, name, preset):
    """``{statistic: value}`` measured for data set ``name`` under ``preset`` (``None`` if not run)."""
    rows = tagged(df, dataset=name, preset=preset)
    if rows.empty:
        return None
    row = rows.iloc[0]
    return {k.removeprefix("stat_"): row[k] for k in rows.columns if k.startswith("stat_") and pd.notna(row[k])}


def _real_in_box(df, phantom, preset):
    """``(phantom_stats, real_stats, real_in_box)``: the real scan's :data:`BOX_STATISTICS` placed in ``phantom``'s
    box, with both own, or why they do not compare: a side not measured, or a phantom measured at another size than
    the scan's voxels (profiles that shrink ``statistics_size``)."""
    stand_in = STAND_INS[phantom]
    mine, real = _statistics_row(df, phantom, preset), _statistics_row(df, stand_in.real, preset)
    if mine is None or real is None:
        return f"{phantom if mine is None else stand_in.real} ({preset}) not measured"
    expected = stand_in.size or datasets.get(phantom).default_size
    if int(mine.get("size", 0)) != expected:
        return f"{phantom} measured at size {mine.get('size')}, not at the real scan's voxel size ({expected})"
    return mine, real, in_box(real, (int(mine["nx"]), int(mine["ny"]), int(mine["nz"])))


REAL_IN_BOX = "real, phantom's box"
"""Column of the real scan's statistic placed in its phantom's box."""


def _band(stat, target):
    """Half-width of the band a statistic must fall in: relative, with an absolute floor."""
    return max(RELATIVE_BAND * abs(target), ABSOLUTE_FLOOR.get(stat, 0.0))


def _stand_in_comparison(ok):
    """One row per stand-in, shared preset and statistic: phantom, real scan, real scan in the phantom's box."""
    rows = []
    for phantom, stand_in in STAND_INS.items():
        for preset in stand_in.presets:
            measured = _real_in_box(ok, phantom, preset)
            if isinstance(measured, str):
                continue
            mine, real, boxed = measured
            for stat in BOX_STATISTICS:
                rows.append({"phantom": phantom, "real scan": stand_in.real, "preset": preset, "statistic": stat,
                             "phantom value": mine[stat], "real, own box": real[stat], REAL_IN_BOX: boxed[stat],
                             "difference": f"{mine[stat] / boxed[stat] - 1:+.0%}" if boxed[stat] else "n/a",
                             "within band": bool(abs(mine[stat] - boxed[stat]) <= _band(stat, boxed[stat]))})
    return pd.DataFrame(rows)


def _statistics_rows(compared, phantom, preset):
    """The phantom's and the real scan's statistics as two short rows for a gallery note."""
    rows = tagged(compared, phantom=phantom, preset=preset)
    if rows.empty:
        return ""
    names = {"nontransparent_fraction": "non-transparent", "empty_block_fraction": "empty 8³ blocks",
             "runs_per_scanline": "runs/scanline", "mean_run_length": "mean run"}
    records = rows.to_dict("records")
    mine = ", ".join(f"{names[r['statistic']]} {format_number(r['phantom value'])}" for r in records)
    real = ", ".join(f"{names[r['statistic']]} {format_number(r[REAL_IN_BOX])}" for r in records)
    return f"Phantom: {mine}. Real scan in the same box: {real}."


def _gallery_takeaways(results):
    """What the gallery shows, counted: how many phantoms and real scans, which pairs, which statistics miss."""
    per_run = results.drop_duplicates("run")
    ok = per_run[per_run.status == "ok"]
    sentences = []
    if "kind" in ok:
        phantoms, reals = int((ok.kind == "phantom").sum()), int((ok.kind == "real").sum())
        sentences.append(f"{ok.dataset.nunique()} data sets rendered under {len(ok)} presets: "
                         f"{phantoms} phantom renders and {reals} renders of real scans.")
        pairs = [f"{p} ↔ {s.real}" for p, s in STAND_INS.items() if {p, s.real} <= set(ok.dataset)]
        if pairs:
            many = len(pairs) != 1
            sentences.append(f"{len(pairs)} phantom{'s are' if many else ' is'} shown beside the real scan "
                             f"{'they stand' if many else 'it stands'} in for ({', '.join(pairs)}).")
        compared = _stand_in_comparison(ok)
        if not compared.empty:
            missed = compared[~compared["within band"].astype(bool)]
            held = len(compared) - len(missed)
            sentence = (f"{held} of {len(compared)} stand-in statistics fall within ±{RELATIVE_BAND:.0%} of the real "
                        f"scan's in the same box")
            if not missed.empty:
                sentence += "; outside: " + ", ".join(
                    f"{r['phantom']} {r['preset']} {r['statistic']} {format_number(r['phantom value'])} "
                    f"vs {format_number(r[REAL_IN_BOX])}" for r in missed.to_dict("records"))
            sentences.append(sentence + ".")
    return sentences


def _real_says(df, phantom, stat):
    """Why a stand-in may miss a notes' target: what its real scan shows under the presets they share."""
    if phantom not in STAND_INS:
        return ""
    boxed = {preset: _real_in_box(df, phantom, preset) for preset in STAND_INS[phantom].presets}
    seen = [f"{preset} {format_number(measured[2][stat])}" for preset, measured in boxed.items()
            if not isinstance(measured, str) and stat in measured[2]]
    real = STAND_INS[phantom].real
    if not seen:
        return f"; the phantom follows the real {real} where the two disagree (see the stand-in claims)"
    return f"; the real {real} in the same box: {', '.join(seen)} (the phantom follows the real scan)"


class NotesTarget(Band):
    """A phantom's statistic within a band around the reproduction notes' target; its detail also says what a
    stand-in's real scan shows (:func:`_real_says`): where the two disagree, the phantom follows the real scan."""

    def __call__(self, df):
        result = super().__call__(df)
        name, stat = self.measure.match["dataset"], self.measure.column.removeprefix("stat_")
        return replace(result, detail=f"target {self.expected}{_real_says(df, name, stat)}")


def _target_claims():
    """The statistics claims: a stand-in under a preset it shares with its real scan against the scan placed in the
    phantom's box (:func:`datasets.stats.in_box`), each of :data:`BOX_STATISTICS`; every other target a phantom
    declares from the reproduction notes."""
    claims = []
    for phantom, stand_in in STAND_INS.items():
        for preset in stand_in.presets:
            for stat in BOX_STATISTICS:
                def check(df, phantom=phantom, preset=preset, stat=stat, real=stand_in.real):
                    measured = _real_in_box(df, phantom, preset)
                    if isinstance(measured, str):
                        return ClaimResult("not measured", None, measured)
                    mine, _, boxed = measured
                    band = _band(stat, boxed[stat])
                    return ClaimResult(format_number(mine[stat]), bool(abs(mine[stat] - boxed[stat]) <= band),
                                       f"{real} in the same box {format_number(boxed[stat])} ± {format_number(band)}")
                claims.append(Claim(f"{phantom}.{preset}-{stat}-vs-{stand_in.real}",
                                    f"{phantom} ({preset}): {stat} like the real {stand_in.real}'s",
                                    f"{stand_in.real}'s value in the same box ± {RELATIVE_BAND:.0%}", check,
                                    kind="count"))
    for name in datasets.names(kind="phantom"):
        compared = STAND_INS[name].presets if name in STAND_INS else ()
        for preset, stats in datasets.get(name).targets_by_preset.items():
            for stat, target in stats.items():
                if preset in compared and stat in BOX_STATISTICS:
                    continue
                check = NotesTarget(Measure(f"{name} ({preset}) {stat}", match={"dataset": name, "preset": preset},
                                            column=f"stat_{stat}", unit=""),
                                    target, RELATIVE_BAND, ABSOLUTE_FLOOR.get(stat, 0.0))
                claims.append(Claim(f"{name}.{preset}-{stat}", f"{name} ({preset}): {stat} near the original's",
                                    check.expected, check))
    return tuple(claims)


