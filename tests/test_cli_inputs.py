"""``volbench render`` and ``volbench compare`` given what a new user gives them: sizes this machine
cannot hold, absurd work, YAML surprises, outputs that cannot be written, images that are not
colour. Each is a message before any work (exit 2), never a traceback or a silent answer."""

import numpy as np
import OpenImageIO as oiio
import pytest

import datasets
from pipeline import cli
from pipeline.cli import main
from reports.imageio import write_exr, write_png


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if a phantom is generated or a frame rendered."""
    import pipeline.timing

    monkeypatch.setattr(datasets, "load", lambda *a, **k: pytest.fail("a volume was loaded before the error"))
    monkeypatch.setattr(pipeline.timing, "measure", lambda *a, **k: pytest.fail("a frame was rendered before the error"))


def error(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("volbench: error: ") and "Traceback" not in err
    return err


@pytest.mark.parametrize("flags, match", [
    (["--size", "4096"], r"volumes\[0\] size 4096: phantom 'sphere' needs 3 TiB .* use size ≤ \d+"),
    (["--size", "16", "--image", "100000"], r"image 100000×100000 needs 149 GiB .* use width × height ≤"),
])
def test_sizes_this_machine_cannot_hold_are_refused_before_any_work(capsys, monkeypatch, no_work, flags, match,
                                                                    tmp_path):
    import re

    import core.resources

    monkeypatch.setattr(core.resources, "memory_limit", lambda: 16 * 2 ** 30)
    assert re.search(match, error(capsys, ["render", "sphere", *flags, "--output", str(tmp_path / "o.png")]))


def test_absurd_reference_work_is_refused_with_the_cap_and_how_to_raise_it(capsys, monkeypatch, tmp_path):
    import pipeline.timing

    monkeypatch.setenv("VOLBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(pipeline.timing, "measure", lambda *a, **k: pytest.fail("a frame was rendered"))
    err = error(capsys, ["render", "sphere", "--size", "16", "--image", "32", "--option", "step_factor=1.0e-7",
                         "--output", str(tmp_path / "o.png")])
    assert "takes about 2.84e+11 samples a frame (1024 pixels × 2.77e+08 steps" in err
    assert "more than max_samples=1e+11; use a larger step (step_factor ≥ 2.84e-07)" in err
    assert "--option max_samples=N" in err


@pytest.mark.parametrize("options, match", [
    (["step_factor=0.5", "step_factor=0.25"], "--option step_factor: given twice"),
    (["=5"], "--option '=5': expected NAME=VALUE"),
    (["step_factor=1e-3"], r"--option 'step_factor=1e-3': 1e-3 is read as text, not a number, by YAML 1.1 \(PyYAML\): "
                           "write 1.0e-3"),
])
def test_option_values_are_read_strictly(capsys, no_work, options, match):
    import re

    argv = ["render", "sphere", "--size", "8"] + [arg for option in options for arg in ("--option", option)]
    assert re.search(match, error(capsys, argv))


@pytest.mark.parametrize("content, match", [
    ("width: 8\nheight: 8\nwidth: 16\nvolumes: [{dataset: sphere, size: 8}]\n", "line 3: key 'width' is given twice"),
    ("volumes: [{dataset: sphere, size: 8, isovalue: 5e-1}]\n", "5e-1 is read as text"),
    (b"name: caf\xe9\nvolumes: [{dataset: sphere, size: 8}]\n", r"line 1: not UTF-8 text \(byte 0xe9"),
    ("", "got an empty file"),
])
def test_scene_file_mistakes_are_messages(capsys, no_work, tmp_path, content, match):
    import re

    scene = tmp_path / "scene.yaml"
    scene.write_bytes(content if isinstance(content, bytes) else content.encode())
    assert re.search(match, error(capsys, ["render", str(scene), "--output", str(tmp_path / "o.png")]))


def test_a_scene_file_that_is_a_folder_is_a_message(capsys, no_work, tmp_path):
    (tmp_path / "scenes.yaml").mkdir()
    assert "cannot be read (Is a directory)" in error(capsys, ["render", str(tmp_path / "scenes.yaml"),
                                                               "--output", str(tmp_path / "o.png")])


@pytest.mark.parametrize("flags, match", [
    (["--output", "{tmp}/folder.png"], "--output .*folder.png: is a folder"),
    (["--exr", "/proc/out.exr"], r"--exr /proc/out.exr: cannot create a file in folder /proc"),
    (["--exr", "{tmp}/file/out.exr"], r"folder .*file is not a folder"),
])
def test_outputs_that_cannot_be_written_are_refused_before_the_scene_is_built(capsys, monkeypatch, tmp_path, flags,
                                                                              match):
    import re

    (tmp_path / "folder.png").mkdir()
    (tmp_path / "file").write_text("")
    monkeypatch.setattr(cli, "_scene_from_args", lambda args: pytest.fail("the scene was built before the error"))
    flags = [flag.replace("{tmp}", str(tmp_path)) for flag in flags]
    flags = flags if "--output" in flags else [*flags, "--output", str(tmp_path / "o.png")]
    assert re.search(match, error(capsys, ["render", "sphere", "--size", "8", *flags]))


def test_a_failed_write_leaves_neither_the_png_nor_the_exr(monkeypatch, tmp_path):
    import reports.imageio

    monkeypatch.setenv("VOLBENCH_CACHE", str(tmp_path / "cache"))

    def full_disk(path, image, **kwargs):
        raise OSError(f"{path}: No space left on device")

    monkeypatch.setattr(reports.imageio, "write_exr", full_disk)
    png, exr = tmp_path / "out.png", tmp_path / "out.exr"
    with pytest.raises(OSError, match="No space left"):
        main(["render", "sphere", "--size", "8", "--image", "8", "--warmup", "0", "--repeat", "1",
              "--option", "step_factor=1", "--output", str(png), "--exr", str(exr)])
    assert sorted(path.name for path in tmp_path.iterdir()) == ["cache"]


def _exr_with_channels(path, names):
    spec = oiio.ImageSpec(4, 4, 4, oiio.FLOAT)
    spec.channelnames = names
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec) and out.write_image(np.zeros((4, 4, 4), np.float32))
    out.close()
    return str(path)


@pytest.mark.parametrize("names", [("R", "G", "B", "Z"), ("X", "Y", "Z", "W")])
def test_compare_refuses_files_that_are_not_colour(capsys, tmp_path, names):
    rgba = _exr_with_channels(tmp_path / "rgba.exr", ("R", "G", "B", "A"))
    other = _exr_with_channels(tmp_path / "aov.exr", names)
    assert f"aov.exr: channels {', '.join(names)} are not colour channels" in error(capsys, ["compare", rgba, other])


def test_compare_warns_when_an_exr_is_compared_with_a_png(capsys, tmp_path):
    image = np.zeros((4, 4, 4), np.float32)
    image[1:3, 1:3] = (0.2, 0.1, 0.05, 0.5)
    write_exr(tmp_path / "a.exr", image)
    write_exr(tmp_path / "b.exr", image)
    write_png(tmp_path / "a.png", image)
    assert main(["compare", str(tmp_path / "a.exr"), str(tmp_path / "b.exr")]) == 0
    assert capsys.readouterr().err == ""
    assert main(["compare", str(tmp_path / "a.exr"), str(tmp_path / "a.png")]) == 0
    captured = capsys.readouterr()
    assert '"psnr"' in captured.out
    assert captured.err.startswith(f"volbench: warning: {tmp_path / 'a.exr'} holds linear float values (as EXR) but "
                                   f"{tmp_path / 'a.png'} holds display-encoded integers")
    assert "the metrics measure that encoding too" in captured.err


def test_compare_checks_the_diff_path_can_be_written_before_comparing(capsys, monkeypatch, tmp_path):
    import reports.metrics

    monkeypatch.setattr(reports.metrics, "compare_files", lambda *a, **k: pytest.fail("must fail before comparing"))
    assert "cannot create a file in folder /proc" in error(capsys, ["compare", "a.exr", "b.exr", "--diff",
                                                                    "/proc/diff.png"])
