"""Reading the YAML that people write (scene files, profiles, ``--option`` values), strictly.

PyYAML reads YAML 1.1, and plain YAML lets some mistakes through without a word. Where a value
would silently differ from what was written, this reader stops with an :class:`InputError` that
names the input, the line and the fix:

* a key given twice in one mapping (YAML keeps the last one; a ``<<`` merge may still be
  overridden, as YAML means it to be);
* a number in exponent form that YAML 1.1 reads as text: ``1e3`` and ``1.0e300`` need a dot and
  a signed exponent (``1.0e+3``, ``1.0e+300``), else they arrive as the strings ``"1e3"`` and
  ``"1.0e300"`` (YAML 1.2, and Python, read them as numbers; Snakemake, which reads the
  profiles too, reads them as PyYAML does);
* an integer with a leading zero (``010`` is octal 8) or with colons (``1:30`` is base 60, 90),
  as YAML 1.1 reads them;
* bytes that are not UTF-8 (a file saved in Latin-1, a binary file).

Quoted scalars are text as written and are left alone.
"""

import re
from pathlib import Path

import yaml

from core.errors import InputError

__all__ = ["load_yaml_file", "parse_yaml"]

_EXPONENT_NUMBER = re.compile(r"[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)[eE][-+]?[0-9]+")
"""A float in exponent form as YAML 1.2 and Python read it; YAML 1.1 reads it as a float only
with a dot in the mantissa and a sign in the exponent."""


class _Strictness(yaml.YAMLError):
    """A value that YAML would take silently but that is almost certainly not what was meant."""

    def __init__(self, line, message):
        super().__init__(message)
        self.line = line
        self.message = message


def _yaml11_spelling(text):
    """``text`` (an exponent-form number) spelt so that YAML 1.1 reads it as a float."""
    mantissa, exponent = re.split("[eE]", text)
    if "." not in mantissa:
        mantissa += ".0"
    if exponent[0] not in "+-":
        exponent = "+" + exponent
    return f"{mantissa}e{exponent}"


class _StrictLoader(yaml.SafeLoader):
    """PyYAML's safe loader that refuses the silent surprises listed in the module notes."""

    def construct_mapping(self, node, deep=False):
        seen = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=deep)
            try:
                first = seen.setdefault(key, key_node)
            except TypeError:  # an unhashable key: SafeLoader's own error names it
                continue
            if first is not key_node:
                lines = sorted({first.start_mark.line + 1, key_node.start_mark.line + 1})
                raise _Strictness(lines[-1], f"key {key!r} is given twice in one mapping "
                                             f"(line{'s' if len(lines) > 1 else ''} {' and '.join(map(str, lines))}); "
                                             "YAML would keep the last one silently, so remove one")
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_str(self, node):
        value = super().construct_yaml_str(node)
        if node.style is None and _EXPONENT_NUMBER.fullmatch(value):
            raise _Strictness(node.start_mark.line + 1,
                              f"{value} is read as text, not a number, by YAML 1.1 (PyYAML): write "
                              f"{_yaml11_spelling(value)} for the number (a dot and a signed exponent), or quote "
                              "it if text is meant")
        return value


    def construct_yaml_int(self, node):
        value = super().construct_yaml_int(node)
        digits = node.value.replace("_", "").lstrip("+-")
        if node.style is None and len(digits) > 1 and digits[0] == "0" and digits.isdigit():
            raise _Strictness(node.start_mark.line + 1,
                              f"{node.value} is read as the octal number {value} by YAML 1.1 (PyYAML): write "
                              f"{int(node.value.replace('_', ''), 10)} without the leading zero for the decimal "
                              f"number, or {value} for the octal one")
        self._refuse_base_60(node, value)
        return value

    def construct_yaml_float(self, node):
        value = super().construct_yaml_float(node)
        self._refuse_base_60(node, value)
        return value

    @staticmethod
    def _refuse_base_60(node, value):
        if node.style is None and ":" in node.value:
            raise _Strictness(node.start_mark.line + 1,
                              f"{node.value} is read as the base-60 number {value} by YAML 1.1 (PyYAML): write "
                              f"{value} for that number, or quote it if text (a time) is meant")


_StrictLoader.add_constructor("tag:yaml.org,2002:str", _StrictLoader.construct_yaml_str)
_StrictLoader.add_constructor("tag:yaml.org,2002:int", _StrictLoader.construct_yaml_int)
_StrictLoader.add_constructor("tag:yaml.org,2002:float", _StrictLoader.construct_yaml_float)


def parse_yaml(text, *, what):
    """Parse YAML ``text`` strictly (see the module notes).

    Parameters
    ----------
    text : str
        The YAML document.
    what : str
        How the input is named in error messages (``"scene file s.yaml"``, ``"--option x=1e3"``).

    Returns
    -------
    object
        The document's value (``None`` for an empty document).

    Raises
    ------
    InputError
        Invalid YAML, a duplicate key, or an exponent number that YAML 1.1 reads as text.
    """
    try:
        return yaml.load(text, Loader=_StrictLoader)
    except _Strictness as exc:
        where = f"{what}, line {exc.line}" if "\n" in text.strip() else what
        raise InputError(f"{where}: {exc.message}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"{what}: invalid YAML ({exc})") from None


def load_yaml_file(path, *, what):
    """Read and parse a YAML file strictly; the file must be UTF-8.

    Parameters
    ----------
    path : str or os.PathLike
    what : str
        How the file is named in error messages, e.g. ``"scene file"``; the path follows it.

    Returns
    -------
    object
        The document's value (``None`` for an empty file).

    Raises
    ------
    InputError
        The file cannot be read (missing, a folder, no permission), is not UTF-8, or fails
        :func:`parse_yaml`.
    """
    path = Path(path)
    where = f"{what} {path}"
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{where}: cannot be read ({exc.strerror or exc})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputError(f"{where}, line {line}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start}); "
                         "save the file as UTF-8") from None
    return parse_yaml(text, what=where)
