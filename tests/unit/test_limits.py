"""limits.py: requests checked against fixed limits and the available memory, refused in one line."""

from __future__ import annotations

import pytest

from tumble import limits
from tumble.limits import LimitError


def test_check_steps_counts_the_steps_and_refuses_beyond_the_limit():
    """duration / dt rounded (at least 1); over MAX_STEPS or not finite: LimitError naming key and limit."""
    assert limits.check_steps("duration", 2.0, 1.0 / 240.0) == 480
    assert limits.check_steps("duration", 1e-6, 0.01) == 1
    with pytest.raises(
        LimitError, match=r"^duration: 1e\+07 s at dt 0.001 s is 10,000,000,000 steps; the limit is 1,000,000,000"
    ):
        limits.check_steps("duration", 1e7, 1e-3)
    with pytest.raises(LimitError, match="inf steps"):
        limits.check_steps("--duration", float("inf"), 0.01)


def test_check_memory_refuses_what_does_not_fit_and_says_how_much_would():
    """need = count x bytes each against the memory given: the message names both and the largest count."""
    limits.check_memory("count", "bodies", 1000, 2048, available=2048 * 1000)  # exactly fits
    with pytest.raises(LimitError) as info:
        limits.check_memory("count", "bodies", 1001, 2048, available=2048 * 1000)
    assert str(info.value) == (
        "count: 1,001 bodies need about 2.1 MB of memory; 2.0 MB is available (at most 1,000 bodies)"
    )
    assert isinstance(info.value, ValueError)


def test_show_bytes_uses_decimal_units():
    """512 B, 3.2 MB, 1.9 TB: one decimal beyond bytes, as df -H."""
    assert limits.show_bytes(512) == "512 B"
    assert limits.show_bytes(3.2e6) == "3.2 MB"
    assert limits.show_bytes(1.94e12) == "1.9 TB"
    assert limits.show_bytes(5e18) == "5000.0 PB"


@pytest.mark.parametrize(
    ("text", "expected"), [("100000", 100000), ("1.5 GB", 3 * 2**29), ("2k", 2048), ("3TiB", 3 * 2**40)]
)
def test_parse_bytes_takes_binary_multiples(text, expected):
    """K, M, G, T are powers of 1024, with or without B / iB and spaces."""
    assert limits.parse_bytes(text) == expected


@pytest.mark.parametrize("text", ["", "lots", "2X", "-1G", "1e9"])
def test_parse_bytes_names_the_variable_when_it_cannot_read_the_size(text):
    with pytest.raises(LimitError, match=f"{limits.MEMORY_ENV}="):
        limits.parse_bytes(text)


def test_available_memory_is_capped_by_the_environment(monkeypatch):
    """$TUMBLE_MEMORY lowers the plan; without it the machine's own figure is positive."""
    monkeypatch.delenv(limits.MEMORY_ENV, raising=False)
    machine = limits.available_memory()
    assert machine > 0
    monkeypatch.setenv(limits.MEMORY_ENV, "64M")
    assert limits.available_memory() == min(machine, 64 * 2**20)
