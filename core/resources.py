"""What this machine can hold: sizes are checked against its memory before anything is allocated.

A size in a scene or a backend option (a phantom's edge, the image, a table, a mesh's resolution,
a block grid) is turned into the bytes it will need, and a request this machine cannot hold is
refused with the estimate, the machine's memory and the largest size that fits, instead of
ending minutes later in numpy's ``MemoryError`` (or in swap).

The bound is the machine's physical memory (:func:`memory_limit`), not what happens to be free
at the moment: a scene is refused because it can never fit here, and the same scene gets the same
verdict whatever else the machine is doing.
"""

import psutil

from core.errors import InputError

__all__ = ["check_memory", "format_bytes", "largest_fitting", "memory_limit"]

_UNITS = ("bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB")


def memory_limit():
    """Bytes of physical memory of this machine: the most one request may need.

    Every check goes through this function, so a test can act out a small machine by
    monkeypatching it.
    """
    return int(psutil.virtual_memory().total)


def format_bytes(count):
    """``count`` bytes with a binary unit and three significant digits (``"3.55 PiB"``)."""
    value = float(count)
    for unit in _UNITS[:-1]:
        if abs(value) < 1024:
            break
        value /= 1024
    else:
        unit = _UNITS[-1]
    return f"{int(value)} bytes" if unit == "bytes" else f"{value:.3g} {unit}"


def check_memory(needed, *, what, detail, fix):
    """Raise :class:`InputError` when ``needed`` bytes exceed :func:`memory_limit`.

    Parameters
    ----------
    needed : int or float
        The estimate, in bytes (a float where the count overflows 64 bits).
    what : str
        The input and what it sizes, e.g. ``"volumes[0] size 4096: the phantom"``.
    detail : str
        How the estimate is made, e.g. ``"4096³ voxels × 48 bytes"``.
    fix : str or callable
        What to do instead; a callable receives the limit in bytes, so the message can name the
        largest size that fits.

    Returns
    -------
    int or float
        ``needed``.
    """
    limit = memory_limit()
    if needed > limit:
        advice = fix(limit) if callable(fix) else fix
        raise InputError(f"{what} needs {format_bytes(needed)} ({detail}), this machine has "
                         f"{format_bytes(limit)}; {advice}")
    return needed


def largest_fitting(limit, bytes_each, *, power=1):
    """The largest integer ``n`` with ``n**power · bytes_each <= limit`` (0 if none).

    What a message offers instead of a refused size: ``power=3`` for an edge of a cubic grid,
    2 for the side of a square image.
    """
    n = int((limit / bytes_each) ** (1 / power))
    # The float root can land one off either way of the exact bound.
    while n > 0 and n ** power * bytes_each > limit:
        n -= 1
    while (n + 1) ** power * bytes_each <= limit:
        n += 1
    return n
