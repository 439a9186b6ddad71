"""A built-in vehicle's airspeed sensor and ArduPlane's health check of it (the ``airspeed``
fault), as far as a ground station can tell.

**Health check** (``AP_Airspeed::check_sensor_ahrs_wind_max_failures``, with ARSPD_OPTIONS
bits 0 and 1 set: disable on failure, re-enable on recovery). Every ``CHECK_PERIOD_S``
(0.2 s) while flying, the health probability ``p`` (1 at boot) becomes ``0.9 p`` when the
reading is bad (a faulty pitot: too far from the ground speed) and ``0.98 p + 0.02`` when
it is good. A sensor in use (ARSPD_USE) whose ``p`` falls below 0.1 is disabled, with
``Airspeed sensor 1 failure. Disabling`` at MAV_SEVERITY_ERROR; a disabled one whose ``p``
rises above 0.95 is used again, with ``Airspeed sensor 1 now OK. Re-enabled`` (NOTICE). So
from a fault at ``t`` the sensor is disabled at ``t + 4.4 s`` (0.9^22 < 0.1), and from the
fault's end (``p`` near 0 by then) it is re-enabled about 30 s later (``1 - p`` shrinks by
0.98 per check: from near 1 to below 0.05 in about 148 checks). ArduPlane does not save
ARSPD_USE = 0: a reboot uses the sensor again, with ``p`` = 1, and a pitot still faulty is
disabled again once flying.

**SYS_STATUS** (``GCS_MAVLINK::update_sensor_status_flags``): the differential pressure bit
stays *present* (the sensor is configured) and *healthy* (the driver reads it; health is
cleared only for a used sensor the AHRS does not use), and is *enabled* only while in use.

**WIND without airspeed.** ArduPlane's EKF cannot observe the wind well without airspeed
in straight flight; against real SITL, 15 m/s of true wind was reported as 5.5-8.8 m/s
after the sensor was disabled. Modelled deterministically: while the sensor is not in use
the estimate (:class:`sitl.sim_wind.EkfWindModel`, the same first-order lag) follows

    w' = k R(theta) w,    k = DEGRADED_GAIN = 0.45,  theta = DEGRADED_TURN_DEG = 20 deg

(``R`` the counter-clockwise ENU rotation: 15 m/s from 270 deg reads 6.75 m/s from 250
deg once settled, within 0.5 m/s 15 s after the sensor is disabled) instead of the true
``w``.
"""

from __future__ import annotations

import math

from groundstation.mavlink.codec import mavlink2

__all__ = [
    "CHECK_PERIOD_S",
    "DEGRADED_GAIN",
    "DEGRADED_TURN_DEG",
    "AirspeedSensor",
    "wind_without_airspeed",
]

CHECK_PERIOD_S = 0.2
DEGRADED_GAIN = 0.45
DEGRADED_TURN_DEG = 20.0
_DISABLE_BELOW = 0.1
_ENABLE_ABOVE = 0.95


def wind_without_airspeed(true_xy_m_s: tuple[float, float]) -> tuple[float, float]:
    """What the estimate settles to without airspeed: ``k R(theta) w`` (module docstring)."""
    c, s = math.cos(math.radians(DEGRADED_TURN_DEG)), math.sin(math.radians(DEGRADED_TURN_DEG))
    wx, wy = true_xy_m_s
    return DEGRADED_GAIN * (c * wx - s * wy), DEGRADED_GAIN * (s * wx + c * wy)


class AirspeedSensor:
    """The pitot (``faulty`` or not: the fault outlives reboots) and the autopilot's use of
    it (``in_use``, ``health``: reset at every boot by :meth:`booted`)."""

    def __init__(self, number: int = 1) -> None:
        self.number = number
        self.faulty = False
        self.booted()

    def booted(self) -> None:
        """A (re)boot: ARSPD_USE from storage (in use), health probability 1."""
        self.in_use = True
        self.health = 1.0
        self._since_check_s = 0.0

    def step(self, dt_s: float, flying: bool) -> list[tuple[int, str]]:
        """Run the health check over ``dt_s``; the STATUSTEXTs it sends (severity, text)."""
        if not flying:
            return []  # ArduPlane skips the check at zero airspeed
        self._since_check_s += dt_s
        out: list[tuple[int, str]] = []
        while self._since_check_s >= CHECK_PERIOD_S - 1e-9:
            self._since_check_s -= CHECK_PERIOD_S
            self.health = 0.9 * self.health if self.faulty else 0.98 * self.health + 0.02
            if self.in_use and self.health < _DISABLE_BELOW:
                self.in_use = False
                out.append((mavlink2.MAV_SEVERITY_ERROR,
                            f"Airspeed sensor {self.number} failure. Disabling"))
            elif not self.in_use and self.health > _ENABLE_ABOVE:
                self.in_use = True
                out.append((mavlink2.MAV_SEVERITY_NOTICE,
                            f"Airspeed sensor {self.number} now OK. Re-enabled"))
        return out

    def estimate_target(self, true_xy_m_s: tuple[float, float]) -> tuple[float, float]:
        """The wind the EKF's estimate follows: the true one while the sensor is in use."""
        return true_xy_m_s if self.in_use else wind_without_airspeed(true_xy_m_s)
