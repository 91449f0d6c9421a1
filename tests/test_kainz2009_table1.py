"""kainz2009-table1 (E1/E5/E12/E13): Table 1's scenes, the paper's table and the claims on synthetic results."""

import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kainz2009.methods import PEEL, TILED, VTK
from pipeline.experiments.kainz2009.tables import TABLE1
from pipeline.scene_io import build_scene

NAME = "kainz2009-table1"


def _runs(**settings):
    profile = Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[NAME],
                      settings={NAME: settings})
    return list(experiments.plan(profile).values())


def _evaluate(claim_id, rows):
    claim = next(c for c in experiments.get(NAME).claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def test_paper_table_has_every_scene():
    table1 = experiments.get(NAME).paper_table()
    assert list(table1.scene) == [f"C{i}" for i in range(1, 9)]
    assert table1.set_index("scene").loc["C8", "ours fps"] == "8 – 16"
    assert table1.set_index("scene").loc["C5", "Roessler fps"] == "n.p."


def test_table1_plan_has_every_scene_and_vtk_only_where_it_can():
    runs = _runs()
    assert {r.tags["scene"] for r in runs} == set(TABLE1)
    vtk = {r.tags["scene"] for r in runs if r.backend == VTK}
    assert vtk == {"C1", "C2", "C3"}  # C4 has 9 volumes, C6–C8 meshes
    scenes = {r.tags["scene"]: r.scene for r in runs if r.backend == TILED}
    assert len(scenes["C3"]["volumes"]) == 4 and len(scenes["C5"]["volumes"]) == 21
    assert len(scenes["C7"]["meshes"]) == 3 and len(scenes["C8"]["volumes"]) == 50
    with pytest.raises(InputError, match="unknown.*C9"):
        _runs(scenes=["C9"])


def test_table1_volume_scenes_build(tmp_path):
    runs = {r.tags["scene"]: r for r in _runs(scenes=["C2", "C3"], small_size=8, large_size=16, scan_size=16)
            if r.backend == TILED}
    for name, run in runs.items():
        scene = build_scene(run.scene, cache_dir=tmp_path)
        assert len(scene.volumes) == {"C2": 2, "C3": 4}[name] and not scene.has_geometry()


def _table1_rows(times, psnr=45.0, binning=0.05, pool=2 ** 20):
    return [{"scene": s, "config": TILED, "role": "test", "time_total": t, "psnr": psnr,
             "time_binning": binning * t, "time_pixel": (1 - binning) * t, "info_pool_bytes_used": pool}
            for s, t in times.items()]


def test_table1_claims():
    good = {"C1": 1 / 15, "C2": 1 / 21, "C3": 1 / 20, "C8": 1 / 12}
    rows = _table1_rows(good)
    for claim in ("accuracy", "narrow-band", "pixel-kernel-dominates", "pool-enough"):
        assert _evaluate(claim, rows).holds is True, claim
    rows = _table1_rows({**good, "C8": 1.0}, psnr=35.0, binning=0.2, pool=7 * 2 ** 20)
    for claim in ("accuracy", "narrow-band", "pixel-kernel-dominates", "pool-enough"):
        assert _evaluate(claim, rows).holds is False, claim
    assert _evaluate("accuracy", _table1_rows({"C1": 0.1, "C2": 0.1})).holds is None  # C3 missing


def test_depth_peeling_claims():
    table = [{"scene": s, "config": c, "role": "test", "time_total": t}
             for s, c, t in (("C1", TILED, 0.08), ("C1", PEEL, 0.05), ("C3", TILED, 0.05), ("C3", PEEL, 0.15))]
    assert _evaluate("peeling-wins-one-volume", table).holds is True
    assert _evaluate("tiled-wins-many-volumes", table).holds is True
    table[1]["time_total"], table[3]["time_total"] = 0.1, 0.04
    assert _evaluate("peeling-wins-one-volume", table).holds is False
    assert _evaluate("tiled-wins-many-volumes", table).holds is False
    assert _evaluate("tiled-wins-many-volumes", table[:2]).holds is None
