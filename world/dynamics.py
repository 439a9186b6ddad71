"""Fixed-wing UAV kinematics in wind (the paper's eq. 1 plus the wind triangle) and lateral
guidance as ArduPlane's L1 controller flies it.

Kinematics, a Dubins car at constant *airspeed* ``V`` (TECS holds it) in the ENU wind
``w = (w_x, w_y)`` (the air moves towards it; :mod:`domain.wind_triangle`)::

    x' = V cos(psi) + w_x,   y' = V sin(psi) + w_y,   psi' = u,   |u| <= V / R_min

``psi`` is the air heading and ``u`` the air-relative turn rate, limited by the bank
angle: ``R_min`` is the still-air turn radius. For a step of constant ``u`` and constant
``w`` the motion is the air-relative circular arc plus the drift ``w dt``, integrated
exactly, so the step size does not bend the flown path::

    x1 = x0 + (V / u) (sin psi1 - sin psi0) + w_x dt,   psi1 = psi0 + u dt
    y1 = y0 - (V / u) (cos psi1 - cos psi0) + w_y dt

(straight when ``u = 0``). The ground velocity is ``v_g = V (cos psi, sin psi) + w`` and
the ground course ``chi = atan2(v_g)``.

Guidance produces ``u``, steering the *ground* course as L1 does, so the ground track goes
where it is sent and the aircraft crabs into the wind:

* to a point: the desired course is the bearing ``beta`` of the point, the desired heading
  its crab heading ``psi_d = beta + asin(w_perp / V)`` (``w_perp = w x u_beta``), and
  ``u = sat(k_psi wrap(psi_d - psi))``, saturated at the maximum turn rate. In still air
  that is the turn-then-straight Dubins path whenever the point lies outside the turning
  circle; a point inside the circle on the turning side cannot be reached by turning, so
  the aircraft flies straight until it can (the same test in wind: a heuristic there, the
  ground path of a turn being a trochoid).
* on a circle (loiter): the vector field of Nelson et al. (2007) on the ground course. With
  ``d`` the distance to the centre, ``gamma`` the bearing from the centre to the aircraft
  and ``lam`` = +1 for counter-clockwise (-1 clockwise) circling, the commanded course is::

      chi_d = gamma + lam * (pi/2 + atan(k_orbit * (d - r) / r))

  which points at the centre far away and along the tangent on the circle. The heading
  command is its crab heading ``psi_d``, and the turn rate adds the circle's own rate as
  feed-forward. Flying a ground circle of radius ``d`` at ground speed ``V_g`` needs the
  course rate ``chi' = lam V_g / d``; since ``psi = chi + asin(w_perp(chi) / V)`` and
  ``d w_perp / d chi = w_par``, ``d psi / d chi = V_g / a`` with ``a = sqrt(V^2 - w_perp^2)``
  the airspeed's share along the course, so::

      u = sat(k_psi wrap(psi_d - psi) + lam V_g^2 / (max(d, r) a)),   V_g = w_par + a

  (``w_par``, ``w_perp`` taken along ``chi_d``; in still air ``lam V / max(d, r)``). The
  flown ground circle stays round (ArduPlane's loiter corrects for wind the same way) and
  the bank varies round it; where the downwind side would need more than ``V / R_min``
  (``r < (V + |w|)^2 R_min / V^2``) the turn saturates and the circle bulges downwind.

Still air (``w = (0, 0)``, the default) runs exactly the still-air arithmetic, so calm runs
are bit for bit what they were before wind existed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

from domain.geodesy import wrap_pi
from domain.wind_triangle import crab_heading_rad

__all__ = [
    "CALM",
    "LoiterCommand",
    "PointCommand",
    "UavState",
    "advance_pose",
    "circle_turn_rate",
    "distance_to_circle_m",
    "ground_velocity_m_s",
    "max_turn_rate_rad_s",
    "point_turn_rate",
    "step_kinematics",
    "step_pose",
    "turn_rate_to_circle",
    "turn_rate_to_point",
]

_HEADING_GAIN_PER_S = 2.0
_ORBIT_GAIN = 2.0
_HALF_PI = math.pi / 2.0

CALM: tuple[float, float] = (0.0, 0.0)
"""Still air: the default wind of every function here."""


class UavState(NamedTuple):
    """Planar pose of a UAV in the local ENU frame: ``heading_rad`` is the air heading
    (where the nose points) and ``speed_m_s`` the airspeed; in wind the ground velocity is
    :func:`ground_velocity_m_s`. Immutable; a named tuple rather than a frozen dataclass
    because every step of every simulated UAV makes one (0.3 us against 0.85 us)."""

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


def _saturated(rate_rad_s: float, u_max: float) -> float:
    """``max(-u_max, min(u_max, rate_rad_s))`` by two comparisons, with the builtins' very
    choices (``min`` keeps ``u_max`` unless the rate is below it, ``max`` keeps ``-u_max``
    unless the result is above it; a NaN rate gives ``u_max``), at a third of their cost."""
    rate_rad_s = rate_rad_s if rate_rad_s < u_max else u_max
    return rate_rad_s if rate_rad_s > -u_max else -u_max


def max_turn_rate_rad_s(speed_m_s: float, min_turn_radius_m: float) -> float:
    """u_max = V / R_min."""
    return speed_m_s / min_turn_radius_m


def ground_velocity_m_s(
    state: UavState, wind_xy_m_s: tuple[float, float] = CALM
) -> tuple[float, float]:
    """v_g = V (cos psi, sin psi) + w."""
    return (state.speed_m_s * math.cos(state.heading_rad) + wind_xy_m_s[0],
            state.speed_m_s * math.sin(state.heading_rad) + wind_xy_m_s[1])


def step_kinematics(
    state: UavState,
    turn_rate_rad_s: float,
    dt_s: float,
    *,
    wind_xy_m_s: tuple[float, float] = CALM,
) -> UavState:
    """Advance by ``dt_s`` at constant ``turn_rate_rad_s`` in the constant wind
    ``wind_xy_m_s``: the exact air-relative arc plus ``w dt`` (module docstring)."""
    psi0 = state.heading_rad
    x1, y1, psi1 = advance_pose(state.x_m, state.y_m, psi0, math.cos(psi0), math.sin(psi0),
                                state.speed_m_s, turn_rate_rad_s, dt_s, wind_xy_m_s)
    # UavState(...) rather than dataclasses.replace: this runs every step of every UAV
    return UavState(x1, y1, psi1, state.speed_m_s)


def step_pose(
    x_m: float,
    y_m: float,
    heading_rad: float,
    speed_m_s: float,
    turn_rate_rad_s: float,
    dt_s: float,
    wind_xy_m_s: tuple[float, float] = CALM,
) -> tuple[float, float, float]:
    """:func:`step_kinematics` on a bare pose: ``(x_m, y_m, heading_rad)`` after ``dt_s``
    (for a caller that keeps its own state and need not build a UavState every step)."""
    return advance_pose(x_m, y_m, heading_rad, math.cos(heading_rad), math.sin(heading_rad),
                        speed_m_s, turn_rate_rad_s, dt_s, wind_xy_m_s)


def advance_pose(
    x_m: float,
    y_m: float,
    heading_rad: float,
    cos_heading: float,
    sin_heading: float,
    speed_m_s: float,
    turn_rate_rad_s: float,
    dt_s: float,
    wind_xy_m_s: tuple[float, float],
) -> tuple[float, float, float]:
    """:func:`step_pose` given ``cos_heading = cos(psi0)`` and ``sin_heading = sin(psi0)``,
    for a caller that has them already (guidance to a point takes them too:
    :func:`point_turn_rate`)::

        straight (|u| < 1e-9):  x1 = x0 + V cos(psi0) dt,  y1 = y0 + V sin(psi0) dt,  psi1 = psi0
        arc:                    psi1 = psi0 + u dt,  x1 = x0 + (V / u) (sin psi1 - sin psi0),
                                y1 = y0 - (V / u) (cos psi1 - cos psi0)

    then ``+ w dt`` on each axis unless the air is still, and ``psi1`` wrapped to [-pi, pi).
    """
    wx, wy = wind_xy_m_s
    drift_x, drift_y = (0.0, 0.0) if wx == 0.0 and wy == 0.0 else (wx * dt_s, wy * dt_s)
    if -1e-9 < turn_rate_rad_s < 1e-9:  # |u| < 1e-9
        x1 = x_m + speed_m_s * cos_heading * dt_s
        y1 = y_m + speed_m_s * sin_heading * dt_s
        if drift_x or drift_y:
            x1, y1 = x1 + drift_x, y1 + drift_y
        return x1, y1, heading_rad
    psi1 = heading_rad + turn_rate_rad_s * dt_s
    radius = speed_m_s / turn_rate_rad_s
    x1 = x_m + radius * (math.sin(psi1) - sin_heading)
    y1 = y_m - radius * (math.cos(psi1) - cos_heading)
    if drift_x or drift_y:
        x1, y1 = x1 + drift_x, y1 + drift_y
    return x1, y1, wrap_pi(psi1)


def turn_rate_to_point(
    state: UavState,
    x_m: float,
    y_m: float,
    min_turn_radius_m: float,
    *,
    wind_xy_m_s: tuple[float, float] = CALM,
) -> float:
    """Saturated proportional turn rate that points the ground course at a point, crabbing
    into ``wind_xy_m_s`` (see module docstring)."""
    psi = state.heading_rad
    return point_turn_rate(state.x_m, state.y_m, psi, math.cos(psi), math.sin(psi),
                           state.speed_m_s, x_m, y_m, min_turn_radius_m, wind_xy_m_s)


def point_turn_rate(
    x_m: float,
    y_m: float,
    heading_rad: float,
    cos_heading: float,
    sin_heading: float,
    speed_m_s: float,
    aim_x_m: float,
    aim_y_m: float,
    min_turn_radius_m: float,
    wind_xy_m_s: tuple[float, float],
) -> float:
    """:func:`turn_rate_to_point` on a bare pose, given ``cos_heading = cos(psi)`` and
    ``sin_heading = sin(psi)``::

        psi_d = crab(atan2(dy, dx)),  err = wrap(psi_d - psi),  u = sat(k_psi err)

    0 at the point itself (closer than 1e-6 m), and 0 (fly straight) while the point lies
    inside the turning circle on the side ``err`` turns to (centre
    ``(x, y) + side R_min (-sin psi, cos psi)``) and ``|err| > 1e-3``."""
    dx, dy = aim_x_m - x_m, aim_y_m - y_m
    if math.hypot(dx, dy) < 1e-6:
        return 0.0
    bearing = math.atan2(dy, dx)
    if wind_xy_m_s[0] != 0.0 or wind_xy_m_s[1] != 0.0:
        bearing = crab_heading_rad(bearing, wind_xy_m_s, speed_m_s)
    err = wrap_pi(bearing - heading_rad)
    u_max = max_turn_rate_rad_s(speed_m_s, min_turn_radius_m)
    if err > 1e-3 or err < -1e-3:  # |err| > 1e-3: is the point inside the turning circle?
        side = 1.0 if err >= 0.0 else -1.0
        # centre of the turning circle on the side we would turn to
        cx = x_m - side * min_turn_radius_m * sin_heading
        cy = y_m + side * min_turn_radius_m * cos_heading
        if math.hypot(aim_x_m - cx, aim_y_m - cy) < min_turn_radius_m * 0.999:
            return 0.0
    return _saturated(_HEADING_GAIN_PER_S * err, u_max)


def turn_rate_to_circle(
    state: UavState,
    command: LoiterCommand,
    min_turn_radius_m: float,
    *,
    wind_xy_m_s: tuple[float, float] = CALM,
) -> float:
    """Vector-field turn rate that converges onto the loiter circle over ground, with the
    circle's feed-forward at ground speed in ``wind_xy_m_s`` (module docstring)."""
    return circle_turn_rate(state.x_m, state.y_m, state.heading_rad, state.speed_m_s,
                            command.x_m, command.y_m, command.radius_m, command.clockwise,
                            min_turn_radius_m, wind_xy_m_s)


def circle_turn_rate(
    x_m: float,
    y_m: float,
    heading_rad: float,
    speed_m_s: float,
    centre_x_m: float,
    centre_y_m: float,
    radius_m: float,
    clockwise: bool,
    min_turn_radius_m: float,
    wind_xy_m_s: tuple[float, float],
) -> float:
    """:func:`turn_rate_to_circle` on a bare pose and circle (module docstring: the
    vector field ``chi_d`` and its feed-forward; 0 at the centre itself)."""
    v = speed_m_s
    u_max = max_turn_rate_rad_s(v, min_turn_radius_m)
    radius = max(radius_m, min_turn_radius_m)
    lam = -1.0 if clockwise else 1.0
    dx, dy = x_m - centre_x_m, y_m - centre_y_m
    d = math.hypot(dx, dy)
    if d < 1e-6:
        return 0.0
    gamma = math.atan2(dy, dx)
    chi_d = gamma + lam * (_HALF_PI + math.atan(_ORBIT_GAIN * (d - radius) / radius))
    wx, wy = wind_xy_m_s
    if wx == 0.0 and wy == 0.0:
        err = wrap_pi(chi_d - heading_rad)
        feed_forward = lam * v / max(d, radius)
    else:
        err = wrap_pi(crab_heading_rad(chi_d, wind_xy_m_s, v) - heading_rad)
        c, s = math.cos(chi_d), math.sin(chi_d)
        w_perp = wx * s - wy * c
        along = math.sqrt(max(v * v - w_perp * w_perp, (1e-3 * v) ** 2))
        ground = max(wx * c + wy * s + along, 0.0)
        feed_forward = lam * ground * ground / (max(d, radius) * along)
    return _saturated(_HEADING_GAIN_PER_S * err + feed_forward, u_max)


def distance_to_circle_m(
    state: UavState, command: LoiterCommand, min_turn_radius_m: float
) -> float:
    """|d - r|: how far the aircraft is from the loiter circle it would fly."""
    radius = max(command.radius_m, min_turn_radius_m)
    return abs(math.hypot(state.x_m - command.x_m, state.y_m - command.y_m) - radius)
