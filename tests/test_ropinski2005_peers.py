"""``ropinski2005-peers``: its plan (one job per implementation and scene, the peers only on the scenes they can
render, no early termination), the accuracy claim and the lens's own costs on synthetic rows."""

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.ropinski2005 import peers as P
from test_ropinski2005_table1 import evaluate, planned, timed

NAME = "ropinski2005-peers"


def test_plan():
    runs = {r.id: r for r in planned("smoke", NAME)}
    # Every scene: the reference with and without the lens, then per implementation a job of its own.
    for scene in P.SCENES:
        assert runs[f"{scene}.truth"].backend == runs[f"{scene}.truth.off"].backend == "reference"
        assert "lenses" not in runs[f"{scene}.truth.off"].scene
        gl_on, gl_off = runs[f"{scene}.segments"], runs[f"{scene}.gl.off"]
        assert gl_on.interleave == gl_off.interleave == f"{scene}.gl"
        assert gl_on.options["opaque_threshold"] == gl_off.options["opaque_threshold"] == 1.0
        assert gl_on.reference == f"{scene}.truth" and gl_off.reference == f"{scene}.truth.off"
        vtk = [r for r in runs.values() if r.backend == "vtk-gpu" and r.tags["scene"] == scene]
        assert {r.interleave for r in vtk} == {f"{scene}.vtk-gpu"}
        assert all(r.options["early_termination"] is False and r.options["step_factor"] == 0.5 for r in vtk)
        shear = [r for r in runs.values() if r.backend == "shearwarp" and r.tags["scene"] == scene]
        assert len(shear) == 2 and all(r.options == {"early_termination": False, "min_opacity": 0.0} for r in shear)
    # Cropping and one clipping plane only where one lens face cuts an axis-aligned box: the cutaway.
    assert {r.tags["scene"] for r in runs.values() if r.tags.get("config") in ("vtk-cropping", "vtk-clipping-planes")} \
        == {"seismic-cutaway"}
    assert not any(r.tags["scene"] == "foot" for r in runs.values())  # an iso lens has no peer


def rows(psnr_on, psnr_off=50.0, *, scene="skull", config="vtk-label-map", ratio=1.2):
    """A scene's lens-off and lens-on rows of one implementation, timed together."""
    implementation = P.implementation(config)
    group = f"{scene}.{implementation}"
    return [timed([0.010] * 5, group=group, scene=scene, config=f"{implementation}-off", lens="off",
                  implementation=implementation, psnr=psnr_off, view="headline"),
            timed([0.010 * ratio] * 5, group=group, scene=scene, config=config, lens="on", implementation=config,
                  psnr=psnr_on, view="headline")]


def test_accuracy_claim_names_the_worst_and_every_failure():
    good = rows(45.0) + rows(60.0, config="segments")
    result = evaluate(NAME, "peers-accuracy", good)
    assert result.holds is True and result.measured == "45 dB (vtk-label-map, skull)"
    bad = rows(38.0) + rows(60.0, config="segments") + rows(30.0, scene="engine", config="shearwarp")
    result = evaluate(NAME, "peers-accuracy", bad)
    assert result.holds is False and result.measured == "30 dB (shearwarp, engine)"
    assert "Below 40 dB: vtk-label-map on skull, shearwarp on engine" in result.detail


def test_overhead_and_the_lens_accuracy_cost():
    frame = pd.DataFrame(rows(44.0, 47.5, ratio=1.5) + rows(60.0, 60.0, config="segments", ratio=1.1))
    decision = P.overhead(frame, "skull", "vtk-label-map", resampler=intervals.Resampler())
    assert np.isclose(decision.value, 1.5)
    assert np.isclose(P.psnr_cost(frame, "skull", "vtk-label-map"), 3.5)
    assert np.isclose(P.psnr_cost(frame, "skull", "segments"), 0.0)
    table = P.summary_table(frame)
    assert list(table["implementation"]) == [P.config_words("vtk-label-map"), P.config_words("segments")]
    assert np.allclose(table["time ratio lens / no lens"], [1.5, 1.1])
    words = P._takeaways(frame)
    assert any("changes by −3.5 to −3.5 dB with the lens" in w for w in words)
