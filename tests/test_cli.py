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


def test_render_writes_png_and_exr_and_prints_timings(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("VOLBENCH_CACHE", str(tmp_path / "cache"))
    png, exr = tmp_path / "s.png", tmp_path / "s.exr"
    assert main(["render", "sphere", "--size", "16", "--image", "24", "--repeat", "1", "--warmup", "0",
                 "--option", "step_factor=0.5", "--output", str(png), "--exr", str(exr)]) == 0
    out = capsys.readouterr().out
    assert "time total" in out and "count samples" in out
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


def test_run_dry_run_goes_through_snakemake(tmp_path):
    out = subprocess.run([sys.executable, "-m", "pipeline.cli", "run", "--profile", "smoke", "--dry-run",
                          "--experiment", "volbench-convergence", "--", "--config", f"results={tmp_path}/r",
                          f"cache={tmp_path}/c"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    planned = {line.split("experiment=")[1].split(",")[0] for line in out.stdout.splitlines() if "experiment=" in line}
    assert planned == {"volbench-convergence"}
