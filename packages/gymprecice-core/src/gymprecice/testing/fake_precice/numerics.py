"""preCICE's tolerant comparisons of times, and numbers as its log prints them."""

from __future__ import annotations

NUMERICAL_ZERO = 1e-14


def equals(a: float, b: float) -> bool:
    return abs(a - b) <= NUMERICAL_ZERO


def greater(a: float, b: float) -> bool:
    return a - b > NUMERICAL_ZERO


def greater_equals(a: float, b: float) -> bool:
    return a - b >= -NUMERICAL_ZERO


def num(value: float) -> str:
    """A number as preCICE's log (fmt) prints it: shortest round-trip form, no ``.0``."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def smaller(a: float, b: float) -> bool:
    return a - b < -NUMERICAL_ZERO
