"""When each vehicle on station should go home, so that returns are staggered.

Vehicles launched together would all reach their turn-home time together, and the watch
would lose its whole fleet at once. With ``K`` on station and a usable flight of
``E_use = endurance_s * (1 - reserve / 100)``, one relief every

    S = E_use / K

keeps the returns evenly spaced. Sorted by their energy's turn-home times ``D_1 <= ... <=
D_K``, the planned returns are taken backwards from the last:

    R_K = D_K,   R_i = min(D_i, R_{i+1} - S)

so no vehicle returns later than its energy allows, and each earlier one returns at least
``S`` before the next. A planned return before ``D_i`` is an *early* return: it only
happens when a spare is there to take the vehicle's place; without one the vehicle stays
until ``D_i`` ("unless nothing else is possible").
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["relief_spacing_s", "staggered_returns"]


def relief_spacing_s(endurance_s: float, reserve_pct: float, on_station: int) -> float:
    """``S = endurance_s * (1 - reserve / 100) / K`` (module docstring)."""
    return endurance_s * (1.0 - reserve_pct / 100.0) / max(1, on_station)


def staggered_returns(due_s: Mapping[str, float], spacing_s: float) -> dict[str, float]:
    """Each vehicle's planned return ``R_i`` from its turn-home time ``D_i`` (module
    docstring); ties broken by vehicle id, so every frontend plans alike."""
    order = sorted(due_s, key=lambda v: (due_s[v], v))
    out: dict[str, float] = {}
    later: float | None = None
    for vehicle in reversed(order):
        r = due_s[vehicle] if later is None else min(due_s[vehicle], later - spacing_s)
        out[vehicle] = r
        later = r
    return out
