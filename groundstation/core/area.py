"""The operating area: a circle of ``operating_radius_m`` around home (the mission origin)
or around the boat. Waypoints outside it are clipped onto its edge along the line from the
centre, ``p' = c + (p - c) r / |p - c|``; targets (and prior entries) outside it are
refused and camera detections outside it dropped, before they reach the core.

The rule is defined here once for every frontend: the daemon (``gcs run``: its configured
``operating_radius_m``, 10 km by default, around home or the boat) and ``gcs simulate``
(``SimulationOptions.operating_radius_m``; none by default: the scenario's world is the
area) apply it; ``gcs replay`` feeds the journalled inputs, which it already filtered."""

from __future__ import annotations

import math

__all__ = ["OperatingArea"]


class OperatingArea:
    """``radius_m`` None: no area (everything is inside). :attr:`boat_xy_m` is where the
    boat is (None while unknown: the centre is home)."""

    def __init__(self, radius_m: float | None, around_boat: bool) -> None:
        self.radius_m = radius_m
        self.around_boat = around_boat
        self.boat_xy_m: tuple[float, float] | None = None

    def center(self) -> tuple[float, float]:
        """The centre (local ENU metres)."""
        boat = self.boat_xy_m if self.around_boat else None
        return boat if boat is not None else (0.0, 0.0)

    def contains(self, x_m: float, y_m: float) -> bool:
        if self.radius_m is None:
            return True
        cx, cy = self.center()
        return math.hypot(x_m - cx, y_m - cy) <= self.radius_m

    def clip(self, x_m: float, y_m: float) -> tuple[float, float, bool]:
        """The point moved onto the edge if it lies outside; (x, y, clipped)."""
        if self.radius_m is None:
            return x_m, y_m, False
        cx, cy = self.center()
        d = math.hypot(x_m - cx, y_m - cy)
        if d <= self.radius_m:
            return x_m, y_m, False
        k = self.radius_m / d
        return cx + (x_m - cx) * k, cy + (y_m - cy) * k, True
