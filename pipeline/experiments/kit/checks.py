"""Claims as small declarative checks: what is measured, the bound, and the sentence, in one place.

Most of the papers' claims are one of a few kinds: a ratio of two measurements at most or at least
a bound (a speed-up, a growth from one volume to fifty), a measurement above a floor or below a
ceiling (the worst PSNR of a sweep), a measurement inside a band around a target (a phantom's
statistic against the real scan's), or a growth exponent (time against size on log-log axes). Each
kind is one class here, the way asv declares one kind of measurement per small class: a claim says
which measurements and which bound, and the class computes the value, the verdict and the words
(``measured`` and ``detail`` of :class:`~pipeline.experiments.kit.model.ClaimResult`), so every
paper phrases the same verdict the same way. A check is called with the experiment's successful
rows, as every claim's check is.

>>> speedup = Ratio(Measure("RC", match={"config": "rc"}), Measure("RC-b", match={"config": "rc-b"}), at_least=1.5)
>>> Claim("rcb-faster", "Empty-space skipping speeds up early termination", speedup.expected, speedup)  # doctest: +SKIP
"""

from dataclasses import dataclass, field

import numpy as np

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import with_interval
from pipeline.experiments.kit.model import ClaimResult
from pipeline.experiments.kit.results import numeric, rows_matching
from pipeline.experiments.kit.words import as_ratio, format_number

STATISTICS = {"median": np.median, "min": np.min, "max": np.max, "mean": np.mean}
"""How a :class:`Measure` reduces the values of its rows."""

ACCURACY_COLUMNS = ("psnr", "ssim", "flip", "max_error", "frac_over_threshold", "alpha_rmse")
"""Prefixes of the columns that compare an image with its reference: a :class:`Measure` of one is ``accuracy``."""


@dataclass(frozen=True)
class Measure:
    """One number of the results: a statistic of a column over the rows a selection matches.

    Parameters
    ----------
    what : str
        The measurement in words, for sentences and errors (``"RC-b on the head"``).
    match : dict
        Tag columns and the values the rows must have (compared as text).
    column : str
        The column measured (``time_total``: a frame's median time in seconds).
    statistic : {"median", "min", "max", "mean"}
        How several matching rows (views, scenes) reduce to one number.
    unit : str
        Appended to the number in sentences (``"ms"`` scales seconds to milliseconds).
    label : str, optional
        With ``statistic`` ``"min"`` or ``"max"``: the column whose value names the row at the
        extreme (``"scene"``), said beside the number (``"38.5 dB (engine)"``).
    """

    what: str
    match: dict = field(default_factory=dict)
    column: str = "time_total"
    statistic: str = "median"
    unit: str = "ms"
    label: str | None = None

    def _values(self, df):
        rows = rows_matching(df, self.what, **self.match)
        values = numeric(rows, self.column)
        if values.dropna().empty:
            raise ValueError(f"no successful run of {self.what}")
        if values.isna().any():  # a view that measured nothing is missing, not left out of the statistic
            missing = rows[values.isna()]
            names = [f"{run} ({view})" if isinstance(view, str) and view else str(run)
                     for run, view in zip(missing.get("run", missing.index), missing.get("view", [""] * len(missing)))]
            raise ValueError(f"{self.what}: {self.column} missing in {', '.join(names)}")
        return rows, values

    def value(self, df):
        """The number, from ``df`` (the successful rows); ``ValueError`` naming :attr:`what` if none matches."""
        return float(STATISTICS[self.statistic](self._values(df)[1].to_numpy()))

    def named(self, df):
        """``(value, name)``: the number and, with :attr:`label`, the label of the row it comes from."""
        rows, values = self._values(df)
        if self.label is None or self.statistic not in ("min", "max"):
            return float(STATISTICS[self.statistic](values.to_numpy())), None
        at = values.idxmin() if self.statistic == "min" else values.idxmax()
        return float(values[at]), str(rows.loc[at, self.label]) if self.label in rows else None

    def draws(self, df, resampler):
        """Bootstrap draws of :meth:`value` from the rows' timed frames (``None`` without frames)."""
        rows, _ = self._values(df)  # every row has a value: a row without one is refused there
        return intervals.statistic_draws(rows, self.column, self.statistic, resampler)

    @property
    def kind(self):
        """What the measurement is (:data:`~pipeline.experiments.kit.model.CLAIM_KINDS`), read from its column."""
        if self.timed:
            return "timing"
        return "accuracy" if self.column.startswith(ACCURACY_COLUMNS) else "count"

    @property
    def timed(self):
        """Whether the measurement is a frame time (its claims need frames: :func:`~.intervals.timing_decision`)."""
        return intervals.frames_column(self.column) is not None

    def frames(self, df):
        """How many timed frames the matching rows hold (:func:`~.intervals.frame_count`)."""
        return intervals.frame_count(self._values(df)[0], self.column)

    def words(self, value):
        """``"RC-b 12.3 ms"``: the measurement with its value in its unit."""
        shown = value * 1e3 if self.unit == "ms" else value
        return f"{self.what} {format_number(shown)}{' ' + self.unit if self.unit else ''}"


class Check:
    """A claim's check: called with the successful rows, returns a :class:`ClaimResult`."""

    @property
    def kind(self):
        """What the claim measures: its measurements' kind (a ratio of times is a timing)."""
        kinds = {m.kind for m in vars(self).values() if isinstance(m, Measure)}
        if len(kinds) != 1:
            raise ValueError(f"{type(self).__name__} measures {sorted(kinds)}: a claim measures one kind")
        return kinds.pop()

    @property
    def expected(self):
        """The bound in words, for the claims table's ``expected`` column."""
        raise NotImplementedError

    def __call__(self, df):
        raise NotImplementedError


def _bound_words(at_least, at_most, show):
    parts = ([f"≥ {show(at_least)}"] if at_least is not None else []) + ([f"≤ {show(at_most)}"] if at_most is not None else [])
    return " and ".join(parts)


@dataclass(frozen=True)
class Ratio(Check):
    """``numerator / denominator`` at least ``at_least`` and/or at most ``at_most`` (a speed-up, a growth)."""

    numerator: Measure
    denominator: Measure
    at_least: float | None = None
    at_most: float | None = None

    @property
    def expected(self):
        return f"{self.numerator.what} / {self.denominator.what} {_bound_words(self.at_least, self.at_most, as_ratio)}"

    def __call__(self, df):
        top, bottom = self.numerator.value(df), self.denominator.value(df)
        if bottom == 0:
            raise ValueError(f"{self.denominator.what} is 0")
        resampler = intervals.Resampler()
        a, b = self.numerator.draws(df, resampler), self.denominator.draws(df, resampler)
        draws = a / b if a is not None and b is not None else None
        arms = ({m.what: m.frames(df) for m in (self.numerator, self.denominator)} if self.numerator.timed
                else None)
        decision = intervals.draws_decision(top / bottom, draws, arms, at_least=self.at_least, at_most=self.at_most)
        return ClaimResult.decided(with_interval(as_ratio(decision.value), decision, as_ratio), decision,
                                   f"{self.numerator.words(top)}, {self.denominator.words(bottom)}")


@dataclass(frozen=True)
class Bound(Check):
    """A measurement at least ``at_least`` and/or at most ``at_most`` (a PSNR floor, a time ceiling)."""

    measure: Measure
    at_least: float | None = None
    at_most: float | None = None

    @property
    def expected(self):
        unit = self.measure.unit
        scale = 1e3 if unit == "ms" else 1.0
        return f"{self.measure.what} {_bound_words(self.at_least, self.at_most, lambda v: f'{format_number(v * scale)} {unit}'.strip())}"

    def __call__(self, df):
        value, name = self.measure.named(df)
        measured = self.measure.words(value).removeprefix(f"{self.measure.what} ")
        arms = {self.measure.what: self.measure.frames(df)} if self.measure.timed else None
        decision = intervals.draws_decision(value, self.measure.draws(df, intervals.Resampler()), arms,
                                            at_least=self.at_least, at_most=self.at_most)
        scale = 1e3 if self.measure.unit == "ms" else 1.0
        show = lambda v: f"{format_number(v * scale)} {self.measure.unit}".strip()  # noqa: E731
        return ClaimResult.decided(with_interval(measured + (f" ({name})" if name else ""), decision, show),
                                   decision, self.measure.what)


@dataclass(frozen=True)
class Band(Check):
    """A measurement within ``relative`` of ``target`` (or ``absolute``, where that is wider)."""

    measure: Measure
    target: float
    relative: float
    absolute: float = 0.0

    @property
    def half_width(self):
        return max(abs(self.target) * self.relative, self.absolute)

    @property
    def expected(self):
        return f"{format_number(self.target)} ± {format_number(self.half_width)}"

    def __call__(self, df):
        value = self.measure.value(df)
        return ClaimResult(format_number(value), bool(abs(value - self.target) <= self.half_width), self.measure.what)


@dataclass(frozen=True)
class Growth(Check):
    """The exponent of ``measure`` against a numeric tag ``x`` (the slope on log-log axes), bounded.

    ``measure.match`` selects the series; each value of ``x`` is one point (its rows reduced by
    ``measure.statistic``). Three points at least.
    """

    measure: Measure
    x: str
    at_least: float | None = None
    at_most: float | None = None

    @property
    def expected(self):
        return f"exponent of {self.measure.what} against {self.x} {_bound_words(self.at_least, self.at_most, format_number)}"

    def __call__(self, df):
        rows = rows_matching(df, self.measure.what, **self.measure.match)
        xs = numeric(rows, self.x)
        points = [(x, self.measure.value(rows[xs == x])) for x in sorted(xs.dropna().unique())]
        if len(points) < 3:
            raise ValueError(f"need three values of {self.x} for {self.measure.what}, got {len(points)}")
        x, y = np.log(np.array(points, float)).T
        exponent = float(np.polyfit(x, y, 1)[0])
        resampler = intervals.Resampler()
        draws = [self.measure.draws(rows[xs == value], resampler) for value, _ in points]
        slopes = None
        if all(d is not None for d in draws):
            # One slope per draw: polyfit fits every column of a (points, draws) array at once.
            slopes = np.polyfit(x, np.log(np.column_stack(draws).T), 1)[0]
        arms = ({f"{self.x} {format_number(value)}": self.measure.frames(rows[xs == value]) for value, _ in points}
                if self.measure.timed else None)
        decision = intervals.draws_decision(exponent, slopes, arms, at_least=self.at_least, at_most=self.at_most)
        return ClaimResult.decided(with_interval(format_number(exponent), decision, format_number), decision,
                                   f"{len(points)} points of {self.x} from {format_number(points[0][0])} to "
                                   f"{format_number(points[-1][0])}")


def worst_psnr(what, at_least, **match):
    """A :class:`Bound` on the worst PSNR against the reference of the rows matching ``match``, naming its scene.

    Parameters
    ----------
    what : str
        The measurement in words (:attr:`Measure.what`), for the claim's ``expected`` text and its errors.
    at_least : float
        The floor, in dB.
    **match
        Tag columns and the values the rows must have (:attr:`Measure.match`).

    Returns
    -------
    Bound
        Its ``measured`` text is the worst PSNR with the ``scene`` of its row (``"38.5 dB (engine)"``).
    """
    return Bound(Measure(what, match=match, column="psnr", statistic="min", unit="dB", label="scene"),
                 at_least=at_least)
