"""kainz2009-depthcap (E4/E6): each cap against unbounded lists, and the claims on synthetic images."""

import numpy as np
import pandas as pd

from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kainz2009.depthcap import CAPS, SCENES
from pipeline.experiments.kainz2009.methods import TILED
from reports.imageio import write_exr

NAME = "kainz2009-depthcap"


def _evaluate(claim_id, rows):
    claim = next(c for c in experiments.get(NAME).claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def test_depthcap_plan_compares_each_cap_with_unbounded_lists():
    profile = Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[NAME])
    runs = list(experiments.plan(profile).values())
    for scene in SCENES:
        here = {r.id: r for r in runs if r.tags["scene"] == scene}
        unbounded = here[f"{scene}.unbounded"]
        assert unbounded.options["fragments"] == "global" and unbounded.reference == f"{scene}.truth"
        capped = [r for r in here.values() if r.tags["role"] == "test"]
        assert sorted(r.options["depth_cap"] for r in capped) == list(CAPS)
        assert all(r.reference == unbounded.id and r.options["fragments"] == "local" for r in capped)
    assert all(r.options.get("empty_space") == "box" for r in runs if r.tags["scene"] == "pile"
               and r.backend == TILED)  # two fragments per volume: the pile passes the cap


def _image(tmp_path, name, image):
    path = tmp_path / f"{name}.exr"
    write_exr(str(path), image.astype(np.float32))
    return str(path)


def _cap_rows(tmp_path, wrong_by_cap, times=None, psnr=50.0):
    """Unbounded and capped rows of one scene; ``wrong_by_cap`` pixels (of 10 000) off by 0.1 at each cap."""
    truth = np.zeros((100, 100, 4), np.float32)
    truth[..., :] = (0.3, 0.3, 0.3, 0.6)
    rows = [{"scene": "screw", "run": "screw.unbounded", "role": "unbounded", "view": "axis", "status": "ok",
             "exr": _image(tmp_path, "unbounded", truth), "psnr": psnr, "reference": "screw.truth"}]
    for cap, wrong in wrong_by_cap.items():
        image = truth.copy()
        image.reshape(-1, 4)[:wrong, 0] += 0.1
        rows.append({"scene": "screw", "run": f"screw.cap{cap}", "role": "test", "view": "axis", "status": "ok",
                     "cap": cap, "reference": "screw.unbounded", "exr": _image(tmp_path, f"cap{cap}", image),
                     "count_fragments_dropped": 10 * wrong, "time_total": (times or {}).get(cap, 1.0)})
    return rows


def test_depthcap_claims(tmp_path):
    rows = _cap_rows(tmp_path, {16: 900, 32: 100, 55: 4, 63: 0}, times={16: 0.8, 63: 1.0})
    for claim in ("cap55-error", "error-shrinks", "unbounded-exact", "small-cap-faster"):
        assert _evaluate(claim, rows).holds is True, claim
    assert _evaluate("cap55-error", rows).measured == "0.04 % (screw)"
    rows = _cap_rows(tmp_path, {16: 900, 32: 1000, 55: 5, 63: 0}, times={16: 1.2, 63: 1.0}, psnr=30.0)
    for claim in ("cap55-error", "error-shrinks", "unbounded-exact", "small-cap-faster"):
        assert _evaluate(claim, rows).holds is False, claim  # 5 of 10 000 is 0.05 %: not fewer
