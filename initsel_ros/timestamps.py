"""Exact timestamps: decimal-second text and ROS ``sec``/``nanosec`` pairs as integer nanoseconds
(the one home of these conversions: datasets, the status record and the node's messages).

Datasets store time either as decimal seconds in text (TUM ``1341839327.392692``, KITTI
``1.036205e-01``) or as integer nanoseconds (EuRoC, bag headers). Both are kept here as Python
integers, so a stamp reaches a published header without a float round trip.
"""

from __future__ import annotations

import decimal

from initsel_ros.errors import DatasetError

NS_PER_S = 1_000_000_000


def parse_seconds_ns(text: str) -> int:
    """Decimal seconds (``'1341839327.392692'``, ``'1.036205e-01'``) -> integer nanoseconds.

    Parsed as a decimal, so ``1341839327.392692`` is exactly ``1341839327392692000``; digits below
    one nanosecond are rounded half to even.

    Raises:
        DatasetError: not a finite number.
    """
    try:
        value = decimal.Decimal(text.strip())
    except decimal.InvalidOperation as exc:
        raise DatasetError(f'{text!r} is not a number') from exc
    if not value.is_finite():
        raise DatasetError(f'non-finite time {text!r}')
    return int((value * NS_PER_S).to_integral_value(rounding=decimal.ROUND_HALF_EVEN))


def stamp_ns(sec: int, nanosec: int) -> int:
    """A ``builtin_interfaces/Time`` (or ROS 1 ``time``) as integer nanoseconds, exactly."""
    return int(sec) * NS_PER_S + int(nanosec)


def split_ns(ns: int) -> tuple[int, int]:
    """Integer nanoseconds -> ``(sec, nanosec)`` with ``0 <= nanosec < 1e9`` (floor division)."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return sec, nanosec


def seconds_to_ns(seconds: float) -> int:
    """Float seconds -> integer nanoseconds, rounded (a float already lost what text keeps:
    parse decimal text with :func:`parse_seconds_ns`)."""
    return round(float(seconds) * 1e9)


def ns_to_seconds(ns: int) -> float:
    """Integer nanoseconds -> float seconds (for timing and interpolation only)."""
    sec, nanosec = split_ns(ns)
    return sec + nanosec * 1e-9


__all__ = [
    'NS_PER_S',
    'ns_to_seconds',
    'parse_seconds_ns',
    'seconds_to_ns',
    'split_ns',
    'stamp_ns',
]
