"""The cost model (Eqs. 1–9, note 001 §2.2 and §2.6) and ``xue2005-costmodel`` (E4, E5) on synthetic frames."""

import re

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments.kit import intervals
from pipeline.experiments.xue2005 import costmodel as cm
from pipeline.experiments.xue2005.costmodel_check import STAND_INS, scene_model, with_passes
from pipeline.experiments.xue2005.tables import IMPLIED_CULLING, IMPLIED_GAMMAS, paper_speedup
from reports import blocks
from reports.html import ReportContext
from test_xue2005_earlyz import NOISY, evaluate, planned, timed, with_isbvr

NAME = "xue2005-costmodel"

ALPHAS = (0, 0.25, 0.5, 0.75, 0.9, 1.0)

EQ5_TABLE = {  # note 001 §2.2: Eq. 5 by γ (rows) and α (columns), as printed
    0.05: ("0.952", "1.231", "1.739", "2.963", "5.128", "10.0"),
    0.1: ("0.909", "1.143", "1.538", "2.353", "3.448", "5.0"),
    0.2: ("0.833", "1.000", "1.250", "1.667", "2.083", "2.5"),
    0.5: ("0.667", "0.727", "0.800", "0.889", "0.952", "1.0"),
}

EQ9_TABLE = {  # note 001 §2.6: Eq. 9 with φ = 0.05 by γ and α', as printed
    0.05: ("0.998", "1.307", "1.896", "3.448", "6.78", "19.0"),
    0.1: ("0.995", "1.282", "1.802", "3.030", "5.128", "9.52"),
    0.2: ("0.990", "1.235", "1.639", "2.439", "3.448", "4.76"),
}


def printed(value, text):
    """``value`` rounded as the guide printed ``text`` (its decimals, 3 at most)."""
    decimals = len(text.split(".")[1]) if "." in text else 0
    return f"{value:.{decimals}f}" if decimals or value < 10 else f"{value:.3g}"


# ----------------------------------------------------------------------------------------- the formulas
@pytest.mark.parametrize("gamma", sorted(EQ5_TABLE))
def test_eq5_reproduces_the_guides_table(gamma):
    assert [printed(cm.normalised_speedup(a, gamma), t) for a, t in zip(ALPHAS, EQ5_TABLE[gamma])] == \
        list(EQ5_TABLE[gamma])


@pytest.mark.parametrize("gamma", sorted(EQ9_TABLE))
def test_eq9_reproduces_the_guides_table_at_phi_005(gamma):
    assert [printed(cm.isbvr_normalised_speedup(a, 0.05, gamma), t) for a, t in zip(ALPHAS, EQ9_TABLE[gamma])] == \
        list(EQ9_TABLE[gamma])


COUNTS = {"fragments": 1000.0, "shaded": 300.0, "surface_t": 40.0, "surface_p": 10.0}
TIMES = {"t_simple": 2.0, "t_complex": 25.0}


def test_the_per_slice_forms_agree():
    alpha, gamma = cm.culling_rate(1000, 300), cm.shader_ratio(2.0, 25.0)
    assert (alpha, gamma) == (pytest.approx(0.7), pytest.approx(0.08))
    eq4 = cm.per_slice_speedup(fragments=1000, shaded=300, **TIMES)
    eq2 = cm.two_pass_speedup(fragments=1000, setup=1000, shaded=300, t_simple=2.0, t_culled=2.0, t_complex=25.0)
    assert eq4 == pytest.approx(eq2) == pytest.approx(cm.normalised_speedup(alpha, gamma))
    # Eq. 1 term by term: F_s·T_s + (F − F_c)·T_z + F_c·T_c.
    assert cm.two_pass_time(fragments=1000, setup=500, shaded=300, t_simple=2.0, t_culled=1.0, t_complex=25.0) == \
        pytest.approx(500 * 2 + 700 * 1 + 300 * 25)
    assert cm.per_slice_time(fragments=1000, shaded=300, **TIMES) == pytest.approx(1000 * 2 + 700 * 2 + 300 * 25)


def test_the_isbvr_forms_agree():
    init = cm.isbvr_init_time(surface_t=40, surface_p=10, t_simple=2.0)
    volume = cm.isbvr_volume_time(fragments=1000, shaded=300, **TIMES)
    assert (init, volume) == (pytest.approx(100.0), pytest.approx(700 * 2 + 300 * 25))
    eq9 = cm.isbvr_speedup(**COUNTS, **TIMES)
    assert eq9 == pytest.approx(1000 * 25 / (init + volume))
    alpha, phi, gamma = cm.culling_rate(1000, 300), cm.surface_share(1000, 40, 10), cm.shader_ratio(2.0, 25.0)
    assert phi == pytest.approx(0.05)
    assert eq9 == pytest.approx(cm.isbvr_normalised_speedup(alpha, phi, gamma))
    # Culled fragments priced once (T_s) instead of twice: iSBVR beats per-slice two-pass at equal culling.
    assert eq9 > cm.per_slice_speedup(fragments=1000, shaded=300, **TIMES)
    assert cm.implied_culling(eq9, gamma=gamma, phi=phi) == pytest.approx(alpha)


def test_break_even_and_ceilings():
    assert cm.break_even_culling(0.2) == pytest.approx(0.25)  # the paper's example
    assert cm.normalised_speedup(0.25, 0.2) == pytest.approx(1.0)
    assert cm.pays_off(0.26, 0.2) and not cm.pays_off(0.24, 0.2)
    for gamma in (0.05, 0.1, 0.3):
        edge = cm.break_even_culling(gamma)
        assert cm.normalised_speedup(edge, gamma) == pytest.approx(1.0)
        assert cm.pays_off(min(edge + 1e-6, 1.0), gamma) and not cm.pays_off(edge - 1e-6, gamma)
        assert cm.per_slice_ceiling(gamma) == pytest.approx(cm.normalised_speedup(1.0, gamma))
        assert cm.isbvr_ceiling(gamma) == pytest.approx(cm.isbvr_normalised_speedup(1.0, 0.0, gamma))
        assert cm.isbvr_ceiling(gamma) == pytest.approx(2 * cm.per_slice_ceiling(gamma))
    assert cm.break_even_culling(0.5) == pytest.approx(1.0)
    assert cm.break_even_culling(1.0) == np.inf and cm.break_even_culling(3.0) == np.inf
    assert not cm.pays_off(1.0, 0.5)


def test_arrays_broadcast():
    draws = np.array([1.0, 2.0, 4.0])
    result = cm.isbvr_speedup(**COUNTS, t_simple=draws, t_complex=25.0)
    assert isinstance(result, np.ndarray) and result.shape == (3,)
    assert result == pytest.approx([cm.isbvr_speedup(**COUNTS, t_simple=t, t_complex=25.0) for t in draws])
    assert isinstance(cm.isbvr_speedup(**COUNTS, **TIMES), float)
    assert cm.break_even_culling([0.2, 2.0]).tolist() == [pytest.approx(0.25), np.inf]


def test_the_implied_culling_rates_are_the_guides():
    for scene, rates in IMPLIED_CULLING.items():
        delta = paper_speedup(scene, "ess+ert")
        assert [round(cm.implied_culling(delta, gamma=g), 3) for g in IMPLIED_GAMMAS] == list(rates), scene


@pytest.mark.parametrize("call, message", [
    (lambda: cm.culling_rate(0, 0), "fragments: expected a fragment count (F) > 0"),
    (lambda: cm.culling_rate(100, 120), "cannot exceed the fragments generated"),
    (lambda: cm.culling_rate(100, -1), "shaded: expected a fragment count (F_c) >= 0"),
    (lambda: cm.normalised_speedup(1.5, 0.2), "alpha: expected a culling rate (α) in [0, 1]"),
    (lambda: cm.normalised_speedup(0.5, 0.0), "gamma: expected a shader time ratio T_s / T_c (γ) > 0"),
    (lambda: cm.isbvr_normalised_speedup(0.5, -0.1, 0.2), "phi: expected a share of init fragments (φ) >= 0"),
    (lambda: cm.shader_ratio("fast", 1.0), "t_simple: expected a time per fragment (T_s)"),
    (lambda: cm.shader_ratio(True, 1.0), "t_simple: expected a time per fragment (T_s)"),
    (lambda: cm.isbvr_speedup(**COUNTS, t_simple=np.nan, t_complex=1.0), "t_simple: expected finite"),
    (lambda: cm.isbvr_speedup(**COUNTS, t_simple=1.0, t_complex=0.0),
     "t_complex: expected a time per fragment (T_c) > 0"),
    (lambda: cm.implied_culling(2.0, gamma=1.0), "gamma: expected a shader time ratio (γ) below 1"),
    (lambda: cm.implied_culling(0.0), "speedup: expected a speed-up (δ) > 0"),
])
def test_bad_inputs_are_named(call, message):
    with pytest.raises(InputError, match=re.escape(message)):
        call()


# --------------------------------------------------------------------------------------- the experiment
def scene_rows(scene, *, basic_draw, isbvr_init, isbvr_draw, simple_draw, taps=0, counts=None, views=("headline",),
               noisy=False):
    """Rows of one scene's Basic, ESS+ERT and trivial-shader runs, each view alike (seconds per frame)."""
    counts = {"count_fragments_generated": 1000, "count_fragments": 300, "count_surface_fragments_t": 40,
              "count_surface_fragments_p": 10, **(counts or {})}
    steady, factors = [1.0] * 5, NOISY if noisy else [1.0] * 5
    rows = []
    for view in views:
        for config, init, draw, frames in (("basic", 0.0, basic_draw, steady),
                                           ("ess+ert", isbvr_init, isbvr_draw, factors),
                                           ("simple", 0.0, simple_draw, steady)):
            if config == "simple" and taps:
                continue
            row = timed([draw * f for f in frames], group=scene, config=config, scene=scene, extra_taps=taps, view=view,
                        run=f"{scene}.t{taps}.{config}", **(counts if config == "ess+ert" else
                                                           {"count_fragments_generated": 1000,
                                                            "count_fragments": 1000}))
            row.update({"time_init": init, "frames_init": intervals.format_frames([init] * 5),
                        "time_total": init + draw + 1e-4,
                        "frames_total": intervals.format_frames([(init + draw) * f + 1e-4 for f in frames])})
            if config == "ess+ert":
                row["psnr"] = 60.0
            rows.append(row)
    return rows


# T_s = 2 µs, T_c = 25 µs per fragment over F = 1000: Eq. 9 gives 25 ms / (50·2 + 700·2 + 300·25 µs) = ×2.778.
EXACT = {"basic_draw": 25e-3, "isbvr_init": 0.1e-3, "isbvr_draw": 8.9e-3, "simple_draw": 2e-3}


def stand_ins(**scene):
    return [row for name in STAND_INS for row in scene_rows(name, **{**EXACT, **scene})]


def test_eq9_within_20_percent():
    result = evaluate(NAME, "eq9-within-20", stand_ins())
    assert result.holds is True and result.measured.startswith("predicted / measured ×1 (95 % CI ×1–×1)")
    assert "aneurysm: predicted ×2.78, measured ×2.78" in result.detail
    assert "α' 0.7, φ 0.05, γ 0.08" in result.detail
    # ESS+ERT twice as fast as Eq. 9 says: predicted / measured = 0.5 on every stand-in.
    fast = evaluate(NAME, "eq9-within-20", stand_ins(isbvr_init=0.05e-3, isbvr_draw=4.45e-3))
    assert fast.holds is False and fast.measured.startswith("predicted / measured ×0.5")
    # One stand-in off is enough to fail.
    rows = stand_ins()
    rows = [r for r in rows if r["scene"] != "bonsai"] + scene_rows("bonsai", **{**EXACT, "isbvr_draw": 15e-3})
    one = evaluate(NAME, "eq9-within-20", rows)
    assert one.holds is False and one.measured.endswith("(bonsai)")


def test_eq9_inconclusive_when_the_interval_straddles_the_band():
    # ESS+ERT's volume pass 1 or 3 times as long a frame: predicted / measured ×0.8 or ×2.4.
    rows = stand_ins(isbvr_init=0.08e-3, isbvr_draw=7.12e-3, noisy=True)
    result = evaluate(NAME, "eq9-within-20", rows)
    assert result.inconclusive and result.interval[0] < 1.2 < result.interval[1]


def test_the_prediction_uses_each_views_counts():
    rows = pd.DataFrame(scene_rows("head", **EXACT, views=("a", "b")))
    model = scene_model(rows, "head", 0, intervals.Resampler())
    assert model["views"] == 2 and model["fragments"] == 2000 and model["shaded"] == 600
    assert model["predicted"][0] == pytest.approx(cm.isbvr_speedup(**COUNTS, t_simple=2e-6, t_complex=25e-6))
    assert model["measured"][0] == pytest.approx(25e-3 / 9e-3)
    assert model["whole"][0] == pytest.approx((25e-3 + 1e-4) / (9e-3 + 1e-4))
    assert model["predicted"][1].shape == (intervals.DRAWS,)


def test_passes_add_the_frames_of_both_stages():
    rows = pd.DataFrame([{"time_init": 1.0, "time_draw": 2.0, "frames_init": "1 1 2", "frames_draw": "2 4 2"}])
    out = with_passes(rows)
    assert out.frames_passes.iloc[0] == "3 5 4" and out.time_passes.iloc[0] == 4.0  # the median of the sums
    assert with_passes(rows.drop(columns="frames_init")).time_passes.iloc[0] == 3.0


def sweep(times):
    """The head stand-in at ``{taps: (basic draw, ESS+ERT draw)}``, with the other stand-ins."""
    rows = [r for r in stand_ins() if r["scene"] != "head"]
    for taps, (basic, isbvr) in times.items():
        rows += scene_rows("head", **{**EXACT, "basic_draw": basic, "isbvr_draw": isbvr}, taps=taps)
    return rows


def test_the_speedup_rises_with_the_shaders_cost():
    rising = evaluate(NAME, "speedup-rises-with-complexity", sweep({0: (25e-3, 8.9e-3), 4: (40e-3, 12e-3),
                                                                     16: (90e-3, 22e-3)}))
    assert rising.holds is True and "head, ESS+ERT over Basic: 0 taps: ×2.78" in rising.detail
    falling = evaluate(NAME, "speedup-rises-with-complexity", sweep({0: (25e-3, 8.9e-3), 4: (40e-3, 12e-3),
                                                                      16: (90e-3, 30e-3)}))
    assert falling.holds is False and "(4 → 16 taps)" in falling.measured
    none = evaluate(NAME, "speedup-rises-with-complexity", stand_ins())
    assert none.holds is None and "no successful ESS+ERT run with extra taps" in none.detail


def test_the_plan_groups_each_stand_in_with_its_micro_benchmark(monkeypatch):
    with_isbvr(monkeypatch)
    for scale, views in (("smoke", 1), ("default", 3), ("full", 4)):
        runs = planned(scale, NAME)
        groups = {}
        for run in runs:
            groups.setdefault(run.interleave, []).append(run)
            assert len(run.views) == views and run.views[0]["view"] == "headline"
            assert run.options["step_factor"] == 1.0 and run.options["count_fragments"] is True
            assert run.scene["volumes"][0]["preset"] == "isbvr"
        assert sorted(groups) == sorted(STAND_INS)
        for name in ("aneurysm", "golden_lady", "bonsai"):
            assert sorted(r.id for r in groups[name]) == [f"{name}.basic", f"{name}.ess+ert", f"{name}.simple"]
        assert sorted(r.id for r in groups["head"]) == ["head.basic", "head.ess+ert", "head.simple", "head.t16.basic",
                                                         "head.t16.ess+ert", "head.t4.basic", "head.t4.ess+ert"]
        by_id = {r.id: r for r in runs}
        assert by_id["head.simple"].options["shader"] == "simple" and by_id["head.simple"].options["zinit"] == "none"
        assert by_id["head.t4.ess+ert"].options == {"zinit": "ess+ert", "extra_taps": 4, "step_factor": 1.0,
                                                     "count_fragments": True}
        assert by_id["head.t4.ess+ert"].reference == "head.t4.basic" and by_id["head.t4.basic"].reference is None


def test_bad_settings_are_named(monkeypatch):
    with_isbvr(monkeypatch)
    with pytest.raises(InputError, match="sweep_scene: 'head' is not among the scenes run"):
        planned("default", NAME, **{NAME: {"scenes": ["bonsai"]}})
    with pytest.raises(InputError, match="extra_taps: need 0"):
        planned("default", NAME, **{NAME: {"extra_taps": [4, 16]}})


def test_the_paper_table_holds_the_implied_culling():
    table = experiments.get(NAME).paper_table()
    head = table[table["stand-in"] == "head"].iloc[0]
    assert head["ESS+ERT / Basic"] == pytest.approx(3.329, abs=1e-3)
    assert head["implied α' (γ = 0.1, φ = 0)"] == pytest.approx(0.777)


def test_the_page(tmp_path):
    rows = pd.DataFrame(sweep({0: (25e-3, 8.9e-3), 4: (40e-3, 12e-3), 16: (90e-3, 22e-3)}))
    for column in ("png", "exr", "record"):
        rows[column] = ""
    report = tmp_path / "report"
    out = experiments.get(NAME).report(rows, ReportContext(report, tmp_path, NAME))
    takeaways = next(b for b in out if isinstance(b, blocks.Takeaways))
    assert any("aneurysm 0.7 (paper ≥ 0.706)" in s for s in takeaways.sentences)
    table = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("Eq. 9 per stand-in"))
    assert table.frame.scene.tolist() == list(STAND_INS)
    assert table.frame["Eq. 9 / measured"].tolist() == [1.0] * 4
    sweep_table = next(b for b in out if isinstance(b, blocks.Table) and b.title == "Shader-complexity sweep")
    assert sweep_table.frame["extra taps"].tolist() == [0, 4, 16]
    figures = [b for b in out if isinstance(b, blocks.Figure)]
    assert len(figures) == 2 and all("no data" not in (report / f.path).read_text() for f in figures)
