"""Transfer functions, gradient-magnitude opacity tables and per-data-set presets.

Conventions (CONVENTIONS, Transfer functions and classification):

* A :class:`TransferFunction` is an ``(N, 4)`` float32 RGBA table over the normalised scalar ``s``
  in [0, 1], colours *not* premultiplied. Entry ``i`` holds the classification of
  ``s = i / (N - 1)``, so with 256 entries entry ``v`` is exactly uint8 value ``v``. Lookups
  interpolate linearly between entries and clamp at the ends; GPU backends reproduce this with a
  linearly filtered 1-D texture addressed at ``s·(N−1)/N + 0.5/N``.
* Opacity in the table is the opacity of one reference step ``Δ0`` (``reference_step``; ``None``
  means the volume's smallest spacing). A renderer stepping by ``Δ`` (measured in the volume's
  object space) uses ``α' = 1 − (1 − α)^(Δ/Δ0)`` (:func:`correct_opacity`).
* A :class:`GradientOpacity` multiplies the opacity by ``g(u)``, ``u = |∇s|·Δ0 / (√3/2)``, i.e.
  the gradient magnitude per reference step scaled so that 1 is the largest central-difference
  gradient of a [0, 1] signal (VolPack's 0..221 scale for 8-bit data).
"""

from dataclasses import dataclass

import numpy as np

from core.errors import InputError
from core.resources import check_memory, largest_fitting
from core.validation import check_positive_int, check_scalar

MAX_GRADIENT = np.sqrt(3.0) / 2.0


def _table_size(size, width, *, name):
    """``size`` as the entry count of a ``width``-channel table this machine can build.

    Building one holds the float64 grid, a float64 column per channel, their float64 stack and
    the float32 table: ``8 + 20·width`` bytes an entry.
    """
    size = check_positive_int(size, name=f"{name} size", minimum=2)
    per_entry = 8 + 20 * width
    check_memory(size * per_entry, what=f"{name} size {size}", detail=f"{size} entries × {per_entry} bytes while built",
                 fix=lambda limit: f"use size ≤ {largest_fitting(limit, per_entry)} (256 entries resolve 8-bit data exactly)")
    return size


def _piecewise_linear(points, size, width, *, name):
    """Evaluate control points ``[(x, v1, ..., v_width), ...]`` at ``i/(size-1)``."""
    array = np.asarray(points, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != width + 1 or len(array) < 1:
        raise InputError(
            f"{name}: expected control points [x, {width} values] per row, got shape {array.shape}"
        )
    xs = array[:, 0]
    if not np.isfinite(array).all():
        raise InputError(f"{name}: control points contain NaN or infinite values")
    if np.any(np.diff(xs) < 0):
        raise InputError(f"{name}: control point positions must be non-decreasing, got {xs.tolist()}")
    if xs[0] < 0 or xs[-1] > 1:
        raise InputError(f"{name}: control point positions must lie in [0, 1], got {xs.tolist()}")
    grid = np.linspace(0.0, 1.0, size)
    return np.stack([np.interp(grid, xs, array[:, 1 + c]) for c in range(width)], axis=-1)


def _check_unit_table(table, width, *, name):
    table = np.asarray(table, dtype=np.float32)
    if width == 1 and table.ndim == 1:
        table = table[:, None]
    if table.ndim != 2 or table.shape[1] != width or table.shape[0] < 2:
        raise InputError(f"{name}: expected a table of shape (N >= 2, {width}), got {table.shape}")
    if not np.isfinite(table).all():
        raise InputError(f"{name}: table contains NaN or infinite values")
    if table.min() < 0 or table.max() > 1:
        raise InputError(
            f"{name}: entries must lie in [0, 1], got range [{table.min():.4g}, {table.max():.4g}]"
        )
    return np.ascontiguousarray(table)


@dataclass(frozen=True, eq=False)
class TransferFunction:
    """A 1-D RGBA lookup table (post-classification).

    Parameters
    ----------
    table : array_like, shape (N, 4)
        Non-premultiplied RGBA in [0, 1]; alpha is per reference step.
    reference_step : float, optional
        ``Δ0`` in the volume's object units. ``None`` uses the volume's smallest spacing.
    name : str, optional
        Label for reports.
    """

    table: np.ndarray
    reference_step: float | None = None
    name: str = "tf"

    def __post_init__(self):
        object.__setattr__(self, "table", _check_unit_table(self.table, 4, name=f"transfer function {self.name!r}"))
        if self.reference_step is not None:
            step = check_scalar(self.reference_step, name=f"transfer function {self.name!r} reference_step", low=0, low_open=True)
            object.__setattr__(self, "reference_step", step)

    @classmethod
    def from_points(cls, points, *, size=256, reference_step=None, name="tf"):
        """Build a table from piecewise-linear control points ``[(s, r, g, b, a), ...]``."""
        size = _table_size(size, 4, name=f"transfer function {name!r}")
        table = _piecewise_linear(points, size, 4, name=f"transfer function {name!r}")
        return cls(table, reference_step=reference_step, name=name)

    @classmethod
    def ramp(cls, low, high, *, color=(1.0, 1.0, 1.0), alpha=1.0, size=256, name="ramp"):
        """Opacity 0 below ``low``, rising linearly to ``alpha`` at ``high``, constant colour."""
        low = check_scalar(low, name=f"{name} low", low=0, high=1)
        high = check_scalar(high, name=f"{name} high", low=0, high=1)
        if not high > low:
            raise InputError(f"{name}: expected low < high, got {low} and {high}")
        r, g, b = color
        return cls.from_points(
            [(0, r, g, b, 0), (low, r, g, b, 0), (high, r, g, b, alpha), (1, r, g, b, alpha)],
            size=size, name=name,
        )

    @classmethod
    def step(cls, threshold, *, color=(1.0, 1.0, 1.0), alpha=1.0, size=256, name="step"):
        """Binary classification: opacity ``alpha`` for ``s >= threshold``, 0 below.

        The jump falls between the two table entries around ``threshold``, so the edge is as
        sharp as the table allows (the thesis's aliasing test, Fig. 5.10).
        """
        threshold = check_scalar(threshold, name=f"{name} threshold", low=0, high=1)
        size = _table_size(size, 4, name=name)
        grid = np.linspace(0.0, 1.0, size)
        table = np.zeros((size, 4), dtype=np.float32)
        table[:, :3] = color
        table[grid >= threshold, 3] = alpha
        return cls(table, name=name)

    @classmethod
    def constant(cls, *, color=(1.0, 1.0, 1.0), alpha, size=256, name="constant"):
        """The same RGBA for every scalar (homogeneous-medium closed-form tests)."""
        table = np.empty((_table_size(size, 4, name=name), 4), dtype=np.float32)
        table[:] = (*color, alpha)
        return cls(table, name=name)

    @property
    def size(self):
        return self.table.shape[0]

    def lookup(self, s):
        """Classify normalised scalars ``s`` (any shape) → RGBA (shape + (4,)), float64."""
        s = np.clip(np.asarray(s, dtype=np.float64), 0.0, 1.0)
        x = s * (self.size - 1)
        i0 = np.minimum(np.floor(x).astype(np.int64), self.size - 2)
        w = (x - i0)[..., None]
        table = self.table.astype(np.float64)
        return table[i0] * (1 - w) + table[i0 + 1] * w

    def nonzero_threshold(self):
        """Smallest normalised scalar whose opacity exceeds 0 (1.0 if none): a default isovalue."""
        nonzero = np.flatnonzero(self.table[:, 3] > 0)
        return 1.0 if nonzero.size == 0 else float(nonzero[0]) / (self.size - 1)


@dataclass(frozen=True, eq=False)
class GradientOpacity:
    """Opacity modulation ``g(u)`` by gradient magnitude (Levoy / VolPack).

    Parameters
    ----------
    table : array_like, shape (M,)
        Factors in [0, 1]; entry ``i`` is ``g(i / (M - 1))``. See the module notes for ``u``.
    name : str, optional
    """

    table: np.ndarray
    name: str = "gradient"

    def __post_init__(self):
        table = _check_unit_table(self.table, 1, name=f"gradient opacity {self.name!r}")[:, 0]
        object.__setattr__(self, "table", np.ascontiguousarray(table))

    @classmethod
    def from_points(cls, points, *, size=256, name="gradient"):
        """Build from control points ``[(u, g), ...]`` with ``u`` in [0, 1]."""
        size = _table_size(size, 1, name=f"gradient opacity {name!r}")
        return cls(_piecewise_linear(points, size, 1, name=f"gradient opacity {name!r}")[:, 0], name=name)

    def lookup(self, u):
        u = np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0)
        return np.interp(u, np.linspace(0, 1, self.table.size), self.table.astype(np.float64))


def correct_opacity(alpha, step, reference_step):
    """Opacity correction ``α' = 1 − (1 − α)^(Δ/Δ0)`` (works on arrays)."""
    alpha = np.asarray(alpha, dtype=np.float64)
    return 1.0 - np.power(1.0 - np.clip(alpha, 0.0, 1.0), step / reference_step)


@dataclass(frozen=True, eq=False)
class Preset:
    """A named classification of one data set: what the papers call a transfer-function preset.

    Parameters
    ----------
    transfer_function : TransferFunction
    gradient_opacity : GradientOpacity, optional
        VolPack-style density × gradient classification.
    isovalue : float, optional
        Normalised isovalue for ``iso`` mode; defaults to where the opacity first rises.
    description : str, optional
    """

    transfer_function: TransferFunction
    gradient_opacity: GradientOpacity | None = None
    isovalue: float | None = None
    description: str = ""

    @property
    def effective_isovalue(self):
        if self.isovalue is not None:
            return self.isovalue
        return self.transfer_function.nonzero_threshold()


# Control points shared by the data sets' presets (normalised scalar, then RGBA).
BONE_COLOR = (0.95, 0.92, 0.85)
SKIN_COLOR = (0.9, 0.65, 0.5)

VOLPACK_GRADIENT_RAMP = ((0.0, 0.0), (5 / 221, 0.0), (20 / 221, 1.0), (1.0, 1.0))
"""VolPack's brainsmall example gradient ramp (0→0, 5→0, 20→1, 221→1 on its 0..221 scale)."""


def volpack_density_ramp(*, color=(1.0, 1.0, 1.0), name="volpack"):
    """VolPack's brainsmall example: density ramp (0→0, 24→1, 255→1) × the gradient ramp."""
    r, g, b = color
    tf = TransferFunction.from_points([(0, r, g, b, 0), (24 / 255, r, g, b, 1), (1, r, g, b, 1)], name=name)
    return Preset(tf, GradientOpacity.from_points(VOLPACK_GRADIENT_RAMP, name=f"{name}-gradient"),
                  description="VolPack brainsmall classification: density ramp × gradient ramp")
