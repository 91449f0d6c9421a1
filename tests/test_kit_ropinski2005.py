"""The kit helper ropinski2005's count claims share: judging.counts_compared."""

import math

import pytest

from pipeline.experiments.kit import judging

COUNTS = {"foot": (40.0, 100.0), "skull": (90.0, 100.0), "seismic": (10.0, 0.0)}


def compare(labels, *, fewer):
    return judging.counts_compared(labels, COUNTS.get, fewer=fewer, measured=lambda r, label: f"{r:g} ({label})",
                                   words=lambda label, a, b: f"{label}: {a:g} of {b:g}", extra="; counted")


def test_fewer_holds_where_every_label_has_fewer_and_the_largest_ratio_decides():
    result = compare(["foot", "skull"], fewer=True)
    assert result.holds is True and result.measured == "0.9 (skull)"
    assert result.detail == "foot: 40 of 100; skull: 90 of 100; counted"


def test_a_zero_denominator_is_an_infinite_ratio_and_one_label_the_wrong_way_fails():
    result = compare(["foot", "seismic"], fewer=True)
    assert result.holds is False and result.measured == f"{math.inf:g} (seismic)"
    more = compare(["seismic", "foot"], fewer=False)
    assert more.holds is False and more.measured == "0.4 (foot)"
    assert compare(["seismic"], fewer=False).holds is True


def test_no_label_is_not_measurable():
    with pytest.raises(ValueError):
        compare([], fewer=True)
