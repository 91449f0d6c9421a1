"""The ``volpack`` backend: VolPack, Lacroute's shear-warp library, through ctypes (see :mod:`.renderer`)."""

from renderers.volpack.renderer import VolPackRenderer

__all__ = ["VolPackRenderer"]
