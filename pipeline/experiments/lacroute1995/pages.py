"""How this paper's pages show its runs: its charts as figures, and what the shear-warp backend cannot measure here."""

from pipeline.experiments.kit.pages import not_measurable
from pipeline.experiments.kit.planning import missing_options, unregistered
from pipeline.experiments.lacroute1995.planning import SW


def shearwarp_missing(*options, more=()):
    """The page's note of what cannot be measured here: the shear-warp backend, or its ``options``, where this
    machine lacks them, then the ``(what, why)`` pairs of ``more``."""
    return not_measurable(unregistered(SW) + missing_options(SW, *options) + list(more))
