"""The operating area: a circle of ``operating_radius_m`` around home (the mission origin)
or around the boat. Targets (and prior entries) outside it are refused and camera
detections outside it dropped, before they reach the core. A waypoint may be kept a band
``b`` inside its edge (``gcs run``: the band that keeps a loiter inside the area's geofence,
``mavlink/fence_items.py`` ``keep_in_m``; none in ``gcs simulate``): one farther than
``w = r - b`` from the centre ``c`` is clipped onto that circle along the line from the
centre, ``p' = c + (p - c) w / |p - c|``; a band as wide as the area leaves the centre.

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

    def clip(self, x_m: float, y_m: float, keep_in_m: float = 0.0
             ) -> tuple[float, float, bool]:
        """The point moved onto the circle ``keep_in_m`` inside the edge if it lies beyond
        it (module docstring); (x, y, clipped)."""
        if self.radius_m is None:
            return x_m, y_m, False
        w_m = max(0.0, self.radius_m - keep_in_m)
        cx, cy = self.center()
        d = math.hypot(x_m - cx, y_m - cy)
        if d <= w_m:
            return x_m, y_m, False
        k = w_m / d
        return cx + (x_m - cx) * k, cy + (y_m - cy) * k, True
