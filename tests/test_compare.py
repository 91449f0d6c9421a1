"""pipeline.compare and scripts/compare-results on two small results folders written here."""

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import compare
from pipeline.collect import claims_table
from pipeline.experiments import get
from reports.imageio import read_image, write_exr

ROOT = Path(__file__).resolve().parent.parent
EXPERIMENTS = ["volbench-convergence", "volbench-speed-accuracy"]
TIMING_CLAIM = ("volbench-speed-accuracy", "tradeoff")
"""Halving the step doubles the time: a ratio of timings, judged (every run of the folder is ``ok``)."""
RANKING_CLAIMS = {("volbench-speed-accuracy", f"ranking-{scene}")
                  for scene in ("skull-bone", "engine-semi", "skull-mip", "foot-iso")}
"""The index's ranking per scene: each reads the contenders' timings."""
EXACT_ISO_CLAIM = ("volbench-speed-accuracy", "exact-iso-beats-oversampling")


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    """A results folder as the pipeline writes it (records, images, metrics, CSVs; nothing rendered)."""
    from test_reports_html import synthetic_results

    *_, results = synthetic_results(tmp_path_factory.mktemp("original"), experiments=EXPERIMENTS,
                                    outcome=lambda run: ("ok", "", ""))
    return results


@pytest.fixture
def folders(original, tmp_path):
    """``(a, b)``: the original and a copy elsewhere, whose CSVs still name the original's files."""
    return original, Path(shutil.copytree(original, tmp_path / "copy"))


def _edit_csv(path, edit):
    """Rewrite a CSV as ``edit(frame)`` returns it, read as text (so other values keep their bytes)."""
    edit(pd.read_csv(path, dtype=str, keep_default_na=False)).to_csv(path, index=False)


def _row(folder, backend):
    """The index in runs.csv (as :func:`pipeline.compare.read_runs` sorts it) and the row of an ``ok`` run of ``backend``."""
    frame = compare.read_runs(folder)
    index = frame.index[(frame.backend == backend) & frame.psnr.notna()][0]
    return index, frame.loc[index]


def _set(folder, row, column, value):
    """Set ``column`` of the runs.csv row of ``row``'s run and view."""
    def edit(frame):
        frame.loc[(frame.experiment == row.experiment) & (frame.run == row.run) & (frame.view == row.view), column] = value
        return frame

    _edit_csv(folder / "runs.csv", edit)


def test_a_copy_elsewhere_is_the_same(folders):
    a, b = folders
    assert compare.differences(a, b) == []
    # Its files are read in the copy, not where its CSVs say the run wrote them.
    assert compare.read_runs(b).record.str.startswith(str(b.resolve())).all()
    assert "original" in pd.read_csv(b / "runs.csv").record[0]


def test_timings_durations_and_the_environment_are_left_out(folders):
    a, b = folders

    def edit(frame):
        for column in [c for c in frame.columns if c.startswith("time_")]:
            frame[column] = [str(float(value) * 3) if value else value for value in frame[column]]
        frame["stat_generation_seconds"] = "12.5"
        frame["hostname"] = frame["node"] = "elsewhere"
        return frame

    _edit_csv(b / "runs.csv", edit)
    assert compare.run_differences(a, b) == []


@pytest.mark.parametrize("column", [
    "time_total", "time_composite_min", "stat_generation_seconds",  # times and durations
    "frames_total", "frames_technique",  # every timed frame
    "once_rle_build", "once_first_frame",  # each process's preprocessing, timed once
    "load_foreign_cores", "load_steal_share", "load_waited_share", "load_job_foreign_cores", "load_average",
    "info_frames", "info_warmup", "info_settled", "info_first_frame", "info_disturbed", "info_starved",
    "info_preprocessing_frame", "rerun",
])
def test_what_the_timing_harness_measured_or_decided_from_the_times_is_timing(column):
    assert compare.is_timing(column)


@pytest.mark.parametrize("column", ["count_samples", "psnr", "info_step", "info_untimed", "interleave", "view",
                                    "option_step_factor", "stat_mean"])
def test_what_the_scene_and_options_decide_is_not_timing(column):
    assert not compare.is_timing(column)


def test_the_timing_harness_columns_are_left_out(folders):
    a, b = folders
    timing = {"frames_total": "0.0012 0.0013 0.0011", "load_foreign_cores": "0.7", "load_waited_share": "0.2",
              "info_frames": "3", "info_disturbed": "other work used 0.70 cores while it was timed",
              "info_starved": "2 workers had 1.3 free cores (other work used 0.70)", "rerun": "timed twice: ..."}
    _edit_csv(b / "runs.csv", lambda frame: frame.assign(**timing))  # in one folder only, as a rerun under load
    assert compare.run_differences(a, b) == []
    _edit_csv(b / "runs.csv", lambda frame: frame.assign(count_new="1"))
    assert compare.run_differences(a, b) == [f"runs.csv columns only in {b}: count_new"]


def test_a_changed_value_or_a_missing_row_is_a_run_difference(folders):
    a, b = folders
    _, row = _row(a, "reference")
    _set(b, row, "psnr", repr(float(row.psnr) + 1e-9))  # a CPU render's metric: exact
    found = compare.run_differences(a, b)
    assert len(found) == 1 and found[0].startswith(f"runs.csv psnr differs in 1 rows: {row.experiment}/{row.run}/{row.view}")
    _edit_csv(b / "runs.csv", lambda frame: frame[frame.run != row.run])
    assert compare.run_differences(a, b)[0].startswith(
        f"runs.csv rows (experiment, run, view) only in {a}: ('{row.experiment}', '{row.run}', '{row.view}')")


def test_a_device_render_metric_may_differ_as_its_image_may(folders):
    a, b = folders
    _, row = _row(a, "gl-raycast")
    _set(b, row, "psnr", repr(float(row.psnr) * (1 + 1e-6)))
    assert compare.run_differences(a, b) == []
    _set(b, row, "psnr", repr(float(row.psnr) * (1 + 1e-3)))
    assert compare.run_differences(a, b)[0].startswith("runs.csv psnr differs in 1 rows")


@pytest.mark.parametrize("backend, change, differs", [
    ("reference", 1e-6, True),  # a CPU backend's images are bit-identical
    ("gl-raycast", 5e-7, False),
    ("gl-raycast", 1e-5, True),
])
def test_images_are_compared_in_their_own_folder(folders, backend, change, differs):
    a, b = folders
    _, row = _row(b, backend)
    image = read_image(row.exr)
    image[0, 0, 0] += change
    write_exr(row.exr, image)
    found = compare.image_differences(a, b)
    assert bool(found) == differs
    if differs:
        assert found[0].startswith(f"{row.experiment}/{row.run}/{row.view}: {backend}")


def test_the_claims_are_the_same_with_the_same_verdicts_but_for_timing_claims(folders):
    a, b = folders
    claims = pd.read_csv(a / "claims.csv", dtype=str, keep_default_na=False)
    assert (claims.verdict[claims.claim.isin(["monotone", TIMING_CLAIM[1]])] == "holds").all()

    def edit(frame):
        frame.loc[frame.claim.isin(["monotone", TIMING_CLAIM[1]]), "verdict"] = "fails"
        frame.loc[frame.claim == "order", "statement"] = "something else"
        return frame[frame.claim != "default-step"]

    _edit_csv(b / "claims.csv", edit)
    assert compare.claim_differences(a, b) == [
        f"claims (experiment, claim) only in {a}: ('volbench-convergence', 'default-step')",
        f"claim volbench-convergence/monotone: holds in {a}, fails in {b}",
        "claim volbench-convergence/order: statement 'The error falls with the step at least linearly (observed order, "
        f"worst scene)' in {a}, 'something else' in {b}",
    ]


def test_timing_claims_are_found_by_their_judgement_on_other_timings(original, tmp_path):
    frame = compare.read_runs(original)
    experiments = [get(name) for name in EXPERIMENTS]
    assert compare.varying_claims(frame, experiments, workdir=tmp_path) == {TIMING_CLAIM, EXACT_ISO_CLAIM,
                                                                            *RANKING_CLAIMS}


def test_claims_judged_with_the_values_of_another_run(folders, tmp_path):
    a, b = folders

    def edit(frame):
        for column in [c for c in frame.columns if c.startswith("time_")]:
            frame[column] = [str(float(value) * factor) if value else value
                             for value, factor in zip(frame[column], np.linspace(0.5, 4, len(frame)))]
        return frame

    _edit_csv(b / "runs.csv", edit)
    experiments = [get(name) for name in EXPERIMENTS]
    first, second = compare.read_runs(a), compare.read_runs(b)
    expected = claims_table(first, experiments)
    assert not claims_table(second, experiments).equals(expected)  # the timing claim's measured value moved
    pd.testing.assert_frame_equal(compare.claims_with_values_of(second, first, experiments, workdir=tmp_path), expected)


def test_claims_judged_with_the_values_of_a_run_that_fills_other_columns(folders, tmp_path):
    """A harness column only one run filled (a disturbed view there, none here) comes from the source,
    and a column the source left empty is empty in the result (a CI run failed on this)."""
    a, b = folders
    _edit_csv(b / "runs.csv", lambda frame: frame.assign(
        info_disturbed=np.where(frame.experiment == TIMING_CLAIM[0], "the machine was busy", "")))
    experiments = [get(name) for name in EXPERIMENTS]
    quiet, disturbed = compare.read_runs(a), compare.read_runs(b)
    assert "info_disturbed" not in quiet
    assert not claims_table(disturbed, experiments).equals(claims_table(quiet, experiments))
    for frame, source in ((quiet, disturbed), (disturbed, quiet)):
        pd.testing.assert_frame_equal(compare.claims_with_values_of(frame, source, experiments, workdir=tmp_path),
                                      claims_table(source, experiments))


def test_scheduling_dependent_record_entries_are_replaced_in_copies(folders, tmp_path):
    a, b = folders
    _, row = _row(b, "shearwarp")
    record = json.loads(Path(row.record).read_text())
    record["views"][0]["info"] = {"worker_samples": [10, 30], "frames": 1}
    Path(row.record).write_text(json.dumps(record))
    frame = compare.read_runs(b)
    replaced = compare.with_varying_values(frame, tmp_path, columns=lambda column, values: values,
                                           entries=lambda index, view, part, name, value: [20, 20])
    copy = replaced.loc[replaced.run == row.run, "record"].iloc[0]
    assert Path(copy).is_relative_to(tmp_path)
    assert json.loads(Path(copy).read_text())["views"][0]["info"] == {"worker_samples": [20, 20], "frames": 1}
    assert json.loads(Path(row.record).read_text()) == record  # the folder's own record stays


def test_phantoms_are_compared_by_their_data(folders):
    a, b = folders
    volumes = pd.read_csv(a / "volumes.csv", dtype=str, keep_default_na=False)
    changed, kept = volumes.key[0], volumes.key[1]
    _edit_csv(b / "volumes.csv", lambda frame: frame.assign(sha256=frame.sha256.where(frame.key != changed, "0" * 64)))
    found = compare.phantom_differences(a, b)
    assert len(found) == 1 and found[0].startswith(f"phantom {changed} (")
    assert compare.phantom_differences(a, b, keys={kept}) == []
    _edit_csv(b / "volumes.csv", lambda frame: frame[frame.key != kept])
    assert compare.phantom_differences(a, b, keys={kept}) == [f"phantom {kept} is not in {b}/volumes.csv"]


def test_the_script_prints_the_differences_and_exits_1_when_there_are_any(folders):
    a, b = folders
    script = [str(ROOT / "scripts" / "compare-results")]
    same = subprocess.run([*script, str(a), str(b)], capture_output=True, text=True, timeout=120)
    assert same.returncode == 0, same.stderr
    assert same.stdout == ("verdicts: 9 of 9 claims (100.0 %) have the same verdict; of the 6 that read timings, 6 "
                           "(100.0 %); 0 changed to or from inconclusive\n"
                           "intervals: of the 2 timing claims both gave an interval, 2 (100.0 %) agree within their "
                           "95 % intervals (about 95 % where the intervals cover the spread between runs)\n"
                           f"{a} and {b}: the same runs, images, claims (no timing claim flipped) and phantoms\n")
    _edit_csv(b / "claims.csv", lambda frame: frame.assign(verdict=frame.verdict.where(frame.claim != "monotone", "fails")))
    assert compare.main([str(a), str(b)]) == 1
    (b / "volumes.csv").unlink()
    with pytest.raises(InputError, match=f"^{b}: no volumes.csv; give the results folder of a finished pipeline run"):
        compare.differences(a, b)  # before any comparison
    missing = subprocess.run([*script, str(a), str(b / "nowhere")], capture_output=True, text=True, timeout=120)
    assert missing.returncode == 2
    assert missing.stderr == f"compare-results: {b / 'nowhere'}: no runs.csv; give the results folder of a finished " \
                             "pipeline run (results/<profile>)\n"


def test_a_timing_claim_that_flips_is_a_difference_and_one_that_turns_inconclusive_is_listed(folders, capsys):
    a, b = folders
    experiment, claim = TIMING_CLAIM
    _edit_csv(b / "claims.csv", lambda frame: frame.assign(
        verdict=frame.verdict.where(frame.claim != claim, "inconclusive")))
    assert compare.claim_differences(a, b) == [] and compare.timing_flips(a, b) == []
    assert compare.main([str(a), str(b)]) == 0
    out = capsys.readouterr().out
    assert f"changed to inconclusive: {experiment}/{claim}: holds in {a}" in out
    assert "verdicts: 8 of 9 claims (88.9 %) have the same verdict; of the 6 that read timings, 5 (83.3 %); 1 changed" in out
    _edit_csv(b / "claims.csv", lambda frame: frame.assign(verdict=frame.verdict.where(frame.claim != claim, "fails")))
    assert compare.claim_differences(a, b) == []  # the verdicts of timing claims are timing_flips' to compare
    [flip] = compare.timing_flips(a, b)
    assert flip.startswith(f"timing claim {experiment}/{claim} flipped: holds in {a} (") and f"fails in {b}" in flip
    assert compare.main([str(a), str(b)]) == 1


def test_the_agreement_is_over_the_claims_both_folders_judged():
    # A run of some experiments against a whole run: its share is of the claims both have, the rest counted apart.
    first = pd.DataFrame({"experiment": ["e", "e", "f"], "claim": ["a", "b", "c"],
                          "verdict": ["holds", "fails", "holds"], "measured": ["", "", ""]})
    second = first[first.experiment == "e"].assign(verdict=["holds", "inconclusive"])
    changes = compare.verdict_changes(first, second)
    assert compare.agreement_words(changes, timing=[("e", "b")]) == (
        "1 of 2 claims (50.0 %) have the same verdict; of the 1 that read timings, 0 (0.0 %); "
        "1 claim in one folder only")


def test_a_folder_judged_again_by_this_code_says_what_it_wrote(folders, capsys):
    a, b = folders
    changes, found = compare.rejudge_differences(b)  # a copy elsewhere: its files are read where it is
    assert found == [] and (changes.change == "same").all() and len(changes) == 9
    assert compare.main(["--rejudge", str(b)]) == 0
    assert capsys.readouterr().out.endswith(f"{b}: every claim judged again as written\n")


def test_a_claim_judged_again_differently_is_named_with_its_cell(folders, capsys):
    _, b = folders
    _edit_csv(b / "claims.csv", lambda frame: frame.assign(
        verdict=frame.verdict.where(frame.claim != "monotone", "inconclusive"),
        detail=frame.detail.where(frame.claim != "monotone", "written by other code")))
    _edit_csv(b / "claims.csv", lambda frame: frame[frame.claim != "tradeoff"])
    changes, found = compare.rejudge_differences(b)
    assert "claim volbench-convergence/monotone: detail 'written by other code' as written" in "\n".join(found)
    assert any(s.startswith("claim volbench-convergence/monotone: verdict 'inconclusive' as written, 'holds'")
               for s in found)
    assert any("volbench-speed-accuracy" in s and "tradeoff" in s for s in found)  # a claim only one side has
    assert compare.main(["--rejudge", str(b)]) == 1
    assert f"{len(found)} differences" in capsys.readouterr().out


def test_rejudge_takes_one_finished_folder_and_comparing_takes_two(folders, capsys):
    _, b = folders
    with pytest.raises(SystemExit):
        compare.main(["--rejudge", "a", "b"])
    with pytest.raises(SystemExit):
        compare.main(["a"])
    (b / "tables" / "volbench-convergence.csv").unlink()  # each experiment is judged on its own table
    assert compare.main(["--rejudge", str(b)]) == 2
    assert "no tables/volbench-convergence.csv; give the results folder of a finished" in capsys.readouterr().err


def test_two_runs_intervals_agree_where_their_midpoints_are_within_what_both_allow():
    """Issue 35's two runs of kruger2003 rcb-over-sbvr-head (×2.41, CI 2.19–2.82; ×3.08, CI 2.73–3.34) do not
    agree; two intervals that differ by less than their half-widths in quadrature do."""
    def claims(*rows):
        return pd.DataFrame([{"experiment": "e", "claim": claim, "interval_low": low, "interval_high": high}
                             for claim, low, high in rows], dtype=str)

    first = claims(("rcb", "2.19", "2.82"), ("near", "1.0", "1.2"), ("count", "", ""), ("point", "2", "2"),
                   ("untimed", "1", "2"))
    second = claims(("rcb", "2.73", "3.34"), ("near", "1.1", "1.3"), ("count", "", ""), ("point", "2", "2"),
                    ("untimed", "5", "6"))
    agreement = compare.interval_agreement(first, second, timing={("e", c) for c in ("rcb", "near", "count", "point")})
    assert list(agreement.claim) == ["rcb", "near", "point"]  # with an interval in both, of the timing claims
    assert agreement.apart.round(2).tolist() == [2.37, 1.39, 0.0] and agreement.agree.tolist() == [False, True, True]
    assert compare.interval_words(agreement) == (
        "of the 3 timing claims both gave an interval, 2 (66.7 %) agree within their 95 % intervals (about 95 % where "
        "the intervals cover the spread between runs)")
    assert compare.intervals_apart(agreement, "a", "b") == [
        "intervals apart: e/rcb: 2.19–2.82 in a, 2.73–3.34 in b (2.4 apart)"]
    assert compare.interval_words(agreement.iloc[:0]) == ""
