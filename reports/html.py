"""The static HTML report: ``index.html`` plus one page per paper, CSV and SVG beside them.

Everything a page shows or links to lives inside the report folder (images, charts, each run's
JSON record and EXR images are copied in), so the folder opens from disk and can be moved or
archived as a whole.

The index answers "which technique should I use, and where does it fail": take-aways computed from
the numbers (:mod:`reports.takeaways`), a techniques × data sets table (median frame time with
its fastest and slowest frame, PSNR / SSIM / FLIP against the reference, links to every run's
record and EXR), the claims per paper, the backends that cannot run here and the papers whose
backends do not exist yet, how frames are timed with the views whose timings were disturbed, and
the provenance of the numbers (date, machine, real data). A paper's page shows each claim with its
verdict, its 95 % interval and its margin, and says in one line when some of its timed views were
disturbed.
"""

import hashlib
import html
import json
import math
import multiprocessing
import os
import re
import shutil
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import jinja2
import numpy as np
import pandas as pd

from core.outcomes import CAUSE_WORDS
from core.papers import PAPERS
from reports import blocks, decision, nodes, outcomes, takeaways
from reports.imageio import read_image, write_png
from reports.metrics import difference_image

TEMPLATES = Path(__file__).parent / "templates"
GIB = 1024 ** 3


@dataclass
class ReportContext:
    """What an experiment's ``report`` method uses: where to place files in the report folder, and its
    claims as ``claims.csv`` judged them (``claims``: one row per claim; pages read verdicts, never judge)."""

    report_dir: Path
    results_dir: Path
    experiment: str
    _copied: set = field(default_factory=set)
    claims: object = None

    def _relative(self, source):
        resolved = Path(source).resolve()
        try:
            return resolved.relative_to(self.results_dir.resolve())
        except ValueError:
            # Files of one name from two folders (a phantom's cache entry and a real scan's) stay apart.
            folder = hashlib.sha256(str(resolved.parent).encode()).hexdigest()[:10]
            return Path("external") / folder / resolved.name

    def _copy(self, path, folder):
        if path is None or (isinstance(path, float) and pd.isna(path)) or path == "":
            return None
        source = Path(path)
        if not source.exists():
            return None
        relative = Path(folder) / self._relative(source)
        target = self.report_dir / relative
        if target not in self._copied:
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source, target)
            self._copied.add(target)
        return relative.as_posix()

    def image(self, path):
        """Copy an image from the results folder into the report; return its relative path."""
        return self._copy(path, "img")

    def file(self, path):
        """Copy a run's record or EXR into the report's ``data`` folder; return its relative path.

        ``None`` when ``path`` is missing or does not exist (the link is then left out).
        """
        return self._copy(path, "data")

    def difference(self, reference_exr, test_exr, scale):
        """Write the difference image of two EXRs at a fixed ``scale``; return its relative path."""
        if any(p is None or (isinstance(p, float) and pd.isna(p)) for p in (reference_exr, test_exr)):
            return None
        relative = Path("img") / "diff" / self._relative(test_exr).with_suffix("")
        relative = relative.with_name(f"{relative.name}-diff-{scale:g}.png")
        target = self.report_dir / relative
        if target not in self._copied:
            target.parent.mkdir(parents=True, exist_ok=True)
            write_png(target, difference_image(read_image(reference_exr), read_image(test_exr), scale=scale))
            self._copied.add(target)
        return relative.as_posix()

    def colorbar(self, scale):
        """The SVG colour bar of difference images at ``scale``; return its relative path."""
        from reports import plots

        relative = Path("plots") / f"colorbar-{scale:g}.svg"
        target = self.report_dir / relative
        if target not in self._copied:
            plots.difference_colorbar(target, scale)
            self._copied.add(target)
        return relative.as_posix()

    def run_links(self, frame):
        """``frame`` with ``record`` and ``exr`` columns replaced by links copied into the report."""
        frame = frame.copy()
        for column in ("record", "exr"):
            if column in frame:
                frame[column] = [self.file(p) for p in frame[column]]
        return frame

    def plot_path(self, name):
        """``(absolute path, relative path)`` for an SVG chart of this experiment."""
        relative = Path("plots") / f"{self.experiment}-{name}.svg"
        absolute = self.report_dir / relative
        absolute.parent.mkdir(parents=True, exist_ok=True)
        return absolute, str(relative)


# ------------------------------------------------------------------------------------------ tables
def _format_cell(value):
    if isinstance(value, (float, np.floating)):
        if pd.isna(value):
            return ""
        if math.isinf(value):
            return "∞" if value > 0 else "−∞"
        return f"{value:.4g}"
    if value is None or (not isinstance(value, str) and pd.isna(value)):
        return ""
    return str(value)


def _link(href, text):
    if href is None or (isinstance(href, float) and pd.isna(href)) or href == "":
        return ""
    return f'<a href="{html.escape(str(href))}">{html.escape(text)}</a>'


def _table_html(frame, links=None):
    """HTML of a table: escaped cells, ``links`` columns as links, readable headers."""
    links = links or {}
    columns = []
    for column in frame.columns:
        numeric = column not in links and pd.api.types.is_numeric_dtype(frame[column].dtype) \
            and not pd.api.types.is_bool_dtype(frame[column].dtype)
        if column in links:
            cells = [_link(v, links[column]) for v in frame[column]]
        else:
            cells = [html.escape(_format_cell(v)) for v in frame[column]]
        columns.append((html.escape(str(column).replace("_", " ")), "num" if numeric else "text", cells))
    head = "".join(f'<th class="{kind}">{name}</th>' for name, kind, _ in columns)
    body = "".join("<tr>" + "".join(f'<td class="{kind}">{cells[i]}</td>' for _, kind, cells in columns) + "</tr>\n"
                   for i in range(len(frame)))
    return f'<div class="scroll"><table class="data">\n<tr>{head}</tr>\n{body}</table></div>'


def _render_block(block, ctx):
    report_dir = ctx.report_dir
    if isinstance(block, blocks.Table):
        csv = None
        if block.csv_name:
            csv = f"csv/{block.csv_name}"
            (report_dir / "csv").mkdir(exist_ok=True)
            block.frame.to_csv(report_dir / csv, index=False)
        return {"kind": "table", "title": block.title, "caption": block.caption,
                "html": _table_html(block.frame, block.links), "csv": csv}
    if isinstance(block, blocks.Figure):
        return {"kind": "figure", "title": block.title, "caption": block.caption, "path": block.path,
                "anchor": block.anchor}
    if isinstance(block, blocks.HeatMap):
        return {"kind": "heatmap", "title": block.title, "caption": block.caption, "columns": list(block.columns),
                "thresholds": [takeaways.number(t) for t in block.thresholds],
                "rows": [(row, [_heat_cell(block.cells.get((row, column)), block.thresholds)
                                for column in block.columns]) for row in block.rows]}
    if isinstance(block, blocks.Gallery):
        items = []
        for item in block.items:
            panels = [(item.label or ("render" if item.difference else ""), item.image)]
            if item.difference:
                panels.append(("difference", item.difference))
            panels.extend(tuple(extra) for extra in item.extra)
            items.append({"caption": item.caption, "note": item.note, "panels": panels})
        scale = block.diff_scale
        return {"kind": "gallery", "title": block.title, "caption": block.caption, "items": items,
                "colorbar": ctx.colorbar(scale) if scale else None, "scale": scale,
                "wide": any(len(i["panels"]) > 1 for i in items)}
    if isinstance(block, blocks.Text):
        return {"kind": "text", "text": block.text}
    if isinstance(block, blocks.Takeaways):
        return {"kind": "takeaways", "sentences": list(block.sentences)}
    raise TypeError(f"unknown report block {type(block).__name__}")


def _heat_cell(cell, thresholds):
    """A heat-map cell for the template: its text, CSS class (by PSNR against ``thresholds``) and links."""
    if cell is None:
        return {"text": "not planned", "css": "absent", "link": None, "image": None, "note": ""}
    if cell.value is None or not _finite(cell.value):
        css = "absent"
    else:
        css = "broken" if cell.value < thresholds[0] else "poor" if cell.value < thresholds[1] else "good"
    return {"text": cell.text, "css": css, "link": cell.link, "image": cell.image, "note": cell.note}


def _status_summary(frame, ctx, *, stated_above=()):
    """``(counts, problems)`` of an experiment's runs: runs per status, and its runs that made no frame
    grouped by backend, cause and message (:func:`reports.outcomes.problem_groups`).

    A group of a backend in ``stated_above`` (its failure is stated at the top of the page) gives no
    message again.
    """
    if frame.empty:
        return {"ok": 0, "skipped": 0, "failed": 0}, []
    runs = outcomes.per_run(frame)
    counts = runs.status.value_counts().to_dict()
    problems = []
    for group in outcomes.problem_groups(runs):
        shown = group["runs"][:PROBLEM_RUNS_SHOWN]
        problems.append({
            **group, "what": CAUSE_WORDS.get(group["cause"], group["status"]),
            "reason": "stated at the top of this page" if group["backend"] in stated_above else group["reason"],
            "shown": [(run, ctx.file(record)) for run, record in zip(shown, group["records"])],
            "more": len(group["runs"]) - len(shown),
        })
    return {s: int(counts.get(s, 0)) for s in ("ok", "skipped", "failed")}, problems


PROBLEM_RUNS_SHOWN = 6
"""Runs of one problem group linked by name; the rest are counted (every record is in the CSV)."""


# ------------------------------------------------------------------------- techniques × data sets
def _technique_matrix(rows, ctx, psnr_min):
    """Techniques (rows) × data sets (columns); each cell one run with its numbers and links."""
    if rows.empty:
        return None
    datasets = list(dict.fromkeys(rows.dataset))
    matrix = []
    for technique, group in rows.groupby("technique", sort=False):
        cells = []
        for dataset in datasets:
            match = group[group.dataset == dataset]
            if match.empty:
                cells.append(None)
                continue
            r = match.iloc[0]
            cells.append({
                "time": takeaways.number(r.time_total * 1e3),
                "range": f"{takeaways.number(r.time_min * 1e3)}–{takeaways.number(r.time_max * 1e3)}",
                "psnr": takeaways.number(r.psnr), "ssim": takeaways.number(r.ssim),
                "flip": takeaways.number(r.flip), "fails": bool(r.psnr < psnr_min) and r.backend != decision.REFERENCE,
                "record": ctx.file(r.record), "exr": ctx.file(r.exr), "run": r.run,
            })
        matrix.append({"technique": group.backend.iloc[0], "setting": takeaways.setting_words(group.setting.iloc[0]),
                       "cells": cells})
    return {"datasets": datasets, "rows": matrix}


# ------------------------------------------------------------------------------------ provenance
def provenance(environment, runs_df=None, real_data=None):
    """``[(label, text)]``: when and where the numbers were measured, and where real data came from."""
    environment = dict(environment or {})
    runs_df = runs_df if runs_df is not None else pd.DataFrame()

    def values(column):
        if column in runs_df:
            found = [v for v in pd.unique(runs_df[column].dropna())]
            if found:
                return found
        return [environment[column]] if environment.get(column) not in (None, "") else []

    dates = sorted(str(d) for d in values("date"))
    if len(dates) > 1:
        date = f"{dates[0]} to {dates[-1]}"
    else:
        date = dates[0] if dates else "not recorded"
    memory = values("memory_bytes")
    threads = values("numba_threads")
    facts = [
        ("run date (UTC)", date),
        ("CPU", ", ".join(str(v) for v in values("cpu_model")) or "not recorded"),
        ("cores", ", ".join(str(int(float(v))) for v in values("cpu_cores")) or "not recorded"),
        ("memory", ", ".join(f"{float(v) / GIB:.1f} GiB" for v in memory) or "not recorded"),
        ("Numba threads", ", ".join(str(int(float(v))) for v in threads) or "not recorded"),
        ("git commit", ", ".join(str(v) for v in values("git_commit")) or "not recorded"),
    ]
    if real_data:
        used = [d["name"] for d in real_data.get("datasets", [])]
        where = real_data.get("folder", "not configured")
        text = f"read in place from {where}"
        if real_data.get("error"):
            text += f" ({real_data['error']})"
        elif used:
            text += f"; {len(used)} scans listed ({', '.join(used)}), sources in the index"
        facts.append(("real data", text))
    return facts


# --------------------------------------------------------------------------------------- building
def _jinja():
    return jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES), autoescape=True,
                              undefined=jinja2.StrictUndefined, keep_trailing_newline=True)


def _holds(value):
    if value is True or value is False:
        return value
    if isinstance(value, str) and value in ("True", "False"):
        return value == "True"
    return None


def _experiment_blocks(experiment, frame, ctx):
    """The experiment's report blocks; a column no run reported becomes a stated gap, not a crash.

    As with claims (holds ``None`` when a needed column is missing), a section whose backend did
    not report a counter or stage (a KeyError naming the column) says so in place of its charts,
    so one missing measurement cannot take the whole report down. Where the experiment's timings
    come from more than one node, the section opens by saying so (:func:`reports.nodes.node_warning`).
    """
    measured = frame[frame.status == "ok"] if "status" in frame else frame
    warning = nodes.node_warning(measured, what=f"Every ratio and comparison of {experiment.name}")
    across_nodes = [blocks.Text(warning)] if warning else []
    try:
        return across_nodes + experiment.report(frame, ctx)
    except KeyError as exc:
        missing = exc.args[0] if exc.args else exc
        return across_nodes + [blocks.Text(f"Not measurable here: this section needs {missing}, which no "
                                           "successful run of this experiment reported.")]


def build_report(runs_df, claims_df, experiments, *, results_dir, environment, backends=None, planned=None,
                 real_data=None, phantoms=None, notices=(), techniques=None, psnr_min=takeaways.PSNR_GOOD,
                 harness=None):
    """Write the report into ``results_dir/report``; return the path of ``index.html``.

    Parameters
    ----------
    runs_df, claims_df : pandas.DataFrame
        ``runs.csv`` and ``claims.csv`` (a ``record`` column in ``runs_df`` links each row to its
        run's JSON record).
    experiments : list
        The profile's experiments; those with a true ``overview`` attribute feed the index's
        techniques × data sets table.
    results_dir : path
    environment : dict
        ``environment.json`` (host, devices, date, memory).
    backends : list of dict, optional
        Every registered backend: ``name``, ``available``, ``reason``, ``description``.
    planned : list of dict, optional
        Papers whose experiments or backends do not exist yet: ``paper``, ``title``, ``needs``,
        ``reason``.
    real_data : dict, optional
        ``folder``, ``error`` (when unreadable) and ``datasets``: ``name``, ``file``, ``modality``,
        ``source``.
    phantoms : pandas.DataFrame, optional
        ``volumes.csv``: one row per generated phantom (:func:`pipeline.collect.phantom_manifest`).
    notices : sequence of str
        Sentences every page shows first, above its title (e.g. that the report mixes runs of two
        pipeline runs).
    techniques : dict, optional
        ``{paper: backend}``: the backend whose frames are the paper's technique. A paper whose
        technique made no frame in this run is marked "not reproduced on this machine".
    psnr_min : float
        The PSNR (dB) the take-aways and the table call accurate.
    """
    results_dir = Path(results_dir)
    report_dir = results_dir / "report"
    if report_dir.exists():
        shutil.rmtree(report_dir)
    (report_dir / "csv").mkdir(parents=True)
    for csv in [results_dir / "runs.csv", results_dir / "claims.csv", results_dir / "volumes.csv",
                *(results_dir / "tables" / f"{e.name}.csv" for e in experiments)]:
        if csv.exists():
            shutil.copyfile(csv, report_dir / "csv" / csv.name)
    claims_df = claims_df.copy()
    if "holds" in claims_df:
        claims_df["holds"] = claims_df["holds"].map(_holds).astype(object)
    claims_df["verdict"] = _verdicts(claims_df)
    # Results written before these columns existed.
    for column, missing in (("kind", ""), ("target", "paper"), ("paper_value", ""), ("ours", "")):
        claims_df[column] = claims_df[column].fillna(missing).astype(str) if column in claims_df else missing
    env = _jinja()
    facts = provenance(environment, runs_df, real_data)
    banner = decision.timing_banner(runs_df)
    node_rows = nodes.nodes_table(runs_df)
    runs = outcomes.per_run(runs_df)
    backend_runs = outcomes.backend_outcomes(runs)
    silent = outcomes.silent_backends(backend_runs)
    techniques = dict(techniques or {})
    pages, overview_rows, overview_runs, failures, atlas = {}, [], [], {}, None
    global _SECTION_INPUTS
    _SECTION_INPUTS = (experiments, runs_df, claims_df, report_dir, results_dir, silent)
    try:
        built = _map_in_processes(_section, range(len(experiments)))
    finally:
        _SECTION_INPUTS = None
    for experiment, (section, overview, experiment_failures) in zip(experiments, built):
        if overview is not None:
            overview_rows.append(overview[0])
            overview_runs.append(overview[1])
        page = getattr(experiment, "page", None) or experiment.paper
        if experiment_failures is not None:
            failures.update(experiment_failures)
            atlas = f"{page}.html"
        pages.setdefault(page, []).append(section)

    page_template = env.get_template("paper.html")
    summaries, studies = [], []
    study_pages = {e.page for e in experiments if getattr(e, "page", None)}
    for page, sections in pages.items():
        claims = [c for s in sections for c in s["claims"]]
        page_backends = set().union(*(s["backends"] for s in sections))
        technique = techniques.get(page)
        reproduced = backend_runs[technique]["ran"] if technique in backend_runs else None
        # What made no frame on this page, once, at its top: which backend, how many runs, the message.
        alerts = [outcomes.did_not_run(name, silent[name]) + "." for name in silent if name in page_backends]
        if reproduced is False:
            alerts.insert(0, f"Not reproduced on this machine: {technique}, the backend of this paper's technique, "
                             f"made no frame. Claims that need its runs are blocked; the runs of the other backends "
                             f"that did succeed are shown below.")
        # Sections of one paper may say the same thing (the device every run of the page used): once.
        page_runs = runs[runs.experiment.isin([s["name"] for s in sections]) & ~runs.backend.isin(silent)]
        disturbed = outcomes.disturbance_notice(outcomes.timing_disturbances(
            runs_df[runs_df.experiment.isin([s["name"] for s in sections])]))
        page_takeaways = takeaways.ranked(takeaways.claims(pd.DataFrame(claims))
                                          + [t for s in sections for t in s["takeaways"]]
                                          + takeaways.problems(outcomes.problem_groups(page_runs)))
        title = PAGE_TITLES.get(page) or PAPERS.get(page, page)
        (report_dir / f"{page}.html").write_text(page_template.render(
            paper=page, paper_title=title, sections=sections, environment=environment,
            notices=list(notices), alerts=alerts, disturbed=disturbed, verdict_classes=VERDICT_CLASSES,
            nodes=node_rows, provenance=facts, takeaways=page_takeaways, shown=takeaways.SHOWN))
        summary = {
            "paper": page, "title": title, "page": f"{page}.html",
            "experiments": [(s["name"], s["title"]) for s in sections],
            "technique": technique, "reproduced": reproduced,
            "claims": {verdict: sum(c["verdict"] == verdict for c in claims) for verdict in VERDICT_CLASSES},
            "runs": {k: sum(s["counts"][k] for s in sections) for k in ("ok", "skipped", "failed")},
        }
        (studies if page in study_pages else summaries).append(summary)

    index_ctx = ReportContext(report_dir, results_dir, "index")
    overview = pd.concat(overview_rows, ignore_index=True) if overview_rows else decision.technique_rows(pd.DataFrame())
    matrix = _technique_matrix(overview, index_ctx, psnr_min)
    if not overview.empty:
        overview.drop(columns=["record", "exr"]).to_csv(report_dir / "csv" / "techniques.csv", index=False)
    panels = _decision_panels(overview, pd.concat(overview_runs, ignore_index=True) if overview_runs else None,
                              failures, index_ctx, psnr_min, silent)
    backends = [{**b, "runs": backend_runs.get(b["name"])} for b in backends or []]
    index_alerts = [outcomes.did_not_run(name, outcome) + "." for name, outcome in silent.items()]
    index_alerts += [f"{summary['title']}: not reproduced on this machine ({summary['technique']} made no frame)."
                     for summary in summaries if summary["reproduced"] is False]
    index_takeaways = takeaways.ranked(
        _decision_sentences(panels, psnr_min, _rankings(claims_df, experiments))
        + _claims_summary(claims_df)
        + _backend_sentences(backend_runs, planned or [], silent)
        + takeaways.problems(outcomes.problem_groups(runs[~runs.backend.isin(silent)]))
    )
    index = report_dir / "index.html"
    common = dict(papers=summaries, studies=studies, environment=environment, nodes=node_rows, provenance=facts,
                  notices=list(notices), banner=banner)
    index.write_text(env.get_template("index.html").render(
        **common, takeaways=index_takeaways, shown=takeaways.SHOWN, alerts=index_alerts, panels=panels, atlas=atlas,
        verdict_classes=VERDICT_CLASSES, matrix=matrix, psnr_min=takeaways.number(psnr_min), backends=backends,
        planned=list(planned or []), kinds=_claims_by_kind(claims_df)))
    (report_dir / "appendix.html").write_text(env.get_template("appendix.html").render(
        **common, timing=_timing(runs_df, environment, index_ctx), real_data=real_data,
        phantoms=_phantom_summary(phantoms), harness=_harness(harness, runs_df)))
    return index


KIND_WORDS = {"timing": "a timing", "count": "a count", "accuracy": "an image's accuracy",
              "cost model": "a cost model against the times"}
"""The index's words for each kind of claim (``claims.csv``'s ``kind``), in the order it lists them."""


def _claims_by_kind(claims_df):
    """``[{"kind", "words", "claims": {verdict: count}}]``: the verdicts of each kind of claim (what it measures)."""
    if "kind" not in claims_df:
        return []
    counts = claims_df[claims_df["kind"] != ""].groupby("kind")["verdict"].value_counts().unstack(fill_value=0)
    counts = counts.reindex(columns=list(VERDICT_CLASSES), fill_value=0)
    order = [kind for kind in dict.fromkeys([*KIND_WORDS, *counts.index]) if kind in counts.index]
    return [{"kind": kind, "words": KIND_WORDS.get(kind, kind), "claims": counts.loc[kind].astype(int).to_dict()}
            for kind in order]


_SECTION_INPUTS = None
"""What :func:`_section` reads besides its experiment, set by :func:`build_report` for the processes it forks."""


def _section(index):
    """Experiment ``index``'s section of its page: ``(section, (overview rows, runs) or None, atlas failures or None)``.

    The charts (matplotlib's layout: most of a report's time) are drawn here, in a process of its own
    per core (:func:`_map_in_processes`); what it returns are the page's strings and tables.
    """
    experiments, runs_df, claims_df, report_dir, results_dir, silent = _SECTION_INPUTS
    experiment = experiments[index]
    frame = runs_df[runs_df.experiment == experiment.name].dropna(axis=1, how="all")
    judged = claims_df[claims_df.experiment == experiment.name]
    ctx = ReportContext(report_dir, results_dir, experiment.name, claims=judged)
    counts, problems = _status_summary(frame, ctx, stated_above=silent)
    claims = [{**claim, "cells": claim_cells(claim)} for claim in judged.to_dict("records")]
    paper_table = experiment.paper_table()
    rendered = ([_render_block(b, ctx) for b in _experiment_blocks(experiment, frame, ctx)]
                if counts["ok"] else [])
    section = {
        "name": experiment.name, "title": experiment.title,
        "description": takeaways.rst_inline(experiment.description),
        "counts": counts, "problems": problems, "claims": claims,
        "paper_table": _table_html(paper_table) if paper_table is not None else None,
        "takeaways": [s for b in rendered if b["kind"] == "takeaways" for s in b["sentences"]],
        "blocks": [b for b in rendered if b["kind"] != "takeaways"],
        "csv": f"csv/{experiment.name}.csv",
        "backends": set(frame.backend) if "backend" in frame else set(),
    }
    overview = ((decision.technique_rows(frame), outcomes.per_run(frame))
                if getattr(experiment, "overview", False) else None)
    failures = experiment.failures(frame) if getattr(experiment, "atlas", False) and counts["ok"] else None
    return section, overview, failures


def _map_in_processes(function, items):
    """``[function(item) for item in items]``, over as many forked processes as this process may use cores.

    Forked: the children share the parent's data (:data:`_SECTION_INPUTS`) without pickling it; one core
    (or one item) maps in this process.
    """
    items = list(items)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if cores < 2 or len(items) < 2 or "fork" not in multiprocessing.get_all_start_methods():
        return [function(item) for item in items]
    with ProcessPoolExecutor(max_workers=min(cores, len(items)), mp_context=multiprocessing.get_context("fork")) as pool:
        return list(pool.map(function, items))


PAGE_TITLES = {"atlas": "Stability atlas — where each technique breaks"}
"""Titles of the report pages that are not a paper's (:attr:`Experiment.page`)."""


def _decision_panels(overview, runs, failures, ctx, psnr_min, silent):
    """The index's decision panel: per scene, the chart of every technique's Pareto front and its table."""
    from reports import plots  # matplotlib: only where a chart is drawn
    panels = decision.panel(overview, runs, psnr_min=psnr_min, failures=failures, stated_above=silent)
    techniques = sorted({b for item in panels for b in item["points"].backend})
    for item in panels:
        path, rel = ctx.plot_path(f"decision-{item['scene']}")
        plots.pareto_fronts(item["points"], path, psnr_min=psnr_min, techniques=techniques,
                       title=f"{item['kind'].capitalize()} ({item['scene']}): time against accuracy")
        item["chart"] = rel
        for row in item["table"]:
            row["record"] = ctx.file(row["record"])
        del item["points"]
    return panels


def _ratio_end(value):
    """An interval's end as a ratio, with the digits it takes not to read as ×1 when it is not 1."""
    value = float(value)
    digits = 3
    while digits < 6 and value != 1 and float(takeaways.number(value, digits)) == 1:
        digits += 1
    return takeaways.number(value, digits)


def _rankings(claims_df, experiments):
    """``{scene: row}``: the ranking claims (``ranking-<scene>``) of the overview experiments, as claims.csv rows."""
    overview = {e.name for e in experiments if getattr(e, "overview", False)}
    if claims_df.empty or not {"experiment", "claim"} <= set(claims_df.columns):
        return {}
    rows = claims_df[claims_df.experiment.isin(overview) & claims_df.claim.astype(str).str.startswith("ranking-")]
    return {row["claim"].removeprefix("ranking-"): row for row in rows.to_dict("records")}


def _claims_summary(claims_df):
    """The index's word on the claims: their count, and the failing ones by likely cause (each paper's page
    lists its own failing claims; the index does not repeat them)."""
    sentences = takeaways.claims(claims_df)[:1]
    failing = claims_df[claims_df.verdict == "fails"] if "verdict" in claims_df else claims_df.iloc[:0]
    if sentences and len(failing):
        causes = pd.Series([takeaways.likely_cause(row).split(" (")[0] for row in failing.to_dict("records")])
        counts = ", ".join(f"{n} {cause}" for cause, n in causes.value_counts().items())
        sentences.append(f"Failing claims by likely cause: {counts}; each paper's page lists its own, first.")
    return sentences


def _decision_sentences(panels, psnr_min, rankings=None):
    """Per scene of the decision panel: the fastest technique that reaches ``psnr_min``, and how it compares with
    the next one.

    ``rankings`` maps a scene to its ranking claim's row of claims.csv (an overview experiment's claim
    ``ranking-<scene>``: the next's time over the fastest's, timed together, with its interval). A ratio is said
    only from that claim, as "faster" where its interval excludes ×1 and as a tie where it does not; without one
    (times of separate jobs, fewer frames than an interval needs), or where either technique was timed on a
    disturbed machine, the ranking is said without a ratio.
    """
    rankings = rankings or {}
    sentences = []
    for item in panels:
        accurate = [r for r in item["table"] if r["accurate"]]
        if not accurate:
            sentences.append(f"{item['kind'].capitalize()} ({item['scene']}): no technique reaches "
                             f"{takeaways.number(psnr_min)} dB here.")
            continue
        best = accurate[0]
        sentence = (f"{item['kind'].capitalize()} ({item['scene']}): {best['backend']} is the fastest at "
                    f"≥ {takeaways.number(psnr_min)} dB ({best['setting']}, {best['ms']} ms, {best['psnr']} dB)")
        if len(accurate) > 1:
            sentence += _next_words(best, accurate[1], rankings.get(item["scene"]))
        sentences.append(sentence + ".")
    return sentences


def _next_words(best, runner, ranking):
    """How ``best`` compares with ``runner``, the next technique at the bar, from their ranking claim's row."""
    named = f"the next, {runner['backend']} ({runner['ms']} ms)"
    if best.get("disturbed") or runner.get("disturbed"):
        return f"; {named}, was timed while the machine was disturbed, so no ratio between them is claimed"
    verdict = (ranking or {}).get("verdict")
    measured = str((ranking or {}).get("measured", ""))
    about_them = measured.startswith(f"{runner['backend']} (") and f"/ {best['backend']} (" in measured
    if verdict not in ("holds", "inconclusive") or not about_them or not (
            _finite(ranking.get("interval_low")) and _finite(ranking.get("interval_high"))):
        why = ("timed in a separate job" if best.get("timed_with") != runner.get("timed_with")
               else "timed with too few frames for an interval")
        return f"; {named}, was {why}, so no ratio between them is claimed"
    interval = f"95 % CI ×{_ratio_end(ranking['interval_low'])}–×{_ratio_end(ranking['interval_high'])}"
    ratio = runner["time"] / best["time"]
    if verdict == "holds":
        return f", ×{takeaways.number(ratio)} faster than {named}, timed together ({interval})"
    return (f"; it ties with {named}, timed together: the next takes ×{takeaways.number(ratio)} its time, "
            f"but the interval reaches ×1 ({interval})")


def _timing(runs_df, environment, ctx):
    """What the index's timing section shows: the profile's frame budget and the disturbed and starved timings.

    ``budget`` says how many timed frames a view gets at least, with the profile's ``repeat`` and
    ``min_time`` where ``environment`` records the profile; ``disturbances`` is :func:`reports.outcomes.timing_disturbances`
    with each group's first runs linked to their records (``None`` for results written before
    disturbances were recorded).
    """
    try:
        profile = json.loads((environment or {}).get("profile") or "{}")
    except (TypeError, ValueError):
        profile = {}
    if not isinstance(profile, dict):
        profile = {}
    repeat, min_time = profile.get("repeat"), profile.get("min_time")
    budget = f"at least {takeaways.number(repeat)} of them" if _finite(repeat) else "at least the profile's repeat"
    if not _finite(min_time):
        budget += " and they took at least its min_time"
    elif float(min_time) > 0:
        budget += f" and they took at least {takeaways.number(min_time)} s"
    budget += " (the profile's repeat and min_time; a timed comparison may ask for more)"
    replicates = profile.get("replicates", 1)
    if _finite(replicates) and int(replicates) > 1:
        budget += (f", shared among the {int(replicates)} processes that time each timed run one after another "
                   "(the profile's replicates), each with its own cold frame and warm-up and at least three timed "
                   "frames")
    disturbances = outcomes.timing_disturbances(runs_df)
    if disturbances:
        for group in disturbances["disturbed"] + disturbances["starved"]:
            shown = group["runs"][:PROBLEM_RUNS_SHOWN]
            group["shown"] = [(run, ctx.file(record)) for run, record in zip(shown, group["records"])]
            group["more"] = len(group["runs"]) - len(shown)
    return {"budget": budget, "disturbances": disturbances, "replicates": int(replicates) if _finite(replicates) else 1,
            "spread": _process_spread(runs_df)}


def _process_spread(runs_df):
    """``[{"backend", "views", "between", "within", "ratio"}]``: per backend, how much a view's total time varied
    between the processes that timed it and within one (runs.csv's ``spread_between``, ``spread_within``: the
    medians over its views), widest first; empty where no view was timed in several processes."""
    if runs_df is None or "spread_between" not in runs_df:
        return []
    rows = runs_df.assign(between=pd.to_numeric(runs_df["spread_between"], errors="coerce"),
                          within=pd.to_numeric(runs_df.get("spread_within"), errors="coerce"))
    rows = rows.dropna(subset=["between"])
    out = []
    for backend, group in rows.groupby("backend"):
        between, within = float(group["between"].median()), float(group["within"].median())
        out.append({"backend": backend, "views": len(group), "between": f"{100 * between:.1f} %",
                    "within": f"{100 * within:.1f} %", "ratio": f"×{between / within:.1f}" if within > 0 else "–",
                    "order": between})
    return sorted(out, key=lambda row: -row["order"])


def _seconds(value):
    """Seconds for the harness table: ``"12.3"``, ``"1 234"``, ``"–"`` for none."""
    if value is None or not _finite(value) or float(value) <= 0:
        return "–"
    value = float(value)
    return f"{value:,.0f}".replace(",", " ") if value >= 100 else f"{value:.3g}"


def _share(part, whole):
    return f"{100 * part / whole:.0f} %" if whole and _finite(part) and _finite(whole) and whole > 0 else "–"


def _harness(account, runs_df):
    """The appendix's account of the harness itself (``None`` without one): where the run's wall time went,
    per experiment and for the whole run, and how quiet the machine was while views were timed.

    ``account`` is :func:`pipeline.harness.account` of the pipeline run that made the report.
    """
    quiet = outcomes.quiet_summary(runs_df)
    if account is None and quiet is None:
        return None
    out = {"quiet": None, "table": None}
    if quiet:
        quiet = dict(quiet)
        for key in ("orchestrator_max", "orchestrator_median", "foreign_median"):
            quiet[key] = f"{quiet[key]:.2f}" if quiet[key] is not None else None
        out["quiet"] = quiet
    if account:
        rows = []
        for row in account["rows"]:
            other = max(0.0, row["overhead"] - row["cold"] - row["startup"])
            rows.append({"name": row["name"], "experiment": row["experiment"], "steps": row["steps"],
                         "wall": _seconds(row["wall"]), "timed": _seconds(row["timed"]),
                         "untimed": _seconds(row["untimed"]), "work": _seconds(row["work"]),
                         "cold": _seconds(row["cold"]),
                         "startup": _seconds(row["startup"]), "other": _seconds(other),
                         "share": _share(row["timed"] + row["untimed"], row["wall"])})
        span = account["span"]
        out["table"] = {
            "run": account["run"], "started": account["started"], "rows": rows,
            "span": _seconds(span), "minutes": takeaways.number(span / 60, 3), "gaps": _seconds(account["gaps"]),
            "wall": _seconds(account["wall"]), "timed": _seconds(account["timed"]),
            "untimed": _seconds(account["untimed"]), "timed_share": _share(account["timed"], span),
            "frames_share": _share(account["timed"] + account["untimed"], span),
            "gaps_share": _share(account["gaps"], span)}
    return out


def _phantom_summary(phantoms):
    """What the index says of the generated phantoms (``volumes.csv``), or ``None`` without them."""
    if phantoms is None or phantoms.empty:
        return None
    rows = [{**row, "seconds": takeaways.number(row["generation_seconds"]) if pd.notna(row["generation_seconds"]) else "",
             "digest": row["sha256"][:16]} for row in phantoms.fillna({"params": ""}).to_dict("records")]
    return {"count": len(phantoms), "megabytes": takeaways.number(phantoms["bytes"].sum() / 1e6),
            "seconds": takeaways.number(phantoms["generation_seconds"].sum()), "rows": rows}


def _backend_sentences(backend_runs, planned, silent):
    """What the index says of the backends: which made frames in this run, which made none."""
    sentences = []
    made = [name for name, outcome in backend_runs.items() if outcome["ran"]]
    if backend_runs:
        sentence = (f"{len(made)} of the {len(backend_runs)} backends this profile uses made frames here "
                    f"({', '.join(made) or 'none'})")
        if silent:
            sentence += f"; {', '.join(silent)} made none (stated at the top)"
        sentences.append(sentence + ".")
    if planned:
        sentences.append(f"{len(planned)} papers have no experiment yet because their backends do not exist: "
                         + ", ".join(p["paper"] for p in planned) + " (listed below with what each needs).")
    return sentences


VERDICT_CLASSES = {"holds": "holds", "fails": "fails", "inconclusive": "inconclusive", "blocked": "blocked",
                   "not measured": "unmeasured"}
"""A claim's verdict → its CSS class (its colour in every table), in the order the report counts them."""


_INTERVAL_WORDS = re.compile(r"\s*\(95 % CI ([^()]+)\)")
"""The interval a check writes into its ``measured`` text (``"×1.12 (95 % CI ×1.08–×1.17)"``)."""


def _finite(value):
    try:
        return math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


def margin_words(margin):
    """``"+12 %"``: a claim's margin (relative, positive on the holding side) in words; ``"—"`` without one."""
    if not _finite(margin):
        return "—"
    percent = 100 * float(margin)
    size = f"{abs(percent):.0f}" if abs(percent) >= 100 else takeaways.number(abs(percent), 2)
    return f"{'−' if percent < 0 and size != '0' else '+'}{size} %"


def claim_cells(claim):
    """A claim of ``claims.csv`` as its row of a page's claims table: ``measured``, ``interval``, ``margin``.

    The check writes the interval into ``measured`` in the value's own unit; the table shows it in a
    column of its own. Where it did not, the interval comes from ``interval_low``/``interval_high``
    (a ratio where the measured value is one, else in the value's unit: milliseconds where the value
    says ``ms``). ``"—"`` where the claim has no interval (it rests on counts, images, a single frame,
    or results written before intervals existed). ``behind`` says what a timing interval rests on: the
    timed frames of its thinnest arm (``frames``).
    """
    measured = str(claim.get("measured") or "")
    found = _INTERVAL_WORDS.search(measured)
    if found:
        interval = found.group(1).strip()
        measured = (measured[:found.start()] + measured[found.end():]).strip()
    elif _finite(claim.get("interval_low")) and _finite(claim.get("interval_high")):
        low, high = float(claim["interval_low"]), float(claim["interval_high"])
        if measured.startswith("×"):
            interval = f"×{takeaways.number(low)}–×{takeaways.number(high)}"
        elif re.match(r"^\S+ ms\b", measured):
            interval = f"{takeaways.number(low * 1e3)}–{takeaways.number(high * 1e3)} ms"
        else:
            interval = f"{takeaways.number(low)}–{takeaways.number(high)}"
    else:
        interval = "—"
    frames, processes = claim.get("frames"), claim.get("processes")
    behind = ""
    if interval != "—" and _finite(frames):
        behind = f"{int(float(frames))} frames"
        if _finite(processes):
            count = int(float(processes))
            behind = f"{count} process{'es' * (count != 1)}, {behind}"
    return {"measured": measured, "interval": interval, "behind": behind,
            "margin": margin_words(claim.get("margin"))}


def _verdicts(claims_df):
    """The ``verdict`` column of a claims table; one written before verdicts existed is read from ``holds``."""
    if "verdict" in claims_df:
        verdicts = claims_df["verdict"].where(claims_df["verdict"].isin(list(VERDICT_CLASSES)))
    else:
        verdicts = pd.Series(None, index=claims_df.index, dtype=object)
    from_holds = claims_df.get("holds", pd.Series(None, index=claims_df.index)).map(
        {True: "holds", False: "fails"}).fillna("not measured")
    return verdicts.fillna(from_holds)
