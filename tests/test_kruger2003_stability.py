"""``kruger2003-stability``: the threshold and block-size sweeps' claims on synthetic results."""

from test_kruger2003_methods import NOISY, evaluate, five_frames, timed

NAME = "kruger2003-stability"


def test_stability_claims():
    rows = [five_frames({"scene": "head", "sweep": "threshold", "value": t, "time_total": s, "psnr": p, "role": "test",
                         "count_samples": n})
            for t, s, p, n in ((0.8, 1.0, 35.0, 5e5), (0.95, 1.2, 42.0, 6e5), (1.0, 1.5, 50.0, 8e5))]
    rows += [{"scene": "head", "sweep": "block", "value": b, "time_total": 1.0, "psnr": 44.0 + d, "role": "test"}
             for b, d in ((4, 0.0), (8, 0.05), (16, 0.0))]
    assert evaluate(NAME, "threshold-trades-error", rows).holds is True
    assert evaluate(NAME, "blocks-lossless", rows).holds is True
    rows[-1]["psnr"] = 40.0  # a block size that skips something visible
    assert evaluate(NAME, "blocks-lossless", rows).holds is False
    rows[0]["psnr"] = 51.0
    assert evaluate(NAME, "threshold-trades-error", rows).holds is False


def _thresholds(low_frames, low_psnr=35.0):
    return [timed(frames, group="head.threshold", scene="head", sweep="threshold", value=t, psnr=p, role="test",
                  view="headline", run=f"head.t{t:g}", count_samples=n)
            for t, frames, p, n in ((0.8, low_frames, low_psnr, 5e5), (1.0, [1.5] * 5, 50.0, 8e5))]


def test_the_threshold_speed_up_rests_on_its_interval():
    result = evaluate(NAME, "threshold-trades-error", _thresholds([1.0] * 5))
    assert result.holds is True and result.measured.startswith(
        "T 0.8 ×1.5 faster than T 1 (time at T 1 / at T 0.8 ×1.5 (95 % CI ×1.5–×1.5)); 35 dB")
    assert "samples 5e+05 and 8e+05" in result.detail
    # T = 0.8 at 0.5 or 1.5 s a frame against 1.5 s: faster, or not at all.
    straddling = evaluate(NAME, "threshold-trades-error", _thresholds([0.5 * f for f in NOISY]))
    assert straddling.inconclusive and straddling.interval[0] <= 1.0 < straddling.interval[1]
    slower = evaluate(NAME, "threshold-trades-error", _thresholds([2.0] * 5))
    assert slower.holds is False and not slower.inconclusive
    # No interval rescues the accuracy half.
    lossless = evaluate(NAME, "threshold-trades-error", _thresholds([1.0] * 5, low_psnr=50.0))
    assert lossless.holds is False and "not less accurate" in lossless.detail
