"""``kruger2003-table1``: the scenes a profile names, every claim on synthetic results, devices and ratios."""

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments.kruger2003 import table1 as T
from reports.imageio import write_exr
from test_kruger2003_methods import NOISY, evaluate, small_profile, timed, with_gl_backends

NAME = "kruger2003-table1"


def test_unknown_scene_is_an_error(monkeypatch):
    with_gl_backends(monkeypatch)
    with pytest.raises(InputError, match="unknown.*bonsai"):
        experiments.plan(small_profile(**{NAME: {"scenes": ["bonsai"]}}))


def _table1_rows(times, scenes=("head", "engine"), psnr=45.0):
    rows = []
    for scene in scenes:
        for config, seconds in times[scene].items():
            # Five unrounded frames: the paper's own ratios sit exactly on some bounds.
            rows.append({"scene": scene, "view": "headline", "role": "test", "config": config,
                         "time_total": seconds, "frames_total": " ".join([repr(float(seconds))] * 5), "psnr": psnr,
                         "run": f"{scene}.{config}"})
    return rows


PAPER_LIKE = {"head": {"sbvr": 1 / 7.1, "rc": 1 / 4.8, "rc-a": 1 / 14.4, "rc-b": 1 / 23.4},
              "engine": {"sbvr": 1 / 10.4, "rc": 1 / 6.3, "rc-a": 1 / 6.3, "rc-b": 1 / 13.6}}


def test_table1_claims_hold_on_the_papers_own_numbers():
    rows = _table1_rows(PAPER_LIKE)
    for claim in ("rc-slower-than-sbvr", "ert-gain-opaque", "ert-none-semi-transparent", "ess-gain",
                  "rcb-over-rc-head", "rcb-over-sbvr-head", "accuracy"):
        assert evaluate(NAME, claim, rows).holds is True, claim
    assert evaluate(NAME, "rcb-over-sbvr-head", rows).measured == "×3.3 (95 % CI ×3.3–×3.3) (head)"
    assert evaluate(NAME, "rc-slower-than-sbvr", rows).detail.startswith(
        "head: ×0.676 (95 % CI ×0.676–×0.676); engine: ×0.606 (95 % CI ×0.606–×0.606); whole-frame")


def test_table1_claims_fail_where_the_numbers_do():
    slow = {"head": {"sbvr": 1.0, "rc": 0.9, "rc-a": 0.8, "rc-b": 0.8},
            "engine": {"sbvr": 1.0, "rc": 1.2, "rc-a": 0.5, "rc-b": 0.5}}
    rows = _table1_rows(slow, psnr=35.0)
    for claim in ("rc-slower-than-sbvr", "ert-gain-opaque", "ert-none-semi-transparent", "ess-gain",
                  "rcb-over-rc-head", "rcb-over-sbvr-head", "accuracy"):
        assert evaluate(NAME, claim, rows).holds is False, claim
    assert evaluate(NAME, "ert-gain-opaque", _table1_rows(slow, scenes=("engine",))).holds is None


def _timed_rows(times, views=("headline", "orbit000", "orbit090"), frames=lambda seconds, view: [seconds] * 5,
                group="head", samples=None):
    """Rows of the head, each config over ``views`` with the frames ``frames(seconds, view)``."""
    return [timed(frames(seconds, view), group=group, scene="head", view=view, role="test", config=config,
                  run=f"head.{config}", **({"count_samples": samples[config]} if samples else {}))
            for config, seconds in times.items() for view in views]


def test_table1_speed_claims_read_every_view_with_samples_beside():
    # The paper's frame rates average a rotation: RC-b is as slow as RC at the headline view only.
    rows = _timed_rows({"rc": 1.0, "rc-b": 0.1},
                       frames=lambda seconds, view: [1.0 if view == "headline" else seconds] * 5,
                       samples={"rc": 6e6, "rc-b": 1e6})
    result = evaluate(NAME, "rcb-over-rc-head", rows)
    assert result.holds is True and result.measured == "×10 (95 % CI ×10–×10) (head)"
    assert result.interval == pytest.approx((10.0, 10.0)) and "samples ×6" in result.detail


def test_table1_speed_claims_rest_on_intervals_of_interleaved_frames():
    paper = {"rc": 5.0, "rc-b": 1.0}  # ×5 ≥ ×4.88 on medians
    steady = evaluate(NAME, "rcb-over-rc-head", _timed_rows(paper))
    assert steady.holds is True and steady.margin > 0
    # One disturbed round slowed both: paired by round, the ratio stays ×5.
    disturbed = _timed_rows(paper, frames=lambda seconds, view: [seconds * t for t in NOISY])
    assert evaluate(NAME, "rcb-over-rc-head", disturbed).holds is True
    # Timed apart, the same frames cannot decide.
    alone = evaluate(NAME, "rcb-over-rc-head", _timed_rows(paper, group="",
                                                           frames=lambda seconds, view: [seconds * t for t in NOISY]))
    assert alone.inconclusive and alone.holds is None and alone.interval[0] < 4.88 < alone.interval[1]
    slow = evaluate(NAME, "rcb-over-rc-head", _timed_rows({"rc": 4.0, "rc-b": 1.0}))
    assert slow.holds is False and slow.margin < 0


def _write(path, image):
    write_exr(str(path), image.astype(np.float32))
    return str(path)


def test_image_pair_claims(tmp_path):
    base = np.zeros((8, 8, 4), np.float32)
    base[2:6, 2:6] = (0.5, 0.4, 0.3, 0.97)
    rows = []
    for config, image in (("rc", base), ("rc-a", base - np.float32(0.02) * (base > 0)), ("rc-b", None)):
        image = rows[-1]["image"] if image is None else image
        rows.append({"scene": "head", "view": "headline", "role": "test", "config": config, "image": image,
                     "exr": _write(tmp_path / f"{config}.exr", image), "option_opaque_threshold": 0.95})
    assert evaluate(NAME, "ess-lossless", rows).holds is True
    assert evaluate(NAME, "ert-bound", rows).holds is True  # 0.02 ≤ 1 − 0.95
    rows[1]["exr"] = _write(tmp_path / "far.exr", base * 0.5)
    assert evaluate(NAME, "ert-bound", rows).holds is False
    assert evaluate(NAME, "ess-lossless", rows).holds is False


def test_fragment_fraction_claim_needs_the_slicer_counters():
    rows = [{"scene": "head", "view": view, "role": "test", "config": "sbvr",
             "count_fragments": 1000, "count_fragments_contributing": contributing}
            for view, contributing in (("headline", 300), ("orbit000", 30), ("orbit090", 40))]
    assert evaluate(NAME, "fragments-contribute", rows).holds is True  # the median over the views: 4 %
    assert evaluate(NAME, "fragments-contribute", rows).measured == "4 % (head)"
    rows[1]["count_fragments_contributing"] = 300
    assert evaluate(NAME, "fragments-contribute", rows).holds is False
    for row in rows:
        del row["count_fragments_contributing"]
    assert evaluate(NAME, "fragments-contribute", rows).holds is None


def test_device_sentence_and_ratios_per_device():
    rows = pd.DataFrame([{"config": c, "scene": "head", "view": "headline", "time_total": t, "gl_renderer": device,
                          "gl_software_rasterizer": device.startswith("llvmpipe")}
                         for device, scale in (("llvmpipe (LLVM 15)", 1.0), ("NVIDIA H100", 0.01))
                         for c, t in (("sbvr", 3.0 * scale), ("rc", 5.0 * scale), ("rc-a", 2.0 * scale),
                                      ("rc-b", 1.0 * scale))])
    software = T._device_takeaways(rows[rows.gl_renderer.str.startswith("llvmpipe")])
    assert "CPU rasterizer" in software[0] and "no GPU run" in software[0]
    both = T._device_takeaways(rows)
    assert "per device" in both[0] and "NVIDIA H100" in both[0]
    groups = dict(list(rows.groupby(T.gl_devices(rows))))
    assert set(groups) == {"llvmpipe (LLVM 15)", "NVIDIA H100"}
    ratio = T._ratio_table(groups["NVIDIA H100"])
    assert ratio["RC-b / RC (ours)"].iloc[0] == pytest.approx(5.0)


def test_a_view_without_its_comparison_is_missing_not_left_out():
    rows = _table1_rows(PAPER_LIKE)
    rows[0]["psnr"] = float("nan")  # the worst PSNR was taken over the other views
    result = evaluate(NAME, "accuracy", rows)
    assert result.holds is None and "no PSNR against the reference for head.sbvr (headline)" in result.detail
