"""``kruger2003-passes``: fragments per main pass, the iso-surface caster and the M sweep on synthetic results."""

import json

from test_kruger2003_methods import NOISY, evaluate, five_frames, timed

NAME = "kruger2003-passes"


def _record(tmp_path, name, counts):
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps({"views": [{"view": "headline", "info": {"fragments_per_main_pass": counts}}]}))
    return str(path)


def test_passes_claims(tmp_path):
    rows = [{"part": "passes", "role": "test", "config": "rc", "time_total": 2.0,
             "record": _record(tmp_path, "rc", [100, 100, 100, 100])},
            {"part": "passes", "role": "test", "config": "rc-a", "time_total": 1.0,
             "record": _record(tmp_path, "rca", [100, 80, 40, 10])},
            {"part": "iso", "role": "test", "config": "rc-a", "time_total": 0.5}]
    for row, samples in zip(rows, (4000, 2000, 1000)):
        row["count_samples"] = samples
    rows += [{"part": "m-sweep", "role": "test", "config": "rc-b", "m": m, "time_total": t}
             for m, t in ((1, 3.0), (8, 1.0), (64, 2.0))]
    rows = [five_frames(row) for row in rows]
    for claim in ("rc-flat", "rca-falls", "iso-faster", "m-u-shape"):
        assert evaluate(NAME, claim, rows).holds is True, claim
    assert evaluate(NAME, "m-u-shape", rows).measured == "fastest inside at M = 8; end / M = 8 time ×2 (95 % CI ×2–×2) (M 64)"
    rows[0]["record"] = _record(tmp_path, "rc2", [100, 90, 50, 20])
    rows[1]["record"] = _record(tmp_path, "rca2", [100, 100, 100, 90])
    rows[2] = five_frames({**rows[2], "time_total": 1.5})
    rows[-1] = five_frames({**rows[-1], "time_total": 0.5})
    for claim in ("rc-flat", "rca-falls", "iso-faster", "m-u-shape"):
        assert evaluate(NAME, claim, rows).holds is False, claim


def test_the_iso_surface_caster_must_be_strictly_faster():
    rows = [five_frames({"part": "passes", "role": "test", "config": "rc-a", "time_total": 1.0, "count_samples": 2000,
                         "interleave": "iso", "view": "headline"}),
            five_frames({"part": "iso", "role": "test", "config": "rc-a", "time_total": 1.0, "count_samples": 1000,
                         "interleave": "iso", "view": "headline"})]
    result = evaluate(NAME, "iso-faster", rows)
    assert result.holds is False and result.measured == "×1 (95 % CI ×1–×1)"  # equal times do not beat


def _sweep(times, frames=lambda m, t: [t] * 5, group="m-sweep"):
    return [timed(frames(m, t), group=group, part="m-sweep", role="test", config="rc-b", m=m, view="headline",
                  run=f"foot.m{m}", count_passes_main=64 // m, count_samples=1000 * m) for m, t in times]


def test_the_u_shape_rests_on_both_ends_against_the_fastest_inner_m():
    rows = _sweep(((1, 3.0), (8, 1.0), (16, 1.2), (64, 2.0)))
    result = evaluate(NAME, "m-u-shape", rows)
    assert result.holds is True
    assert result.measured == "fastest inside at M = 8; end / M = 8 time ×2 (95 % CI ×2–×2) (M 64)"
    assert "M 1: 3e+03 ms, 64 main passes, 1e+03 samples" in result.detail
    # M = 64 at ×1 or ×3 of M = 8, frame by frame: is the far end slower at all?
    noisy = _sweep(((1, 3.0), (8, 1.0), (64, 1.0)), frames=lambda m, t: [t * f for f in NOISY] if m == 64 else [t] * 5)
    assert evaluate(NAME, "m-u-shape", noisy).inconclusive
    falls = evaluate(NAME, "m-u-shape", _sweep(((1, 3.0), (8, 1.0), (64, 0.5))))
    assert falls.holds is False and falls.measured.startswith("fastest inside at M = 8; end / M = 8 time ×0.5")


def test_the_iso_surface_caster_against_dvr_with_an_interval():
    def rows(iso_frames):
        return [timed([1.0] * 5, group="iso", part="passes", role="test", config="rc-a", view="headline",
                      run="foot.rc-a", count_samples=4e5),
                timed(iso_frames, group="iso", part="iso", role="test", config="rc-a", view="headline",
                      run="foot-iso.rc-a", count_samples=5e5)]
    faster = evaluate(NAME, "iso-faster", rows([0.5] * 5))
    assert faster.holds is True and faster.measured == "×2 (95 % CI ×2–×2)"
    assert "samples DVR / iso ×0.8" in faster.detail
    assert evaluate(NAME, "iso-faster", rows([f / 2 for f in NOISY])).inconclusive  # ×2 or ×0.67 a frame
    assert evaluate(NAME, "iso-faster", rows([2.0] * 5)).holds is False
