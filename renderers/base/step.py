"""The world step every backend with a ``step_factor`` shares: its option and its formula."""

from core.validation import LIMITED_PRECISION_MIN_STEP_FACTOR, check_step_factor
from renderers.base.options import Option

WORLD_STEP_DOC = "World step as a fraction of the smallest world-space voxel edge."


def step_factor_option(default, doc=WORLD_STEP_DOC, *, limited_precision=True, modes=None):
    """The ``step_factor`` option: a step in units of the smallest voxel edge, > 0.

    Parameters
    ----------
    default : float
        The backend's default step factor.
    doc : str, optional
        Its meaning for this backend (where the step is taken, if not in world space).
    limited_precision : bool, optional
        The backend composites in float32 (or fixed point), so steps finer than
        :data:`core.validation.LIMITED_PRECISION_MIN_STEP_FACTOR` are refused
        (:func:`core.validation.check_step_factor`); ``False`` for float64 compositing.
    modes : frozenset of str, optional
        The render modes that sample at the step (``None``: every mode; see :class:`renderers.base.Option`).
    """
    if limited_precision:
        doc = (f"{doc} Finer than {LIMITED_PRECISION_MIN_STEP_FACTOR:.3g} is refused: float32 (or "
               "fixed-point) compositing rounds faint samples to nothing.")
    return Option("step_factor", float, default, doc, low=0, low_open=True,
                  check=check_step_factor if limited_precision else None, modes=modes)


def world_step(scene, step_factor):
    """``step_factor`` times the smallest world-space voxel edge of ``scene`` (``None``: no volume).

    The world step ``Δ`` of every backend that samples its volumes at one common step
    (:meth:`core.scene.Scene.min_world_voxel_size`: ``|A·e_i|·s_i`` over all volumes); a scene
    without volumes has no voxel to measure it by, and nothing to sample.
    """
    if not scene.volumes:
        return None
    return step_factor * scene.min_world_voxel_size()
