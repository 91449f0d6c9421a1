"""The renderer interface: what every backend implements and reports (pbrt-v4 style ``base/``)."""

from renderers.base.interface import Capabilities, RenderResult, Renderer

__all__ = ["Capabilities", "RenderResult", "Renderer"]
