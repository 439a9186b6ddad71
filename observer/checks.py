"""Argument checks shared by the observer's modules (one-line ValueErrors naming the
argument)."""

from __future__ import annotations

import math
import numbers

__all__ = ["finite_number", "is_finite_number"]


def is_finite_number(value: object) -> bool:
    """A real number (not a bool) that is finite (a float is checked first: the
    ``numbers.Real`` check is an ABC's, several times slower, and every float passes it)."""
    if type(value) is float:
        return math.isfinite(value)
    return (isinstance(value, numbers.Real) and not isinstance(value, bool)
            and math.isfinite(float(value)))


def finite_number(name: str, value: object) -> float:
    """``value`` as a float if it is a real number (not a bool) and finite; else ValueError
    naming ``name`` (a float first, as in :func:`is_finite_number`)."""
    if type(value) is float and math.isfinite(value):
        return value
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v
