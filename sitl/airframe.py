"""Point-mass fixed-wing airframe: lateral motion by world.dynamics (eq. 1, exact arcs),
altitude as a first-order climb at a bounded rate, airspeed as a bounded acceleration.

    h' = clamp(k_h (h_cmd - h), -sink_max, climb_max)      (k_h = 0.5 1/s)
    V' = clamp(k_v (V_cmd - V), -a_max, a_max)

A glide (a pilot mode with the throttle closed and the sticks centred: no RC input) flies
wings level at the commanded airspeed and sinks at ``V / GLIDE_RATIO`` (about 2.2 m/s for
an X8 at 22 m/s). Ground contact: when the altitude (above home; flat ground, no terrain)
reaches 0 while descending, the aircraft stops there (``on_ground``, speed 0) and
``touchdown_sink_m_s`` records the sink rate at impact.

Roll for ATTITUDE is the coordinated-turn bank angle ``phi = atan(-V u / g)`` (right wing
down positive; u is counter-clockwise positive).

Wind: ``speed_m_s`` is the airspeed and ``heading_rad`` the air heading (yaw); the ground
velocity is the air vector plus the drift ``d``, and guidance is given the wind::

    v_g = V (cos psi, sin psi) + d,     d = min(1, V / V_to) w     (0 on the ground)

``d`` is the wind ``w`` once the aircraft flies; below the take-off airspeed ``V_to``
(the first seconds of a take-off, which starts at V = 0) the launcher or the wheels still
hold it, so the wind carries it only in proportion (a plane does not blow backwards off
the runway).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

from world.dynamics import (
    LoiterCommand,
    UavState,
    step_pose,
    turn_rate_to_circle,
    turn_rate_to_point,
)

__all__ = ["GLIDE", "GROUND", "STRAIGHT", "Airframe", "Guidance"]

GRAVITY_M_S2 = 9.80665
CLIMB_MAX_M_S = 5.0
SINK_MAX_M_S = 5.0
_ALT_GAIN_PER_S = 0.5
_ACCEL_MAX_M_S2 = 2.0
GLIDE_RATIO = 10.0
TAKEOFF_AIRSPEED_M_S = 10.0
_CALM = (0.0, 0.0)


@dataclass(frozen=True)
class Guidance:
    """What the autopilot asks the airframe to do: ``kind`` is 'ground', 'straight',
    'glide', 'point' or 'loiter' (then ``radius_m`` is the flown radius, ``clockwise`` its
    sense)."""

    kind: str
    x_m: float = 0.0
    y_m: float = 0.0
    radius_m: float = 0.0
    clockwise: bool = True

    @cached_property
    def circle(self) -> LoiterCommand:
        """The circle of a 'loiter' guidance, built once per guidance (it is immutable; the
        autopilot hands the airframe the same one step after step while its target holds)."""
        return LoiterCommand(self.x_m, self.y_m, self.radius_m, self.clockwise)


GROUND = Guidance("ground")
GLIDE = Guidance("glide")
STRAIGHT = Guidance("straight")
"""The guidance kinds without a target, built once (a Guidance is immutable)."""


@dataclass
class Airframe:
    """Kinematic state of one aircraft in the local ENU frame (alt relative to home)."""

    x_m: float
    y_m: float
    heading_rad: float
    speed_m_s: float
    alt_m: float
    min_turn_radius_m: float
    on_ground: bool = True
    climb_m_s: float = 0.0
    turn_rate_rad_s: float = 0.0
    touchdown_sink_m_s: float | None = None
    drift_xy_m_s: tuple[float, float] = _CALM
    """What the wind added to the ground velocity in the last step (``d`` above)."""

    def step(
        self,
        guidance: Guidance,
        alt_cmd_m: float,
        speed_cmd_m_s: float,
        dt_s: float,
        wind_xy_m_s: tuple[float, float] = _CALM,
    ) -> None:
        """Advance by ``dt_s`` following ``guidance`` in the ENU wind ``wind_xy_m_s``."""
        if guidance.kind == "ground":
            self.speed_m_s = 0.0
            self.climb_m_s = 0.0
            self.turn_rate_rad_s = 0.0
            self.drift_xy_m_s = _CALM
            return
        self.on_ground = False
        dv = max(
            -_ACCEL_MAX_M_S2 * dt_s, min(_ACCEL_MAX_M_S2 * dt_s, speed_cmd_m_s - self.speed_m_s)
        )
        self.speed_m_s = max(0.1, self.speed_m_s + dv)
        wind = wind_xy_m_s
        if wind != _CALM and self.speed_m_s < TAKEOFF_AIRSPEED_M_S:
            share = self.speed_m_s / TAKEOFF_AIRSPEED_M_S
            wind = (share * wind[0], share * wind[1])
        state = UavState(self.x_m, self.y_m, self.heading_rad, self.speed_m_s)
        r_min = self.min_turn_radius_m
        if guidance.kind == "point":
            u = turn_rate_to_point(state, guidance.x_m, guidance.y_m, r_min, wind_xy_m_s=wind)
        elif guidance.kind == "loiter":
            u = turn_rate_to_circle(state, guidance.circle, r_min, wind_xy_m_s=wind)
        else:
            u = 0.0
        self.x_m, self.y_m, self.heading_rad = step_pose(
            self.x_m, self.y_m, self.heading_rad, self.speed_m_s, u, dt_s, wind)
        self.turn_rate_rad_s = u
        self.drift_xy_m_s = wind
        if guidance.kind == "glide":
            climb = -self.speed_m_s / GLIDE_RATIO
        else:
            climb = max(
                -SINK_MAX_M_S, min(CLIMB_MAX_M_S, _ALT_GAIN_PER_S * (alt_cmd_m - self.alt_m))
            )
        self.alt_m += climb * dt_s
        self.climb_m_s = climb
        if self.alt_m <= 0.0 and climb < 0.0:  # ground contact: the aircraft stops there
            self.touchdown_sink_m_s = -climb
            self.alt_m = 0.0
            self.on_ground = True
            self.speed_m_s = 0.0
            self.climb_m_s = 0.0
            self.turn_rate_rad_s = 0.0
            self.drift_xy_m_s = _CALM

    @property
    def ground_velocity_m_s(self) -> tuple[float, float]:
        """(east, north) ground velocity: ``V (cos psi, sin psi) + d``."""
        v, psi = self.speed_m_s, self.heading_rad
        dx, dy = self.drift_xy_m_s
        return v * math.cos(psi) + dx, v * math.sin(psi) + dy

    @property
    def ground_speed_m_s(self) -> float:
        """|v_g| (the airspeed itself in still air)."""
        if self.drift_xy_m_s == _CALM:
            return self.speed_m_s
        return math.hypot(*self.ground_velocity_m_s)

    @property
    def course_rad(self) -> float:
        """ENU direction of the ground velocity (the heading in still air or when the
        aircraft barely moves over ground)."""
        if self.drift_xy_m_s == _CALM:
            return self.heading_rad
        vx, vy = self.ground_velocity_m_s
        if math.hypot(vx, vy) < 0.1:
            return self.heading_rad
        return math.atan2(vy, vx)

    @property
    def roll_rad(self) -> float:
        """Coordinated-turn bank angle, right wing down positive (aviation convention):
        a clockwise (right) turn has ENU turn rate u < 0, so phi = atan(-V u / g)."""
        return math.atan(-self.speed_m_s * self.turn_rate_rad_s / GRAVITY_M_S2)

    def distance_to_m(self, x_m: float, y_m: float) -> float:
        """Horizontal distance to a point."""
        return math.hypot(x_m - self.x_m, y_m - self.y_m)
