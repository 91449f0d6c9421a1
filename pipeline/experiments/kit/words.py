"""Numbers in words for claims and pages: the one way every paper writes a number, a ratio, a share.

Below both :mod:`.judging` (a claim's ``measured`` and ``detail``) and :mod:`.pages` (which re-exports
them), so that judging a claim never imports page code.
"""

from reports.takeaways import number


def format_number(value, digits=3):
    """A short number for claims and tables: 3 significant digits, ``n/a``, ``∞``."""
    return number(value, digits)


def as_percent(value):
    """``"12.5 %"`` of a share ``0.125``."""
    return f"{format_number(100 * value)} %"


def as_ratio(value):
    """``"×1.12"``."""
    return f"×{format_number(value)}"
