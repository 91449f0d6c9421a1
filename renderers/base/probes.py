"""Probes that several backends share (``Renderer.probe``: can it run here, and if not, why)."""


def numba_probe():
    """``(True, "")`` if Numba imports, else ``(False, reason)``: the probe of the Numba backends."""
    try:
        import numba  # noqa: F401
    except ImportError as exc:
        return False, f"numba cannot be imported: {exc}"
    return True, ""
