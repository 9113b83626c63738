"""The bounds table: every kind refuses what is outside it, in readable units, and the
docs show the table as the code has it."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from bench.config.bounds import BOUNDS, MAX_DURATION_S, bound, bounded_quantity, check, markdown_table
from bench.errors import ConfigError


@pytest.mark.parametrize("kind", list(BOUNDS))
def test_every_bound_takes_its_ends_and_refuses_beyond_them(kind):
    b = BOUNDS[kind]
    if b.high is not None:
        assert check(kind, b.high) == b.high
        with pytest.raises(ConfigError, match=r"expected .* <= "):
            check(kind, b.high * 1.5 + 1, file="f.toml", key="k")
    if b.low is not None:
        below = b.low - max(1.0, abs(b.low)) * 0.5 if b.low != 0 else -1.0
        with pytest.raises(ConfigError, match=r"expected .* >?=? "):
            check(kind, below)
        if not b.low_open:
            assert check(kind, b.low) == b.low
        else:
            with pytest.raises(ConfigError, match=">"):
                check(kind, b.low)
    for x in (math.nan, math.inf, -math.inf):
        with pytest.raises(ConfigError, match="finite"):
            check(kind, x)


def test_a_message_names_file_key_value_and_bound():
    with pytest.raises(ConfigError) as info:
        check("duration", 1e300, file="case.toml", key="scenario.duration", shown="1e300 s")
    assert str(info.value) == (
        "case.toml: scenario.duration: expected a duration <= 2592000 s (30 days), found '1e300 s'"
    )


def test_periods_are_zero_or_at_least_a_millisecond():
    assert check("period", 0.0) == 0.0 and check("period", 1e-3) == 1e-3
    with pytest.raises(ConfigError, match="expected a period of 0 or >= 1 ms, found '1 ns'"):
        bounded_quantity("1 ns", "time", "s", "period", key="params.every")


def test_huge_integers_are_compared_exactly():
    with pytest.raises(ConfigError, match="<= 10000"):
        check("runs", 10**400)
    assert check("runs", 10_000) == 10_000


def test_the_bounds_are_those_the_brief_promises():
    assert MAX_DURATION_S == 2_592_000.0
    assert bound("rate").high == 10_000.0 and bound("imu_rate").high == 1000.0
    assert bound("runs").high == 10_000 and bound("segments").high == 100_000
    assert bound("events").high == 1_000_000 and bound("period").low == 1e-3
    assert bound("text_file").high == 64 * 2**20
    with pytest.raises(KeyError, match="known: duration"):
        bound("durations")


def test_docs_show_the_bounds_table():
    text = (Path(__file__).resolve().parents[2] / "docs" / "test_cases.md").read_text()
    assert markdown_table() in text, "docs/test_cases.md: the bounds table is out of date"
