"""``kruger2003-table1``: the scenes a profile names, every claim on synthetic results, devices and ratios."""

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments.kruger2003 import table1 as T
from reports.imageio import write_exr
from test_kruger2003_methods import evaluate, small_profile, with_gl_backends

NAME = "kruger2003-table1"


def test_unknown_scene_is_an_error(monkeypatch):
    with_gl_backends(monkeypatch)
    with pytest.raises(InputError, match="unknown.*bonsai"):
        experiments.plan(small_profile(**{NAME: {"scenes": ["bonsai"]}}))


def _table1_rows(times, scenes=("head", "engine"), psnr=45.0):
    rows = []
    for scene in scenes:
        for config, seconds in times[scene].items():
            rows.append({"scene": scene, "view": "headline", "role": "test", "config": config,
                         "time_total": seconds, "psnr": psnr, "run": f"{scene}.{config}"})
    return rows


PAPER_LIKE = {"head": {"sbvr": 1 / 7.1, "rc": 1 / 4.8, "rc-a": 1 / 14.4, "rc-b": 1 / 23.4},
              "engine": {"sbvr": 1 / 10.4, "rc": 1 / 6.3, "rc-a": 1 / 6.3, "rc-b": 1 / 13.6}}


def test_table1_claims_hold_on_the_papers_own_numbers():
    rows = _table1_rows(PAPER_LIKE)
    for claim in ("rc-slower-than-sbvr", "ert-gain-opaque", "ert-none-semi-transparent", "ess-gain",
                  "rcb-over-rc-head", "rcb-over-sbvr-head", "accuracy"):
        assert evaluate(NAME, claim, rows).holds is True, claim
    assert evaluate(NAME, "rcb-over-sbvr-head", rows).measured == "×3.3 (head)"
    assert "head: RC at ×0.676 of SBVR's speed" in evaluate(NAME, "rc-slower-than-sbvr", rows).detail


def test_table1_claims_fail_where_the_numbers_do():
    slow = {"head": {"sbvr": 1.0, "rc": 0.9, "rc-a": 0.8, "rc-b": 0.8},
            "engine": {"sbvr": 1.0, "rc": 1.2, "rc-a": 0.5, "rc-b": 0.5}}
    rows = _table1_rows(slow, psnr=35.0)
    for claim in ("rc-slower-than-sbvr", "ert-gain-opaque", "ert-none-semi-transparent", "ess-gain",
                  "rcb-over-rc-head", "rcb-over-sbvr-head", "accuracy"):
        assert evaluate(NAME, claim, rows).holds is False, claim
    assert evaluate(NAME, "ert-gain-opaque", _table1_rows(slow, scenes=("engine",))).holds is None


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
    rows = [{"scene": "head", "view": "headline", "role": "test", "config": "sbvr",
             "count_fragments": 1000, "count_fragments_contributing": 30}]
    assert evaluate(NAME, "fragments-contribute", rows).holds is True
    rows[0]["count_fragments_contributing"] = 300
    assert evaluate(NAME, "fragments-contribute", rows).holds is False
    del rows[0]["count_fragments_contributing"]
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
    groups = dict(list(rows.groupby(T._devices(rows))))
    assert set(groups) == {"llvmpipe (LLVM 15)", "NVIDIA H100"}
    ratio = T._ratio_table(groups["NVIDIA H100"])
    assert ratio["RC-b / RC (ours)"].iloc[0] == pytest.approx(5.0)
