"""``xue2005-earlyz`` (E2): the micro-benchmark's claims on synthetic frames, its plan and its page.

Also the helpers ``test_xue2005_costmodel`` shares.
"""

import numpy as np
import pandas as pd
import pytest

import renderers
from core.errors import InputError
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kit import intervals
from pipeline.experiments.xue2005.earlyz import CONFIGS, DATASET, FILL, per_fragment
from reports import blocks
from reports.html import ReportContext

NAME = "xue2005-earlyz"

NOISY = [1.0, 1.0, 3.0, 1.0, 3.0]
"""Frame factors whose resampled median is 1 or 3: against steady frames, a ratio whose interval spans ×1–×3."""


def with_isbvr(monkeypatch):
    """The registry with ``gl-isbvr``, whether or not its package is importable here."""
    monkeypatch.setattr(renderers, "BACKENDS", {"gl-isbvr": "renderers.gl.not_here:Isbvr", **renderers.BACKENDS})


def profile(scale, *names, **settings):
    return Profile(name="t", scale=scale, volume_size=16, image_size=24, warmup=0, repeat=1, experiments=list(names),
                   settings=settings)


def planned(scale, *names, **settings):
    return [r for r in experiments.plan(profile(scale, *names, **settings)).values() if r.experiment in names]


def timed(frames, *, group, stage="draw", **row):
    """A successful row whose ``stage`` was timed over ``frames`` (seconds), in interleave ``group``."""
    return {"experiment": "x", "interleave": group, "status": "ok", **row,
            f"time_{stage}": float(np.median(frames)), f"frames_{stage}": intervals.format_frames(frames)}


def evaluate(experiment, claim_id, rows):
    """The result of claim ``claim_id`` of ``experiment`` on ``rows`` (dicts, as the successful rows)."""
    claim = next(c for c in experiments.get(experiment).claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def micro(per_fragment_ns, *, fragments=1000, culled_shaded=0, views=("front",), noisy=()):
    """Rows of the micro-benchmark: ``{config or taps: ns per fragment}``; configs in ``noisy`` get noisy frames."""
    rows = []
    for key, value in per_fragment_ns.items():
        config, taps = (key, 0) if key in ("simple", "culled") else ("volume", key)
        for view in views:
            factors = NOISY if key in noisy else [1.0] * 5
            rows.append(timed([value * 1e-9 * fragments * f for f in factors], group="micro", config=config,
                              extra_taps=taps, view=view, run=f"micro.{config}.t{taps}",
                              count_fragments_generated=fragments,
                              count_fragments=culled_shaded if config == "culled" else fragments))
    return rows


STEADY = {"simple": 2.0, "culled": 1.0, 0: 40.0, 4: 60.0, 16: 110.0}


def test_the_claims_hold_on_a_steady_device():
    rows = micro(STEADY)
    for claim in ("tz-at-most-ts", "gamma-falls", "cull-all-culls"):
        assert evaluate(NAME, claim, rows).holds is True, claim
    tz = evaluate(NAME, "tz-at-most-ts", rows)
    assert tz.measured == "T_z / T_s 0.5 (95 % CI 0.5–0.5)"
    assert tz.detail.startswith("T_z 1 ns, T_s 2 ns per fragment")
    gamma = evaluate(NAME, "gamma-falls", rows)
    # 0 → 4 taps: γ × 40/60 = 0.667; 4 → 16: × 60/110 = 0.545: the step closest to the bound decides.
    assert gamma.measured == "γ ×0.667 (95 % CI ×0.667–×0.667) (0 → 4 taps)"
    assert "0 taps: γ 0.05, T_c 40 ns" in gamma.detail


def test_the_claims_fail():
    assert evaluate(NAME, "tz-at-most-ts", micro({**STEADY, "culled": 3.0})).holds is False
    flat = evaluate(NAME, "gamma-falls", micro({**STEADY, 16: 60.0}))  # 4 → 16 taps: γ the same
    assert flat.holds is False and "(4 → 16 taps)" in flat.measured
    shaded = evaluate(NAME, "cull-all-culls", micro(STEADY, culled_shaded=7))
    assert shaded.holds is False and shaded.measured == "7 of 1e+03 fragments shaded"


def test_an_interval_across_the_bound_is_inconclusive():
    result = evaluate(NAME, "tz-at-most-ts", micro({**STEADY, "culled": 1.5}, noisy=("culled",)))
    assert result.inconclusive and result.interval[0] < 1.0 < result.interval[1]  # 0.75 or 2.25 a frame


def test_gamma_needs_two_complexities():
    result = evaluate(NAME, "gamma-falls", micro({"simple": 2.0, "culled": 1.0, 0: 40.0}))
    assert result.holds is None and "fewer than two shader complexities" in result.detail


def test_per_fragment_time_pools_the_views():
    rows = pd.DataFrame(micro({"simple": 2.0}, fragments=1000, views=("a",))
                        + micro({"simple": 4.0}, fragments=3000, views=("b",)))
    value, draws = per_fragment(rows, intervals.Resampler())
    assert value == pytest.approx((2e-6 + 12e-6) / 4000)  # Σ draw time / Σ F, not the mean of the two
    assert draws.shape == (intervals.DRAWS,) and np.allclose(draws, value)


def test_the_plan_times_every_configuration_together(monkeypatch):
    with_isbvr(monkeypatch)
    for scale, size in (("smoke", 32), ("default", 128), ("full", 256)):
        runs = planned(scale, NAME)
        assert {r.interleave for r in runs} == {"micro"} and {r.backend for r in runs} == {"gl-isbvr"}
        assert sorted(r.id for r in runs) == ["micro.culled", "micro.simple", "micro.volume.t0", "micro.volume.t16",
                                              "micro.volume.t4"]
        for run in runs:
            assert run.views == ({"view": "front", "azimuth": 0.0, "elevation": 0.0},)
            camera = run.scene["camera"]
            assert camera["projection"] == "orthographic" and camera["view_height"] == pytest.approx(FILL * size)
            assert run.scene["volumes"][0]["dataset"] == DATASET and run.scene["volumes"][0]["size"] == size
            assert run.options["step_factor"] == 1.0 and run.options["count_fragments"] is True
            assert run.repeat >= 3 and run.warmup >= 1
            expected = CONFIGS[run.tags["config"]][0]
            assert {k: run.options[k] for k in expected} == expected
        culled = next(r for r in runs if r.id == "micro.culled")
        assert culled.options["zinit"] == "cull-all" and culled.options["shader"] == "volume"
        assert {r.options.get("extra_taps", 0) for r in runs if r.tags["config"] == "volume"} == {0, 4, 16}


def test_no_runs_without_the_backend(monkeypatch):
    monkeypatch.setattr(renderers, "BACKENDS", {"reference": renderers.BACKENDS["reference"]})
    assert planned("default", NAME) == []


def test_the_sweep_needs_two_complexities(monkeypatch):
    with_isbvr(monkeypatch)
    with pytest.raises(InputError, match="extra_taps: need at least two different counts"):
        planned("default", NAME, **{NAME: {"extra_taps": [4, 4]}})


def test_the_page(tmp_path):
    rows = pd.DataFrame(micro(STEADY))
    for end, factor in (("min", 0.9), ("max", 1.1)):
        rows[f"time_draw_{end}"] = rows.time_draw * factor
    for column in ("png", "exr", "record"):
        rows[column] = ""
    report = tmp_path / "report"
    out = experiments.get(NAME).report(rows, ReportContext(report, tmp_path, NAME))
    takeaways = next(b for b in out if isinstance(b, blocks.Takeaways))
    assert any("T_s 2 ns, T_z 1 ns, T_c 40–110 ns" in s for s in takeaways.sentences)
    assert any("pays off above a culling rate of 5.26 %" in s for s in takeaways.sentences)  # γ 0.05: 0.05 / 0.95
    table = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("T_s, T_z and T_c"))
    assert table.frame["ns per fragment"].round(6).tolist() == [2.0, 1.0, 40.0, 60.0, 110.0]
    assert table.frame["γ = T_s / T_c"].iloc[2:].round(4).tolist() == [0.05, 0.0333, 0.0182]
    assert table.frame["γ = T_s / T_c"].iloc[:2].isna().all()
    figures = [b for b in out if isinstance(b, blocks.Figure)]
    assert len(figures) == 2 and all("no data" not in (report / f.path).read_text() for f in figures)
    assert any(isinstance(b, blocks.Text) and "twice as fast with colour writes off" in b.text for b in out)
    assert "up to 2×" in experiments.get(NAME).paper_table()["paper's number"].tolist()
