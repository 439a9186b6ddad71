"""The wind triangle: how air-relative flight becomes ground track, for every layer.

Frames as everywhere in floe: local ENU metres, angles in radians counter-clockwise from
east. A wind is the ENU vector ``w = (w_x, w_y)`` the air moves *towards*, in m/s. Pilots,
METARs and ArduPilot (``SIM_WIND_DIR``, the WIND message's ``direction``) give the compass
direction the wind blows *from*::

    w = -s (sin(from), cos(from))          (from in compass radians, clockwise from north)

An aircraft with airspeed ``V`` and heading ``psi`` moves over ground at::

    v_g = V (cos psi, sin psi) + w

To hold the ground course ``chi`` it crabs into the wind: with ``w_par = w . u`` and
``w_perp = w x u`` (``u`` the unit vector of ``chi``; ``a x b = a_x b_y - a_y b_x``)::

    psi = chi + asin(w_perp / V)              (the crab angle; needs |w_perp| < V)
    |v_g| = w_par + sqrt(V^2 - w_perp^2)      (ground speed along chi; > 0 needs |w| < V
                                               for every chi)
"""

from __future__ import annotations

import math

__all__ = [
    "crab_heading_rad",
    "ground_speed_along_m_s",
    "wind_from_vector",
    "wind_vector_m_s",
]


def wind_vector_m_s(speed_m_s: float, from_deg: float) -> tuple[float, float]:
    """ENU vector of a wind of ``speed_m_s`` blowing from compass ``from_deg``."""
    a = math.radians(from_deg)
    return -speed_m_s * math.sin(a), -speed_m_s * math.cos(a)


def wind_from_vector(wx_m_s: float, wy_m_s: float) -> tuple[float, float]:
    """(speed m/s, compass degrees it blows from, in [0, 360)) of an ENU wind vector."""
    speed = math.hypot(wx_m_s, wy_m_s)
    if speed == 0.0:
        return 0.0, 0.0
    return speed, math.degrees(math.atan2(-wx_m_s, -wy_m_s)) % 360.0


def crab_heading_rad(
    course_rad: float, wind_xy_m_s: tuple[float, float], airspeed_m_s: float
) -> float:
    """Heading that makes good the ground course ``course_rad`` (see module docstring).
    A cross wind at or above the airspeed cannot be crabbed out: the aircraft then heads
    straight across it (crab of +-90 deg) and drifts."""
    wx, wy = wind_xy_m_s
    w_perp = wx * math.sin(course_rad) - wy * math.cos(course_rad)
    ratio = max(-1.0, min(1.0, w_perp / airspeed_m_s))
    return course_rad + math.asin(ratio)


def ground_speed_along_m_s(
    course_rad: float, wind_xy_m_s: tuple[float, float], airspeed_m_s: float
) -> float | None:
    """Ground speed made good along ``course_rad``; None where it cannot be flown (the
    cross wind is at or above the airspeed, or the head wind leaves no progress)."""
    wx, wy = wind_xy_m_s
    c, s = math.cos(course_rad), math.sin(course_rad)
    w_par = wx * c + wy * s
    w_perp = wx * s - wy * c
    if abs(w_perp) >= airspeed_m_s:
        return None
    speed = w_par + math.sqrt(airspeed_m_s * airspeed_m_s - w_perp * w_perp)
    return speed if speed > 0.0 else None
