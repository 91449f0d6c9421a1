"""Tests of the HTML report (reports.html, reports.takeaways) on a small synthetic results folder.

:func:`synthetic_report` writes the records a pipeline run would write (images, JSON records,
metrics), without rendering: each run's image is a fixed picture plus an error that grows with
its step, so the numbers and the pictures agree. The browser test (test_report_browser.py)
reuses it.
"""

import html
import json
import re
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pandas as pd
import pytest

import datasets
from pipeline.collect import collect, phantom_manifest
from pipeline.experiments import Profile, plan, selected
from pipeline.experiments import papers
from pipeline.experiments.planned import planned, techniques
from pipeline.rendering import evaluate
from pipeline.records import metrics_record_path, run_record_path, write_json
from pipeline.scene_io import phantom_requests
from reports import blocks, outcomes, takeaways
from reports.html import build_report, provenance
from reports.imageio import read_image, write_exr, write_png

SIZE = 24
ENVIRONMENT = {"date": "2025-01-31 14:05", "cpu_model": "Test CPU 9000", "cpu_cores": 2,
               "memory_bytes": 8 * 1024 ** 3, "numba_threads": 2, "git_commit": "abc123", "hostname": "test"}
REAL_DATA = {"folder": "/data/real", "error": "", "sources_file": "/data/real/SOURCES.md",
             "datasets": [{"name": "cthead", "file": "cthead_256x256x99_uint8.raw", "modality": "CT head",
                           "source": "example/repo @ 0123 : cthead"}]}
BACKENDS = [{"name": "reference", "available": True, "reason": "", "description": "CPU ray caster"},
            {"name": "gl-raycast", "available": False, "reason": "no OpenGL 4.3 context (EGL missing)",
             "description": "OpenGL ray caster"},
            # Its probe passes on the machine that builds the report while every run of it failed (issue 20).
            {"name": "cl-tiled", "available": True, "reason": "", "description": "OpenCL tiled caster"}]


def _truth_image(seed):
    y, x = np.mgrid[0:SIZE, 0:SIZE] / (SIZE - 1)
    alpha = np.clip(1.2 - np.hypot(x - 0.5, y - 0.5) * 2, 0, 1)
    rgb = np.stack([0.3 + 0.6 * x, 0.4 + 0.2 * np.sin(6 * y + seed), 0.5 * np.ones_like(x)], axis=-1)
    return np.concatenate([rgb * alpha[..., None], alpha[..., None]], axis=-1).astype(np.float32)


def _image(run):
    """The truth picture of the run's scene, plus an error ∝ step² (none for a truth run)."""
    scene = run.tags.get("scene", run.tags.get("dataset", "x"))
    image = _truth_image(sum(map(ord, scene)) % 7)
    step = float(run.options.get("step_factor", 1.0))
    if run.reference is not None:
        y, x = np.mgrid[0:SIZE, 0:SIZE] / (SIZE - 1)
        image = image.copy()
        image[..., 0] = np.clip(image[..., 0] + 0.04 * step ** 2 * np.sin(9 * x) * image[..., 3], 0, image[..., 3])
    return image


def _record(run, results, status="ok", reason="", cause=""):
    record = {"experiment": run.experiment, "run": run.id, "backend": run.backend, "options": run.options,
              "tags": run.tags, "reference": run.reference, "spec_hash": run.spec_hash(), "status": status,
              "reason": reason, "cause": cause, "planned_views": [view["view"] for view in run.views],
              "views": [], "statistics": None, "environment": dict(ENVIRONMENT),
              "backend_environment": {"numba": "0.0", "numba_threads": 2}}
    path = run_record_path(results, run.experiment, run.id)
    if status == "ok":
        folder = path.with_suffix("")
        folder.mkdir(parents=True, exist_ok=True)
        step = float(run.options.get("step_factor", 1.0))
        total = 2e-3 / step
        for view in run.views:
            image = _image(run)
            exr, png = folder / f"{view['view']}.exr", folder / f"{view['view']}.png"
            write_exr(exr, image)
            write_png(png, image)
            record["views"].append({
                "view": view["view"], "camera": {}, "exr": str(exr), "png": str(png),
                "timings": {"total": total, "prepare": 0.25 * total, "render": 0.75 * total},
                "timings_min": {"total": 0.9 * total, "prepare": 0.2 * total, "render": 0.7 * total},
                "timings_max": {"total": 1.3 * total, "prepare": 0.3 * total, "render": 1.0 * total},
                "counters": {"samples": 1000}, "info": {"frames": run.repeat, "warmup": run.warmup},
                # A timed run's frames, spread 2 % about their median, in two processes as the default
                # profile times them: its claims get intervals (one process decides no timing claim).
                **(_timed_processes(total, run.repeat) if run.repeat > 1 else {})})
        if run.statistics:
            record["statistics"] = {"nontransparent_fraction": 0.06, "empty_block_fraction": 0.3,
                                    "runs_per_scanline": 4.0, "mean_run_length": 2.5, "megabytes": 0.1, "size": 8}
    write_json(path, record)
    return path


def _timed_processes(total, repeat):
    """A timed view's ``frames`` and ``processes`` as :func:`pipeline.records.merge_processes` writes them for two
    processes that timed the same ``repeat`` frames about ``total`` seconds."""
    frames = [total * (0.98 + 0.01 * (i % 5)) for i in range(repeat)]
    return {"frames": {"total": frames + frames},
            "processes": [{"pid": pid, "frames": {"total": frames}, "timings": {"total": total}} for pid in (11, 12)]}


def _volbench_outcome(run):
    """``(status, reason, cause)`` of a run in the synthetic volbench results: no real engine, one failure."""
    if run.tags.get("dataset") == "engine_real":
        return "skipped", "real data set 'engine_real' is unavailable: no such file. Point volbench at it", "no-data"
    if run.id == "engine-semi.reference.0":
        return "failed", "RuntimeError: kaboom", "error"
    return "ok", "", ""


VOLBENCH_EXPERIMENTS = ["volbench-phantoms", "volbench-convergence", "volbench-speed-accuracy"]
VOLBENCH_SETTINGS = {"volbench-phantoms": {"datasets": ["ct_skull", "cthead", "sphere", "engine_real"]},
                     "volbench-convergence": {"step_factors": [2.0, 1.0, 0.5, 0.25]}}


def synthetic_results(root, *, experiments=VOLBENCH_EXPERIMENTS, settings=VOLBENCH_SETTINGS, outcome=_volbench_outcome):
    """A results folder with every experiment's records, metrics and CSVs, as the pipeline writes them.

    ``outcome(run)`` gives each run's ``(status, reason, cause)``; a run whose status is ``ok`` gets its
    images. Returns ``(runs_df, claims_df, experiments, results_dir)``.
    """
    results = Path(root) / "results"
    # volbench's own pages by default; the papers' experiments test their report code with their own data.
    profile = Profile(name="t", volume_size=8, image_size=SIZE, results=str(results), cache=str(Path(root) / "cache"),
                      experiments=list(experiments), settings=dict(settings))
    runs = plan(profile)
    paths = [_record(run, results, *outcome(run)) for run in runs.values()]
    for run in runs.values():
        if run.reference is not None:
            evaluate(run_record_path(results, run.experiment, run.id),
                     run_record_path(results, run.experiment, run.reference),
                     metrics_record_path(results, run.experiment, run.id))
    experiments = selected(profile)
    runs_df, claims_df = collect(paths, experiments, results_dir=results)
    write_json(results / "environment.json", ENVIRONMENT)
    requests = phantom_requests([entry for run in runs.values() for entry in run.volume_entries],
                                size=profile.volume_size)
    for request in requests.values():
        datasets.load(request["dataset"], cache_dir=profile.cache, **request["kwargs"])
    phantom_manifest(requests, cache_dir=profile.cache).to_csv(results / "volumes.csv", index=False)
    return pd.read_csv(results / "runs.csv", low_memory=False), claims_df, experiments, results


def synthetic_report(root, **options):
    """Build the report of :func:`synthetic_results` (``options`` go to it); return the path of ``index.html``."""
    runs_df, claims_df, experiments, results = synthetic_results(root, **options)
    return build_report(runs_df, claims_df, experiments, results_dir=results, environment=ENVIRONMENT,
                        backends=BACKENDS, planned=planned(["reference"], papers().values()), real_data=REAL_DATA,
                        phantoms=pd.read_csv(results / "volumes.csv"), techniques=techniques(papers().values()))


class _Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.links, self.ids, self.rows = [], set(), []
        self._row = None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if "id" in attrs:
            self.ids.add(attrs["id"])
        for key in ("href", "src"):
            if attrs.get(key):
                self.links.append((tag, attrs[key]))
                if self._row is not None:
                    self._row.append(attrs[key])
        if tag == "tr":
            self._row = []
            self.rows.append(self._row)


def page_links(path):
    parser = _Links()
    parser.feed(Path(path).read_text())
    return parser


def broken_links(report_dir):
    """``[(page, link)]`` for every local link or image of every page that does not resolve on disk."""
    report_dir = Path(report_dir)
    broken = []
    pages = {p.name: page_links(p) for p in report_dir.glob("*.html")}
    for name, parser in pages.items():
        for _tag, link in parser.links:
            parts = urlsplit(link)
            if parts.scheme or parts.netloc:
                broken.append((name, link))  # the report must not need the network
                continue
            target = (report_dir / unquote(parts.path)) if parts.path else report_dir / name
            if not target.is_file():
                broken.append((name, link))
            elif parts.fragment and target.suffix == ".html":
                if parts.fragment not in pages.get(target.name, page_links(target)).ids:
                    broken.append((name, link))
    return broken


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    return synthetic_report(tmp_path_factory.mktemp("report"))


def test_every_link_and_image_resolves_inside_the_report(report):
    assert broken_links(report.parent) == []
    assert {p.name for p in report.parent.glob("*.html")} == {"index.html", "volbench.html", "appendix.html"}


def test_index_has_the_techniques_by_data_sets_table_with_links(report):
    text = report.read_text()
    section = text[text.index('id="techniques"'):text.index('id="papers"')]
    for name in ("skull-bone", "engine-semi", "reference", "step 0.5 voxel", "PSNR", "SSIM", "FLIP", " ms"):
        assert name in section, name
    records = re.findall(r'href="(data/runs/volbench-speed-accuracy/[^"]+\.json)"', section)
    exrs = re.findall(r'href="(data/runs/volbench-speed-accuracy/[^"]+\.exr)"', section)
    # Every sweep run that rendered (all but the one failed) has its record and EXR.
    runs = pd.read_csv(report.parent.parent / "runs.csv", low_memory=False)
    rendered = runs[(runs.experiment == "volbench-speed-accuracy") & (runs.role == "sweep") & (runs.status == "ok")]
    assert len(records) == len(exrs) == len(rendered) >= 7
    assert json.loads((report.parent / records[0]).read_text())["experiment"] == "volbench-speed-accuracy"
    assert "not run" in section  # the failed cell
    assert (report.parent / "csv" / "techniques.csv").is_file()


def test_index_lists_unavailable_backends_and_planned_papers(report):
    text = report.read_text()
    assert "no OpenGL 4.3 context (EGL missing)" in text
    for paper in ("Lacroute 1995", "Krüger", "Kainz"):
        assert paper in text
    assert "backend not implemented yet" in text and "shearwarp, volpack" in text


def test_pages_show_provenance_and_takeaways(report):
    for page in ("appendix.html", "volbench.html"):  # the index opens with the decision panel instead
        text = (report.parent / page).read_text()
        for fact in ("2025-01-31 14:05", "Test CPU 9000", "8.0 GiB", "Numba threads", "/data/real"):
            assert fact in text, (page, fact)
    for page in ("index.html", "volbench.html"):
        assert 'class="takeaways"' in (report.parent / page).read_text()
    page = (report.parent / "volbench.html").read_text()
    assert "At ≥ 40 dB PSNR the fastest setting on skull-bone is" in page
    assert "observed order" in page
    # engine_real under two presets (no data), and one failure: each message once, with its count.
    assert "3 runs made no frame: reference × 2" in page and "reference × 1 (engine-semi.reference.0): RuntimeError: kaboom" in page
    # The take-aways sit above the first section.
    assert page.index('class="takeaways"') < page.index('<section id="volbench-phantoms"')


def test_every_run_table_row_links_its_record_and_exr(report):
    parser = page_links(report.parent / "volbench.html")
    data_rows = [row for row in parser.rows if any(link.endswith(".exr") for link in row)]
    assert len(data_rows) >= 3 + 12 + 7  # phantoms ok, convergence sweep, speed sweep
    for row in data_rows:
        assert any(link.endswith(".json") for link in row), row


def test_difference_images_share_one_fixed_scale_with_a_colour_bar(report):
    page = (report.parent / "volbench.html").read_text()
    assert "plots/colorbar-0.1.svg" in page and "0 (black) to 0.1" in page
    diffs = sorted((report.parent / "img" / "diff").rglob("*-diff-0.1.png"))
    assert diffs
    # Error ∝ step²: step 2 shows far brighter than step 0.25 on the same scale.
    by_name = {p.parent.name: read_image(p)[..., :3].mean() for p in diffs if "skull-bone" in p.parent.name}
    assert by_name["skull-bone.step2"] > 5 * by_name["skull-bone.step0.25"]


def test_phantom_beside_real_scan_and_untimed_frames_labelled(report):
    page = (report.parent / "volbench.html").read_text()
    assert "ct_skull stands in for cthead" in page
    gallery = page[page.index("Phantoms beside the real scans"):]
    assert "phantom ct_skull" in gallery and "real scan cthead" in gallery
    assert "single untimed frame" in page.lower()
    assert "Real scan (CT head)" not in gallery.split("Every reference render")[1]  # paired scans are not repeated


def test_the_appendix_lists_every_phantom_with_the_digest_of_its_data(report):
    phantoms = pd.read_csv(report.parent / "csv" / "volumes.csv")
    assert not phantoms.empty and phantoms["sha256"].str.len().eq(64).all()
    assert 'id="phantoms"' not in report.read_text()
    section = (report.parent / "appendix.html").read_text().split('id="phantoms"')[1].split("<h2")[0]
    assert f"{len(phantoms)} phantoms" in section and 'href="csv/volumes.csv"' in section
    for row in phantoms.itertuples():
        assert f"<code>{row.sha256[:16]}</code>" in section and row.dataset in section


def test_images_open_full_size(report):
    page = (report.parent / "volbench.html").read_text()
    for src in re.findall(r'<img src="(img/[^"]+)"', page):
        assert f'<a href="{src}"><img src="{src}"' in page


# ------------------------------------------------------------------------------------ take-aways
def _settings(times, psnrs):
    return pd.DataFrame({"scene": "skull", "technique": [f"ref (step={s})" for s in (2, 1, 0.5)],
                         "time_total": times, "psnr": psnrs})


def test_fastest_at_accuracy_follows_the_numbers():
    frame = _settings([0.001, 0.002, 0.004], [30.0, 45.0, 60.0])
    assert takeaways.fastest_at_accuracy(frame) == [
        "At ≥ 40 dB PSNR the fastest setting on skull is ref (step 1) at 2 ms (45 dB), "
        "×2 faster than the slowest that gets there."]
    frame = _settings([0.001, 0.002, 0.004], [41.0, 45.0, 60.0])
    assert "ref (step 2) at 1 ms (41 dB)" in takeaways.fastest_at_accuracy(frame)[0]
    frame = _settings([0.001, 0.002, 0.004], [20.0, 25.0, 30.0])
    assert takeaways.fastest_at_accuracy(frame) == [
        "On skull no setting reaches 40 dB PSNR; the most accurate is ref (step 0.5) at 30 dB (4 ms)."]


def test_accuracy_failures_name_the_failing_settings():
    frame = _settings([0.001, 0.002, 0.004], [30.0, 35.0, 60.0])
    sentence = takeaways.accuracy_failures(frame)[0]
    assert sentence.index("ref (step 2) on skull (30 dB)") < sentence.index("ref (step 1) on skull (35 dB)")
    assert takeaways.accuracy_failures(_settings([1, 2, 3], [50.0, 55.0, 60.0])) == [
        "Every setting reaches 40 dB PSNR on every scene (worst 50 dB)."]


def test_claims_sentence_counts_and_names_failures():
    claims = pd.DataFrame({"statement": ["a", "b", "c", "d"], "expected": ["≥ 1"] * 4,
                           "measured": ["2", "0.5", "3", "n/a"], "holds": [True, False, True, None]})
    assert takeaways.claims(claims) == [
        "2 of 3 measured claims hold; 1 fail; 1 not measured.",
        "Fails: b (measured 0.5, expected ≥ 1); likely cause: cause not determined."]
    claims.loc[1, "holds"] = True
    assert takeaways.claims(claims) == ["3 of 3 measured claims hold; 1 not measured."]


def test_a_target_of_ours_failing_beside_the_papers_number_is_one_failure():
    claims = pd.DataFrame({"experiment": ["e"] * 3, "statement": ["paper ×3", "ours ≥ ×2", "other"],
                           "expected": ["≥ 3", "≥ 2", "≥ 1"], "measured": ["1.5", "1.5", "0.5"],
                           "target": ["paper", "ours", "paper"], "paper_value": ["×3", "×3", ""],
                           "holds": [False, False, False]})
    sentences = [str(s) for s in takeaways.claims(claims)]
    assert sentences[0] == "0 of 3 measured claims hold; 3 fail."  # counted, each a verdict of its own
    assert [s.split(" (")[0] for s in sentences[1:]] == ["Fails: paper ×3", "Fails: other"]
    assert "our own looser target fails too" in sentences[1]
    claims.loc[1, "holds"] = True  # ours holds: the paper's failure is said alone
    assert not any("looser" in str(s) for s in takeaways.claims(claims))


def test_order_range_and_problems():
    assert takeaways.order_range({"a": 1.31, "b": 2.04})[0].startswith("The error falls with the step at observed "
                                                                      "order 1.3–2 (a 1.3, b 2)")
    runs = outcomes.per_run(pd.DataFrame({
        "experiment": "e", "run": ["x", "y", "z", "w"], "backend": ["b", "b", "c", "c"],
        "status": ["skipped", "failed", "failed", "skipped"], "cause": ["no-data", "error", "error", "unsupported"],
        "reason": ["data absent", "boom at 0x7f00aa11bb22", "boom at 0x7f00cc33dd44", "no mip"]}))
    # One fault with different object addresses is one message; a planned limit is said apart.
    assert takeaways.problems(outcomes.problem_groups(runs)) == [
        "3 runs made no frame: b × 1 (x): data absent; b × 1 (y): boom at 0x…; c × 1 (z): boom at 0x….",
        "1 run was skipped as a planned limit: c × 1 (w): no mip."]


def test_provenance_prefers_the_runs_own_facts():
    runs = pd.DataFrame({"date": ["2025-01-02 10:00", "2025-01-01 09:00"], "numba_threads": [4, 4]})
    facts = dict(provenance({"cpu_model": "X", "cpu_cores": 8, "memory_bytes": 2 ** 34}, runs, None))
    assert facts["run date (UTC)"] == "2025-01-01 09:00 to 2025-01-02 10:00"
    assert facts["Numba threads"] == "4" and facts["memory"] == "16.0 GiB" and facts["cores"] == "8"
    assert dict(provenance({}, None, None))["memory"] == "not recorded"


def test_a_section_whose_column_no_run_reported_says_so_instead_of_crashing():
    from reports.html import _experiment_blocks

    class NeedsACounter:
        name = "needs-a-counter"

        def report(self, results, ctx):
            return [results["count_voxel_runs"]]

    class Broken:
        name = "broken"

        def report(self, results, ctx):
            raise ValueError("a real bug stays loud")

    frame = pd.DataFrame({"count_samples": [1, 2]})
    (block,) = _experiment_blocks(NeedsACounter(), frame, None)
    assert "Not measurable here" in block.text and "count_voxel_runs" in block.text
    with pytest.raises(ValueError, match="stays loud"):
        _experiment_blocks(Broken(), frame, None)


def test_a_section_whose_timings_span_nodes_opens_by_saying_so():
    from reports.html import _experiment_blocks

    class Ratio:
        name = "ratio"

        def report(self, results, ctx):
            return [blocks.Text("a ratio")]

    one = pd.DataFrame({"status": ["ok", "ok"], "node": ["a", "a"]})
    assert [b.text for b in _experiment_blocks(Ratio(), one, None)] == ["a ratio"]
    two = one.assign(node=["a", "b"])
    warning, body = _experiment_blocks(Ratio(), two, None)
    assert "different nodes (a, b)" in warning.text and "ratio" in warning.text and body.text == "a ratio"
    failed_elsewhere = pd.DataFrame({"status": ["ok", "failed"], "node": ["a", "b"]})
    assert len(_experiment_blocks(Ratio(), failed_elsewhere, None)) == 1


# ------------------------------------------------------------------- a backend that cannot run here
POCL_FAULT = ("backend 'cl-tiled' is not available here: PoCL 9.9 (LLVM 99) cannot build kernels for pthread-Zen 9: "
              "error: unknown target CPU 'generic'. To fix: install Debian's pocl-opencl-icd (make setup does)")


def _cl_cannot_run(run):
    if run.backend == "cl-tiled":
        return "skipped", POCL_FAULT, "unavailable"
    return "ok", "", ""


@pytest.fixture(scope="module")
def silent_backend_report(tmp_path_factory):
    return synthetic_report(tmp_path_factory.mktemp("silent"), experiments=["volbench-speed-accuracy", "kainz2009-scaling"],
                            settings={}, outcome=_cl_cannot_run)


def test_a_backend_that_made_no_frame_is_stated_once_at_the_top(silent_backend_report):
    index = html.unescape(silent_backend_report.read_text())
    assert index.count("cannot build kernels for pthread-Zen 9") == 1
    alerts = index[index.index('class="alerts"'):index.index('class="takeaways"')]
    runs = pd.read_csv(silent_backend_report.parent / "csv" / "runs.csv", low_memory=False)
    count = runs[runs.backend == "cl-tiled"].drop_duplicates(["experiment", "run"]).shape[0]
    message = POCL_FAULT.removeprefix("backend 'cl-tiled' is not available here: ")
    assert f"cl-tiled made no frame here (0 of {count} runs): it cannot run here: {message}" in alerts
    assert "not reproduced on this machine (cl-tiled made no frame)" in alerts
    papers = index[index.index('id="papers"'):index.index('id="backends"')]
    assert "made no frame" in papers and "blocked" in papers
    backends = index[index.index('id="backends"'):]
    assert f"0 of {count} runs" in backends
    assert "9 of the 10 backends this profile uses made frames here" in index and "cl-tiled made none" in index


def test_a_paper_whose_technique_made_no_frame_is_not_reproduced_and_its_claims_blocked(silent_backend_report):
    page = html.unescape((silent_backend_report.parent / "kainz2009.html").read_text())
    assert page.count("cannot build kernels for pthread-Zen 9") == 1
    assert page.index("Not reproduced on this machine") < page.index('class="takeaways"')
    assert "cl-tiled ran on" not in page and "cl-tiled on " not in page  # no page says it ran
    claims = pd.read_csv(silent_backend_report.parent / "csv" / "claims.csv")
    kainz = claims[claims.experiment == "kainz2009-scaling"].set_index("claim")
    assert kainz.loc["flat-volumes", "verdict"] == "blocked"
    assert "cl-tiled, which cannot run here" in kainz.loc["flat-volumes", "detail"]
    assert '<td class="verdict blocked">blocked</td>' in page
    # What did run is still shown: depth peeling's runs are charted and tabled with their images.
    assert 'src="plots/kainz2009-scaling-time.svg"' in page
    assert re.search(r'href="data/runs/kainz2009-scaling/clouds\.n01\.gl-peel/[^"]+\.exr"', page)


def test_files_of_one_name_from_two_folders_outside_the_results_stay_apart(tmp_path):
    from reports.html import ReportContext

    (tmp_path / "a").mkdir(), (tmp_path / "b").mkdir()
    (tmp_path / "a" / "head.json").write_text("a"), (tmp_path / "b" / "head.json").write_text("b")
    ctx = ReportContext(tmp_path / "report", tmp_path / "results", "x")
    first, second = ctx.file(tmp_path / "a" / "head.json"), ctx.file(tmp_path / "b" / "head.json")
    assert first != second
    assert [(tmp_path / "report" / path).read_text() for path in (first, second)] == ["a", "b"]


def test_a_takeaway_keeps_its_importance_across_processes():
    import pickle

    sentence = takeaways.Takeaway("A claim fails.", takeaways.FAILING_CLAIM)
    copy = pickle.loads(pickle.dumps(sentence))
    assert copy == sentence and copy.importance == takeaways.FAILING_CLAIM


def test_index_counts_the_verdicts_of_each_kind_of_claim(report):
    claims = pd.read_csv(report.parent / "csv" / "claims.csv")
    html = report.read_text()
    assert "claims that measure" in html
    for kind, words in (("count", "a count"), ("accuracy", "an image&#39;s accuracy"),
                        ("timing", "a timing")):
        part = claims[claims.kind == kind]
        assert not part.empty
        held = int((part.verdict == "holds").sum())
        assert f'<td class="text">{words}</td>\n<td class="holds">{held}</td>' in html
    volbench = (report.parent / "volbench.html").read_text()
    assert "<th class=\"text\">kind</th>" in volbench and '<td class="text kind">accuracy</td>' in volbench
