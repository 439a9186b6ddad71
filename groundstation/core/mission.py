"""What a :class:`~groundstation.core.commands.FlyToTarget` means as a flight, for every
body that flies it: ArduPlane's uploaded mission (``vehicle/jobs.py``) and the offline
simulator's UAV (``runners/simulate/vehicle.py``).

* ``loiter_s >= 1``: a timed loiter of ``round(loiter_s)`` whole seconds (``NAV_LOITER_TIME``
  takes whole seconds) on the circle of ``loiter_radius_m`` around the aim point; the timer
  starts on reaching the circle, and its end is the ``LoiterEnded`` the core hears;
* ``loiter_s < 1``: the paper's pass-over: fly to the aim point itself (a waypoint);
  arriving ends the leg;
* a pass with ``through`` cells (``core/route.py``) flies on through each of them as a
  plain waypoint (``NAV_WAYPOINT``: reached within ``WP_RADIUS`` or on passing the line
  normal to the leg); reaching the last one ends the leg;
* then hold: circle the last point for ever (``NAV_LOITER_UNLIM``) until the next command.
"""

from __future__ import annotations

from dataclasses import dataclass

from groundstation.core.commands import FlyToTarget

__all__ = ["MIN_LOITER_S", "ROUTE_POINTS_MAX", "TargetMission", "target_mission"]

ROUTE_POINTS_MAX = 3
"""The most points a pass flies through after its aim point (``CoreConfig.route_cells``
is at most this). A routing core sends always ``route_cells`` of them, the last point
repeated when there are fewer (ArduPlane reaches it at once, within ``WP_RADIUS``), so
the mission's length never changes between uploads (``core/route.py``)."""

MIN_LOITER_S = 1.0
"""The shortest timed loiter; a shorter one is a pass over the aim point."""


@dataclass(frozen=True)
class TargetMission:
    """The flight of one ``FlyToTarget`` (module docstring); ``loiter_s`` 0 is a pass."""

    target: str
    x_m: float
    y_m: float
    loiter_s: int
    loiter_radius_m: float
    through: tuple[tuple[float, float], ...] = ()
    """The centres (m) of the cells a pass flies through after the aim point (empty when
    the visit loiters)."""

    @property
    def pass_over(self) -> bool:
        return self.loiter_s == 0

    @property
    def end_xy_m(self) -> tuple[float, float]:
        """Where the flight ends and holds: the last cell flown through, else the aim."""
        return self.through[-1] if self.through else (self.x_m, self.y_m)


def target_mission(command: FlyToTarget, aim_xy_m: tuple[float, float] | None = None,
                   loiter_radius_m: float | None = None) -> TargetMission:
    """The flight ``command`` asks for; ``aim_xy_m`` (the aim point clipped into the
    operating area) and ``loiter_radius_m`` (the vehicle's own) replace the command's."""
    x_m, y_m = aim_xy_m if aim_xy_m is not None else (command.x_m, command.y_m)
    radius = command.loiter_radius_m if loiter_radius_m is None else loiter_radius_m
    loiter_s = round(command.loiter_s) if command.loiter_s >= MIN_LOITER_S else 0
    through = tuple((c.x_m, c.y_m) for c in command.through) if loiter_s == 0 else ()
    return TargetMission(command.target, x_m, y_m, loiter_s, radius, through)
