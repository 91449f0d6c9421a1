"""``xue2005-octree`` (E6, Fig. 7): Φ_p's octree node size against the pseudo early ray termination it buys."""

import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import STRICTLY_ABOVE_ONE, all_of, median_count
from pipeline.experiments.kit.model import Claim, ClaimResult, Experiment, scaled
from pipeline.experiments.kit.pages import (as_percent, as_ratio, claim_takeaways, difference_gallery, figure,
                                            format_number, linked_table)
from pipeline.experiments.kit.planning import listed, orbit_views, timed_frames, volume_and_image_size
from pipeline.experiments.kit.results import nonempty_or, numeric, ok_rows, rows_matching, stage_points, tagged
from pipeline.experiments.xue2005.methods import ISBVR, isbvr_not_measurable, mode_runs, stand_in
from pipeline.experiments.xue2005.surfaces import (LOSSLESS_PSNR, LOSSLESS_SHARE, device_sentence, image_errors,
                                                   lossless_result, off_percent)
from pipeline.experiments.xue2005.tables import PAPER_PHI_P_NODE, PHI_P_NODES, STATEMENTS, statements
from reports import plots

SCENE = "head"
"""The head stand-in: the paper's Fig. 7 shows the Siemens head, whose thin skull holds few whole cubes."""

COLLAPSE = 0.1
"""Coverage "collapses" at 8³: at most a tenth of what 2³ sets ("almost no pixels")."""

COARSEST = 8
"""The node size where the paper sees almost no ERT pixels."""

NODE = "option_phi_p_node"


def _nodes(df):
    """``{node size: rows}`` of the ERT runs in ``df``; ValueError when there are none, or when Φ_p has no cube
    at any node size (a shell too thin for the volume's size: nothing to compare)."""
    rows = rows_matching(df, "ERT", config="ert")
    sizes = numeric(rows, NODE)
    found = nonempty_or({int(n): rows[sizes == n] for n in sorted(sizes.dropna().unique())}, "no successful ERT run")
    if not (numeric(rows, "count_cubes_p") > 0).any():
        raise ValueError("Φ_p has no cube at any node size: no block of the volume is wholly opaque")
    return found


def _coverage_collapses(df):
    found = _nodes(df)
    for node in (PAPER_PHI_P_NODE, COARSEST):
        if node not in found:
            raise ValueError(f"no successful ERT run at node size {node}")
    compared = {n: found[n] for n in (PAPER_PHI_P_NODE, COARSEST)}
    wrote = {n: median_count(rows, "count_init_fragments") for n, rows in compared.items()}
    if wrote[PAPER_PHI_P_NODE] <= 0:
        raise ValueError(f"the Φ_p pass set no pixel at {PAPER_PHI_P_NODE}³: nothing to collapse from")
    share = wrote[COARSEST] / wrote[PAPER_PHI_P_NODE]
    culled = {n: median_count(rows, "count_fragments_generated") - median_count(rows, "count_fragments")
              for n, rows in compared.items()}
    return ClaimResult(f"{as_percent(share)} of the {PAPER_PHI_P_NODE}³ coverage", bool(share <= COLLAPSE),
                       f"fragments the Φ_p pass wrote (≈ pixels it set): {format_number(wrote[PAPER_PHI_P_NODE])} at "
                       f"{PAPER_PHI_P_NODE}³, {format_number(wrote[COARSEST])} at {COARSEST}³; slice fragments culled "
                       f"(F − F'_c): {format_number(culled[PAPER_PHI_P_NODE])} and {format_number(culled[COARSEST])}; "
                       "median over the views")


def _triangles_fall(df):
    counts = {n: median_count(rows, "count_surface_triangles_p") for n, rows in _nodes(df).items()}
    if len(counts) < 2:
        raise ValueError("fewer than two node sizes")
    values = list(counts.values())
    holds = all(a >= b for a, b in zip(values, values[1:])) and values[-1] < values[0]
    return ClaimResult(" → ".join(f"{format_number(c)} ({n}³)" for n, c in counts.items()), bool(holds),
                       "Φ_p's triangles at each node size (median over the views)")


def _paper_node_fastest(df):
    found = _nodes(df)
    if PAPER_PHI_P_NODE not in found or len(found) < 2:
        raise ValueError(f"need ERT at {PAPER_PHI_P_NODE}³ and another node size")
    resampler = intervals.Resampler()
    decisions = {f"{n}³": intervals.ratio_decision(rows, found[PAPER_PHI_P_NODE], at_least=STRICTLY_ABOVE_ONE,
                                                   resampler=resampler)
                 for n, rows in found.items() if n != PAPER_PHI_P_NODE}
    fastest = min(found, key=lambda n: float(numeric(found[n], "time_total").median()))
    return all_of(decisions, show=as_ratio, what=f"fastest here {fastest}³; time / time at {PAPER_PHI_P_NODE}³ ",
                  extra="Whole frames, median over the views, timed together")


CLAIMS = (
    Claim("coverage-collapses", "At 8³ Φ_p sets almost no pixels for ERT (Fig. 7: thin bone holds no whole cube)",
          f"fragments the Φ_p pass writes at {COARSEST}³ ≤ {as_percent(COLLAPSE)} of those at {PAPER_PHI_P_NODE}³ "
          "(occlusion-query counts)", _coverage_collapses, kind="count"),
    Claim("triangles-fall", "Φ_p's triangle count falls as the node size grows (§4.2)",
          "triangles never rise from one node size to the next and end below where they start", _triangles_fall,
          kind="count"),
    Claim("paper-node-fastest", f"{PAPER_PHI_P_NODE}³, the paper's \"good balance\" between Φ_p's triangles and "
          "ERT (§4.2, no times given), is read here as the fastest node size",
          f"time at each other node size / at {PAPER_PHI_P_NODE}³ > 1 (whole frames, median over the views)",
          _paper_node_fastest, paper_value="2×2×2 nodes", kind="timing"),
    Claim("ert-lossless", "ERT's cube sets are conservative at every node size: Basic's image",
          f"PSNR against Basic ≥ {format_number(LOSSLESS_PSNR)} dB and ≤ {100 * LOSSLESS_SHARE:g} % of pixels off by "
          "> 1/255, every node size and view", lambda df: lossless_result(image_errors(df, "ERT", config="ert")),
          kind="accuracy"))


COLUMNS = {"node_size": "node size (voxels)", "count_cubes_p": "Φ_p cubes",
           "count_surface_triangles_p": "Φ_p triangles",
           "count_surface_fragments_p": "F_p", "count_init_fragments": "fragments the Φ_p pass wrote",
           "culled": "slice fragments culled (F − F'_c)", "init_ms": "T_a init (ms)", "frame_ms": "frame (ms)",
           "frame_ms_min": "fastest (ms)", "frame_ms_max": "slowest (ms)", "psnr": "PSNR vs Basic (dB)",
           "off_percent": "pixels off > 1/255 (%)"}


def _page_rows(ok):
    rows = tagged(ok, backend=ISBVR, config="ert")
    if rows.empty:
        return rows
    rows["node_size"] = numeric(rows, NODE)
    rows["culled"] = numeric(rows, "count_fragments_generated") - numeric(rows, "count_fragments")
    rows["init_ms"] = numeric(rows, "time_init") * 1e3
    rows = stage_points(rows, "time_total", name="frame_ms")
    rows["off_percent"] = off_percent(rows, ok, "ERT", config="ert")
    return rows.sort_values(["view", "node_size"])


def _coverage_chart(rows, ctx):
    medians = rows.groupby("node_size")[["count_init_fragments", "culled"]].median().reset_index()
    long = pd.concat([medians.assign(measure="fragments the Φ_p pass wrote (≈ pixels set)",
                                     count=medians.count_init_fragments),
                      medians.assign(measure="slice fragments culled (F − F'_c)", count=medians.culled)])
    top = medians.set_index("node_size").count_init_fragments
    return figure(ctx, "coverage", plots.lines, long, heading="ERT coverage against the node size",
                  caption="Occlusion-query counts, the median over the views; the same on every machine.",
                  x="node_size", y="count", group="measure", log_x=True,
                  title="ERT coverage: " + ", ".join(f"{format_number(top[n])} at {int(n)}³" for n in top.index),
                  x_label="Φ_p octree node size (voxels a side, log scale)", y_label="fragments (count)")


def _triangle_chart(rows, ctx):
    medians = rows.groupby("node_size").count_surface_triangles_p.median().reset_index()
    medians["series"] = "Φ_p triangles"
    title = "Φ_p triangles: " + ", ".join(f"{format_number(c)} at {int(n)}³" for n, c in
                                          zip(medians.node_size, medians.count_surface_triangles_p))
    return figure(ctx, "triangles", plots.lines, medians, heading="Φ_p's triangles against the node size",
                  caption="The cube set's boundary faces, two triangles each (median over the views).",
                  x="node_size", y="count_surface_triangles_p", group="series", title=title, log_x=True,
                  x_label="Φ_p octree node size (voxels a side, log scale)", y_label="triangles (count)")


def _time_chart(rows, basic, ctx):
    frames = rows.assign(series=[f"ERT, view {v}" for v in rows.view])
    fastest = frames.loc[frames.frame_ms.idxmin()]
    guides = ()
    if not basic.empty:
        level = float(numeric(basic, "time_total").median() * 1e3)
        guides = (("Basic (median over the views)", [frames.node_size.min(), frames.node_size.max()], [level, level]),)
    return figure(ctx, "frame-time", plots.lines, frames, heading="Frame time against the node size",
                  caption="Each view's median frame, bars from its fastest to its slowest frame; dotted: the paper's "
                          f"{PAPER_PHI_P_NODE}³; grey: Basic. Timed together.",
                  x="node_size", y="frame_ms", group="series", y_range=("frame_ms_min", "frame_ms_max"),
                  title=f"Fastest at {int(fastest.node_size)}³ ({format_number(fastest.frame_ms)} ms, "
                        f"{fastest.view}); the paper chose {PAPER_PHI_P_NODE}³",
                  x_label="Φ_p octree node size (voxels a side, log scale)", y_label="median frame time (ms)",
                  log_x=True, vlines=(PAPER_PHI_P_NODE,), guides=guides)


def _gallery(rows, results, ctx):
    return difference_gallery(
        "ERT at each node size and its difference from Basic (first view)", rows[rows.view == rows.view.iloc[0]],
        ctx, against=results, label=lambda row: f"ERT, Φ_p at {int(row.node_size)}³",
        caption="Left the image, right |image − Basic|.",
        note=lambda row: f"{format_number(row.off_percent)} % off, {format_number(row.frame_ms)} ms")


class Octree(Experiment):
    """Φ_p's octree node size: ERT coverage, triangles, times and images."""

    name = "xue2005-octree"
    paper = "xue2005"
    title = "Φ_p's octree node size: 1³, 2³, 4³ and 8³ (E6, Fig. 7)"
    settings = frozenset({"volume_size", "image_size", "orbit", "nodes", "repeat"})
    scales = scaled(smoke={"orbit": 0}, default={"orbit": 2}, full={"orbit": 3})
    description = (
        "Φ_p's cube set is the outer layer of the octree blocks that are wholly opaque; its front faces, drawn "
        "with LESS before the slices, stop every slice fragment behind them (pseudo early ray termination). "
        "Coarse blocks are cheap to draw but fit only inside thick opaque material. On the head stand-in (a "
        "skull shell a few voxels thick, as the paper's Siemens head) ERT alone runs at node sizes 1, 2, 4 and 8, "
        "timed together with Basic SBVR: the fragments the Φ_p pass writes (≈ the pixels it sets) and the slice "
        "fragments it culls (F − F'_c) are occlusion-query counts, the same on every machine; the frame times "
        "are this machine's.")
    claims = CLAIMS

    def runs(self, profile):
        size, image = map(int, volume_and_image_size(profile, self))
        orbit = int(profile.setting(self, "orbit", 1))
        nodes = listed(profile, self, "nodes", PHI_P_NODES, known=PHI_P_NODES)
        frames = timed_frames(profile, self)
        spec, tags = stand_in(SCENE, size, image)
        views = orbit_views(tags["dataset"], orbit)
        tags["size"] = size
        runs = mode_runs(self.name, SCENE, spec, views, ["basic"], frames, tags, group=SCENE)
        for node in nodes:
            runs += mode_runs(self.name, f"{SCENE}.n{node}", spec, views, ["ert"], frames, tags,
                              options={"phi_p_node": node}, group=SCENE, reference=f"{SCENE}.basic")
        return runs

    def paper_table(self):
        return pd.DataFrame([s for s in STATEMENTS if "Fig. 7" in s["source"]] + statements(
            (f"{PAPER_PHI_P_NODE}³ chosen as the trade-off between triangles and ERT", "§4.2", "no numbers")))

    def report(self, results, ctx):
        ok = ok_rows(results)
        out = [claim_takeaways(ctx, device_sentence(tagged(ok, backend=ISBVR)))]
        rows = _page_rows(ok)
        if not rows.empty:
            basic = rows_matching(ok, "Basic", config="basic")
            out += [_coverage_chart(rows, ctx), _triangle_chart(rows, ctx), _time_chart(rows, basic, ctx),
                    linked_table("Node sizes: cubes, triangles, coverage and times", rows, list(COLUMNS), ctx,
                                 names=COLUMNS, csv_name="octree.csv",
                                 caption="Every view; counts from occlusion queries, times: the view's median "
                                         "frame (whole frame) and init passes."),
                    _gallery(rows, results, ctx)]
        return out + isbvr_not_measurable()
