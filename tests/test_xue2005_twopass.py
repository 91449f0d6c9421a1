"""``xue2005-twopass`` (E3): Eq. 5 against per-slice two-pass early termination, on synthetic frames."""

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments.kit import intervals
from pipeline.experiments.xue2005 import costmodel as cm
from pipeline.experiments.xue2005.earlyz import DATASET, FILL
from pipeline.experiments.xue2005.twopass import THRESHOLD, opacity_for, point_model, point_models
from reports import blocks
from reports.html import ReportContext
from test_xue2005_earlyz import NOISY, evaluate, planned, timed, with_isbvr

NAME = "xue2005-twopass"

F = 1_000_000
T_S, T_C = 2e-9, 20e-9
"""Seconds per fragment: γ = 0.1, so the break-even α is 0.111 and the ceiling ×5."""


def point(label, alpha, *, taps=0, factor=1.0, noisy=False, kind="sweep", isbvr=None):
    """Rows of one point (trivial shader, Basic, slice-ert; ESS+ERT with ``isbvr``, its ``(F_t + F_p, F'_c, passes
    time)``), each timed as Eqs. 3 and 4 say, slice-ert's passes ``factor`` times that; ``noisy`` slice-ert frames."""
    group, shaded = f"{label}.t{taps}", round((1 - alpha) * F)
    times = {"simple": (0.0, F * T_S), "basic": (0.0, F * T_C),
             "slice-ert": (factor * F * T_S, factor * ((F - shaded) * T_S + shaded * T_C))}
    counts = {config: {"count_fragments": F, "count_init_fragments": 0} for config in times}
    counts["slice-ert"] = {"count_fragments": shaded, "count_init_fragments": 40 if shaded < F else 0}
    if isbvr is not None:
        surfaces, isbvr_shaded, passes = isbvr
        times["ess+ert"] = (passes * 0.1, passes * 0.9)
        counts["ess+ert"] = {"count_fragments": isbvr_shaded, "count_init_fragments": surfaces,
                             "count_surface_fragments_t": 0, "count_surface_fragments_p": surfaces}
    rows = []
    for config, (init, draw) in times.items():
        factors = NOISY if noisy and config == "slice-ert" else [1.0] * 5
        row = timed([draw * f for f in factors], group=group, config=config, view="front", run=f"{group}.{config}",
                    kind=kind, opacity=0.1, extra_taps=taps, count_fragments_generated=F, info_timing="finish",
                    reference="" if config in ("simple", "basic") else f"{group}.basic", **counts[config])
        row.update({"time_init": init, "frames_init": intervals.format_frames([init * f for f in factors]),
                    "time_total": init + draw + 1e-4,
                    "frames_total": intervals.format_frames([(init + draw) * f + 1e-4 for f in factors])})
        rows.append(row)
    return rows


def sweep(*alphas, **options):
    return [row for alpha in alphas for row in point(f"a{100 * alpha:g}", alpha, **options)]


# ---------------------------------------------------------------------------------------------- design
@pytest.mark.parametrize("slices", [32, 128, 256])
@pytest.mark.parametrize("culling", [0.0, 0.3, 0.6, 0.9])
def test_the_opacity_culls_the_share_aimed_at(slices, culling):
    opacity = opacity_for(culling, slices)
    accumulated = 1 - (1 - opacity) ** np.arange(1, slices + 1)  # after 1, 2, ... slices
    opaque_after = int(np.argmax(accumulated >= THRESHOLD)) + 1 if accumulated[-1] >= THRESHOLD else slices
    culled = (slices - opaque_after) / slices  # slice-ert culls every slice behind the one that turned opaque
    assert culled <= culling and culling - culled <= 1.5 / slices
    if culling == 0:
        assert culled == 0


def test_bad_design_inputs_are_named():
    for call, message in ((lambda: opacity_for(1.0, 32), "culling: expected a culled fraction in [0, 1)"),
                          (lambda: opacity_for(0.5, 0), "slices: expected a number of slices > 0"),
                          (lambda: opacity_for(0.5, 32, threshold=1.0), "threshold: expected")):
        with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")):
            call()


# ---------------------------------------------------------------------------------------------- claims
def test_the_claims_hold_where_eq5_is_exact():
    rows = sweep(0.0, 0.5, 0.9)
    even = evaluate(NAME, "break-even", rows)
    # α 0: Eq. 5 ×0.909 ≤ 1 (a loss predicted, 9 % clear); α 0.5: ×1.54 > 1 (a gain, 54 % clear): the closest decides.
    assert even.holds is True and even.measured == "Basic / slice-ert ×0.909 (95 % CI ×0.909–×0.909) (α 0, 0 taps)"
    assert "α 0.5, 0 taps: ×1.54" in even.detail and "Eq. 6 predicts a gain: break-even α 0.111 at γ 0.1" in even.detail
    ceiling = evaluate(NAME, "below-ceiling", rows)
    assert ceiling.holds is True and ceiling.measured.startswith("measured δ / 1/(2γ) ×0.69 ")  # 3.45 of ×5
    within = evaluate(NAME, "eq5-within-20", rows)
    assert within.holds is True and within.measured.startswith("predicted / measured ×1 (95 % CI ×1–×1)")


def test_the_claims_fail():
    slow = sweep(0.0, 0.5, 0.9, factor=2.0)  # slice-ert twice as slow as Eq. 3 says
    even = evaluate(NAME, "break-even", slow)
    assert even.holds is False and even.measured.endswith("(α 0.5, 0 taps)")  # ×0.769 where a gain is predicted
    within = evaluate(NAME, "eq5-within-20", slow)
    assert within.holds is False and within.measured.startswith("predicted / measured ×2 ")
    losing = evaluate(NAME, "break-even", point("a0", 0.0, factor=0.5) + point("a90", 0.9))
    assert losing.holds is False and losing.measured.endswith("(α 0, 0 taps)")  # ×1.82 where a loss is predicted
    fast = evaluate(NAME, "below-ceiling", sweep(0.5, 0.9, factor=0.25))  # ×13.8 at α 0.9, past ×5
    assert fast.holds is False and fast.measured.endswith("(α 0.9, 0 taps)")


def test_break_even_leaves_out_points_near_it_and_needs_both_sides():
    result = evaluate(NAME, "break-even", sweep(0.0, 0.1, 0.5))  # 0.1 is within 0.05 of 0.111
    assert result.holds is True and "within ±0.05 of the break-even, not judged: α 0.1, 0 taps" in result.detail
    assert "α 0.1, 0 taps:" not in result.detail.split("; within")[0]
    gains = evaluate(NAME, "break-even", sweep(0.5, 0.9))
    assert gains.holds is None and "no point where Eq. 6 predicts a loss by more than 0.05" in gains.detail


def test_an_interval_across_the_bound_is_inconclusive():
    # slice-ert's frames 1 or 3 times Eq. 3's time at α 0.5: ×1.54 or ×0.513, across 1.
    result = evaluate(NAME, "break-even", point("a0", 0.0) + point("a50", 0.5, noisy=True))
    assert result.inconclusive and result.interval[0] < 1.0 < result.interval[1]


def test_the_point_model():
    rows = pd.DataFrame(point("opaque", 0.97, kind="opaque", isbvr=(20_000, 30_000, 1e-3)))
    m = point_model(rows, intervals.Resampler())
    assert (m["alpha"], m["gamma"][0], m["break_even"]) == (pytest.approx(0.97), pytest.approx(0.1),
                                                           pytest.approx(1 / 9))
    assert m["predicted"][0] == pytest.approx(cm.normalised_speedup(0.97, 0.1))
    assert m["measured"][0] == pytest.approx(m["predicted"][0]) and m["predicted"][1].shape == (intervals.DRAWS,)
    assert m["ceiling_share"][0] == pytest.approx(m["measured"][0] * 0.2)
    assert (m["side"], m["pays_off"], m["depth_writes"]) == ("gain", True, 40)
    assert m["t_first"] == pytest.approx(T_S) and m["t_simple"] == pytest.approx(T_S)
    # ESS+ERT: φ = 20 000 / 10⁶, α' = 0.97, Basic's 20 ms passes over its 1 ms.
    assert m["isbvr"]["phi"] == pytest.approx(0.02) and m["isbvr"]["alpha"] == pytest.approx(0.97)
    assert m["isbvr"]["measured"][0] == pytest.approx(20.0)
    models = point_models(pd.DataFrame(sweep(0.9, 0.0) + sweep(0.5, taps=4)))
    assert [(m["taps"], m["alpha"]) for m in models] == [(0, 0.0), (0, pytest.approx(0.9)), (4, 0.5)]


# ------------------------------------------------------------------------------------------------ plan
def test_the_plan_groups_every_point(monkeypatch):
    with_isbvr(monkeypatch)
    for scale, size, taps, culling in (("smoke", 32, [0], [0.0, 0.9]), ("default", 128, [0, 4, 16], [0, 0.3, 0.6, 0.9]),
                                       ("full", 256, [0, 4, 16], [0, 0.1, 0.25, 0.5, 0.75, 0.9])):
        runs = planned(scale, NAME)
        groups = {}
        for run in runs:
            groups.setdefault(run.interleave, []).append(run)
            assert run.views == ({"view": "front", "azimuth": 0.0, "elevation": 0.0},)
            assert run.scene["camera"] == {"projection": "orthographic", "view_height": pytest.approx(FILL * size)}
            volume = run.scene["volumes"][0]
            assert volume["dataset"] == DATASET and volume["size"] == size
            opacities = {p[4] for p in volume["transfer_function"]["points"]}
            assert opacities == {run.tags["opacity"]}
            assert run.options["order"] == "front-to-back" and run.options["count_fragments"] is True
            assert run.options["step_factor"] == 1.0 and run.repeat >= 3 and run.warmup >= 1
        labels = [f"a{100 * c:g}" for c in culling] + ["opaque"]
        assert sorted(groups) == sorted(f"{label}.t{k}" for label in labels for k in taps)
        for name, members in groups.items():
            configs = sorted(r.tags["config"] for r in members)
            opaque = name.startswith("opaque")
            assert configs == sorted(["simple", "basic", "slice-ert"] + (["ess+ert"] if opaque else [])), name
            assert len({r.tags["opacity"] for r in members}) == 1
            by_config = {r.tags["config"]: r for r in members}
            tested = by_config["slice-ert"]
            assert tested.options["zinit"] == "slice-ert" and tested.options["opaque_threshold"] == THRESHOLD
            assert tested.reference == by_config["basic"].id and by_config["basic"].options["zinit"] == "none"
            assert by_config["simple"].options["shader"] == "simple" and "extra_taps" not in by_config["simple"].options
            assert tested.options["extra_taps"] == by_config["basic"].options["extra_taps"] == tested.tags["extra_taps"]
        opacity = {r.interleave.split(".")[0]: r.tags["opacity"] for r in runs}
        assert opacity["opaque"] == 1.0
        assert [opacity[f"a{100 * c:g}"] for c in culling] == [round(opacity_for(c, size), 6) for c in culling]


def test_bad_settings_are_named(monkeypatch):
    with_isbvr(monkeypatch)
    for settings, message in (({"culling": [0.5, 1.0]}, r"culling: expected distinct culled fractions in \[0, 1\)"),
                              ({"culling": []}, "culling: expected distinct"),
                              ({"extra_taps": [0, -4]}, "extra_taps: expected distinct counts >= 0"),
                              ({"opaque": "yes"}, "opaque: expected true or false")):
        with pytest.raises(InputError, match=message):
            planned("default", NAME, **{NAME: settings})
    assert not any(r.interleave.startswith("opaque") for r in planned("smoke", NAME, **{NAME: {"opaque": False}}))


# ------------------------------------------------------------------------------------------------ page
def test_the_page(tmp_path):
    rows = pd.DataFrame(sweep(0.0, 0.5, 0.9) + sweep(0.0, 0.5, 0.9, taps=4, factor=1.2)
                        + point("opaque", 0.97, kind="opaque", isbvr=(20_000, 30_000, 1e-3)))
    for column in ("png", "exr", "record"):
        rows[column] = np.nan  # no image written
    report = tmp_path / "report"
    out = experiments.get(NAME).report(rows, ReportContext(report, tmp_path, NAME))
    sentences = next(b for b in out if isinstance(b, blocks.Takeaways)).sentences
    assert any(s.startswith("The opacities set α = 1 − F'_c / F") and "0 taps γ 0.1 (break-even α 0.111, ceiling ×5)"
               in s for s in sentences)
    assert any("0 taps: loses up to α 0 and wins from α 0.5, Eq. 6's break-even α 0.111" in s for s in sentences)
    assert any("ESS+ERT culls α' 0.97 with φ = (F_t + F_p) / F = 0.02: ×20 against its ceiling 1/γ = ×10" in s
               for s in sentences)
    assert any("first passes cost 2 ns per slice fragment against T_s 2 ns" in s and "timing 'finish'" in s
               for s in sentences)
    table = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("Every point"))
    assert table.frame["extra taps"].tolist() == [0, 0, 0, 0, 4, 4, 4]
    assert table.frame["Eq. 5 / measured"].round(6).tolist() == [1.0] * 4 + [1.2] * 3
    assert table.frame["first pass (ns / F)"].round(6).tolist() == [2.0] * 4 + [2.4] * 3
    contrast = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("At opacity 1"))
    assert contrast.frame["φ"].tolist() == [1.0, pytest.approx(0.02)]
    assert contrast.frame["ceiling"].tolist() == [pytest.approx(5.0), pytest.approx(10.0)]
    figure = next(b for b in out if isinstance(b, blocks.Figure))
    assert "no data" not in (report / figure.path).read_text()
