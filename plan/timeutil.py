"""Exact conversions between user-facing times/rates and integer nanoseconds (no floats)."""

from __future__ import annotations

import re
from decimal import Decimal, InvalidOperation
from fractions import Fraction

NS_PER_S = 1_000_000_000
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


def rate_to_period_ns(rate_hz: object) -> int:
    """The period of a rate in Hz as whole nanoseconds; refuses rates whose period is fractional."""
    rate = _exact(rate_hz)
    if rate <= 0:
        raise ValueError(f"{rate_hz!r} Hz must be greater than zero")
    period = NS_PER_S / rate
    if period.denominator != 1:
        raise ValueError(f"{rate_hz!r} Hz has a period of {float(period):.3f} ns, not a whole "
                         f"number of nanoseconds; rates near it that fit: "
                         f"{', '.join(nearby_whole_rates(rate))} Hz")
    return int(period)


def nearby_whole_rates(rate: Fraction, count: int = 2) -> list[str]:
    """Rates in Hz near ``rate`` whose period is a whole number of ns, as decimal text.

    Those are the divisors of 1e9 (1, 2, 4, 5, 8, 10, ...) and their reciprocals (0.5, 0.25, ...).
    """
    divisors = [2**i * 5**j for i in range(10) for j in range(10)]
    small = {Fraction(1, d) for d in divisors if d <= 1000}
    rates = sorted({Fraction(d) for d in divisors} | small)
    below = [r for r in rates if r < rate][-count:]
    above = [r for r in rates if r > rate][:count]
    return [exact_rate_text(r) for r in below + above]


def exact_rate_text(value: Fraction) -> str:
    """The exact decimal text of a rate whose denominator is 2**a * 5**b ('0.25', '40')."""
    if value.denominator == 1:
        return str(value.numerator)
    return format(Decimal(value.numerator) / Decimal(value.denominator), "f")


def format_ns(ns: int) -> str:
    """A duration in ns as text in the largest unit that divides it ('10ms', '1500ms')."""
    for unit in ("s", "ms", "us"):
        scale = _UNITS[unit]
        if ns % scale == 0:
            return f"{ns // scale}{unit}"
    for unit in ("s", "ms", "us"):
        if ns >= _UNITS[unit]:
            return f"{Decimal(ns) / Decimal(_UNITS[unit]):f}{unit}"
    return f"{ns}ns"


def format_rate(period_ns: int) -> str:
    """The rate in Hz of a period, as text ('100', '33.3333')."""
    rate = Fraction(NS_PER_S, period_ns)
    if rate.denominator == 1:
        return str(rate.numerator)
    return f"{float(rate):.4g}"
