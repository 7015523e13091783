"""Exact conversions of durations and rates to integer nanoseconds: no float time anywhere."""

import json
from fractions import Fraction

import pytest
from hypothesis import given
from hypothesis import strategies as st

from plan.timeutil import (
    NS_PER_S,
    format_ns,
    gcd_ns,
    parse_duration_ns,
    parse_tick_ns,
    rate_to_period_ns,
    tick_at_ns,
    tick_text,
    tick_time_ns,
)


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


@pytest.mark.parametrize(("rate", "period"), [
    (30, Fraction(100_000_000, 3)),
    (15, Fraction(200_000_000, 3)),
    ("60", Fraction(50_000_000, 3)),
    (7, Fraction(1_000_000_000, 7)),
])
def test_rates_of_ros_sensors_have_exact_fractional_periods(rate, period):
    result = rate_to_period_ns(rate)
    assert result == period
    assert type(result) is Fraction


def test_rate_faster_than_a_nanosecond_refused():
    with pytest.raises(ValueError, match="shorter than 1 ns"):
        rate_to_period_ns(3_000_000_000)


def test_the_tick_of_30_hz_15_hz_and_50_hz_is_a_150th_of_a_second():
    tick = gcd_ns([rate_to_period_ns(r) for r in (50, 30, 15)])
    assert tick == Fraction(NS_PER_S, 150)
    assert gcd_ns([20_000_000, 100_000_000]) == 20_000_000
    assert type(gcd_ns([20_000_000, 100_000_000])) is int


def test_time_of_a_30_hz_tick_is_rounded_half_up_once():
    tick = rate_to_period_ns(30)
    assert [tick_time_ns(k, tick) for k in range(4)] == [0, 33_333_333, 66_666_667, 100_000_000]
    assert tick_time_ns(1, Fraction(3, 2)) == 2  # 1.5 ns: half up
    assert tick_time_ns(3, Fraction(1, 2)) == 2  # 1.5 ns again, from another tick


@given(st.integers(0, 10**15), st.integers(1, 10**12), st.integers(1, 10**6))
def test_tick_time_is_the_exact_time_rounded_half_up(k, num, den):
    tick = Fraction(num, den)
    exact = k * tick
    ns = tick_time_ns(k, tick)
    assert type(ns) is int
    assert exact - Fraction(1, 2) < ns <= exact + Fraction(1, 2)


@given(st.integers(0, 10**15), st.integers(1, 10**12))
def test_a_whole_ns_tick_is_not_rounded(k, tick):
    assert tick_time_ns(k, tick) == k * tick
    assert tick_at_ns(k * tick, tick) == k


@given(st.integers(0, 10**12), st.integers(1, 10**12), st.integers(1, 10**6))
def test_tick_at_is_the_last_tick_at_or_before(ns, num, den):
    tick = Fraction(num, den)
    if tick < 1:  # a tick shorter than 1 ns is refused when a scenario loads
        tick = 1 / tick
    k = tick_at_ns(ns, tick)
    assert tick_time_ns(k, tick) <= ns < tick_time_ns(k + 1, tick)
    assert tick_at_ns(tick_time_ns(k, tick), tick) == k


@pytest.mark.parametrize("tick", [20_000_000, Fraction(20_000_000, 3), Fraction(1_000_000_000, 7)])
def test_tick_as_json_text_and_back(tick):
    text = tick_text(tick)
    assert parse_tick_ns(json.loads(json.dumps(text))) == tick
    assert isinstance(text, int) == (Fraction(tick).denominator == 1)  # whole: as before


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
    (7, "7ns"), (Fraction(100_000_000, 3), "1/30s"), (Fraction(20_000_000, 3), "1/150s"),
])
def test_format_ns(ns, text):
    assert format_ns(ns) == text
