"""Backend options, each declared once: one :class:`Option` row of the backend's ``option_table``.

As pbrt-v4 creates its objects from a parameter dictionary and mitsuba3 documents its plugins
from their parameter tables, a backend states each option once (name, type, default, range or
choices, meaning) and :class:`~renderers.base.Renderer` derives the rest from the table: the
keyword-only constructor with its validation (:func:`take_options`), the attributes, the
``options`` record, the constructor's signature (:func:`signature`, which the registry's
``option_names`` reads) and the class docstring's Parameters section (:func:`document`). Checks
that relate several options, or need the device or the scene, stay in the backend.
"""

import inspect
import math
import textwrap
from dataclasses import dataclass
from typing import Callable

from core.errors import InputError
from core.validation import check_choice, check_positive_int, check_scalar

DOC_WIDTH = 100
"""Line width of the generated Parameters section."""


@dataclass(frozen=True)
class Option:
    """One keyword option of a backend.

    Parameters
    ----------
    name : str
        The keyword, and the key in the backend's ``options`` record.
    type : {bool, int, float, str}
        What a value must be. ``None`` is a value too where it is the default (it then means
        "the backend decides", as ``doc`` says).
    default : object
        The value when the option is not given (validated like a given one).
    doc : str
        The meaning in words, whole sentences; the docs add the range and the default.
    low, high : float, optional
        Bounds of an ``int`` or ``float`` (``None``: unbounded; an ``int`` needs ``low``).
    low_open, high_open : bool
        Whether a ``float``'s bound itself is excluded.
    choices : tuple of str
        The values a ``str`` option takes (empty: any string).
    check : callable, optional
        ``check(value, name=...) -> value``, a further check of this option alone after type and
        range (:func:`core.validation.check_step_factor`'s precision floor, a power of two).
    attribute : str, optional
        The backend attribute that holds the value where it cannot be ``name`` (a method has it).
    recorded : bool
        Whether the ``options`` record (every result's, runs.csv's ``option_*`` columns) has it.
    modes : frozenset of str, optional
        The render modes in which the option changes anything (``None``: every mode). A quality-sweep setting that
        varies an option of other modes only repeats another (:meth:`renderers.base.Renderer.quality_sweep_for`).
    """

    name: str
    type: type
    default: object
    doc: str
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple = ()
    check: Callable | None = None
    attribute: str | None = None
    recorded: bool = True
    modes: frozenset | None = None

    @property
    def holder(self):
        """The attribute name that holds the value."""
        return self.attribute or self.name

    def validate(self, value, backend):
        """``value`` checked and converted, or an :class:`InputError` "<backend> option <name>: ..."."""
        label = f"{backend} option {self.name}"
        if value is None and self.default is None:
            return None
        if self.type is bool:
            if not isinstance(value, bool):
                raise InputError(f"{label}: expected True or False, got {value!r}")
        elif self.type is int:
            value = check_positive_int(value, name=label, minimum=self.low)
            if self.high is not None and value > self.high:
                raise InputError(f"{label}: expected an integer from {self.low} to {self.high}, got {value!r}")
        elif self.type is float:
            value = check_scalar(value, name=label, low=-math.inf if self.low is None else self.low,
                                 high=math.inf if self.high is None else self.high,
                                 low_open=self.low_open, high_open=self.high_open)
        elif self.choices:
            value = check_choice(value, self.choices, name=label)
        elif not isinstance(value, str):
            raise InputError(f"{label}: expected a string, got {value!r}")
        return value if self.check is None else self.check(value, name=label)

    def range_text(self):
        """The values it takes (``"(0, 1]"``, ``"≥ 1"``, ``"0 to 24"``; empty where any of its type)."""
        low, high = self.low, self.high
        if self.type is int:
            return f"≥ {low}" if high is None else f"{low} to {high}"
        if self.type is not float or (low is None and high is None):
            return ""
        if high is None:
            return f"{'>' if self.low_open else '≥'} {low:g}"
        if low is None:
            return f"{'<' if self.high_open else '≤'} {high:g}"
        return f"{'(' if self.low_open else '['}{low:g}, {high:g}{')' if self.high_open else ']'}"

    def numpydoc(self):
        """This option's entry of a numpydoc Parameters section."""
        kind = "{" + ", ".join(f'"{choice}"' for choice in self.choices) + "}" if self.choices else self.type.__name__
        facts = f"Range {self.range_text()}. " if self.range_text() else ""
        body = textwrap.fill(f"{self.doc} {facts}Default ``{self.default!r}``.", DOC_WIDTH, initial_indent="    ",
                             subsequent_indent="    ", break_long_words=False, break_on_hyphens=False)
        return f"{self.name} : {kind}, optional\n{body}"


def check_known(backend, given, valid):
    """Refuse option names ``backend`` does not take, listing the valid ones (before any work).

    Parameters
    ----------
    backend : str
        The backend's registry name.
    given : iterable of str
        Option names asked for.
    valid : sequence of str
        The names it takes, in their declared order.
    """
    unknown = sorted(set(given) - set(valid))
    if unknown:
        raise InputError(f"backend {backend!r}: unknown option{'s' if len(unknown) > 1 else ''} "
                         f"{', '.join(unknown)}; valid options: {', '.join(valid) or 'none'}")


def take_options(backend, table, given):
    """``{attribute: value}`` for every option of ``table``: given, else its default, validated."""
    check_known(backend, given, [option.name for option in table])
    return {option.holder: option.validate(given.get(option.name, option.default), backend) for option in table}


def signature(table):
    """The keyword-only constructor signature the table declares (what ``inspect.signature`` shows)."""
    return inspect.Signature([inspect.Parameter(option.name, inspect.Parameter.KEYWORD_ONLY, default=option.default)
                              for option in table])


def document(docstring, table):
    """``docstring`` with the table's Parameters section before its first numpydoc section.

    The section is generated, so the docs cannot drift from the options; a docstring without
    sections gets it at the end.
    """
    section = "Parameters\n----------\n" + "\n".join(option.numpydoc() for option in table)
    lines = inspect.cleandoc(docstring).splitlines()
    for index, (line, underline) in enumerate(zip(lines, lines[1:])):
        if line.strip() and underline.strip() and set(underline.strip()) == {"-"}:
            return "\n".join(lines[:index] + section.splitlines() + [""] + lines[index:])
    return "\n".join(lines + [""] + section.splitlines())
