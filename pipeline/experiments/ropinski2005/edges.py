"""``ropinski2005-edges`` (E8): where the lens lies against the volume and the camera, and no holes."""

import numpy as np
import pandas as pd

from core.camera import Camera
from core.errors import InputError
from pipeline.experiments.kit.judging import counted, measured, median_count, worst_of
from pipeline.experiments.kit.model import SIZES, Claim, ClaimResult
from pipeline.experiments.kit.pages import (as_percent, claim_takeaways, difference_gallery, format_number,
                                            linked_table, unless_missing)
from pipeline.experiments.kit.planning import UNTIMED, headline_view, listed, truth_run
from pipeline.experiments.kit.results import (nonempty_or, numeric, ok_rows, read_exr, reference_exr, rows_matching,
                                              text_column)
from pipeline.experiments.ropinski2005.correctness import ACCURACY_PSNR, NO_TERMINATION
from pipeline.experiments.ropinski2005.methods import (CONFIGS, STEP, LensExperiment, lens_coverage, lens_run,
                                                       lens_settings, raycast_not_measurable)
from pipeline.experiments.ropinski2005.pages import RUN_COLUMNS, psnr_note, tests_of
from pipeline.experiments.ropinski2005.scenes import SETUPS, LensSetup, extent, lens_entry, lens_scene, scene_tags
from reports import blocks

SCENE = "seismic"
"""The cube filled to its faces (note 004 §5): every pixel of its footprint is covered, so a hole shows."""

APPEARANCE = {"mode": "dvr", "preset": "layers", "opacity_scale": 0.2}
"""A transparency lens: every region contributes, so a region missing or counted twice changes the image."""

COVERED = 0.1
"""Alpha at or above which the reference covers a pixel."""

HOLE = 0.1
"""A covered pixel is a hole where the method's alpha is below this share of the reference's (a region left
out empties a pixel of the filled cube; a lens boundary a voxel off changes its alpha far less)."""

GRAZING_VIEW = {"view": "axis", "azimuth": 0.0, "elevation": 0.0}
"""Looking down the world's −z axis: the rays run parallel to four faces of an axis-aligned box lens."""

GRAZING_VIEW_HEIGHT = 1.2
"""The grazing case's picture height, in edges (orthographic): the box's footprint and a margin."""

CAMERA_DISTANCE = 2.2
"""The camera's distance from the box centre in the enclosing-camera case, in edges (perspective, 30° field
of view: the picture shows ±0.59 edges at the box centre)."""


CASES = {
    "partly-front": "a sphere around the box corner nearest the camera: partly inside, partly in front and beside",
    "partly-behind": "a sphere around the farthest corner: partly inside, partly behind (the guide's regression test "
                     "for the hole)",
    "in-front": "a sphere wholly between the camera and the box: lens ∩ box is empty",
    "behind": "a sphere wholly behind the box: lens ∩ box is empty, and the paper's transition images give its rays "
              "no region (note 004 §2.8)",
    "enclosing-volume": "a sphere enclosing the whole box: region₁ is every ray's whole span",
    "enclosing-camera": "perspective, a sphere around the camera reaching past the box centre: every ray starts inside "
                        "the lens",
    "grazing": "an axis-aligned box lens from the top face down to the centre, seen from above: rays parallel to four "
               "of its faces, the faces on pixel centres",
}
"""The edge cases of note 004 §4.1 (9), in report order: where each lens lies, in words (placed by
:func:`case_scene`)."""


def toward_camera(view):
    """The unit vector from the box centre towards the camera of ``view`` (a view mapping)."""
    return np.asarray(Camera(azimuth=view["azimuth"], elevation=view["elevation"],
                             up=tuple(view.get("up", (0.0, 1.0, 0.0)))).basis()[2], float)


def grazing_size(image):
    """The box lens's edge (a fraction of the box's) whose faces lie on pixel centres of an ``image``² picture.

    The grazing view's picture is :data:`GRAZING_VIEW_HEIGHT` edges high, so pixel centres lie at
    ``(k + ½)·p`` from the middle, ``p = height / image``; the face nearest a quarter edge out is taken.
    """
    pitch = GRAZING_VIEW_HEIGHT / image
    k = max(0, round(0.25 / pitch - 0.5))
    return 2 * (k + 0.5) * pitch


def case_scene(case, image, *, size, real_data=None):
    """``(scene mapping, view)`` of edge case ``case`` (a key of :data:`CASES`)."""
    if case not in CASES:
        raise InputError(f"unknown edge case {case!r}; known: {', '.join(CASES)}")
    setup = SETUPS[SCENE]
    box = extent(setup.dataset, size, real_data=real_data)
    if case == "grazing":
        side = grazing_size(image)
        spec = lens_scene(SCENE, image, size=size, real_data=real_data)
        # From above the top face (z) down to the centre, so that nothing opaque lies in front of it.
        lens = LensSetup(setup.dataset, setup.preset, "box", (0.0, 0.0, 0.3), APPEARANCE, size=(side, side, 0.6))
        spec["lenses"] = [lens_entry(lens, box)]
        spec["camera"] = {"view_height": round(GRAZING_VIEW_HEIGHT * max(box), 6)}
        view = GRAZING_VIEW
    else:
        view = headline_view(setup.dataset)
        toward = toward_camera(view)  # the sphere's centre and radius, fractions of the edge
        corner = 0.5 * np.sign(toward)
        far = np.sqrt(3) / 2 + 0.25 + 0.05  # the box's bounding sphere, the lens's radius and a margin
        center, radius = {"partly-front": (corner, 0.35), "partly-behind": (-corner, 0.35),
                          "in-front": (far * toward, 0.25), "behind": (-far * toward, 0.25),
                          "enclosing-volume": (np.zeros(3), 0.9),
                          "enclosing-camera": (CAMERA_DISTANCE * toward, CAMERA_DISTANCE - 0.25)}[case]
        spec = lens_scene(SCENE, image, size=size, real_data=real_data, appearance=APPEARANCE,
                          center=tuple(float(c) for c in center), radius=radius)
        if case == "enclosing-camera":
            spec["camera"] = {"projection": "perspective", "distance": round(CAMERA_DISTANCE * max(box), 6)}
    spec["name"] = f"{SCENE}-{case}"
    return spec, view


def coverage_holes(reference, test):
    """``(holes, covered)``: pixels the reference covers (alpha ≥ :data:`COVERED`) that ``test`` leaves below
    :data:`HOLE` of the reference's alpha, and the pixels the reference covers."""
    ref_alpha, test_alpha = np.asarray(reference)[..., 3], np.asarray(test)[..., 3]
    covered = ref_alpha >= COVERED
    return int(np.count_nonzero(covered & (test_alpha < HOLE * ref_alpha))), int(np.count_nonzero(covered))


def hole_counts(frame):
    """Per test row of ``frame``: its hole pixels and the reference's covered pixels (reads both images)."""
    out = []
    for row in rows_matching(frame, "the lens methods' runs", role="test").itertuples():
        reference = reference_exr(frame, row)
        if reference is None:
            raise ValueError(f"run {row.run} ({row.view}): its reference {row.reference} did not render")
        holes, covered = coverage_holes(read_exr(reference), read_exr(row.exr))
        out.append({"case": row.case, "config": row.config, "view": row.view, "holes": holes, "covered": covered})
    return pd.DataFrame(nonempty_or(out, "no lens method's run to compare with the reference"))


def _no_holes(df):
    counts = hole_counts(df)
    worst, per_case = worst_of(counts, "holes", "case")
    return ClaimResult(f"{int(worst.holes)} hole pixels of {int(worst.covered)} covered ({worst.config}, {worst.case})",
                       bool(counts.holes.max() == 0), ", ".join(f"{c}: {int(h)}" for c, h in per_case.items())
                       + f" (most hole pixels per case over {counts.config.nunique()} methods); a hole: alpha below "
                         f"{as_percent(HOLE)} of the reference's where the reference's is ≥ {format_number(COVERED)}")


def _accuracy(df):
    rows = measured(rows_matching(df, "the lens methods' runs", role="test"), "psnr",
                    "no lens method's image compared with the reference")
    worst, per_case = worst_of(rows, "psnr", "case", lowest=True)
    return ClaimResult(f"{format_number(worst.psnr)} dB ({worst.config}, {worst.case})",
                       bool(rows.psnr.min() >= ACCURACY_PSNR),
                       ", ".join(f"{c}: ≥ {format_number(p)} dB" for c, p in per_case.items())
                       + f" (worst method per case); step {format_number(STEP)} voxel")


def _hole_closed(df):
    stencil = rows_matching(df, "segments-stencil's runs", role="test", config="segments-stencil")
    behind = nonempty_or(stencil[text_column(stencil, "case") == "behind"],
                         "no successful segments-stencil run of the fully-behind lens")
    rays = counted(behind, "count_hole_rays", "segments-stencil")
    counts = hole_counts(df)
    holes = int(counts[(counts.case == "behind") & (counts.config == "segments-stencil")].holes.max())
    others = {case: median_count(part, "count_hole_rays") for case, part in stencil.groupby("case", sort=False)}
    return ClaimResult(f"{format_number(rays)} rays without a region, {holes} hole pixels",
                       bool(rays > 0 and holes == 0),
                       "hole_rays per case: " + ", ".join(f"{c}: {format_number(n)}" for c, n in others.items()))


CLAIMS = (
    Claim("no-holes", "No lens method leaves a hole, wherever the lens lies against the box and the camera (note 004 "
          "§4.2 E8)", f"no pixel whose reference alpha is ≥ {format_number(COVERED)} has a method's alpha below "
          f"{as_percent(HOLE)} of it, every method and edge case", _no_holes, kind="accuracy"),
    Claim("edges-accurate", "And each renders the reference's image in every edge case",
          f"PSNR ≥ {format_number(ACCURACY_PSNR)} dB against the reference, every method and edge case", _accuracy,
          kind="accuracy"),
    Claim("hole-closed", "The paper's transition images give a lens wholly behind the box's rays no region (note 004 "
          "§2.8); the stencil method finds those rays and renders their region₀",
          "segments-stencil: hole_rays > 0 in the fully-behind case, and no hole pixel there", _hole_closed,
          kind="count"),
)


def case_table(tests, counts):
    """Per case and method: PSNR, hole pixels, coverage and counters."""
    rows = []
    for (case, config), part in tests.groupby(["case", "config"], sort=False):
        mine = counts[(counts.case == case) & (counts.config == config)]  # none: their maxima are NaN
        rows.append({"case": case, "method": config,
                     "PSNR (dB)": numeric(part, "psnr").min() if "psnr" in part else np.nan,
                     "max |difference|": numeric(part, "max_error").max() if "max_error" in part else np.nan,
                     "hole pixels": mine.holes.max(), "covered pixels": mine.covered.max(),
                     "rays through the lens (%)": 100 * lens_coverage(part),
                     "hole rays (stencil)": median_count(part, "count_hole_rays")})
    return pd.DataFrame(rows)


class Edges(LensExperiment):
    name = "ropinski2005-edges"
    title = "Edge cases: where the lens lies against the volume and the camera (E8)"
    settings = frozenset({"cases", "methods", "volume_size", "image_size"})
    scales = SIZES
    description = (
        "Not in the paper, whose recipe misses one case (note 004 §2.8): a ray whose lens lies wholly behind the "
        "box is marked \"no region₀\" by transition₀ and has an empty lens ∩ box, so no region renders it. The "
        "seismic cube (filled to its faces, so every pixel of its footprint is covered) gets a transparency "
        "lens placed, from the case's one view, around the corner nearest the camera and around the farthest one "
        "(partly outside), wholly in front of the box and wholly behind it, around the whole box, around the "
        "camera (perspective), and as an axis-aligned box seen along its axis with its faces on pixel centres "
        "(grazing rays). The reference renders each case exactly; every lens method of gl-raycast renders it "
        "too and is compared by PSNR and by coverage: a hole is a pixel the reference covers that the method "
        "leaves nearly empty. Early termination is off (the reference never ends a ray early: note E7). "
        "segments-stencil counts the rays the paper's transition images give no region."
    )
    claims = CLAIMS

    def lens_runs(self, profile):
        cases = listed(profile, self, "cases", tuple(CASES), known=CASES)
        methods = listed(profile, self, "methods", CONFIGS, known=CONFIGS)
        size, image, _, _ = lens_settings(profile, self)
        runs = []
        for case in cases:
            spec, view = case_scene(case, image, size=size, real_data=profile.real_data)
            tags = scene_tags(SCENE, image_size=image, case=case)
            truth = truth_run(self.name, case, spec, (view,), STEP, tags)
            runs.append(truth)
            for method in methods:
                runs.append(lens_run(self.name, f"{case}.{method}", spec, (view,), method, UNTIMED,
                                     {**tags, "role": "test"}, group=case, reference=truth.id, options=NO_TERMINATION))
        return runs

    def report(self, results, ctx):
        ok = ok_rows(results)
        tests = tests_of(ok)
        out = [claim_takeaways(ctx)]
        if not tests.empty:
            counts = unless_missing(hole_counts, ok, empty=pd.DataFrame(columns=["case", "config", "holes", "covered"]))
            out.append(blocks.Table("Each case and method against the reference", case_table(tests, counts).round(3),
                                    csv_name="edges.csv",
                                    caption="Hole pixels: covered by the reference (alpha ≥ "
                                            f"{format_number(COVERED)}) and below {as_percent(HOLE)} of its alpha "
                                            "in the method's image. Hole rays: rays the paper's transition images "
                                            "give no region (segments-stencil only; it renders their region₀). "
                                            "One untimed frame per run, early termination off."))
            out.append(difference_gallery("The reference's image of each case", ok[text_column(ok, "role") == "truth"],
                                          ctx, label=lambda row: str(row.case), note=lambda row: "",
                                          caption="; ".join(f"{name}: {what}" for name, what in CASES.items())))
            out.append(difference_gallery(
                "Every edge case: each method's image and its difference from the reference", tests, ctx,
                against=results, label=lambda row: f"{row.case}, {row.config}", note=psnr_note,
                caption="Left the method's image, right |method − reference| (a hole shows as the cube's colour at "
                        "full strength)."))
            out.append(linked_table("Every run", tests, ["case", "config", "psnr", "max_error", "count_lens_rays",
                                                         "count_hole_rays"], ctx, csv_name="edges_runs.csv",
                                    names={**RUN_COLUMNS, "max_error": "max |difference|",
                                           "count_hole_rays": "hole rays (stencil)"}))
        return out + raycast_not_measurable(CONFIGS)
