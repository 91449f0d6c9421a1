"""Builders for the data sets' classification presets, written in raw voxel values.

The notes give transfer functions in grey levels ("α = 0 below 60, 0.9 above 100"); these helpers
take such values and a ``scale`` (255 for 8-bit data, 4095 for 12-bit CT in uint16) and build the
normalised :class:`~core.transfer.Preset`. Colours are chosen so that renders look like the
usual CT/MR renditions: bone ivory, skin orange, vessels red, metal grey-blue.
"""

from core.transfer import (  # BONE_COLOR and SKIN_COLOR are re-exported for the registry
    BONE_COLOR, SKIN_COLOR, VOLPACK_GRADIENT_RAMP, GradientOpacity, Preset, TransferFunction,
    volpack_density_ramp,
)

VESSEL_COLOR = (0.85, 0.12, 0.10)
SOFT_COLOR = (0.80, 0.45, 0.40)
ALUMINIUM_COLOR = (0.70, 0.76, 0.88)
STEEL_COLOR = (0.95, 0.72, 0.40)
WHITE = (1.0, 1.0, 1.0)


def points(control, *, scale=255.0, name, description="", gradient=None, isovalue=None):
    """A preset from control points ``[(value, (r, g, b), alpha), ...]`` in raw values.

    Parameters
    ----------
    control : list of tuple
        Increasing raw values with a colour and an opacity; the table interpolates linearly
        between them and holds the end values outside.
    scale : float
        Raw value that maps to 1 (the top of the volume's value range).
    gradient : sequence of (u, g), optional
        Gradient-magnitude opacity control points (``u`` on the 0–1 scale of
        :class:`~core.transfer.GradientOpacity`).
    isovalue : float, optional
        Raw isovalue for ``iso`` mode.
    """
    rows = [(min(v / scale, 1.0), *color, alpha) for v, color, alpha in control]
    if rows[0][0] > 0:
        rows.insert(0, (0.0, *rows[0][1:]))
    if rows[-1][0] < 1:
        rows.append((1.0, *rows[-1][1:]))
    tf = TransferFunction.from_points(rows, name=name)
    g = None if gradient is None else GradientOpacity.from_points(gradient, name=f"{name}-gradient")
    return Preset(tf, g, None if isovalue is None else isovalue / scale, description)


def opaque(low, high, color, *, alpha=1.0, scale=255.0, name, description=""):
    """Opacity 0 up to ``low``, rising linearly to ``alpha`` at ``high`` (an opaque surface)."""
    return points([(low, color, 0.0), (high, color, alpha)], scale=scale, name=name,
                  description=description or f"opaque surface: α 0 → {alpha:g} over {low:g}–{high:g}")


def surfaces(low, high, color, *, scale=255.0, name, description=""):
    """VolPack-style surfaces: a density ramp times the brainsmall gradient ramp."""
    return points([(low, color, 0.0), (high, color, 1.0)], scale=scale, name=name,
                  gradient=VOLPACK_GRADIENT_RAMP,
                  description=description or f"density ramp {low:g}–{high:g} × gradient ramp (boundaries only)")


def step(threshold, color, *, alpha=1.0, scale=255.0, name, description=""):
    """Binary classification: ``alpha`` at and above ``threshold``, 0 below (Fig. 5.10a)."""
    tf = TransferFunction.step(threshold / scale, color=color, alpha=alpha, name=name)
    return Preset(tf, None, threshold / scale,
                  description or f"binary step at {threshold:g}: the thesis's aliasing test")


def constant(alpha, *, low_color=(0.25, 0.35, 0.9), high_color=(1.0, 0.85, 0.4), name, description=""):
    """The same opacity for every value, colour ramping with the value (no empty space)."""
    tf = TransferFunction.from_points([(0, *low_color, alpha), (1, *high_color, alpha)], name=name)
    return Preset(tf, None, None, description or f"uniform α = {alpha:g} per step")


def identity(color=WHITE, *, name="identity", description=""):
    """Opacity equal to the normalised scalar (``α = v / 255`` for 8-bit data)."""
    tf = TransferFunction.from_points([(0, *color, 0.0), (1, *color, 1.0)], name=name)
    return Preset(tf, None, None, description or "opacity = normalised scalar")


def volpack(color=WHITE):
    """VolPack's brainsmall classification (density ramp 0→24 × gradient ramp 5→20 of 221)."""
    return volpack_density_ramp(color=color)
