"""The renderer interface: what every backend implements and reports (pbrt-v4 style ``base/``)."""

from renderers.base.interface import Capabilities, RenderResult, Renderer
from renderers.base.options import Option
from renderers.base.step import step_factor_option, world_step

__all__ = ["Capabilities", "Option", "RenderResult", "Renderer", "step_factor_option", "world_step"]
