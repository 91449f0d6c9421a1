"""core.resources: the machine's memory as the bound that sizes are checked against, and the
sizes in core that are refused by it before anything is allocated."""

import psutil
import pytest

import core.resources as resources
from core.errors import InputError
from core.resources import check_memory, format_bytes, largest_fitting
from core.transfer import GradientOpacity, TransferFunction


@pytest.fixture
def small_machine(monkeypatch):
    """A machine of 1 GiB: every check goes through memory_limit."""
    monkeypatch.setattr(resources, "memory_limit", lambda: 2 ** 30)


def test_the_limit_is_the_machines_physical_memory():
    assert resources.memory_limit() == psutil.virtual_memory().total


def test_bytes_are_written_in_binary_units_with_three_digits():
    assert format_bytes(512) == "512 bytes"
    assert format_bytes(256 * 2 ** 30) == "256 GiB"
    assert format_bytes(4 * 10 ** 15) == "3.55 PiB"
    assert format_bytes(25276510208) == "23.5 GiB"


@pytest.mark.parametrize("limit, each, power", [(10 ** 3, 48, 3), (25276510208, 48, 3), (10 ** 12, 16, 2),
                                                 (100, 7, 1), (47, 48, 3), (2 ** 62, 1, 3),
                                                 # the float root lands one below, and one above, the bound:
                                                 (48 * 5 ** 3, 48, 3), (2 ** 54 - 1, 1, 2)])
def test_the_largest_fitting_size_is_exact(limit, each, power):
    n = largest_fitting(limit, each, power=power)
    assert n ** power * each <= limit < (n + 1) ** power * each


def test_more_than_the_machine_holds_is_refused_with_the_estimate_the_limit_and_the_fix(small_machine):
    assert check_memory(2 ** 30, what="w", detail="d", fix="f") == 2 ** 30
    with pytest.raises(InputError, match=r"^thing needs 2 GiB \(how\), this machine has 1 GiB; use ≤ 1073741824$"):
        check_memory(2 ** 31, what="thing", detail="how", fix=lambda limit: f"use ≤ {limit}")


@pytest.mark.parametrize("build", [
    lambda size: TransferFunction.from_points([(0, 1, 1, 1, 0), (1, 1, 1, 1, 1)], size=size),
    lambda size: TransferFunction.ramp(0.2, 0.8, size=size),
    lambda size: TransferFunction.step(0.5, size=size),
    lambda size: TransferFunction.constant(alpha=0.5, size=size),
    lambda size: GradientOpacity.from_points([(0, 0), (1, 1)], size=size),
])
def test_a_table_too_large_to_build_is_refused_before_it_is_allocated(small_machine, build):
    with pytest.raises(InputError, match=r"size 10000000000 needs .* this machine has 1 GiB; use size ≤ \d+"):
        build(10 ** 10)
    assert build(256) is not None
