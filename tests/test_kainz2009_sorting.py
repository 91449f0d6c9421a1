"""kainz2009-sorting (E7): every order and its gather + sort ablation, and the claims on synthetic results."""

import numpy as np
import pandas as pd
import pytest

from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kainz2009.sorting import ORDERS, SCENES, Sorting, _sorting_rows, _sorting_takeaways
from reports.imageio import write_exr

NAME = "kainz2009-sorting"


def _evaluate(claim_id, rows):
    claim = next(c for c in Sorting.claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def _frames(seconds, *, spread=0.0, seed=0, stage="pixel", n=9):
    """A stage's median and its ``n`` timed frames within ± ``spread`` of ``seconds``, as a run's columns."""
    values = seconds * (1 + spread * np.random.default_rng(seed).uniform(-1, 1, n))
    return {f"time_{stage}": float(np.median(values)), f"frames_{stage}": " ".join(f"{v:.6g}" for v in values)}


def test_sorting_plan_times_every_order_and_the_sort_alone():
    profile = Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[NAME],
                      settings={NAME: {"small_size": 8, "triangles": 500}})
    sorting = list(experiments.plan(profile).values())
    assert {(r.tags["scene"], r.options["triangle_order"], r.options.get("stop_after", "composite"))
            for r in sorting} == {(s, o, p) for s in SCENES for o in ORDERS
                                  for p in ("composite", "sort") if p == "composite" or o != "scene"}
    boxes = {r.scene["name"] for r in sorting if r.tags["scene"] == "boxes"}
    assert len(boxes) == 1  # one scene for every order
    # Every order of a scene and its ablations timed together, the scenes apart.
    assert {(r.tags["scene"], r.interleave) for r in sorting} == {("boxes", "boxes"), ("coil+clouds", "coil-clouds")}


def _image(tmp_path, name, image):
    path = tmp_path / f"{name}.exr"
    write_exr(str(path), image.astype(np.float32))
    return str(path)


def _rows(tmp_path, *, sort_only, pixel, changed=0.0, spread=0.0):
    """Full and gather + sort rows of one scene: pixel-kernel seconds per order."""
    image = np.full((8, 8, 4), 0.25, np.float32)
    rows = []
    for i, (order, seconds) in enumerate(pixel.items()):
        shown = image + (changed if order == "back-to-front" else 0.0)
        rows.append({"scene": "boxes", "order": order, "part": "full", "role": "test", "time_total": 2 * seconds,
                     **_frames(seconds, spread=spread, seed=i), "time_binning": 0.1 * seconds,
                     "count_sort_moves": 100 * i, "exr": _image(tmp_path, f"full-{order}", shown)})
    for i, (order, seconds) in enumerate(sort_only.items()):
        rows.append({"scene": "boxes", "order": order, "part": "gather+sort", "role": "ablation",
                     "time_total": 2 * seconds, **_frames(seconds, spread=spread, seed=10 + i)})
    return rows


def test_sorting_claims(tmp_path):
    pixel = {"scene": 0.011, "front-to-back": 0.010, "back-to-front": 0.012}
    rows = _rows(tmp_path, sort_only={"front-to-back": 0.002, "back-to-front": 0.004}, pixel=pixel)
    result = _evaluate("sort-small", rows)
    assert result.holds is True and result.measured == "×0.25 (95 % CI ×0.25–×0.25) (boxes)"   # 2 ms against 8 ms
    assert result.detail.endswith("boxes: worst-case sort 2 ms, traversal 8 ms, sort moves front-to-back: 100, "
                                  "back-to-front: 200")
    assert _evaluate("order-invariant", rows).holds is True
    table = _sorting_rows(pd.DataFrame(rows)).set_index(["order", "part"])
    assert table.loc[("back-to-front", "full"), "gather+sort share (%)"] == pytest.approx(100 / 3)
    sentences = _sorting_takeaways(_sorting_rows(pd.DataFrame(rows)))
    assert "worst / best ×1.2" in sentences[0]
    rows = _rows(tmp_path, sort_only={"front-to-back": 0.002, "back-to-front": 0.009}, pixel=pixel, changed=1e-3)
    assert _evaluate("sort-small", rows).holds is False                              # 7 ms against 3 ms
    assert _evaluate("order-invariant", rows).holds is False
    assert _evaluate("sort-small", rows[:3]).holds is None                           # no ablation runs
    # 5 ms of sort against 6 ms of traversal, the frames scattered by a third: cannot tell.
    rows = _rows(tmp_path, sort_only={"front-to-back": 0.002, "back-to-front": 0.007}, pixel=pixel, spread=0.3)
    assert _evaluate("sort-small", rows).inconclusive
