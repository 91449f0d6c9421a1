"""``kruger2003-stability``: the threshold and block-size sweeps' claims on synthetic results."""

from test_kruger2003_methods import evaluate

NAME = "kruger2003-stability"


def test_stability_claims():
    rows = [{"scene": "head", "sweep": "threshold", "value": t, "time_total": s, "psnr": p, "role": "test"}
            for t, s, p in ((0.8, 1.0, 35.0), (0.95, 1.2, 42.0), (1.0, 1.5, 50.0))]
    rows += [{"scene": "head", "sweep": "block", "value": b, "time_total": 1.0, "psnr": 44.0 + d, "role": "test"}
             for b, d in ((4, 0.0), (8, 0.05), (16, 0.0))]
    assert evaluate(NAME, "threshold-trades-error", rows).holds is True
    assert evaluate(NAME, "blocks-lossless", rows).holds is True
    rows[-1]["psnr"] = 40.0  # a block size that skips something visible
    assert evaluate(NAME, "blocks-lossless", rows).holds is False
    rows[0]["psnr"] = 51.0
    assert evaluate(NAME, "threshold-trades-error", rows).holds is False
