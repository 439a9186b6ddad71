"""Where to send a vehicle so that it meets a (possibly moving) target, and when.

In still air two fixed-point iterations::

    t_arr = D(pose, p) / V,   p <- p_hat + v_hat * t_arr

with ``D`` the Dubins distance from the vehicle's pose to the point (free final heading) and
``V`` its airspeed (:func:`travel_time_s`); the flight time returned is one more evaluation
at the final ``p`` (the iteration stops before ``t_arr`` is recomputed there). In a wind
``w`` the planner's travel times are used: the earliest ``t_arr`` at which the vehicle,
flying a Dubins path through the moving air, is over ``p_hat + v_hat t_arr``
(:func:`planner.wind.time_in_wind_s`; in the air's frame the target moves at
``v_hat - w``), the aim point is ``p_hat + v_hat t_arr``. A target the vehicle cannot catch
in that wind (it drifts away through the air at the airspeed or faster) is aimed at as in
still air. A fixed point (a search cell's centre) is the case ``v_hat = 0``.
"""

from __future__ import annotations

import math
from typing import Protocol

from planner import dubins_distance_to_point
from planner.problem import wind_problem
from planner.wind import time_in_wind_s

__all__ = ["Pose", "intercept", "travel_time_s"]


class Pose(Protocol):
    """What the intercept needs of a vehicle (``decision.VehicleRecord`` has it)."""

    x_m: float
    y_m: float
    heading_rad: float
    speed_m_s: float


def travel_time_s(pose: Pose, x_m: float, y_m: float, turn_radius_m: float) -> float:
    """Predicted time (s) for ``pose`` to fly to (x_m, y_m) in still air: the Dubins
    distance at its airspeed (at least 1 m/s)."""
    d = dubins_distance_to_point(pose.x_m, pose.y_m, pose.heading_rad, x_m, y_m, turn_radius_m)
    return d / max(pose.speed_m_s, 1.0)


def intercept(
    pose: Pose,
    xy_m: tuple[float, float],
    v_m_s: tuple[float, float],
    wind_m_s: tuple[float, float],
    turn_radius_m: float,
) -> tuple[float, float, float]:
    """(x_m, y_m, t_arr_s): the aim point for a target at ``xy_m`` moving at ``v_m_s`` and
    the flight time to it (module docstring)."""
    tx, ty = xy_m
    vx, vy = v_m_s
    speed = max(pose.speed_m_s, 1.0)
    if wind_m_s[0] != 0.0 or wind_m_s[1] != 0.0:
        t_arr = math.inf
        if wind_problem(wind_m_s, speed) is None:
            t_arr = time_in_wind_s(
                pose.x_m, pose.y_m, pose.heading_rad, tx, ty, wind_m_s, speed, turn_radius_m,
                (vx, vy),
            )
        if math.isfinite(t_arr):
            return tx + vx * t_arr, ty + vy * t_arr, t_arr
    x, y = tx, ty
    t_arr = 0.0
    for _ in range(2):
        t_arr = travel_time_s(pose, x, y, turn_radius_m)
        x, y = tx + vx * t_arr, ty + vy * t_arr
    return x, y, travel_time_s(pose, x, y, turn_radius_m)
