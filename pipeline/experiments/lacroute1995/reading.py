"""Reading this paper's results: the angle a view's name gives, chart titles made from a claim's check."""

import re


def angle_of(view):
    """The angle in a view name (``az22.5`` → 22.5, ``deg090`` → 90)."""
    match = re.search(r"(-?\d+(?:\.\d+)?)$", str(view))
    if not match:
        raise ValueError(f"view {view!r} names no angle")
    return float(match.group(1))


def title_or(make, ok, fallback, errors=(KeyError, ValueError)):
    """``make(ok)``, a chart title built from a claim's result, or ``fallback`` when it cannot be measured."""
    try:
        return make(ok)
    except errors:
        return fallback
