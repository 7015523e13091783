"""Exact conversions between user-facing times/rates and nanoseconds (no floats).

Periods and the tick are exact: an int number of ns, or a Fraction where they are not
whole (30 Hz). The time of tick ``k`` is ``tick_time_ns``: rounded to whole ns once."""

from __future__ import annotations

import math
import re
from decimal import Decimal, InvalidOperation
from fractions import Fraction

NS_PER_S = 1_000_000_000
Ns = int | Fraction
"""An exact time in ns: an int, or a Fraction where a period is not whole (30 Hz)."""
_UNITS = {"s": NS_PER_S, "ms": 1_000_000, "us": 1_000, "ns": 1}
_DURATION = re.compile(r"^\s*([+-]?[0-9]*\.?[0-9]+)\s*(s|ms|us|ns)?\s*$")


def _exact(value: object) -> Fraction:
    """A YAML number (int, float or numeric string) as an exact fraction of its decimal text."""
    if isinstance(value, bool):
        raise ValueError("a boolean is not a number")
    if isinstance(value, int):
        return Fraction(value)
    try:
        number = Decimal(str(value))
    except (InvalidOperation, ValueError) as exc:
        raise ValueError(f"{value!r} is not a number") from exc
    if not number.is_finite():
        raise ValueError(f"{value!r} is not a finite number")
    return Fraction(number)


def parse_duration_ns(value: object) -> int:
    """Parse '30s', '10ms', '250us', '100ns' or a plain number of seconds into whole nanoseconds."""
    if isinstance(value, str):
        match = _DURATION.match(value)
        if not match:
            raise ValueError(f"{value!r} is not a duration like '30s', '10ms', '250us' or '100ns'")
        amount, unit = _exact(match.group(1)), _UNITS[match.group(2) or "s"]
    else:
        amount, unit = _exact(value), NS_PER_S
    ns = amount * unit
    if ns.denominator != 1:
        raise ValueError(f"{value!r} is not a whole number of nanoseconds")
    if ns <= 0:
        raise ValueError(f"{value!r} must be greater than zero")
    return int(ns)


def rate_to_period_ns(rate_hz: object) -> Ns:
    """The exact period of a rate in Hz in ns: an int when whole (50 Hz: 20000000), else a
    Fraction (30 Hz: 100000000/3); the schedule counts it in ticks, never rounded."""
    rate = _exact(rate_hz)
    if rate <= 0:
        raise ValueError(f"{rate_hz!r} Hz must be greater than zero")
    period = NS_PER_S / rate
    if period < 1:
        raise ValueError(f"{rate_hz!r} Hz has a period shorter than 1 ns; rates up to "
                         f"{NS_PER_S} Hz fit")
    return exact_ns(period)


def exact_ns(value: Fraction | int) -> Ns:
    """A time in ns as an int when it is whole, else as its exact Fraction."""
    value = Fraction(value)
    return value.numerator if value.denominator == 1 else value


def gcd_ns(values: list[Ns]) -> Ns:
    """The greatest common divisor of exact times in ns (the longest tick that divides each)."""
    den = math.lcm(*(Fraction(v).denominator for v in values))
    return exact_ns(Fraction(math.gcd(*(int(v * den) for v in values)), den))


def tick_time_ns(tick: int, tick_ns: Ns) -> int:
    """The time of tick ``tick`` in whole ns: ``tick * tick_ns`` rounded half up, once, in
    integer arithmetic. Exact (no rounding) when the tick is a whole number of ns. Every
    /clock value, header stamp and bag time comes from here, so they agree in every process.
    """
    if type(tick_ns) is int:  # the common case, at every tick: no Fraction made
        return tick * tick_ns
    t = Fraction(tick_ns)
    return (2 * tick * t.numerator + t.denominator) // (2 * t.denominator)


def tick_at_ns(ns: int, tick_ns: Ns) -> int:
    """The last tick whose time (``tick_time_ns``) is at or before ``ns``: the inverse of
    ``tick_time_ns`` on its values, and ``ns // tick_ns`` for a whole-ns tick."""
    if type(tick_ns) is int:
        return ns // tick_ns
    t = Fraction(tick_ns)
    # tick_time_ns(k) <= ns  <=>  k * t < ns + 1/2: the largest such k, with integers only
    return -(-(2 * ns + 1) * t.denominator // (2 * t.numerator)) - 1


def tick_text(tick_ns: Ns) -> int | str:
    """The tick as JSON holds it (manifest, foreign gate): an int, or 'numerator/denominator'."""
    t = exact_ns(tick_ns)
    return t if isinstance(t, int) else f"{t.numerator}/{t.denominator}"


def parse_tick_ns(value: int | str) -> Ns:
    """The tick that ``tick_text`` wrote (an int, or 'numerator/denominator' ns)."""
    return exact_ns(Fraction(str(value)))


def exact_rate_text(value: Fraction) -> str:
    """The exact decimal text of a rate whose denominator is 2**a * 5**b ('0.25', '40')."""
    if value.denominator == 1:
        return str(value.numerator)
    return format(Decimal(value.numerator) / Decimal(value.denominator), "f")


def format_ns(ns: Ns) -> str:
    """A duration in ns as text in the largest unit that divides it ('10ms', '1500ms'); a
    fractional one as an exact fraction of a second ('1/30s')."""
    if isinstance(ns, Fraction) and ns.denominator != 1:
        return f"{ns / NS_PER_S}s"
    for unit in ("s", "ms", "us"):
        scale = _UNITS[unit]
        if ns % scale == 0:
            return f"{ns // scale}{unit}"
    for unit in ("s", "ms", "us"):
        if ns >= _UNITS[unit]:
            return f"{Decimal(ns) / Decimal(_UNITS[unit]):f}{unit}"
    return f"{ns}ns"


def format_rate(period_ns: Ns) -> str:
    """The rate in Hz of a period, as text ('100', '33.3333')."""
    rate = Fraction(NS_PER_S, period_ns)
    if rate.denominator == 1:
        return str(rate.numerator)
    return f"{float(rate):.4g}"


def divides_rate(slow_hz: int, period_ns) -> bool:
    """Whether ``slow_hz`` is the rate of a node of period ``period_ns`` divided by a whole
    n >= 1 (its period a whole multiple of ``period_ns``: a controller manager run in the
    physics step every n-th activation)."""
    if slow_hz <= 0:
        return False
    ratio = Fraction(NS_PER_S, slow_hz) / Fraction(period_ns)
    return ratio.denominator == 1 and ratio >= 1


def whole_divisions(hz, count: int = 6) -> str:
    """The first ``count`` whole rates ``hz`` / n, n = 1, 2, ... ('500, 250, 125, 100, 50,
    25 Hz'): the rates a controller manager in a node of rate ``hz`` may have."""
    hz = Fraction(hz)
    rates = [hz / n for n in range(1, 10_000) if (hz / n).denominator == 1][:count]
    return ", ".join(str(int(r)) for r in rates) + " Hz" if rates else "none whole"
