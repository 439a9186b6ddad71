"""argparse value types shared by the subcommands (errors become one-line usage errors)."""

from __future__ import annotations

import argparse
import math

__all__ = ["positive_float"]


def positive_float(text: str) -> float:
    """A finite number > 0 (``--duration``, ``--speed``...)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value
