"""``xue2005-fuzziness`` (E11): the haze sweep it plans and its claims on synthetic results."""

import pandas as pd
import pytest

from core.errors import InputError
from pipeline.experiments.xue2005.fuzziness import CONFIGS, HAZES, summary
from test_xue2005_sweeps import NOISY, evaluate, planned, timed, with_isbvr

NAME = "xue2005-fuzziness"


def sweep(speedups, *, culled=None, ert=None, frames=None):
    """Rows of the haze sweep: Basic at 10 ms, ESS+ERT and ESS at 10 / s ms for each haze's speed-up ``s``.

    ``culled`` gives ESS+ERT's culled fraction per haze (default: falling with the speed-up), ``ert`` ERT's
    speed-up per haze (default 1.2 everywhere), ``frames`` ESS+ERT's frame factors at the last haze.
    """
    culled = culled or [1 - 1 / s for s in speedups]
    ert = ert or [1.2] * len(speedups)
    rows = []
    for k, (haze, s) in enumerate(zip(HAZES, speedups)):
        last = k == len(speedups) - 1
        for config, speed, alpha in (("basic", 1.0, 0.0), ("ess", s, culled[k]), ("ert", ert[k], 0.1),
                                     ("ess+ert", s, culled[k])):
            ms = [10.0 / speed * f for f in (frames if last and frames and config == "ess+ert" else [1.0] * 5)]
            rows.append(timed([m * 1e-3 for m in ms], group=f"golden_lady.h{haze:g}", run=f"h{haze:g}.{config}",
                              scene="golden_lady", haze=haze, config=config, count_fragments_generated=1000,
                              count_fragments=round(1000 * (1 - alpha)), count_cubes_t=20 + k, count_cubes_p=4,
                              count_surface_fragments_t=30, count_surface_fragments_p=10))
    return rows


def test_every_haze_and_mode_is_one_group_each_haze_on_its_own_phantom(monkeypatch):
    with_isbvr(monkeypatch)
    runs = planned(NAME)
    assert {run.interleave for run in runs} == {"golden_lady"}  # the claims compare hazes: timed together
    groups = {}
    for run in runs:
        prefix = run.id.rsplit(".", 1)[0]
        groups.setdefault(prefix, []).append(run)
        assert run.reference == (None if run.tags["config"] == "basic" else f"{prefix}.basic"), run.id
    assert sorted(groups) == [f"golden_lady.h{h:g}" for h in HAZES]
    for members in groups.values():
        assert sorted(m.tags["config"] for m in members) == sorted(CONFIGS)
        (volume,) = {str(m.scene["volumes"]) for m in members}
        assert f"'haze': {members[0].tags['haze']}" in volume and "'preset': 'isbvr'" in volume
    assert len(planned(NAME, scale="smoke")) == 8


@pytest.mark.parametrize("hazes", [[1.0], [1.0, 0.5], [0.0, 4.0], [0.5, 0.5]])
def test_the_hazes_must_increase_within_the_generators_range(monkeypatch, hazes):
    with_isbvr(monkeypatch)
    with pytest.raises(InputError, match="hazes"):
        planned(NAME, hazes=hazes)


def test_the_speedup_must_fall_at_every_step():
    falling = evaluate(NAME, "speedup-falls", sweep([3.0, 2.5, 2.0, 1.5]))
    assert falling.holds is True and "×1.2 (95 % CI ×1.2–×1.2) (haze 0 / 0.5)" in falling.measured  # smallest step
    rising = evaluate(NAME, "speedup-falls", sweep([3.0, 2.5, 2.6, 1.5]))
    assert rising.holds is False and "(haze 0.5 / 1)" in rising.measured
    assert evaluate(NAME, "speedup-falls", sweep([3.0, 2.5, 2.0, 1.5], frames=[1 / f for f in NOISY])).inconclusive


def test_the_culled_fraction_must_fall_at_every_step():
    assert evaluate(NAME, "culled-falls", sweep([3.0, 2.5, 2.0, 1.5])).holds is True
    flat = evaluate(NAME, "culled-falls", sweep([3.0, 2.5, 2.0, 1.5], culled=[0.6, 0.5, 0.5, 0.3]))
    assert flat.holds is False and flat.measured == "α' 60 % → 50 % → 50 % → 30 % (haze 0 → 1.5)"


def test_ess_and_ert_must_each_lose_to_the_haze():
    assert evaluate(NAME, "gains-fall-separately", sweep([3.0, 2.0], ert=[1.4, 1.1])).holds is True
    flat = evaluate(NAME, "gains-fall-separately", sweep([3.0, 2.0]))
    assert flat.holds is False and flat.measured.endswith("(ERT)")


def test_the_summary_has_every_mode_per_haze_with_the_papers_ratio_at_the_registered_haze():
    table = summary(pd.DataFrame(sweep([3.0, 2.5, 2.0])))
    assert len(table) == 9 and list(table.config[:3]) == ["ess", "ert", "ess+ert"]
    at_one = table[(table.haze == 1.0) & (table.config == "ess+ert")].iloc[0]
    assert at_one.speedup == pytest.approx(2.0) and at_one.alpha == pytest.approx(0.5) and at_one.paper == "×2.23"
    assert set(table[table.haze != 1.0].paper) == {""}
