import subprocess
import sys

import numpy as np
import pytest

from pipeline.cli import main
from reports.imageio import read_image, write_exr


def test_list_shows_backends_datasets_experiments(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "reference" in out and "available" in out
    assert "ct_skull" in out and "volbench-convergence" in out


@pytest.mark.parametrize("warmup", [0, 1])
def test_render_writes_png_and_exr_and_prints_timings(tmp_path, capsys, monkeypatch, warmup):
    monkeypatch.setenv("VOLBENCH_CACHE", str(tmp_path / "cache"))
    png, exr = tmp_path / "s.png", tmp_path / "s.exr"
    assert main(["render", "sphere", "--size", "16", "--image", "24", "--repeat", "1", "--warmup", str(warmup),
                 "--option", "step_factor=0.5", "--output", str(png), "--exr", str(exr)]) == 0
    out = capsys.readouterr().out
    assert "time total" in out and "count samples" in out
    # With a warm-up the cold first frame is timed once, beside the frames' extremes.
    assert ("time first_frame" in out and "(once)" in out) == bool(warmup)
    image = read_image(exr)
    assert image.shape == (24, 24, 4) and image[..., 3].max() > 0.5


def test_compare_prints_metrics_and_writes_difference(tmp_path, capsys):
    a = np.zeros((8, 8, 4), np.float32)
    b = a.copy()
    b[..., :] = 0.1
    write_exr(tmp_path / "a.exr", a)
    write_exr(tmp_path / "b.exr", b)
    assert main(["compare", str(tmp_path / "a.exr"), str(tmp_path / "b.exr"), "--diff", str(tmp_path / "d.png")]) == 0
    assert '"rmse": 0.1' in capsys.readouterr().out
    assert (tmp_path / "d.png").exists()


def test_bad_input_is_an_error_message_not_a_traceback(capsys):
    assert main(["render", "no_such_dataset"]) == 2
    assert "unknown data set 'no_such_dataset'" in capsys.readouterr().err
    assert main(["render", "sphere", "--option", "oops"]) == 2
    assert main(["run", "--profile", "nonexistent"]) == 2


@pytest.mark.integration
def test_run_dry_run_goes_through_snakemake(tmp_path):
    out = subprocess.run([sys.executable, "-m", "pipeline.cli", "run", "--profile", "smoke", "--dry-run",
                          "--experiment", "volbench-convergence", "--", "--config", f"results={tmp_path}/r",
                          f"cache={tmp_path}/c"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    planned = {line.split("experiment=")[1].split(",")[0] for line in out.stdout.splitlines() if "experiment=" in line}
    assert planned == {"volbench-convergence"}
    # Through the driver, which gives Snakemake no job-rate limiter (pipeline.driver); a dry run is Snakemake's own.
    assert "-m pipeline.driver" in out.stdout and "--max-jobs-per-timespan" not in out.stdout


def test_unknown_backend_option_lists_the_valid_ones(capsys):
    import renderers
    from core.errors import InputError

    assert main(["render", "sphere", "--size", "8", "--option", "stepfactor=0.5"]) == 2
    err = capsys.readouterr().err
    assert "unknown option stepfactor; valid options: step_factor, step, classification, depth, max_samples" in err
    assert "Traceback" not in err
    with pytest.raises(InputError, match="stepfactor"):
        renderers.get("reference", stepfactor=0.5)


def _scene_file(tmp_path):
    path = tmp_path / "scene.yaml"
    path.write_text("volumes:\n  - dataset: sphere\n    size: 8\n")
    return str(path)


@pytest.mark.parametrize("flags, named", [
    (["--image", "64"], "--image"), (["--mode", "mip"], "--mode"), (["--shading", "none"], "--shading"),
    (["--preset", "bone"], "--preset"), (["--mode", "iso", "--image", "32"], "--image, --mode"),
])
def test_flags_a_scene_file_would_ignore_are_errors(tmp_path, capsys, monkeypatch, flags, named):
    import renderers

    monkeypatch.setattr(renderers, "get", lambda *a, **k: pytest.fail("must fail before rendering"))
    assert main(["render", _scene_file(tmp_path), *flags, "--output", str(tmp_path / "o.png")]) == 2
    err = capsys.readouterr().err
    assert f"{named} do" in err and "in the YAML instead" in err


@pytest.mark.parametrize("flags, match", [
    (["--output", "out.jpg"], "--output .*out.jpg: expected a .png file name"),
    (["--output", "x.png", "--exr", "x.png"], "--exr x.png: expected a .exr file name"),
    (["--output", "no/such/folder/x.png"], "folder no/such/folder does not exist"),
])
def test_output_names_are_checked_before_rendering(tmp_path, capsys, monkeypatch, flags, match):
    import re

    import renderers

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(renderers, "get", lambda *a, **k: pytest.fail("must fail before rendering"))
    assert main(["render", "sphere", "--size", "8", *flags]) == 2
    assert re.search(match, capsys.readouterr().err)


def test_size_on_a_real_data_set_is_refused(capsys):
    assert main(["render", "cthead", "--size", "64"]) == 2
    assert "real scan with its own size" in capsys.readouterr().err


def test_bad_dtype_in_a_raw_file_name_is_a_message(tmp_path, capsys):
    np.zeros(8, np.uint8).tofile(tmp_path / "v_2x2x2_u8.raw")
    (tmp_path / "s.yaml").write_text("volumes:\n  - file: v_2x2x2_u8.raw\n"
                                     "    transfer_function: {points: [[0, 1, 1, 1, 0], [1, 1, 1, 1, 1]]}\n")
    assert main(["render", str(tmp_path / "s.yaml"), "--output", str(tmp_path / "o.png")]) == 2
    assert "unknown dtype name 'u8' (did you mean 'uint8'?)" in capsys.readouterr().err


def test_degenerate_camera_is_an_error_not_a_hang(capsys):
    assert main(["render", "sphere", "--size", "8", "--elevation", "90"]) == 2
    assert "parallel to the view direction" in capsys.readouterr().err


def test_compare_checks_the_diff_name_before_comparing(tmp_path, capsys, monkeypatch):
    import reports.metrics

    monkeypatch.setattr(reports.metrics, "compare_files", lambda *a, **k: pytest.fail("must fail before comparing"))
    assert main(["compare", "a.exr", "b.exr", "--diff", str(tmp_path / "d.jpg")]) == 2
    assert "expected a .png or .exr file name" in capsys.readouterr().err
