"""``xue2005-variants``: its runs (one interleave group per scene, both orders), every claim on synthetic results."""

import numpy as np
import pandas as pd
import pytest

from pipeline.experiments.xue2005 import variants as V
from test_xue2005_table1 import NOISY, evaluate, planned, timed, write

NAME = "xue2005-variants"


def test_plan_times_every_run_of_a_scene_together_in_both_orders():
    runs = planned("default", NAME)
    assert {r.tags["scene"] for r in runs} == {"head", "aneurysm", "bonsai"}
    head = {r.id: r for r in runs if r.tags["scene"] == "head"}
    assert set(head) == {"head.basic", "head.ess+ert", "head.ess", "head.front", "head.f2b.basic", "head.f2b.ess+ert"}
    assert {r.interleave for r in head.values()} == {"head"}
    assert {(r.tags["config"], r.options["zinit"], r.options["order"], r.tags["order"]) for r in head.values()} == {
        ("basic", "none", V.BACK, V.BACK), ("ess+ert", "ess+ert", V.BACK, V.BACK), ("ess", "ess", V.BACK, V.BACK),
        ("front", "front", V.BACK, V.BACK), ("basic", "none", V.FRONT, V.FRONT),
        ("ess+ert", "ess+ert", V.FRONT, V.FRONT)}
    assert all(r.options["step_factor"] == 1.0 and r.repeat >= 3 and len(r.views) == 2 for r in runs)
    smoke = planned("smoke", NAME)
    assert {r.tags["scene"] for r in smoke} == {"head"} and {len(r.views) for r in smoke} == {1}


def order_rows(times, *, frames=lambda seconds: [seconds] * 5, views=("headline", "orbit000"), group="head"):
    """Rows of the head: ``times[(config, order)]`` seconds, with fragments ``count_fragments`` of 1000."""
    return [timed(frames(seconds), group=group, scene="head", view=view, config=config, order=order,
                  run=f"head.{order}.{config}", count_fragments=shaded, count_fragments_generated=1000)
            for (config, order), (seconds, shaded) in times.items() for view in views]


def test_the_same_speedup_in_both_orders():
    same = {("basic", V.FRONT): (0.2, 1000), ("ess+ert", V.FRONT): (0.1, 300),
            ("basic", V.BACK): (0.3, 1000), ("ess+ert", V.BACK): (0.15, 300)}
    result = evaluate(NAME, "order-speedup", order_rows(same))
    assert result.holds is True and result.measured.startswith("front-to-back / back-to-front speed-up ×1 ")
    assert "front to back ×2, back to front ×2" in result.detail
    halved = {**same, ("ess+ert", V.FRONT): (0.2, 300)}
    assert evaluate(NAME, "order-speedup", order_rows(halved)).holds is False
    # A disturbed round slows all four runs of the group: paired, the ratio of ratios stays ×1.
    noisy = order_rows(same, frames=lambda seconds: [seconds * t for t in NOISY])
    assert evaluate(NAME, "order-speedup", noisy).holds is True
    # One run's frames disturbed alone: the interval straddles the tolerance.
    lopsided = order_rows({**same, ("ess+ert", V.FRONT): (0.1, 300)},
                          frames=lambda seconds: [seconds * t for t in NOISY] if seconds == 0.1 else [seconds] * 5)
    assert evaluate(NAME, "order-speedup", lopsided).inconclusive


def test_the_same_image_in_both_orders(tmp_path):
    image = np.zeros((16, 16, 4), np.float32)
    image[4:12, 4:12] = (0.5, 0.4, 0.3, 0.9)
    rows = [{"scene": "head", "view": "headline", "role": "test", "config": config, "order": order,
             "exr": write(tmp_path / f"{config}-{order}.exr", image + np.float32(1e-4 if order == V.FRONT else 0))}
            for config in ("basic", "ess+ert") for order in (V.FRONT, V.BACK)]
    result = evaluate(NAME, "order-image", rows)
    assert result.holds is True and result.measured == "80 dB (head, headline)"
    rows[1]["exr"] = write(tmp_path / "off-basic.exr", image * 0.8)  # Basic's orders are not the claim's ...
    assert evaluate(NAME, "order-image", rows).holds is True
    rows[2]["exr"] = write(tmp_path / "off.exr", image * 0.8)  # ... ESS+ERT's are
    assert evaluate(NAME, "order-image", rows).holds is False


LEAPING = {("basic", V.BACK): (0.4, 1000), ("ess", V.BACK): (0.2, 450), ("front", V.BACK): (0.15, 350),
           ("ess+ert", V.BACK): (0.1, 250)}


def test_front_based_against_exit_based_leaping():
    rows = order_rows(LEAPING)
    culled = evaluate(NAME, "front-culls-more", rows)
    assert culled.holds is True and culled.measured == "α' front-based 0.65, exit-based 0.55 (head)"
    assert evaluate(NAME, "front-faster", rows).holds is True
    combines = evaluate(NAME, "exit-combines", rows)
    assert combines.holds is True and "front α' 0.65 (ideal ×2.86)" in combines.detail
    behind = order_rows({**LEAPING, ("front", V.BACK): (0.25, 600)})  # more data behind: exit-based culls more
    for claim in ("front-culls-more", "front-faster"):
        assert evaluate(NAME, claim, behind).holds is False, claim
    assert evaluate(NAME, "exit-combines", order_rows({**LEAPING, ("front", V.BACK): (0.1, 350)})).holds is False


def test_the_band_combination_is_said_to_be_not_built():
    class Context:
        claims = None  # nothing judged: no results

        def plot_path(self, name):
            raise AssertionError("no plot without results")

    blocks = V.Variants().report(pd.DataFrame({"status": []}), Context())
    assert any("depth-band combination" in getattr(b, "text", "") and "not built" in b.text for b in blocks)


def test_paper_table_quotes_the_statements():
    table = V.Variants().paper_table()
    assert any("front-to-back" in c for c in table.claim) and any("front-based" in c for c in table.claim)
    assert len(table) == 3 and set(table.columns) >= {"claim", "source"}


@pytest.mark.parametrize("claim", ["order-speedup", "front-faster", "exit-combines"])
def test_timing_claims_need_their_runs(claim):
    rows = order_rows({("basic", V.BACK): (0.4, 1000)})
    assert evaluate(NAME, claim, rows).holds is None
