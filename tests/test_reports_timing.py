"""The report's side of timing by intervals: the fifth verdict, the claims table's interval and margin
cells, and the disturbed and starved timings (reports.html, reports.outcomes, reports.takeaways)."""

import html
import json
import re

import numpy as np
import pandas as pd
import pytest

from pipeline.experiments.kit.verdicts import VERDICTS
from reports import outcomes, takeaways
from reports.html import VERDICT_CLASSES, _verdicts, build_report, claim_cells, margin_words


# ---------------------------------------------------------------------------------------- verdicts
def test_every_verdict_has_a_class_in_the_order_the_kit_counts_them():
    assert tuple(VERDICT_CLASSES) == VERDICTS


def test_an_inconclusive_verdict_is_read_as_such_not_from_holds():
    claims = pd.DataFrame({"verdict": ["inconclusive", "holds", None], "holds": [None, True, False]})
    assert list(_verdicts(claims)) == ["inconclusive", "holds", "fails"]


def test_the_claims_sentence_counts_inconclusive_claims_as_measured_and_names_them():
    claims = pd.DataFrame({"statement": ["a", "b", "c", "d"], "expected": ["≥ ×2"] * 4,
                           "measured": ["×3", "×1.5", "×2.1 (95 % CI ×1.9–×2.3)", "n/a"],
                           "verdict": ["holds", "fails", "inconclusive", "not measured"]})
    assert takeaways.claims(claims) == [
        "1 of 3 measured claims hold; 1 fail; 1 inconclusive; 1 not measured.",
        "Fails: b (measured ×1.5, expected ≥ ×2); likely cause: cause not determined.",
        "Inconclusive (cause not determined × 1): c (measured ×2.1 (95 % CI ×1.9–×2.3), expected ≥ ×2)."]


# ------------------------------------------------------------------------------ interval and margin
@pytest.mark.parametrize("claim, cells", [
    # The check's own words of its interval, in a column of their own.
    # With the timed frames of its thinnest arm beneath it.
    ({"measured": "×1.12 (95 % CI ×1.08–×1.17)", "interval_low": 1.08, "interval_high": 1.17, "margin": 0.12,
      "frames": 12.0}, {"measured": "×1.12", "interval": "×1.08–×1.17", "behind": "12 frames", "margin": "+12 %"}),
    # With the processes that timed them.
    ({"measured": "×1.12", "interval_low": 1.08, "interval_high": 1.17, "margin": 0.12, "frames": 6.0,
      "processes": 2.0}, {"measured": "×1.12", "interval": "×1.08–×1.17", "behind": "2 processes, 6 frames",
                          "margin": "+12 %"}),
    ({"measured": "×1.12", "interval_low": 1.08, "interval_high": 1.17, "margin": 0.12, "frames": 5,
      "processes": 1}, {"measured": "×1.12", "interval": "×1.08–×1.17", "behind": "1 process, 5 frames",
                        "margin": "+12 %"}),
    ({"measured": "12.3 ms (engine) (95 % CI 11.9–13 ms)", "interval_low": 0.0119, "interval_high": 0.013,
      "margin": -0.023, "frames": 5},
     {"measured": "12.3 ms (engine)", "interval": "11.9–13 ms", "behind": "5 frames", "margin": "−2.3 %"}),
    # A check that did not write it: from the numbers, in the measured value's unit.
    ({"measured": "×0.862", "interval_low": 0.8175, "interval_high": 1.1089, "margin": -0.569},
     {"measured": "×0.862", "interval": "×0.818–×1.11", "behind": "", "margin": "−57 %"}),
    ({"measured": "2.5 ms", "interval_low": 0.0024, "interval_high": 0.0026, "margin": 128.3},
     {"measured": "2.5 ms", "interval": "2.4–2.6 ms", "behind": "", "margin": "+12830 %"}),
    ({"measured": "1.97", "interval_low": 1.9, "interval_high": 2.05, "margin": 0.0, "frames": np.nan},
     {"measured": "1.97", "interval": "1.9–2.05", "behind": "", "margin": "+0 %"}),
    # Counts and images have no interval; older results have neither column.
    ({"measured": "67.4 dB", "interval_low": np.nan, "interval_high": np.nan, "margin": 0.35},
     {"measured": "67.4 dB", "interval": "—", "behind": "", "margin": "+35 %"}),
    ({"measured": "×2"}, {"measured": "×2", "interval": "—", "behind": "", "margin": "—"}),
])
def test_claim_cells_show_the_interval_and_the_margin(claim, cells):
    assert claim_cells(claim) == cells


def test_margin_words_of_no_margin():
    assert margin_words(None) == margin_words(np.nan) == margin_words("") == "—"


# ----------------------------------------------------------------------- disturbed and starved runs
def _rows(**columns):
    base = {"experiment": ["e1", "e1", "e1", "e2", "e2"], "run": ["a", "a", "b", "c", "d"],
            "view": ["v1", "v2", "v1", "v1", "v1"], "status": "ok", "backend": "shearwarp",
            "record": [f"runs/{r}.json" for r in "aabcd"], "info_disturbed": np.nan, "rerun": np.nan}
    return pd.DataFrame({**base, **columns})


DISTURBED = ["other work used 0.75 cores while it was timed", np.nan,
             "other work used 2.34 cores while it was timed; 3 of 20 frames took over 3× the median",
             "other work used 1.00 cores while it was timed", np.nan]
RERUN = ["timed twice: …; the second too: …; kept the second", np.nan, np.nan,
         "timed twice: …; the second too: …; kept the first (quieter)",
         "timed twice: …; the second was quiet; kept the second"]


def test_disturbed_views_are_grouped_by_experiment_and_cause_with_the_range_of_their_numbers():
    found = outcomes.timing_disturbances(_rows(info_disturbed=DISTURBED, rerun=RERUN))
    groups = [{k: g[k] for k in ("experiment", "cause", "views", "timed_twice", "runs", "records")}
              for g in found["disturbed"]]
    # A view's causes stay together, so that each view is listed once.
    assert groups == [
        {"experiment": "e1", "cause": "other work used 0.75 cores while it was timed", "views": 1,
         "timed_twice": 1, "runs": ["a"], "records": ["runs/a.json"]},
        {"experiment": "e1", "cause": "other work used 2.34 cores while it was timed; 3 of 20 frames took over 3× "
         "the median", "views": 1, "timed_twice": 0, "runs": ["b"], "records": ["runs/b.json"]},
        {"experiment": "e2", "cause": "other work used 1.00 cores while it was timed", "views": 1, "timed_twice": 1,
         "runs": ["c"], "records": ["runs/c.json"]}]
    merged = outcomes.timing_disturbances(_rows(info_disturbed=[DISTURBED[0], np.nan, DISTURBED[3], np.nan, np.nan],
                                                experiment=["e1"] * 5))
    assert [g["cause"] for g in merged["disturbed"]] == ["other work used 0.75–1.00 cores while it was timed"]
    assert found["starved"] == [] and found["views"] == 5
    assert found["quiet_again"] == {"e2": 1}  # run d: disturbed, timed again, quiet
    assert outcomes.disturbance_notice(found).startswith("3 of the 5 timed views on this page were disturbed")


def test_starved_parallel_runs_are_listed_with_their_workers_busy_share():
    rows = _rows(info_starved=[np.nan, np.nan, np.nan, "2 workers had 1.2 free cores (other work used 0.80)",
                               "2 workers had 1.4 free cores (other work used 0.60)"],
                 info_worker_busy=[1.0, 1.0, 1.0, 0.49, 0.55])
    found = outcomes.timing_disturbances(rows)
    (group,) = found["starved"]
    assert group["experiment"] == "e2" and group["runs"] == ["c", "d"]
    assert group["cause"] == "2 workers had 1.2–1.4 free cores (other work used 0.60–0.80)"
    assert group["busy"] == "workers busy 49–55 % of the compositing"
    assert found["disturbed"] == []
    assert outcomes.disturbance_notice(found) == ("2 parallel runs had fewer free cores than workers: their times "
                                                  "and the intervals of the claims that read them are less certain.")


def test_quiet_timings_list_nothing_and_results_before_disturbances_say_nothing():
    untimed = [True, np.nan, np.nan, np.nan, np.nan]
    quiet = outcomes.timing_disturbances(_rows(info_starved=np.nan, info_untimed=untimed))
    assert quiet == {"views": 4, "disturbed": [], "starved": [], "quiet_again": {}}
    assert outcomes.disturbance_notice(quiet) == ""
    assert outcomes.timing_disturbances(_rows().drop(columns=["info_disturbed"])) is None
    assert outcomes.disturbance_notice(None) == ""
    failed = _rows(info_disturbed=DISTURBED, status=["failed"] * 5)
    assert outcomes.timing_disturbances(failed)["disturbed"] == []  # a run that made no frame was not timed
    # Untimed frames (ground truths, accuracy-only runs) are never called disturbed, whatever their record says.
    untimed = outcomes.timing_disturbances(_rows(info_disturbed=DISTURBED, info_untimed=[True] * 5))
    assert untimed["views"] == 0 and untimed["disturbed"] == []


# --------------------------------------------------------------------------------- the pages built
class _Speed:
    """An experiment with no blocks of its own: the page shows its claims and the report's own parts."""

    name, paper, title, description, claims = "fake-speed", "fake2024", "Speed", "Two configurations timed.", ()

    def paper_table(self):
        return None

    def report(self, frame, ctx):
        return []


CLAIMS = pd.DataFrame({
    "experiment": "fake-speed", "paper": "fake2024", "claim": ["fast", "faster", "count"],
    "kind": ["timing", "timing", "count"],
    "statement": ["A beats B", "A beats C", "A samples less"], "expected": ["≥ ×1.5", "≥ ×2", "≤ ×1"],
    "measured": ["×1.62 (95 % CI ×1.55–×1.7)", "×2.1 (95 % CI ×1.8–×2.4)", "×0.5"],
    "holds": [True, None, True], "verdict": ["holds", "inconclusive", "holds"], "detail": "",
    "interval_low": [1.55, 1.8, np.nan], "interval_high": [1.7, 2.4, np.nan], "margin": [0.08, 0.05, 0.5]})


PROFILE = {"profile": json.dumps({"repeat": 5, "min_time": 0.5, "warmup": 1})}


def _report(tmp_path, runs, claims=CLAIMS, environment=PROFILE):
    for record in runs["record"]:
        (tmp_path / record).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / record).write_text(json.dumps({"run": record}))
    runs = runs.assign(record=[str(tmp_path / r) for r in runs["record"]], experiment="fake-speed")
    index = build_report(runs, claims, [_Speed()], results_dir=tmp_path, environment=environment)
    return html.unescape(index.read_text()), html.unescape((index.parent / "fake2024.html").read_text())


def _appendix(tmp_path, runs, claims=CLAIMS, environment=PROFILE):
    """The appendix (how frames are timed, which were disturbed) of :func:`_report`'s report."""
    _report(tmp_path, runs, claims, environment)
    return html.unescape((tmp_path / "report" / "appendix.html").read_text())


def test_pages_list_disturbed_and_starved_runs_and_say_so_on_the_paper_page(tmp_path):
    runs = _rows(info_disturbed=DISTURBED, rerun=RERUN,
                 info_starved=[np.nan] * 4 + ["2 workers had 1.4 free cores (other work used 0.60)"])
    _, page = _report(tmp_path, runs)
    index = _appendix(tmp_path, runs)
    listing = index[index.index('id="disturbances"'):index.index('id="environment"')]
    items = re.findall(r"<li>(.*?)</li>", listing, flags=re.S)
    assert len(items) == 3  # two sets of causes (e1 and e2 are one experiment here), one starved run
    assert "other work used 0.75–1.00 cores while it was timed — 2 views, still disturbed when timed again" in items[0]
    assert "other work used 2.34 cores while it was timed; 3 of 20 frames took over 3× the median — 1 view" in items[1]
    links = re.findall(r'<a href="([^"]+)">(\w)</a>', items[0])
    assert links == [("data/runs/a.json", "a"), ("data/runs/c.json", "c")]
    assert "starved, 2 workers had 1.4 free cores (other work used 0.60) — 1 parallel run" in items[2]
    assert 'href="data/runs/d.json">d</a>' in items[2]
    assert ("until there are at least 5 of them and they took at least 0.5 s (the profile's repeat and min_time"
            in " ".join(index.split()))
    notice = page[page.index('class="disturbed"'):page.index('class="takeaways"')]
    assert ("3 of the 5 timed views on this page were disturbed while timed and 1 parallel run had fewer free cores "
            "than workers") in notice and 'href="appendix.html#disturbances"' in notice


def test_the_appendix_sets_the_spread_between_processes_beside_the_spread_within_one_per_backend(tmp_path):
    runs = _rows(spread_between=[0.10, 0.30, np.nan, 0.02, 0.04], spread_within=[0.01, 0.03, np.nan, 0.02, 0.02],
                 backend=["shearwarp", "shearwarp", "shearwarp", "gl-raycast", "gl-raycast"])
    two = {"profile": json.dumps({"repeat": 3, "min_time": 0.15, "warmup": 1, "replicates": 2})}
    appendix = " ".join(_appendix(tmp_path, runs, environment=two).split())
    section = appendix[appendix.index('id="processes"'):appendix.index('id="disturbances"')]
    cells = re.findall(r"<tr><td>(.*?)</td><td>(\d+)</td><td>(.*?)</td><td>(.*?)</td><td>(.*?)</td></tr>", section)
    assert cells == [("shearwarp", "2", "20.0 %", "2.0 %", "×10.0"), ("gl-raycast", "2", "3.0 %", "2.0 %", "×1.5")]
    assert "shared among the 2 processes that time each timed run" in appendix
    assert "Each timed run is timed in 2 processes" in appendix and "its intervals cover that" not in appendix
    one = " ".join(_appendix(tmp_path, _rows()).split())
    assert 'id="processes"' not in one
    assert "(the profile's <code>replicates</code> is 1): its intervals cover that process" in one


def test_quiet_pages_have_no_listing_and_no_notice(tmp_path):
    _, page = _report(tmp_path, _rows(info_starved=np.nan))
    index = _appendix(tmp_path, _rows(info_starved=np.nan))
    section = index[index.index('id="disturbances"'):index.index('id="environment"')]
    assert "<li>" not in section and "No timed view was still disturbed" in section
    assert 'class="disturbed"' not in page


def test_the_claims_table_shows_interval_margin_and_the_inconclusive_verdict(tmp_path):
    index, page = _report(tmp_path, _rows())
    rows = {re.search(r"<td class=\"text\">(.*?)</td>", row).group(1): row
            for row in re.findall(r"<tr><td class=\"text\">A .*?</tr>", page, flags=re.S)}
    assert "95 % CI" not in rows["A beats B"]  # the interval is said once, in its column
    for statement, cells in (("A beats B", ["×1.62", "×1.55–×1.7", "+8 %", "holds"]),
                             ("A beats C", ["×2.1", "×1.8–×2.4", "+5 %", "inconclusive"]),
                             ("A samples less", ["×0.5", "—", "+50 %", "holds"])):
        assert re.findall(r"<td[^>]*>([^<]*)</td>", rows[statement])[3:7] == cells, statement
    assert '<td class="verdict inconclusive">inconclusive</td>' in page
    papers = index[index.index('id="papers"'):index.index("claims that measure")]
    counts = re.findall(r'<td class="(holds|fails|inconclusive|blocked|unmeasured)">(\d+)</td>', papers)
    assert counts == [("holds", "2"), ("fails", "0"), ("inconclusive", "1"), ("blocked", "0"), ("unmeasured", "0")]


def test_results_without_interval_or_disturbance_columns_still_render(tmp_path):
    old_claims = CLAIMS.drop(columns=["interval_low", "interval_high", "margin", "verdict"])
    _, page = _report(tmp_path, _rows().drop(columns=["info_disturbed", "rerun"]), old_claims, environment={})
    index = _appendix(tmp_path, _rows().drop(columns=["info_disturbed", "rerun"]), old_claims, environment={})
    assert 'id="timing"' in index and 'id="disturbances"' not in index
    assert "until there are at least the profile's repeat and they took at least its min_time (" in " ".join(index.split())
    assert "×1.55–×1.7" in page  # from the check's words
    assert 'class="disturbed"' not in page
