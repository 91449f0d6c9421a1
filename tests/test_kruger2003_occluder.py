"""``kruger2003-occluder``: the coverage sweep it plans and its claims on synthetic results."""

import pytest

from pipeline import experiments
from pipeline.experiments.kruger2003.occluder import OCCLUDED
from test_kruger2003_methods import evaluate, small_profile, with_gl_backends

NAME = "kruger2003-occluder"


def _occluder_rows(main_ms, fractions=(0.0, 0.5, 1.0), rays=1000, passes=10):
    rows = []
    for fraction, ms in zip(fractions, main_ms):
        occluded = round(fraction * rays)
        rows.append({"role": "test", "config": "rc", "fraction": fraction, "time_total": ms * 1.2e-3,
                     "time_main": ms * 1e-3, "count_rays": rays, "count_rays_occluded": occluded,
                     "count_passes_main": passes, "count_fragments_main": passes * (rays - occluded)})
    return rows


def test_occluder_plan_sweeps_coverage_for_rc_and_rca(monkeypatch):
    with_gl_backends(monkeypatch)
    runs = [r for r in experiments.plan(small_profile()).values() if r.experiment == NAME]
    assert {(r.options["variant"], r.options["occluder"]) for r in runs} == {
        (v, f) for v in ("rc", "rc-a") for f in OCCLUDED}
    with pytest.raises(Exception, match="fractions"):
        experiments.plan(small_profile(**{NAME: {"fractions": [0, 1]}}))


def test_occluder_claims():
    rows = _occluder_rows([10.0, 5.2, 0.4])
    assert evaluate(NAME, "occluded-rays-culled", rows).holds is True
    assert evaluate(NAME, "time-proportional", rows).holds is True
    rows[1]["count_fragments_main"] += 7  # a pass drew fragments of hidden rays
    assert evaluate(NAME, "occluded-rays-culled", rows).holds is False
    assert evaluate(NAME, "time-proportional", _occluder_rows([10.0, 9.5, 9.0])).holds is False  # no fall
    assert evaluate(NAME, "time-proportional", _occluder_rows([10.0, 1.0, 0.9])).holds is False  # not linear
