"""lacroute1995-volpack: our shear-warp against VolPack, claims on synthetic tables."""

import numpy as np

from test_lacroute1995_package import evaluate, write


def test_volpack_claims(tmp_path):
    base = np.zeros((8, 8, 4), np.float32)
    base[2:6, 2:6] = (0.5, 0.4, 0.3, 0.8)
    near = base.copy()
    near[3, 3, 0] += 0.004
    far = base.copy()
    far[2:6, 2:6, 0] = 0.0
    rows = [
        {"scene": "s", "role": "test", "config": "volpack-rle", "time_total": 0.010, "psnr": 40.0,
         "exr": write(tmp_path / "vp.exr", base), "run": "vp"},
        {"scene": "s", "role": "test", "config": "volpack-octree", "time_total": 0.021, "psnr": 39.0,
         "exr": write(tmp_path / "oct.exr", base), "run": "oct"},
        {"scene": "s", "role": "test", "config": "shearwarp-1", "time_total": 0.008, "psnr": 40.5,
         "exr": write(tmp_path / "sw.exr", near), "run": "sw"},
        {"scene": "s", "role": "test", "config": "shearwarp-all", "time_total": 0.012, "psnr": 40.5,
         "exr": write(tmp_path / "sw2.exr", near), "run": "sw2"},
    ]
    name = "lacroute1995-volpack"
    assert evaluate(name, "speed-1-worker", rows).holds is True
    assert evaluate(name, "speed-all-cores", rows).holds is False
    assert evaluate(name, "images-agree", rows).holds is True
    assert evaluate(name, "accuracy-parity", rows).holds is True
    assert evaluate(name, "octree-vs-rle", rows).holds is True
    rows[2]["exr"] = write(tmp_path / "far.exr", far)
    assert evaluate(name, "images-agree", rows).holds is False
    missing = evaluate(name, "speed-1-worker", [r for r in rows if not r["config"].startswith("volpack")])
    assert missing.holds is None and "volpack-rle" in missing.detail
    assert evaluate(name, "beats-vtk-cpu", rows).holds is None  # no VTK run
    rows.append({"scene": "s", "role": "test", "config": "vtk-cpu-1", "time_total": 0.030, "psnr": 41.0,
                 "exr": write(tmp_path / "vtk.exr", base), "run": "vtk"})
    beats = evaluate(name, "beats-vtk-cpu", rows)
    assert beats.holds is True and "VTK 30 ms" in beats.detail
    rows[-1]["time_total"] = 0.004
    assert evaluate(name, "beats-vtk-cpu", rows).holds is False
