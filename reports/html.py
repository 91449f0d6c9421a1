"""The static HTML report: ``index.html`` plus one page per paper, CSV and SVG beside them.

Everything a page shows lives inside the report folder (images and charts are copied in), so the
folder opens from disk and can be moved or archived as a whole.
"""

import shutil
from dataclasses import dataclass, field
from pathlib import Path

import jinja2
import pandas as pd

from core.papers import PAPERS
from reports import blocks

TEMPLATES = Path(__file__).parent / "templates"


@dataclass
class ReportContext:
    """What an experiment's ``report`` method uses to place files in the report folder."""

    report_dir: Path
    results_dir: Path
    experiment: str
    _copied: set = field(default_factory=set)

    def image(self, path):
        """Copy an image from the results folder into the report; return its relative path."""
        if path is None or (isinstance(path, float) and pd.isna(path)):
            return None
        source = Path(path)
        try:
            relative = source.resolve().relative_to(self.results_dir.resolve())
        except ValueError:
            relative = Path("external") / source.name
        target = self.report_dir / "img" / relative
        if target not in self._copied:
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source, target)
            self._copied.add(target)
        return str(Path("img") / relative)

    def plot_path(self, name):
        """``(absolute path, relative path)`` for an SVG chart of this experiment."""
        relative = Path("plots") / f"{self.experiment}-{name}.svg"
        absolute = self.report_dir / relative
        absolute.parent.mkdir(parents=True, exist_ok=True)
        return absolute, str(relative)


def _format_cell(value):
    if isinstance(value, float):
        if pd.isna(value):
            return ""
        return f"{value:.4g}"
    return value


def _table_html(frame):
    shown = frame.map(_format_cell) if not frame.empty else frame
    return shown.to_html(index=False, escape=True, border=0, classes="data", na_rep="")


def _render_block(block, report_dir):
    if isinstance(block, blocks.Table):
        csv = None
        if block.csv_name:
            csv = f"csv/{block.csv_name}"
            (report_dir / "csv").mkdir(exist_ok=True)
            block.frame.to_csv(report_dir / csv, index=False)
        return {"kind": "table", "title": block.title, "caption": block.caption, "html": _table_html(block.frame), "csv": csv}
    if isinstance(block, blocks.Figure):
        return {"kind": "figure", "title": block.title, "caption": block.caption, "path": block.path}
    if isinstance(block, blocks.Gallery):
        return {"kind": "gallery", "title": block.title, "caption": block.caption, "items": block.items}
    if isinstance(block, blocks.Text):
        return {"kind": "text", "text": block.text}
    raise TypeError(f"unknown report block {type(block).__name__}")


def _status_summary(frame):
    if frame.empty:
        return {"ok": 0, "skipped": 0, "failed": 0}, []
    per_run = frame.drop_duplicates(["experiment", "run"])
    counts = per_run.status.value_counts().to_dict()
    problems = per_run[per_run.status != "ok"].reindex(columns=["run", "backend", "status", "reason"]).to_dict("records")
    return {s: int(counts.get(s, 0)) for s in ("ok", "skipped", "failed")}, problems


def build_report(runs_df, claims_df, experiments, *, results_dir, environment):
    """Write the report into ``results_dir/report``; return the path of ``index.html``."""
    results_dir = Path(results_dir)
    report_dir = results_dir / "report"
    if report_dir.exists():
        shutil.rmtree(report_dir)
    (report_dir / "csv").mkdir(parents=True)
    for csv in [results_dir / "runs.csv", results_dir / "claims.csv",
                *(results_dir / f"{e.name}.csv" for e in experiments)]:
        if csv.exists():
            shutil.copyfile(csv, report_dir / "csv" / csv.name)
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES), autoescape=True,
                             undefined=jinja2.StrictUndefined, keep_trailing_newline=True)
    pages = {}
    for experiment in experiments:
        frame = runs_df[runs_df.experiment == experiment.name].dropna(axis=1, how="all")
        ctx = ReportContext(report_dir, results_dir, experiment.name)
        counts, problems = _status_summary(frame)
        claims = claims_df[claims_df.experiment == experiment.name].to_dict("records")
        paper_table = experiment.paper_table()
        section = {
            "name": experiment.name, "title": experiment.title, "description": experiment.description,
            "counts": counts, "problems": problems, "claims": claims,
            "paper_table": _table_html(paper_table) if paper_table is not None else None,
            "blocks": [_render_block(b, report_dir) for b in experiment.report(frame, ctx)] if counts["ok"] else [],
            "csv": f"csv/{experiment.name}.csv",
        }
        pages.setdefault(experiment.paper, []).append(section)
    page_template = env.get_template("paper.html")
    summaries = []
    for paper, sections in pages.items():
        (report_dir / f"{paper}.html").write_text(page_template.render(
            paper=paper, paper_title=PAPERS.get(paper, paper), sections=sections, environment=environment))
        claims = [c for s in sections for c in s["claims"]]
        summaries.append({
            "paper": paper, "title": PAPERS.get(paper, paper), "page": f"{paper}.html",
            "experiments": [(s["name"], s["title"]) for s in sections],
            "claims_hold": sum(c["holds"] is True for c in claims),
            "claims_fail": sum(c["holds"] is False for c in claims),
            "claims_unmeasured": sum(c["holds"] is None or pd.isna(c["holds"]) for c in claims),
            "runs": {k: sum(s["counts"][k] for s in sections) for k in ("ok", "skipped", "failed")},
        })
    index = report_dir / "index.html"
    index.write_text(env.get_template("index.html").render(papers=summaries, environment=environment))
    return index
