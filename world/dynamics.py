"""Fixed-wing UAV kinematics (the paper's eq. 1) and lateral guidance.

Kinematics, a Dubins car at constant airspeed ``V``::

    x' = V cos(psi),   y' = V sin(psi),   psi' = u,   |u| <= V / R_min

integrated exactly over a step of constant turn rate (a circular arc), so the step size does
not bend the flown path.

Guidance produces the turn rate ``u``:

* to a point: proportional heading control towards the bearing of the point, saturated at
  the maximum turn rate. That is the turn-then-straight Dubins path whenever the point lies
  outside the turning circle; a point inside the circle on the turning side cannot be
  reached by turning, so the aircraft flies straight until it can.
* on a circle (loiter): the vector field of Nelson et al. (2007). With ``d`` the distance to
  the centre, ``gamma`` the bearing from the centre to the aircraft and ``lam`` = +1 for
  counter-clockwise (-1 clockwise) circling, the commanded course is::

      chi_d = gamma + lam * (pi/2 + atan(k_orbit * (d - r) / r))

  which points at the centre far away and along the tangent on the circle; the turn rate
  adds the circle's own rate ``lam * V / d`` as feed-forward.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from domain.geodesy import wrap_pi

__all__ = [
    "LoiterCommand",
    "PointCommand",
    "UavState",
    "distance_to_circle_m",
    "max_turn_rate_rad_s",
    "step_kinematics",
    "turn_rate_to_circle",
    "turn_rate_to_point",
]

_HEADING_GAIN_PER_S = 2.0
_ORBIT_GAIN = 2.0


@dataclass(frozen=True)
class UavState:
    """Planar pose and airspeed of a UAV in the local ENU frame."""

    x_m: float
    y_m: float
    heading_rad: float
    speed_m_s: float


@dataclass(frozen=True)
class PointCommand:
    """Fly towards a point (pass over it)."""

    x_m: float
    y_m: float


@dataclass(frozen=True)
class LoiterCommand:
    """Circle a point at ``radius_m``; ``clockwise`` as seen from above."""

    x_m: float
    y_m: float
    radius_m: float
    clockwise: bool = True


def max_turn_rate_rad_s(speed_m_s: float, min_turn_radius_m: float) -> float:
    """u_max = V / R_min."""
    return speed_m_s / min_turn_radius_m


def step_kinematics(
    state: UavState,
    turn_rate_rad_s: float,
    dt_s: float,
    *,
    wind_xy_m_s: tuple[float, float] = (0.0, 0.0),
) -> UavState:
    """Advance eq. (1) by ``dt_s`` at constant ``turn_rate_rad_s`` (exact arc), drifted by
    ``wind_xy_m_s * dt_s`` (placeholder for wt/wind-sim's version)."""
    v = state.speed_m_s
    psi0 = state.heading_rad
    wx, wy = wind_xy_m_s
    # UavState(...) rather than dataclasses.replace: this runs every step of every UAV
    if abs(turn_rate_rad_s) < 1e-9:
        new = UavState(
            state.x_m + v * math.cos(psi0) * dt_s,
            state.y_m + v * math.sin(psi0) * dt_s,
            psi0,
            v,
        )
    else:
        psi1 = psi0 + turn_rate_rad_s * dt_s
        radius = v / turn_rate_rad_s
        new = UavState(
            state.x_m + radius * (math.sin(psi1) - math.sin(psi0)),
            state.y_m - radius * (math.cos(psi1) - math.cos(psi0)),
            wrap_pi(psi1),
            v,
        )
    if wx == 0.0 and wy == 0.0:
        return new
    return UavState(new.x_m + wx * dt_s, new.y_m + wy * dt_s, new.heading_rad, v)


def turn_rate_to_point(
    state: UavState,
    x_m: float,
    y_m: float,
    min_turn_radius_m: float,
    *,
    wind_xy_m_s: tuple[float, float] = (0.0, 0.0),
) -> float:
    """Saturated proportional turn rate towards a point (see module docstring);
    ``wind_xy_m_s`` is accepted and not yet used (placeholder for wt/wind-sim)."""
    u_max = max_turn_rate_rad_s(state.speed_m_s, min_turn_radius_m)
    dx, dy = x_m - state.x_m, y_m - state.y_m
    if math.hypot(dx, dy) < 1e-6:
        return 0.0
    err = wrap_pi(math.atan2(dy, dx) - state.heading_rad)
    side = 1.0 if err >= 0.0 else -1.0
    # centre of the turning circle on the side we would turn to
    cx = state.x_m - side * min_turn_radius_m * math.sin(state.heading_rad)
    cy = state.y_m + side * min_turn_radius_m * math.cos(state.heading_rad)
    if math.hypot(x_m - cx, y_m - cy) < min_turn_radius_m * 0.999 and abs(err) > 1e-3:
        return 0.0
    return max(-u_max, min(u_max, _HEADING_GAIN_PER_S * err))


def turn_rate_to_circle(
    state: UavState,
    command: LoiterCommand,
    min_turn_radius_m: float,
    *,
    wind_xy_m_s: tuple[float, float] = (0.0, 0.0),
) -> float:
    """Vector-field turn rate that converges onto the loiter circle; ``wind_xy_m_s`` is
    accepted and not yet used (placeholder for wt/wind-sim)."""
    u_max = max_turn_rate_rad_s(state.speed_m_s, min_turn_radius_m)
    radius = max(command.radius_m, min_turn_radius_m)
    lam = -1.0 if command.clockwise else 1.0
    dx, dy = state.x_m - command.x_m, state.y_m - command.y_m
    d = math.hypot(dx, dy)
    if d < 1e-6:
        return 0.0
    gamma = math.atan2(dy, dx)
    chi_d = gamma + lam * (math.pi / 2.0 + math.atan(_ORBIT_GAIN * (d - radius) / radius))
    err = wrap_pi(chi_d - state.heading_rad)
    feed_forward = lam * state.speed_m_s / max(d, radius)
    return max(-u_max, min(u_max, _HEADING_GAIN_PER_S * err + feed_forward))


def distance_to_circle_m(
    state: UavState, command: LoiterCommand, min_turn_radius_m: float
) -> float:
    """|d - r|: how far the aircraft is from the loiter circle it would fly."""
    radius = max(command.radius_m, min_turn_radius_m)
    return abs(math.hypot(state.x_m - command.x_m, state.y_m - command.y_m) - radius)
