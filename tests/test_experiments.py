from pathlib import Path

import pytest
import yaml

from pipeline import experiments
from core.errors import InputError
from pipeline.experiments import Profile, Run
from pipeline.experiments.kit.model import PROFILE_REQUIRED

ROOT = Path(__file__).resolve().parent.parent
SMOKE = Profile(name="t", volume_size=16, image_size=16, settings={"volbench-phantoms": {"datasets": ["sphere"]}})


def test_registry_names_follow_the_convention():
    names = list(experiments.all_experiments())
    assert {"volbench-phantoms", "volbench-convergence", "volbench-speed-accuracy"} <= set(names)
    for name in names:
        author_year, _, what = name.partition("-")
        assert what and (author_year == "volbench" or author_year[-4:].isdigit()), name


def test_plan_has_unique_runs_whose_references_resolve():
    runs = experiments.plan(SMOKE)
    assert all(run.reference is None or f"{run.experiment}/{run.reference}" in runs for run in runs.values())
    backends = {run.backend for run in runs.values() if run.experiment == "volbench-speed-accuracy"}
    assert "reference" in backends
    phantoms = [run for run in runs.values() if run.experiment == "volbench-phantoms"]
    assert {run.tags["dataset"] for run in phantoms} == {"sphere"}
    assert all(run.statistics["dataset"] == "sphere" for run in phantoms)


def test_spec_hash_changes_with_the_run():
    run = Run("e", "a", "reference", {"volumes": []}, ({"view": "v"},))
    other = Run("e", "a", "reference", {"volumes": []}, ({"view": "v"},), options={"step_factor": 0.5})
    assert run.spec_hash() != other.spec_hash()
    assert run.spec_hash() == Run("e", "a", "reference", {"volumes": []}, ({"view": "v"},)).spec_hash()


def test_bad_runs_and_profiles():
    with pytest.raises(InputError, match="run id"):
        Run("e", "a/b", "reference", {}, ({"view": "v"},))
    with pytest.raises(InputError, match="unique 'view'"):
        Run("e", "a", "reference", {}, ({"view": "v"}, {"view": "v"}))
    with pytest.raises(InputError, match="unknown keys"):
        Profile.from_mapping({"name": "x", "volume_sise": 3})
    with pytest.raises(InputError, match="unknown experiments"):
        experiments.plan(Profile(name="x", experiments=["nobody2020-nothing"]))


def test_profile_setting_typos_are_errors():
    from pipeline.experiments import Profile, check_settings, selected

    with pytest.raises(InputError, match="unknown experiment 'volbench-convergense'"):
        selected(Profile("p", settings={"volbench-convergense": {"step_factors": [1.0]}}))
    with pytest.raises(InputError, match=r"settings.volbench-convergence: unknown keys \['step_factor'\]"):
        selected(Profile("p", settings={"volbench-convergence": {"step_factor": [1.0]}}))
    with pytest.raises(InputError, match="expected 'all' or a list"):
        selected(Profile("p", experiments="volbench-convergence"))
    for name in ("smoke", "default", "full"):  # the shipped profiles use only real keys
        check_settings(Profile.load(ROOT / "config" / f"{name}.yaml"))


def _default_profile():
    return yaml.safe_load((ROOT / "config" / "default.yaml").read_text())


@pytest.mark.parametrize("key", PROFILE_REQUIRED)
def test_a_profile_file_must_set_every_key_a_default_would_change_results_by(key):
    mapping = _default_profile()
    del mapping[key]
    with pytest.raises(InputError, match=rf"profile.*: {key} not set; every profile sets .*render_time_limit: null means no limit"):
        Profile.from_mapping(mapping)


def test_keys_with_safe_defaults_may_be_left_out_and_no_limit_is_said_with_null():
    mapping = {key: value for key, value in _default_profile().items()
               if key not in ("experiments", "settings", "real_data", "cache")}
    profile = Profile.from_mapping({**mapping, "render_time_limit": None})
    assert profile.render_time_limit is None and profile.experiments == "all" and profile.cache == ".cache/volumes"
    with pytest.raises(InputError, match="expected a mapping of keys"):
        Profile.from_mapping(None)  # an empty profile file


@pytest.mark.parametrize("key, value, message", [
    ("image_size", "big", r"image_size \(pixels\): expected an integer >= 1, got 'big'"),
    ("image_size", 0, r"image_size \(pixels\): expected an integer >= 1, got 0"),
    ("volume_size", 4, r"volume_size \(voxels along a phantom's longest axis\): expected an integer >= 8, got 4"),
    ("volume_size", 128.0, r"volume_size .*expected an integer >= 8, got 128.0"),
    ("warmup", -1, r"warmup \(untimed frames\): expected an integer >= 0, got -1"),
    ("repeat", True, r"repeat \(timed frames\): expected an integer >= 1, got True"),
    ("experiments", "volbench-convergence", "experiments: expected 'all' or a list of names, got 'volbench-convergence'"),
    ("experiments", ["volbench-convergence", 3], "experiments: expected 'all' or a list of names"),
    ("settings", ["volbench-convergence"], "settings: expected a mapping of experiment names, got list"),
    ("results", "", "results: expected a folder name, got ''"),
    ("cache", None, "cache: expected a folder name, got None"),
    ("real_data", 5, "real_data: expected a folder name, got 5; null reads the default folder"),
    ("render_time_limit", True, "render_time_limit: expected seconds .* or null for no limit, got True"),
    ("render_time_limit", "300", "render_time_limit: expected seconds .* or null for no limit, got '300'"),
    ("render_time_limit", 0, r"render_time_limit \(seconds; null for no limit\): 0 is outside"),
])
def test_every_profile_value_is_checked_and_the_error_names_key_and_value(key, value, message):
    with pytest.raises(InputError, match=rf"^profile 'default' {message}"):
        Profile.from_mapping({**_default_profile(), key: value})


def test_an_interleave_group_of_two_opengl_stacks_is_timed_in_a_part_per_stack():
    """vtk-gpu and a moderngl backend in one process rendered every image of both empty: a group of both is
    planned, and its job gets it as parts, one per stack, the runs of no stack with the larger part."""
    def run(name, backend):
        return Run("volbench-phantoms", name, backend, {"volumes": []}, ({"view": "v"},), interleave="g")

    slicer, vtk, raycast, cpu = run("a", "gl-slicer"), run("b", "vtk-gpu"), run("c", "gl-raycast"), run("d", "shearwarp")
    parts = experiments.stack_parts([slicer, vtk, raycast, cpu])
    assert [[r.id for r in part] for part in parts] == [["a", "c", "d"], ["b"]]
    assert [[r.id for r in part] for part in experiments.stack_parts([vtk, cpu, slicer])] == [["b", "d"], ["a"]]
    assert experiments.stack_parts([slicer, raycast]) == [[slicer, raycast]]
    assert experiments.stack_parts([cpu]) == [[cpu]]
