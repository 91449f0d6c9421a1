"""``kruger2003-passes``: fragments per main pass, the iso-surface caster and the M sweep on synthetic results."""

import json

from test_kruger2003_methods import evaluate

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
    rows += [{"part": "m-sweep", "role": "test", "config": "rc-b", "m": m, "time_total": t}
             for m, t in ((1, 3.0), (8, 1.0), (64, 2.0))]
    for claim in ("rc-flat", "rca-falls", "iso-faster", "m-u-shape"):
        assert evaluate(NAME, claim, rows).holds is True, claim
    assert evaluate(NAME, "m-u-shape", rows).measured == "fastest at M = 8"
    rows[0]["record"] = _record(tmp_path, "rc2", [100, 90, 50, 20])
    rows[1]["record"] = _record(tmp_path, "rca2", [100, 100, 100, 90])
    rows[2]["time_total"] = 1.5
    rows[-1]["time_total"] = 0.5
    for claim in ("rc-flat", "rca-falls", "iso-faster", "m-u-shape"):
        assert evaluate(NAME, claim, rows).holds is False, claim


def test_the_iso_surface_caster_must_be_strictly_faster():
    rows = [{"part": "passes", "role": "test", "config": "rc-a", "time_total": 1.0},
            {"part": "iso", "role": "test", "config": "rc-a", "time_total": 1.0}]
    result = evaluate(NAME, "iso-faster", rows)
    assert result.holds is False and result.measured == "×1"  # equal times do not beat
