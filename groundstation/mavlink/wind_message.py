"""ArduPilot's WIND message (#168, ardupilotmega dialect) -> floe's wind vector, checked.

Fields: ``direction`` (deg, the compass direction the wind comes FROM), ``speed`` (m/s),
``speed_z`` (m/s, vertical). What ArduPlane actually sends (``GCS_MAVLINK_Plane::send_wind``,
from its AHRS/EKF wind estimate ``w`` in NED)::

    direction = degrees(atan2(-w_E, -w_N))     in [-180, 180], not [0, 360)
    speed     = |w|                            the 3-D length, vertical included
    speed_z   = w_D

(a wind vane, ``AP_WindVane``, sends ``wrap_360`` directions and ``speed_z = 0``). So a
direction in [-180, 360] is valid (taken modulo 360) and the horizontal speed is::

    s_h = sqrt(speed^2 - speed_z^2)   if |speed_z| <= speed  (ArduPlane's 3-D length)
    s_h = speed                       otherwise (a sender that gives the ground-plane speed,
                                      as the message definition says)

and the ENU vector the air moves towards is ``domain.wind_triangle.wind_vector_m_s(s_h,
direction)``. Refused (the reducer counts them as invalid and drops them): any field not
finite, ``speed`` outside [0, 60] m/s (``domain.limits.MAX_WIND_M_S``: above any flyable
weather), ``|speed_z|`` above 60 m/s, ``direction`` outside [-180, 360].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from domain.limits import MAX_WIND_M_S
from domain.wind_triangle import wind_vector_m_s

__all__ = ["BadWindField", "WindVector", "parse_wind_message"]


@dataclass(frozen=True)
class WindVector:
    """A valid WIND message: ENU m/s the air moves towards, and the vertical wind."""

    wx_m_s: float
    wy_m_s: float
    speed_z_m_s: float


@dataclass(frozen=True)
class BadWindField:
    """Why a WIND message was refused: the first bad field and its value."""

    field: str
    value: Any


def parse_wind_message(msg: Any) -> WindVector | BadWindField:
    """The message's wind (module docstring), or the field that makes it unusable."""
    direction = float(msg.direction)
    speed = float(msg.speed)
    speed_z = float(msg.speed_z)
    if not (math.isfinite(speed) and 0.0 <= speed <= MAX_WIND_M_S):
        return BadWindField("speed", speed)
    if not (math.isfinite(direction) and -180.0 <= direction <= 360.0):
        return BadWindField("direction", direction)
    if not (math.isfinite(speed_z) and abs(speed_z) <= MAX_WIND_M_S):
        return BadWindField("speed_z", speed_z)
    horizontal = math.sqrt(speed * speed - speed_z * speed_z) if abs(speed_z) <= speed else speed
    wx, wy = wind_vector_m_s(horizontal, direction % 360.0)
    return WindVector(wx, wy, speed_z)
