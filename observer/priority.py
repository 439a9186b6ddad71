"""Boat-distance priority for the process noise (the paper's closing remark)."""

from __future__ import annotations

import math


def boat_priority_q(
    base_q_per_s: float,
    distance_to_boat_m: float,
    *,
    near_m: float = 300.0,
    far_m: float = 1500.0,
    gain: float = 4.0,
) -> float:
    """Process-noise intensity that rises as the boat gets closer to an iceberg.

    ``q = base * (1 + gain * clamp((far - d) / (far - near), 0, 1))``

    so ``q = base`` at ``d >= far_m``, ``q = base * (1 + gain)`` at ``d <= near_m``, and linear
    in between: a nearer iceberg's uncertainty grows faster, so the planner visits it sooner.
    The result is non-increasing in ``d``.

    Raises:
        ValueError: naming the argument, for negative or non-finite values or near >= far.
    """
    for name, value in (
        ("base_q_per_s", base_q_per_s),
        ("distance_to_boat_m", distance_to_boat_m),
        ("near_m", near_m),
        ("far_m", far_m),
        ("gain", gain),
    ):
        if not math.isfinite(value) or value < 0.0:
            raise ValueError(f"boat_priority_q: {name} must be finite and >= 0, got {value!r}")
    if not near_m < far_m:
        raise ValueError(f"boat_priority_q: near_m ({near_m}) must be < far_m ({far_m})")
    w = min(max((far_m - distance_to_boat_m) / (far_m - near_m), 0.0), 1.0)
    return base_q_per_s * (1.0 + gain * w)
