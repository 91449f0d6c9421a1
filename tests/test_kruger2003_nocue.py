"""``kruger2003-nocue``: the cost of the intermediate pass and the empty-block check on synthetic results."""

from test_kruger2003_methods import evaluate

NAME = "kruger2003-nocue"


def test_nocue_claims():
    rows = [{"config": c, "time_total": t, "count_fragments_main": f}
            for c, t, f in (("rc", 1.0, 1000), ("rc-a", 1.3, 900), ("rc-b", 1.35, 890))]
    assert evaluate(NAME, "overhead", rows).holds is True
    assert evaluate(NAME, "no-empty-blocks", rows).holds is True
    rows[1]["time_total"] = 0.8
    rows[2]["count_fragments_main"] = 400
    assert evaluate(NAME, "overhead", rows).holds is False
    assert evaluate(NAME, "no-empty-blocks", rows).holds is False
