"""A UAV of the offline simulator, flying what the decision core commands.

It executes a :class:`FlyToTarget` as ``core/mission.py`` defines it, the way floe's
ArduPlane mission does (``NAV_LOITER_TIME`` over the aim point, then ``NAV_LOITER_UNLIM``
there):

* ``transit``: with a timed loiter, fly onto the loiter circle (vector field); the loiter
  timer starts on reaching the circle, as ArduPlane's does. On a pass (the paper's
  pass-over) fly to the point itself; arriving within ``arrival_radius_m`` ends it.
* ``loiter``: circle until the timer runs out; then the loiter has *ended* (an event).
* ``hold``: circle the point for ever (until the next command).

A released vehicle (operator override) or one sent home holds on a circle where it is or
over the launch point, and is no longer commanded.

It flies at constant airspeed in the wind it is given for each step, with ArduPlane-like
guidance that steers the ground course (crabbing, loiter circles round over ground:
:mod:`world.dynamics`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from groundstation.core.mission import TargetMission
from world.dynamics import (
    CALM,
    LoiterCommand,
    UavState,
    advance_pose,
    circle_turn_rate,
    distance_to_circle_m,
    point_turn_rate,
)

__all__ = ["OfflineVehicle"]

_ON_CIRCLE_TOLERANCE_M = 15.0


@dataclass
class OfflineVehicle:
    id: str
    state: UavState
    turn_radius_m: float
    arrival_radius_m: float = 30.0
    phase: str = "free"
    aim_xy_m: tuple[float, float] | None = None
    loiter_radius_m: float = 120.0
    loiter_s: float = 0.0
    loiter_end_s: float | None = None
    target: str | None = None
    commanded: bool = True
    lost: bool = False
    through: tuple[tuple[float, float], ...] = ()
    """The waypoints still to fly through after the aim point (``core/route.py``)."""

    def command_fly(self, mission: TargetMission) -> None:
        self.aim_xy_m = (mission.x_m, mission.y_m)
        self.through = mission.through
        self.loiter_s = float(mission.loiter_s)
        self.loiter_radius_m = mission.loiter_radius_m
        self.loiter_end_s = None
        self.target = mission.target
        self.phase = "transit"

    def command_hold(self, x_m: float, y_m: float, loiter_radius_m: float) -> None:
        """Circle (x, y) for ever: an unlimited loiter (release, RTL, no plan)."""
        self.aim_xy_m = (x_m, y_m)
        self.loiter_radius_m = loiter_radius_m
        self.phase = "hold"
        self.target = None
        self.through = ()

    def step(self, t_s: float, dt_s: float,
             wind_xy_m_s: tuple[float, float] = CALM) -> bool:
        """Advance by ``dt_s`` ending at ``t_s + dt_s`` in the wind ``wind_xy_m_s`` (ENU,
        constant over the step); True when a loiter (or pass) ended: a pass through
        waypoints ends at the last one, as ArduPlane's mission reaches its final loiter.

        The guidance and the kinematics are :mod:`world.dynamics`' on the bare pose
        (``point_turn_rate`` or ``circle_turn_rate``, then ``advance_pose``), sharing one
        ``cos psi, sin psi``: the same numbers as ``turn_rate_to_point`` /
        ``turn_rate_to_circle`` and ``step_kinematics`` on the state."""
        s = self.state
        x_m, y_m, psi, speed_m_s = s.x_m, s.y_m, s.heading_rad, s.speed_m_s
        cos_psi, sin_psi = math.cos(psi), math.sin(psi)
        aim = self.aim_xy_m
        passing = self.phase == "transit" and self.loiter_s <= 0.0
        if aim is None:
            rate = 0.0
        elif passing:
            rate = point_turn_rate(x_m, y_m, psi, cos_psi, sin_psi, speed_m_s, aim[0], aim[1],
                                   self.turn_radius_m, wind_xy_m_s)
        else:  # a clockwise loiter circle round the aim point
            rate = circle_turn_rate(x_m, y_m, psi, speed_m_s, aim[0], aim[1],
                                    self.loiter_radius_m, True, self.turn_radius_m,
                                    wind_xy_m_s)
        x_m, y_m, psi = advance_pose(x_m, y_m, psi, cos_psi, sin_psi, speed_m_s, rate, dt_s,
                                     wind_xy_m_s)
        self.state = UavState(x_m, y_m, psi, speed_m_s)
        if aim is None:
            return False
        ended = False
        t_next = t_s + dt_s
        if passing:
            if math.dist((x_m, y_m), aim) <= self.arrival_radius_m:
                here = (x_m, y_m)
                while self.through and math.dist(here, self.through[0]) <= (
                        self.arrival_radius_m):  # reached at once (a repeated point)
                    self.aim_xy_m, self.through = self.through[0], self.through[1:]
                if self.through:  # on to the next waypoint of the mission
                    self.aim_xy_m, self.through = self.through[0], self.through[1:]
                else:
                    self.phase, ended = "hold", True
        elif self.phase == "transit":
            circle = LoiterCommand(*aim, self.loiter_radius_m)
            if distance_to_circle_m(self.state, circle, self.turn_radius_m) <= (
                _ON_CIRCLE_TOLERANCE_M
            ):
                self.phase, self.loiter_end_s = "loiter", t_next + self.loiter_s
        elif self.phase == "loiter" and self.loiter_end_s is not None and (
            t_next >= self.loiter_end_s - 1e-9
        ):
            self.phase, ended = "hold", True
        return ended
