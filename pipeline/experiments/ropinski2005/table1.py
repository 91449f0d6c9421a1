"""``ropinski2005-table1`` (E1): Table 1's frame rates without and with the lens, as overheads beside the paper's."""

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import all_of, decision_words
from pipeline.experiments.kit.model import Claim
from pipeline.experiments.kit.pages import as_percent, as_ratio, claim_takeaways, figure, format_number, frames_caption
from pipeline.experiments.kit.planning import listed, timed_frames
from pipeline.experiments.kit.results import nonempty, numeric, rows_matching, text_column
from pipeline.experiments.ropinski2005.methods import (OFF, PAPER_METHOD, TIMES, LensExperiment, device_takeaways,
                                                       lens_coverage, lens_run, lens_settings, method_name,
                                                       raycast_not_measurable, scenes_of)
from pipeline.experiments.ropinski2005.pages import (headline, interval_columns, median_ms, run_table, samples_ratio,
                                                     tests_of)
from pipeline.experiments.ropinski2005.scenes import SETUPS, lens_scene, lens_views, scene_tags, without_lens
from pipeline.experiments.ropinski2005.tables import (PAPER_DEVICE, PAPER_SIZES, TABLE1, derived_table, paper_drop,
                                                      paper_fps, paper_time_ratio)
from reports import blocks, plots


def image_sizes(frame):
    return sorted(int(s) for s in numeric(frame, "image_size").dropna().unique())


def lens_rows(frame, scene, image, lens):
    """The rows of ``scene`` at ``image`` with the lens (``lens`` "on") or without ("off"); ValueError if none."""
    rows = rows_matching(frame, scene, scene=scene, lens=lens)
    rows = rows[numeric(rows, "image_size") == image]  # a number: runs.csv holds it as 512.0 beside other tables
    return nonempty(rows, what=f"{scene} at {image}² with the lens {lens}")


def overhead(frame, scene, image, *, resampler, at_most=None):
    """time(lens) / time(no lens) of ``scene`` at ``image``, judged against ``at_most`` with its paired interval."""
    return intervals.ratio_decision(lens_rows(frame, scene, image, "on"), lens_rows(frame, scene, image, "off"),
                                    at_most=at_most, resampler=resampler)


def drop(ratio):
    """The fps drop ``1 − fps_lens / fps_no_lens`` of a frame-time ratio ``t_lens / t_no_lens``."""
    return 1.0 - 1.0 / ratio


def _overhead_claim(df, which):
    """Every Table 1 scene's overhead at our smaller (``which`` 0) or larger (-1) image within the paper's."""
    sizes = image_sizes(df)
    if which == 0 and len(sizes) < 2:
        raise ValueError(f"one image size only ({sizes[0]}²): the smaller-viewport claim needs two")
    image, paper_image = sizes[which], PAPER_SIZES[which]
    resampler = intervals.Resampler()
    decisions, notes = {}, {}
    for scene in nonempty([s for s in scenes_of(df) if s in SETUPS and SETUPS[s].paper_row], what="a scene of Table 1"):
        row = SETUPS[scene].paper_row
        bound = paper_time_ratio(row, paper_image)
        decisions[scene] = overhead(df, scene, image, resampler=resampler, at_most=bound)
        share = lens_coverage(lens_rows(df, scene, image, "on"))  # rays meeting lens ∩ box, counted
        notes[scene] = (f"fps drop {as_percent(drop(decisions[scene].value))}, paper {as_ratio(bound)} = "
                        f"{as_percent(paper_drop(row, paper_image))} ({row}, {paper_image}²)"
                        + (f", lens on {as_percent(share)} of the rays" if np.isfinite(share) else ""))
    return all_of(decisions, notes=notes, what=f"time with / without the lens at {image}² ",
                 extra=f"{TIMES}; lens and no lens timed together, frame against frame")


def _bounds(paper_image):
    return ", ".join(f"{as_ratio(paper_time_ratio(row, paper_image))} {row}" for row in TABLE1)


CLAIMS = (
    Claim("overhead-small", "Applying the lens costs at most the paper's share of the frame at the smaller viewport "
          "(Table 1's frame rates at 512² fall by 2.8 % on seismic, 20.3 % on the skull, 14.8 % on the foot)",
          f"time(lens) / time(no lens) ≤ the paper's fps(no lens) / fps(lens) at 512² ({_bounds(512)}; the real CT "
          f"head in the skull's row) at our smaller image, every Table 1 scene ({TIMES})",
          lambda df: _overhead_claim(df, 0),
          paper_value="512²: seismic 60.0→58.3, skull 30.1→24.0, foot 29.7→25.3 fps", kind="timing"),
    Claim("overhead-large", "Applying the lens costs at most the paper's share of the frame at the larger viewport "
          "(Table 1's frame rates at 1024² fall by 7.4 % on seismic, 22.6 % on the skull, 34.5 % on the foot)",
          f"time(lens) / time(no lens) ≤ the paper's fps(no lens) / fps(lens) at 1024² ({_bounds(1024)}; the real "
          f"CT head in the skull's row) at our larger image, every Table 1 scene ({TIMES})",
          lambda df: _overhead_claim(df, -1),
          paper_value="1024²: seismic 53.0→49.1, skull 19.0→14.7, foot 14.8→9.7 fps", kind="timing"),
)


def overhead_table(tests):
    """Per scene and image size: the paper's frame rates and drop beside our frame times, ratio and drop."""
    sizes = image_sizes(tests)
    rows = []
    for scene in scenes_of(tests):
        setup = SETUPS[scene]
        for position, image in enumerate(sizes):
            try:
                decision = overhead(tests, scene, image, resampler=intervals.Resampler())
                on, off = (lens_rows(tests, scene, image, lens) for lens in ("on", "off"))
            except (KeyError, ValueError):
                continue
            paper_image = PAPER_SIZES[0] if position == 0 and len(sizes) > 1 else PAPER_SIZES[-1]
            row = {"scene": scene, "image (px)": image, "paper row": setup.paper_row or "not in Table 1",
                   "paper viewport (px)": paper_image if setup.paper_row else np.nan}
            if setup.paper_row:
                row |= {"paper fps, no lens": paper_fps(setup.paper_row, paper_image, False),
                        "paper fps, lens": paper_fps(setup.paper_row, paper_image, True),
                        "paper fps drop (%)": round(100 * paper_drop(setup.paper_row, paper_image), 1)}
            row |= {"ours ms, no lens": median_ms(off), "ours ms, lens": median_ms(on),
                    **interval_columns(decision.value, decision.interval, "ours time ratio",
                                       ends=("ratio 95 % CI low", "ratio 95 % CI high")),
                    "ours fps drop (%)": 100 * drop(decision.value),
                    "rays through the lens (%)": 100 * lens_coverage(on),
                    "samples lens / no lens": samples_ratio(on, off)}
            rows.append(row)
    return pd.DataFrame(rows)


def _overhead_figure(table, ctx):
    points = [{"series": f"{ours['scene']} (ours)", "image": ours["image (px)"], "drop": ours["ours fps drop (%)"],
               "low": 100 * drop(ours["ratio 95 % CI low"]), "high": 100 * drop(ours["ratio 95 % CI high"])}
              for ours in table.to_dict("records")]
    points += [{"series": f"{row} (paper)", "image": image, "drop": 100 * paper_drop(row, image), "low": np.nan,
                "high": np.nan} for row in TABLE1 for image in PAPER_SIZES]
    return figure(ctx, "table1-overhead", plots.lines, pd.DataFrame(points), heading="Lens overhead against image size",
                  caption="Ours: the fps drop implied by the median frame-time ratio, bars its 95 % bootstrap interval "
                          "(lens and no lens timed together); paper: Table 1's drop at 512² and 1024² (no interval "
                          "given). The sizes differ: compare the shape per data set, not one point against another.",
                  x="image", y="drop", group="series", y_range=("low", "high"), log_x=True,
                  title="Lens overhead per data set: ours beside the paper's Table 1",
                  x_label="image width and height (pixels)",
                  y_label="fps drop with the lens, 1 − t(no lens) / t(lens) (%)")


def _other_takeaways(tests):
    """The overhead of each scene without a Table 1 row (the engine), in words: measured, not judged."""
    sentences = []
    for scene in (s for s in scenes_of(tests) if not SETUPS[s].paper_row):
        try:
            words = [f"{image}² {decision_words(overhead(tests, scene, image, resampler=intervals.Resampler()))}"
                     for image in image_sizes(tests)]
        except (KeyError, ValueError):
            continue
        sentences.append(f"The {scene} ({SETUPS[scene].what}): time with / without the lens {', '.join(words)}; "
                         "measured, not judged, as the paper gives it no frame rate.")
    return sentences


def _gallery(tests, ctx):
    largest = image_sizes(tests)[-1]
    gallery = blocks.Gallery(f"Headline view at {largest}²: each scene with its lens and without",
                             caption="Left with the lens (the paper's method), right without it.")
    shown = headline(tests)
    shown = shown[numeric(shown, "image_size") == largest]
    for scene in scenes_of(shown):
        on, off = (rows_matching(shown, scene, scene=scene, lens=lens) for lens in ("on", "off"))
        if on.empty:
            continue
        row, extra = on.iloc[0], ()
        note = f"{format_number(row.time_total * 1e3)} ms with the lens"
        if not off.empty:
            extra = (("no lens", ctx.image(off.png.iloc[0])),)
            note += f", {format_number(off.time_total.iloc[0] * 1e3)} ms without"
        gallery.items.append(blocks.GalleryItem(f"{scene}: {SETUPS[scene].what}", ctx.image(row.png), label="lens",
                                                extra=extra, note=note))
    return gallery


class Table1(LensExperiment):
    name = "ropinski2005-table1"
    title = "Table 1: frame rates without and with the lens (E1)"
    settings = frozenset({"scenes", "volume_size", "image_sizes", "orbit", "step_factor", "lens_method", "repeat",
                          "min_time"})
    scales = {"smoke": {"volume_size": 32, "image_sizes": [32, 48], "orbit": 0},
              "default": {"volume_size": 128, "image_sizes": [256, 512], "orbit": 0},
              "full": {"volume_size": 256, "image_sizes": list(PAPER_SIZES), "orbit": 4}}
    description = (
        "The paper's only measurement: frame rates of three 256³ data sets (seismic, skull, foot) at 512² and 1024², "
        "without and with the lens, on a GeForce 6800; lens shapes and appearances per row are not given. Here "
        "gl-raycast's single-pass caster renders each lens scene of note 004 §5 (the seismic cube with a spherical "
        "clipping lens sticking out of its front top corner, the skull with a spherical transparency lens, the foot "
        "with a spherical bone-isosurface lens over the metatarsals, the real CT head in the skull's row, and the "
        "engine of Fig. 1 with its rotated cuboid transparency lens) without the lens and with it (the paper's "
        "segments method: lens entry and exit images, three region passes back to front), at two image sizes, from the "
        "headline view (30° yaw, 20° pitch; at full scale around an orbit too). The four runs of a scene are timed "
        "together, frame against frame; each overhead, whole-frame time with the lens over time without it (the median "
        "over the views), is judged with its paired bootstrap interval against the paper's fps(no lens) / fps(lens) of "
        "its row: our smaller image against the paper's 512², our larger against its 1024² (the same sizes at full "
        "scale). A 2005 GPU's frame rates do not transfer; the overhead, a ratio on one machine, does."
    )
    claims = CLAIMS

    def lens_runs(self, profile):
        wanted = listed(profile, self, "scenes", tuple(SETUPS), known=SETUPS)
        size, _, orbit, step = lens_settings(profile, self, orbit=1)
        sizes = sorted(int(s) for s in profile.setting(self, "image_sizes", [profile.image_size]))
        method = profile.setting(self, "lens_method", PAPER_METHOD)
        frames = timed_frames(profile, self)
        runs = []
        for scene_name in wanted:
            views = lens_views(scene_name, orbit)
            for image in sizes:
                spec = lens_scene(scene_name, image, size=size, real_data=profile.real_data)
                tags = scene_tags(scene_name, image_size=image, role="test")
                runs.append(lens_run(self.name, f"{scene_name}.{image}.{OFF}", without_lens(spec), views, OFF, frames,
                                     {**tags, "lens": "off"}, step_factor=step, group=scene_name))
                runs.append(lens_run(self.name, f"{scene_name}.{image}.{method}", spec, views, method, frames,
                                     {**tags, "lens": "on"}, step_factor=step, group=scene_name))
        return runs

    def paper_table(self):
        return pd.DataFrame(derived_table()).assign(device=PAPER_DEVICE)

    def report(self, results, ctx):
        tests = tests_of(results)
        out = [claim_takeaways(ctx, device_takeaways(tests), _other_takeaways(tests))]
        methods = sorted(set(text_column(tests, "config")) - {OFF}) if not tests.empty else [PAPER_METHOD]
        if not tests.empty:
            table = overhead_table(tests)
            if not table.empty:
                out.append(blocks.Table(
                    "Table 1 beside ours: frame times and the lens overhead", table.round(3),
                    csv_name="table1_overhead.csv",
                    caption="Ours: median whole-frame times over the views, with the lens (the paper's method) and "
                            "without, timed together; the time ratio's 95 % interval is a paired bootstrap over the "
                            "frames. The fps drop is 1 − t(no lens) / t(lens), the paper's 1 − fps(lens) / fps(no "
                            "lens). Our smaller image stands beside the paper's 512², our larger beside its 1024². "
                            "Rays through the lens: rays meeting lens ∩ box (counted by the caster); samples: all "
                            "samples taken with the lens over without it (a clip lens skips its own)."))
                out.append(_overhead_figure(table, ctx))
            out.append(run_table(tests, ["scene", "image_size", "method", "time_ms", "time_ms_min", "time_ms_max",
                                         "count_samples", "count_lens_rays", "count_rays"], ctx, method=method_name,
                                 names={"image_size": "image (px)"}, csv_name="table1_runs.csv",
                                 caption=frames_caption(headline(tests))))
            out.append(_gallery(tests, ctx))
        return out + raycast_not_measurable(methods)
