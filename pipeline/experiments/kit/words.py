"""Numbers in words for claims and pages: the one way every paper writes a number, a ratio, a share.

Below both :mod:`.judging` (a claim's ``measured`` and ``detail``) and :mod:`.pages` (which re-exports
them), so that judging a claim never imports page code.
"""

import pandas as pd

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


def full_count(value):
    """``"15,900"``: a counter in full (3 significant digits would read ``1.59e+04``); ``""`` if missing."""
    value = pd.to_numeric(value, errors="coerce")
    return f"{int(value):,}" if pd.notna(value) else ""


def megabytes(value):
    """``"4.89"``: a byte count in MB (10⁶ bytes); ``""`` if missing."""
    value = pd.to_numeric(value, errors="coerce")
    return format_number(value / 1e6) if pd.notna(value) else ""


def short_duration(seconds):
    """``"20.7 ns"``, or in µs from a microsecond on: a time per item (per voxel, per run)."""
    return f"{format_number(seconds * 1e9)} ns" if abs(seconds) < 1e-6 else f"{format_number(seconds * 1e6)} µs"
