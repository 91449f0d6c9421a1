"""kainz2009-depthcap (E4/E6): each cap against unbounded lists, and the claims on synthetic images."""

import numpy as np
import pandas as pd

from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kainz2009.depthcap import CAPS, SCENES, SHALLOW, SPEED_CAPS, DepthCap
from pipeline.experiments.kainz2009.methods import TILED
from reports.imageio import write_exr
from test_kainz2009_package import paper_twin

NAME = "kainz2009-depthcap"


def _evaluate(claim_id, rows):
    claim = next(c for c in DepthCap.claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def _frames(seconds, *, spread=0.02, seed=0, stage="technique", n=9):
    """A stage's median and its ``n`` timed frames within ± ``spread`` of ``seconds``, as a run's columns."""
    values = seconds * (1 + spread * np.random.default_rng(seed).uniform(-1, 1, n))
    return {f"time_{stage}": float(np.median(values)), f"frames_{stage}": " ".join(f"{v:.6g}" for v in values)}


def test_depthcap_plan_compares_each_cap_with_unbounded_lists():
    profile = Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[NAME])
    runs = list(experiments.plan(profile).values())
    for scene in SCENES:
        here = {r.id: r for r in runs if r.tags["scene"] == scene}
        unbounded = here[f"{scene}.unbounded"]
        assert unbounded.options["fragments"] == "global" and unbounded.reference == f"{scene}.truth"
        capped = [r for r in here.values() if r.tags["role"] == "test"]
        assert sorted(r.options["depth_cap"] for r in capped) == list(CAPS)
        assert all(r.reference == unbounded.id and r.options["fragments"] == "local" for r in capped)
    assert all(r.options.get("empty_space") == "box" for r in runs if r.tags["scene"] == "pile"
               and r.backend == TILED)  # two fragments per volume: the pile passes the cap
    # The speed of a smaller cap: a scene under both caps, the two timed together, nothing else grouped.
    shallow = {r.options["depth_cap"]: r for r in runs if r.tags["scene"] == SHALLOW}
    assert sorted(shallow) == sorted(SPEED_CAPS) and len(shallow[16].scene["volumes"]) * 2 <= min(SPEED_CAPS)
    assert {r.key for r in runs if r.interleave} == {r.key for r in shallow.values()}
    assert {r.interleave for r in shallow.values()} == {SHALLOW}


def _image(tmp_path, name, image):
    path = tmp_path / f"{name}.exr"
    write_exr(str(path), image.astype(np.float32))
    return str(path)


def _cap_rows(tmp_path, wrong_by_cap, psnr=50.0):
    """Unbounded and capped rows of one scene; ``wrong_by_cap`` pixels (of 10 000) off by 0.1 at each cap."""
    truth = np.zeros((100, 100, 4), np.float32)
    truth[..., :] = (0.3, 0.3, 0.3, 0.6)
    rows = [{"scene": "screw", "run": "screw.unbounded", "role": "unbounded", "view": "axis", "status": "ok",
             "exr": _image(tmp_path, "unbounded", truth), "psnr": psnr, "reference": "screw.truth"}]
    for cap, wrong in wrong_by_cap.items():
        image = truth.copy()
        image.reshape(-1, 4)[:wrong, 0] += 0.1
        rows.append({"scene": "screw", "run": f"screw.cap{cap}", "role": "test", "view": "axis", "status": "ok",
                     "cap": cap, "reference": "screw.unbounded", "exr": _image(tmp_path, f"cap{cap}", image),
                     "count_fragments_dropped": 10 * wrong, "time_total": 1.0})
    return rows


def _speed_rows(small, large, *, spread=0.02, dropped=0):
    """The shallow scene's rows: kernel seconds at the smallest and the largest cap compared."""
    return [{"scene": SHALLOW, "role": "speed", "view": "headline", "cap": cap, "count_fragments_max": 12,
             "count_fragments": 5000, "count_fragments_dropped": dropped if cap == min(SPEED_CAPS) else 0,
             **_frames(seconds, spread=spread, seed=cap)} for cap, seconds in zip(SPEED_CAPS, (small, large))]


def test_depthcap_claims(tmp_path):
    rows = _cap_rows(tmp_path, {16: 900, 32: 100, 55: 4, 63: 0}) + _speed_rows(0.8, 1.0)
    for claim in ("cap55-error", "error-shrinks", "unbounded-exact", "small-cap-faster"):
        assert _evaluate(claim, rows).holds is True, claim
    assert _evaluate("cap55-error", rows).measured == "0.04 % (screw)"
    speed = _evaluate("small-cap-faster", rows)
    assert speed.measured.startswith("×1.2") and "95 % CI" in speed.measured
    assert "at most 12 per pixel" in speed.detail
    rows = _cap_rows(tmp_path, {16: 900, 32: 1000, 55: 5, 63: 0}, psnr=30.0) + _speed_rows(1.2, 1.0)
    for claim in ("cap55-error", "error-shrinks", "unbounded-exact", "small-cap-faster"):
        assert _evaluate(claim, rows).holds is False, claim  # 5 of 10 000 is 0.05 %: not fewer


def test_small_cap_speed_is_judged_only_where_both_caps_do_the_same_work():
    assert _evaluate("small-cap-faster", _speed_rows(1.0, 1.01, spread=0.3)).inconclusive
    # Had the smaller cap dropped fragments, it would have rendered less: that is not the paper's gain.
    dropped = _evaluate("small-cap-faster", _speed_rows(0.5, 1.0, dropped=40))
    assert dropped.holds is None and not dropped.inconclusive and "dropped 40 fragments" in dropped.detail


def test_the_papers_up_to_forty_percent_is_judged_beside_ours():
    paper, ours = paper_twin(DepthCap, "small-cap-faster")
    assert paper.paper_value == ours.paper_value == "up to 40 %"
    assert "≥ ×1.4 " in paper.expected
    assert _evaluate(paper.id, _speed_rows(0.7, 1.0)).holds is True  # ×1.43
    assert _evaluate(ours.id, _speed_rows(0.7, 1.0)).holds is True
    assert _evaluate(paper.id, _speed_rows(0.8, 1.0)).holds is False  # ×1.25: faster, not the paper's best case
    assert _evaluate(ours.id, _speed_rows(0.8, 1.0)).holds is True
