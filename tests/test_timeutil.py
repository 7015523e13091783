"""Exact conversions of durations and rates to integer nanoseconds: no float time anywhere."""

import pytest

from plan.timeutil import format_ns, parse_duration_ns, rate_to_period_ns


@pytest.mark.parametrize(("value", "ns"), [
    ("30s", 30_000_000_000),
    ("10ms", 10_000_000),
    ("250us", 250_000),
    ("100ns", 100),
    ("1.5s", 1_500_000_000),
    (" 2 ms ", 2_000_000),
    (30, 30_000_000_000),
    (0.01, 10_000_000),  # float seconds, taken from its decimal text, not binary
    (0.1, 100_000_000),
    ("0.001", 1_000_000),
    (1e-9, 1),
])
def test_parse_duration_exact(value, ns):
    result = parse_duration_ns(value)
    assert result == ns
    assert type(result) is int


@pytest.mark.parametrize(("value", "words"), [
    ("0s", "greater than zero"),
    (0, "greater than zero"),
    (-1, "greater than zero"),
    ("-1s", "greater than zero"),
    ("1.5ns", "whole number of nanoseconds"),
    (1e-10, "whole number of nanoseconds"),
    ("ten seconds", "not a duration"),
    ("30 min", "not a duration"),
    (True, "boolean"),
    (float("inf"), "finite"),
    (float("nan"), "finite"),
    (None, "not a number"),
])
def test_parse_duration_refused(value, words):
    with pytest.raises(ValueError, match=words):
        parse_duration_ns(value)


@pytest.mark.parametrize(("rate", "period"), [
    (100, 10_000_000),
    (50, 20_000_000),
    (1, 1_000_000_000),
    (0.5, 2_000_000_000),
    ("40", 25_000_000),
    (1_000_000_000, 1),
    (62.5, 16_000_000),
])
def test_rate_to_period(rate, period):
    result = rate_to_period_ns(rate)
    assert result == period
    assert type(result) is int


def test_rate_with_fractional_period_refused_with_rates_that_fit():
    with pytest.raises(ValueError) as info:
        rate_to_period_ns(30)
    message = str(info.value)
    assert "30 Hz" in message
    assert "not a whole number of nanoseconds" in message
    assert "25, 32, 40" in message  # the whole-ns rates on either side of 30 Hz


@pytest.mark.parametrize(("rate", "words"), [
    (0, "greater than zero"),
    (-10, "greater than zero"),
    (float("inf"), "finite"),
    ("fast", "not a number"),
    (False, "boolean"),
])
def test_rate_refused(rate, words):
    with pytest.raises(ValueError, match=words):
        rate_to_period_ns(rate)


@pytest.mark.parametrize(("ns", "text"), [
    (10_000_000, "10ms"), (1_500_000_000, "1500ms"), (30_000_000_000, "30s"), (250_000, "250us"),
    (7, "7ns"),
])
def test_format_ns(ns, text):
    assert format_ns(ns) == text
