"""The ship watch's figures in ``metrics.json`` (``gcs simulate`` and ``gcs run`` alike).

* ``hourly_mean_uncertainty``: the mean of the run's per-second mean sigma over each hour
  (the last, partial hour included when it holds at least a quarter of an hour);
* ``vehicles_lost``: planes that fell (battery empty) or came down away from the ship;
* ``min_landing_battery_pct``: the lowest charge a recovered plane came home with;
* ``rtl_end_distance_to_ship_m``: ``{median, max}`` over the returns, of the distance from
  where each ended to the ship's true position then (the frontend measures it);
* ``on_station_shortfall_s``: mission seconds with fewer vehicles in the plan than the
  watch plans on station (sampled once a second);
* ``reliefs``: vehicles sent home because their relief had joined, and ``launches``.
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from groundstation.core.watch import WatchView

__all__ = ["WatchMetrics", "hourly_means"]

HOUR_S = 3600.0


def hourly_means(series: Sequence[Sequence[float]]) -> list[float]:
    """Mean of ``[t_s, value]`` samples per hour ``[k h, (k + 1) h)``; a last partial hour
    counts if it spans at least 15 minutes of samples."""
    buckets: dict[int, list[float]] = {}
    for t_s, value in series:
        buckets.setdefault(int(t_s // HOUR_S), []).append(value)
    out: list[float] = []
    for k in sorted(buckets):
        values = buckets[k]
        if len(values) >= 900 or k == 0:
            out.append(statistics.fmean(values))
    return out


@dataclass
class WatchMetrics:
    """Accumulates the watch's figures (module docstring)."""

    shortfall_s: float = 0.0
    lost: list[str] = field(default_factory=list)
    landing_battery_pct: list[float] = field(default_factory=list)
    return_end_m: list[float] = field(default_factory=list)
    reliefs: int = 0
    launches: int = 0

    def sample(self, view: WatchView | None, period_s: float = 1.0) -> None:
        """Once a mission second."""
        if view is None:
            return
        if view.on_station < view.planned_on_station:
            self.shortfall_s += period_s
        self.reliefs = view.reliefs

    def vehicle_lost(self, vehicle: str) -> None:
        self.lost.append(vehicle)

    def landing(self, battery_pct: float, return_end_m: float | None) -> None:
        self.landing_battery_pct.append(battery_pct)
        if return_end_m is not None:
            self.return_end_m.append(return_end_m)

    def to_dict(self, series: Sequence[Sequence[float]]) -> dict[str, Any]:
        ends = self.return_end_m
        return {
            "hourly_mean_uncertainty": hourly_means(series),
            "vehicles_lost": len(self.lost),
            "min_landing_battery_pct": min(self.landing_battery_pct)
            if self.landing_battery_pct else None,
            "rtl_end_distance_to_ship_m": {
                "median": statistics.median(ends) if ends else None,
                "max": max(ends) if ends else None,
                "count": len(ends),
            },
            "on_station_shortfall_s": self.shortfall_s,
            "reliefs": self.reliefs,
            "launches": self.launches,
        }
