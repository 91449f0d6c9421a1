"""lacroute1995-volpack: our shear-warp against VolPack, claims on synthetic tables."""

import numpy as np

from test_lacroute1995_package import evaluate, planned, timed, write

NAME = "lacroute1995-volpack"


def test_plan_times_every_configuration_of_a_scene_together():
    runs = [r for r in planned(NAME) if r.tags["role"] == "test"]
    assert {r.interleave for r in runs} == {r.tags["scene"] for r in runs}
    assert all(r.interleave is None for r in planned(NAME) if r.tags["role"] == "truth")


def _rows(tmp_path, base, near, ours=0.008, spread=0.0):
    def row(config, technique, psnr, image, name):
        return {"scene": "s", "role": "test", "config": config, "psnr": psnr, "exr": write(tmp_path / f"{name}.exr", image),
                "run": name, **timed(technique, spread), **timed(technique * 1.5, stage="total")}

    return [row("volpack-rle", 0.010, 40.0, base, "vp"), row("volpack-octree", 0.021, 39.0, base, "oct"),
            row("shearwarp-1", ours, 40.5, near, "sw"), row("shearwarp-all", 0.012, 40.5, near, "sw2")]


def test_volpack_claims(tmp_path):
    base = np.zeros((8, 8, 4), np.float32)
    base[2:6, 2:6] = (0.5, 0.4, 0.3, 0.8)
    near = base.copy()
    near[3, 3, 0] += 0.004
    far = base.copy()
    far[2:6, 2:6, 0] = 0.0
    rows = _rows(tmp_path, base, near)
    assert evaluate(NAME, "speed-1-worker", rows).holds is True
    assert evaluate(NAME, "speed-all-cores", rows).holds is False
    assert evaluate(NAME, "images-agree", rows).holds is True
    assert evaluate(NAME, "accuracy-parity", rows).holds is True
    assert evaluate(NAME, "octree-vs-rle", rows).holds is True
    rows[2]["exr"] = write(tmp_path / "far.exr", far)
    assert evaluate(NAME, "images-agree", rows).holds is False
    missing = evaluate(NAME, "speed-1-worker", [r for r in rows if not r["config"].startswith("volpack")])
    assert missing.holds is None and "volpack-rle" in missing.detail
    assert evaluate(NAME, "beats-vtk-cpu", rows).holds is None  # no VTK run
    rows.append({"scene": "s", "role": "test", "config": "vtk-cpu-1", "psnr": 41.0, "run": "vtk",
                 "exr": write(tmp_path / "vtk.exr", base), **timed(0.030), **timed(0.031, stage="total")})
    beats = evaluate(NAME, "beats-vtk-cpu", rows)
    assert beats.holds is True and "VTK 30 ms" in beats.detail
    rows[-1].update(timed(0.004))
    assert evaluate(NAME, "beats-vtk-cpu", rows).holds is False


def test_speed_compares_the_technique_with_an_interval(tmp_path):
    image = np.zeros((4, 4, 4), np.float32)
    # The whole frames say ours is slower (×1.5 of 8 ms against 10 ms would not be); the kernels decide.
    rows = _rows(tmp_path, image, image, ours=0.0095)
    for row in rows:
        row["time_total"] = 0.02 if row["config"] == "shearwarp-1" else 0.01
    result = evaluate(NAME, "speed-1-worker", rows)
    assert result.holds is True and result.measured.startswith("×0.95 (s; 95 % CI ×0.95–×0.95)")
    assert "technique ours 9.5 ms, VolPack 10 ms; whole frame ours 20 ms" in result.detail
    # Frames spread ±30 % around medians 5 % apart: the interval straddles 1.
    noisy = evaluate(NAME, "speed-1-worker", _rows(tmp_path, image, image, ours=0.0095, spread=0.3))
    assert noisy.holds is None and noisy.inconclusive and noisy.interval[0] < 1 < noisy.interval[1]
    slower = evaluate(NAME, "speed-1-worker", _rows(tmp_path, image, image, ours=0.02, spread=0.3))
    assert slower.holds is False and slower.interval[0] > 1


def test_a_starved_parallel_run_cannot_fail_the_all_cores_claim(tmp_path):
    image = np.zeros((4, 4, 4), np.float32)
    rows = _rows(tmp_path, image, image)
    starved = "2 workers had 1.0 free cores (other work used 1.00)"
    rows[3]["info_starved"] = starved
    result = evaluate(NAME, "speed-all-cores", rows)  # 12 ms against 10 ms, on one free core
    assert result.holds is None and result.inconclusive and starved in result.detail
    rows[3].update(timed(0.005))
    fast = evaluate(NAME, "speed-all-cores", rows)  # starving can only slow it: a pass stands
    assert fast.holds is True and starved in fast.detail
