"""The Lacroute 1995 package: its experiments registered, every plan, settings, and the helpers its experiments share.

The other ``test_lacroute1995_*`` files import the helpers defined here.
"""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import renderers
from core.camera import Camera
from core.errors import InputError
from pipeline import experiments
from pipeline.collect import claims_table
from pipeline.experiments.kit.model import Profile
from pipeline.experiments.kit.pages import not_measurable
from pipeline.experiments.kit.planning import unregistered
from pipeline.experiments.lacroute1995.planning import truth_and_shearwarp
from reports import blocks
from reports.html import ReportContext
from reports.imageio import write_exr

ROOT = Path(__file__).resolve().parent.parent
NAMES = ("lacroute1995-volpack", "lacroute1995-quality", "lacroute1995-matrix", "lacroute1995-angles",
         "lacroute1995-scaling", "lacroute1995-throughput", "lacroute1995-parallel", "lacroute1995-shading",
         "lacroute1995-projection", "lacroute1995-perspective")


def _with_ours():
    """The registry with shearwarp and volpack, whether or not their packages are here yet."""
    return {"shearwarp": "renderers.shearwarp.renderer:ShearWarpRenderer",
            "volpack": "renderers.volpack.renderer:VolPackRenderer", **renderers.BACKENDS}


@pytest.fixture
def all_backends(monkeypatch):
    monkeypatch.setattr(renderers, "BACKENDS", _with_ours())


def profile(**settings):
    """A small profile of every Lacroute experiment, with ``settings`` by experiment name."""
    return Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=list(NAMES),
                   settings=settings)


def planned(experiment, **settings):
    """The runs of ``experiment`` in :func:`profile` with ``settings``, shearwarp and volpack registered."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(renderers, "BACKENDS", _with_ours())
        return [r for r in experiments.plan(profile(**settings)).values() if r.experiment == experiment]


def evaluate(experiment, claim_id, frame):
    """The :class:`ClaimResult` of claim ``claim_id`` of ``experiment`` on the rows ``frame``."""
    claim = next(c for c in experiments.get(experiment).claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(frame))


def frames(median, spread=0.0, n=15):
    """A ``frames_<stage>`` cell: ``n`` frames evenly spread ± ``spread`` (relative) about ``median``."""
    return " ".join(f"{v:.9g}" for v in median * (1 + spread * np.linspace(-1, 1, n)))


def timed(median, spread=0.0, stage="technique"):
    """A timed run's ``time_<stage>`` (the median) and ``frames_<stage>`` columns."""
    return {f"time_{stage}": median, f"frames_{stage}": frames(median, spread)}


def write(path, image):
    write_exr(path, image.astype(np.float32))
    return str(path)


def alpha_image(alpha):
    image = np.zeros(alpha.shape + (4,), np.float32)
    image[..., 3] = alpha
    image[..., :3] = alpha[..., None] * 0.8
    return image


def check_report(tmp_path, name, rows):
    """``name``'s report on ``rows`` (every run successful) has take-aways and charts that show data."""
    report = tmp_path / "report"
    (report / "csv").mkdir(parents=True)
    frame = pd.DataFrame(rows)
    frame["experiment"], frame["status"] = name, "ok"
    if "run" not in frame:
        frame["run"] = [f"r{i}" for i in range(len(frame))]
    for column in ("time_total_min", "time_total_max"):
        frame[column] = frame.time_total * (0.9 if column.endswith("min") else 1.1)
    for column, value in (("view", "headline"), ("png", ""), ("exr", ""), ("record", "")):
        if column not in frame:
            frame[column] = value
    # The page says what claims.csv says: its claims judged on these rows, as tabulate judges them.
    claims = claims_table(frame, [experiments.get(name)])
    out = experiments.get(name).report(frame, ReportContext(report, tmp_path, name, claims=claims))
    kinds = {type(b) for b in out}
    assert blocks.Takeaways in kinds and blocks.Figure in kinds, name
    takeaways = next(b for b in out if isinstance(b, blocks.Takeaways))
    assert takeaways.sentences, name
    judged = claims[claims.verdict.isin(["holds", "fails", "inconclusive"])]
    assert all(any(s.startswith(statement) for s in takeaways.sentences) for statement in judged.statement), name
    for figure in (b for b in out if isinstance(b, blocks.Figure)):
        svg = (report / figure.path).read_text()
        assert "no data" not in svg, (name, figure.path)


# ------------------------------------------------------------------------------------ the package
def test_experiments_are_registered_with_the_paper():
    registry = experiments.all_experiments()
    assert [cls.name for cls in experiments.papers()["lacroute1995"].experiments] == list(NAMES)
    for name in NAMES:
        experiment = registry[name]
        assert experiment.paper == "lacroute1995" and experiment.title and experiment.description
        assert isinstance(experiment.settings, frozenset)
        assert experiment.claims, name
        table = experiment.paper_table()
        assert isinstance(table, pd.DataFrame) and not table.empty, name


def test_plan_times_comparisons_and_renders_truth_once(all_backends):
    runs = experiments.plan(profile())
    ours = [r for r in runs.values() if r.experiment.startswith("lacroute1995")]
    assert {r.experiment for r in ours} == set(NAMES)
    for run in ours:
        if run.backend == "reference":  # ground truth: one untimed frame
            assert (run.warmup, run.repeat) == (0, 1), run.key
        elif run.warmup == 0:  # picture-only runs (the harness times preprocessing apart in timed runs)
            assert run.experiment in ("lacroute1995-quality", "lacroute1995-perspective"), run.key
        else:  # timed comparisons: at least one warm-up and three timed frames, whatever the profile
            assert run.warmup >= 1 and run.repeat >= 3, run.key
        assert run.reference is None or f"{run.experiment}/{run.reference}" in runs
        assert run.interleave is None or run.warmup >= 1, run.key  # only timed runs are timed together
    groups = {}
    for run in ours:
        if run.interleave:
            groups.setdefault((run.experiment, run.interleave), set()).add(tuple(v["view"] for v in run.views))
    assert groups and all(len(views) == 1 for views in groups.values()), groups  # pairs need the same views


def test_runs_need_registered_backends(monkeypatch):
    monkeypatch.setattr(renderers, "BACKENDS", {"reference": renderers.BACKENDS["reference"]})
    runs = experiments.plan(profile())
    assert not [r for r in runs.values() if r.experiment.startswith("lacroute1995")]
    missing = unregistered("shearwarp", "volpack")
    assert [what for what, _ in missing] == ["shearwarp", "volpack"]
    text = not_measurable(missing)[0].text
    assert "not registered" in text and "volpack" in text


def test_profile_settings_are_checked(all_backends):
    for name, settings in (("lacroute1995-volpack", {"scenes": ["engine"]}),
                           ("lacroute1995-quality", {"datasets": ["nucleon"]}),
                           ("lacroute1995-matrix", {"datasets": ["nucleon"]}),
                           ("lacroute1995-angles", {"angle_step": 0}),
                           ("lacroute1995-throughput", {"brute_force": "some"}),
                           ("lacroute1995-throughput", {"predict": ["nucleon"]}),
                           ("lacroute1995-parallel", {"schedules": ["random"]}),
                           ("lacroute1995-projection", {"datasets": ["nucleon"]}),
                           ("lacroute1995-projection", {"fov": 180}),
                           ("lacroute1995-perspective", {"fovs": [30]}),
                           ("lacroute1995-perspective", {"fovs": [30, 150]})):
        with pytest.raises(InputError, match=name):
            experiments.plan(profile(**{name: settings}))
    with pytest.raises(InputError, match="unknown keys"):
        experiments.plan(profile(**{"lacroute1995-angles": {"angle_steps": 10}}))
    for scale in ("smoke", "default", "full"):
        experiments.check_settings(Profile.load(ROOT / "config" / f"{scale}.yaml"))


def test_smoke_profile_stays_small(all_backends):
    runs = experiments.plan(Profile.load(ROOT / "config" / "smoke.yaml"))
    ours = [r for r in runs.values() if r.experiment.startswith("lacroute1995")]
    assert len(ours) <= 56  # about four minutes of jobs on two cores (16–32³ volumes, 48² images)
    assert all(len(r.views) <= 8 for r in ours)


def test_scene_mappings_build(all_backends, tmp_path):
    """Every planned scene of a small profile is valid scene input (volumes not generated)."""
    from pipeline import scene_io

    runs = experiments.plan(profile())
    for run in runs.values():
        if not run.experiment.startswith("lacroute1995"):
            continue
        scene_io._check_keys(run.scene, scene_io.SCENE_KEYS, where=run.key)
        for volume in run.scene["volumes"]:
            scene_io._check_keys(volume, scene_io.VOLUME_KEYS, where=run.key)
        for view in run.views:
            Camera(**{k: v for k, v in view.items() if k != "view"})


# ------------------------------------------------------------------------------ shared helpers
def test_each_shearwarp_frame_is_checked_against_its_own_truth():
    views = ({"view": "v"},)
    post = truth_and_shearwarp("e", "s", {"name": "s"}, views, 0.25, {"dataset": "d"})
    assert [(r.id, r.backend, r.reference) for r in post] == [("s.truth", "reference", None),
                                                              ("s.shearwarp", "shearwarp", "s.truth")]
    assert all((r.warmup, r.repeat) == (0, 1) for r in post) and "truth" not in post[1].tags
    both = {r.id: r for r in truth_and_shearwarp("e", "s", {"name": "s"}, views, 0.25, {}, pre_classified=True)}
    assert both["s.shearwarp-vs-pre"].reference == "s.truth-pre" and both["s.shearwarp"].reference == "s.truth"
    assert both["s.truth-pre"].options == {"step_factor": 0.25, "classification": "pre"}
    assert both["s.truth"].options == {"step_factor": 0.25}
    assert {r.id: r.tags["truth"] for r in both.values()} == {"s.truth": "post", "s.shearwarp": "post",
                                                              "s.truth-pre": "pre", "s.shearwarp-vs-pre": "pre"}
