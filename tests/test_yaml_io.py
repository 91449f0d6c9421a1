"""core.yaml_io: YAML as people write it, read strictly (duplicate keys, YAML 1.1's silent
readings of numbers, encodings)."""

import pytest

from core.errors import InputError
from core.yaml_io import load_yaml_file, parse_yaml


def test_plain_yaml_reads_as_yaml():
    assert parse_yaml("a: 1\nb: [0.5, 1.0e+3, .inf]\nc: '1e3'\nd: \"1:30\"\ne: 0x10\nf: 0", what="t") == {
        "a": 1, "b": [0.5, 1000.0, float("inf")], "c": "1e3", "d": "1:30", "e": 16, "f": 0}
    assert parse_yaml("", what="t") is None


def test_a_merge_key_may_still_be_overridden():
    assert parse_yaml("base: &b {w: 1, h: 2}\nscene:\n  <<: *b\n  w: 3", what="t")["scene"] == {"w": 3, "h": 2}


@pytest.mark.parametrize("text, message", [
    ("width: 1\nheight: 2\nwidth: 3", r"^t, line 3: key 'width' is given twice in one mapping \(lines 1 and 3\)"),
    ("a:\n  - {x: 1, x: 2}\n", r"^t, line 2: key 'x' is given twice in one mapping \(line 2\)"),
    ("step: 1.0e300\nother: 1", r"^t, line 1: 1.0e300 is read as text, not a number, by YAML 1.1 \(PyYAML\): "
                                r"write 1.0e\+300 for the number"),
    ("x: [1, 1e-7]\ny: 2", "1e-7 is read as text.* write 1.0e-7 "),
    ("x: 2E5\ny: 2", "2E5 is read as text.* write 2.0e\\+5 "),
    ("width: 010\ny: 2", "010 is read as the octal number 8 by YAML 1.1.* write 10 without the leading zero"),
    ("width: 1:30\ny: 2", "1:30 is read as the base-60 number 90 by YAML 1.1"),
    ("a: [b\n", "^t: invalid YAML"),
])
def test_silent_surprises_are_errors_naming_the_line_and_the_fix(text, message):
    with pytest.raises(InputError, match=message):
        parse_yaml(text, what="t")


def test_a_one_line_text_names_no_line():
    with pytest.raises(InputError, match=r"^--option x=1e3: 1e3 is read as text"):
        parse_yaml("1e3", what="--option x=1e3")


def test_files_must_be_readable_utf8(tmp_path):
    latin = tmp_path / "latin.yaml"
    latin.write_bytes("name: ok\ntitle: caf\xe9\n".encode("latin-1"))
    with pytest.raises(InputError, match=r"scene file .*latin.yaml, line 2: not UTF-8 text \(byte 0xe9 at offset 19\); "
                                         "save the file as UTF-8"):
        load_yaml_file(latin, what="scene file")
    with pytest.raises(InputError, match=r"scene file .*: cannot be read \(Is a directory\)"):
        load_yaml_file(tmp_path, what="scene file")
    with pytest.raises(InputError, match=r"cannot be read \(No such file or directory\)"):
        load_yaml_file(tmp_path / "missing.yaml", what="scene file")
    (tmp_path / "ok.yaml").write_text("name: café\n", encoding="utf-8")
    assert load_yaml_file(tmp_path / "ok.yaml", what="scene file") == {"name": "café"}
