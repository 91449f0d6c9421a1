"""kainz2009-coverage (E11): both coverage methods timed and checked for watertightness, and the claims."""

import numpy as np
import pandas as pd

from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kainz2009.coverage import METHODS, Coverage
from reports.imageio import write_exr
from test_kainz2009_package import paper_twin

NAME = "kainz2009-coverage"


def _evaluate(claim_id, rows):
    claim = next(c for c in Coverage.claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def _frames(seconds, *, spread=0.02, seed=0, stage="binning", n=9):
    """A stage's median and its ``n`` timed frames within ± ``spread`` of ``seconds``, as a run's columns."""
    values = seconds * (1 + spread * np.random.default_rng(seed).uniform(-1, 1, n))
    return {f"time_{stage}": float(np.median(values)), f"frames_{stage}": " ".join(f"{v:.6g}" for v in values)}


def test_coverage_plan_times_both_methods_and_bins_closed_boundaries_unbounded():
    profile = Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[NAME],
                      settings={NAME: {"triangle_counts": [500, 2000], "views": 3}})
    coverage = list(experiments.plan(profile).values())
    timed = {(r.tags["triangles"], r.options["coverage"], r.interleave) for r in coverage if r.tags["role"] == "test"}
    assert timed == {(t, m, f"sphere{t}") for t in (500, 2000) for m in METHODS}  # each count's two methods together
    tight = [r for r in coverage if r.tags["role"] == "watertight"]
    assert {r.options["coverage"] for r in tight} == set(METHODS)
    assert all(r.options["fragments"] == "global" and len(r.views) == 3 and r.interleave is None for r in tight)


def _image(tmp_path, name, image):
    path = tmp_path / f"{name}.exr"
    write_exr(str(path), image.astype(np.float32))
    return str(path)


def _rows(tmp_path, binning, *, unpaired=0, fragments=(100, 100), changed=0.0, spread=0.02):
    rows = [{"scene": f"sphere{t}", "triangles": t, "role": "test", "config": m, "time_total": 0.01,
             "count_records": t // 2, **_frames(seconds, spread=spread, seed=i)}
            for t, by_method in binning.items() for i, (m, seconds) in enumerate(by_method.items())]
    image = np.full((8, 8, 4), 0.5, np.float32)
    for method, count in zip(METHODS, fragments):
        for view in ("az0el0", "az37el12"):
            rows.append({"scene": "watertight", "role": "watertight", "config": method, "view": view,
                         "count_unpaired_pixels": unpaired if method == "edge" else 0, "count_fragments": count,
                         "exr": _image(tmp_path, f"{method}-{view}", image + (changed if method == "edge" else 0))})
    return rows


def test_coverage_claims(tmp_path):
    rows = _rows(tmp_path, {1000: {"bitmask": 0.001, "edge": 0.003}, 4000: {"bitmask": 0.002, "edge": 0.005}})
    result = _evaluate("bitshift-faster", rows)
    assert result.holds is True and result.measured.startswith("×2.49 (95 % CI ×") and result.measured.endswith("(4000 triangles)")
    assert result.detail.startswith("1000 triangles: ×2.99 (95 % CI ×") and result.interval[0] < 2.49 < result.interval[1]  # the least
    assert result.detail.endswith("tile records 1000: 500, 4000: 2e+03")
    for claim in ("watertight", "same-fragments"):
        assert _evaluate(claim, rows).holds is True, claim
    rows = _rows(tmp_path, {1000: {"bitmask": 0.003, "edge": 0.002}}, unpaired=3, fragments=(100, 98))
    for claim in ("bitshift-faster", "watertight", "same-fragments"):
        assert _evaluate(claim, rows).holds is False, claim
    rows = _rows(tmp_path, {1000: {"bitmask": 0.001, "edge": 0.003}}, changed=0.1)
    assert _evaluate("same-fragments", rows).holds is False                          # same counts, other image
    assert _evaluate("bitshift-faster", [r for r in rows if r.get("config") == "bitmask"]).holds is None
    # One count clearly faster, the other within the scatter of its frames: inconclusive.
    rows = _rows(tmp_path, {1000: {"bitmask": 0.001, "edge": 0.003}, 4000: {"bitmask": 0.002, "edge": 0.00202}},
                 spread=0.3)
    assert _evaluate("bitshift-faster", rows).inconclusive


def test_a_tie_is_not_faster(tmp_path):
    # Equal times timed together (one interleave group, the same frames): ×1 with a zero-width interval, which
    # an inclusive bound (≥ ×1) once counted as "faster".
    rows = _rows(tmp_path, {1000: {"bitmask": 0.002, "edge": 0.002}}, spread=0.0)
    for row in rows:
        if row["role"] == "test":
            row.update(interleave="sphere1000", view="az0el0", experiment=NAME)
    result = _evaluate("bitshift-faster", rows)
    assert result.interval == (1.0, 1.0) and result.holds is False


def test_the_papers_four_times_is_judged_beside_ours(tmp_path):
    paper, ours = paper_twin(Coverage, "bitshift-faster")
    assert paper.paper_value == ours.paper_value == "×4"
    assert "≥ ×4 at every triangle count" in paper.expected
    rows = _rows(tmp_path, {1000: {"bitmask": 0.001, "edge": 0.0045}, 4000: {"bitmask": 0.002, "edge": 0.0085}})
    assert _evaluate(paper.id, rows).holds is True and _evaluate(ours.id, rows).holds is True
    rows = _rows(tmp_path, {1000: {"bitmask": 0.001, "edge": 0.0045}, 4000: {"bitmask": 0.002, "edge": 0.005}})
    result = _evaluate(paper.id, rows)  # faster, not four times: ours holds, the paper's fails
    assert result.holds is False and result.measured.endswith("(4000 triangles)")
    assert _evaluate(ours.id, rows).holds is True
