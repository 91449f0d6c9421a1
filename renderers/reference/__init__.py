"""The reference backend: a double-precision numba ray caster, the ground truth for accuracy."""

from renderers.reference.renderer import ReferenceRenderer

__all__ = ["ReferenceRenderer"]
