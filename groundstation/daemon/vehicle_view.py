"""The live map's vehicle panel: what the state document adds per vehicle for the operator
(docs/control.md), from what the daemon already reads; no telemetry stream is added for it
(docs/links.md: the rate plan's budget).

=================  ================================================================
field              from
=================  ================================================================
``airspeed_m_s``   VFR_HUD ``airspeed``
``groundspeed_m_s`` VFR_HUD ``groundspeed`` (else GLOBAL_POSITION_INT's velocity)
``heading_deg``    compass degrees, 0 = north, clockwise (GLOBAL_POSITION_INT ``hdg``,
                   VFR_HUD ``heading``)
``alt_m``          GLOBAL_POSITION_INT ``relative_alt``
``gps``            SYS_STATUS' GPS sensor bit (MAV_SYS_STATUS_SENSOR_GPS, 0x20): ``ok``
                   (present, enabled, healthy), ``unhealthy``, ``absent``; None before a
                   SYS_STATUS. GPS_RAW_INT's fix type is not read: the rate plan turns
                   that stream off to keep telemetry within 40 % of the link
``battery_v``      SYS_STATUS / BATTERY_STATUS voltage; ``battery_pct`` the remaining %
``link_quality``   the controller's link state, the telemetry's age (s) and, on a link
                   with a SiK radio, its RADIO_STATUS ``rssi``/``remrssi`` (0..255)
``loiter``         the commanded loiter: the mission's last item, an unlimited loiter
                   at its last point with the configured radius (``x_m``, ``y_m``,
                   ``radius_m``); None without a mission
=================  ================================================================

Latitude and longitude are not added: the page converts the local ENU position itself
(``web/geo.js``, exactly as pymap3d does); pymap3d takes ~1 ms a point here, too much to
spend per vehicle on every state document.
"""

from __future__ import annotations

import math
from typing import Any

from groundstation.mavlink.link_budget import LinkBudget
from groundstation.mavlink.telemetry_events import VehicleSnapshot
from groundstation.vehicle.state import FlyRecord

__all__ = ["GPS_SENSOR_BIT", "gps_state", "vehicle_panel"]

GPS_SENSOR_BIT = 0x20  # MAV_SYS_STATUS_SENSOR_GPS


def gps_state(sensors: tuple[int, int, int] | None) -> str | None:
    """``ok``, ``unhealthy`` or ``absent`` from SYS_STATUS' present/enabled/health masks."""
    if sensors is None:
        return None
    present, enabled, health = sensors
    if not present & GPS_SENSOR_BIT:
        return "absent"
    return "ok" if enabled & health & GPS_SENSOR_BIT else "unhealthy"


def heading_deg(heading_rad: float | None) -> float | None:
    """ENU radians counter-clockwise from east -> compass degrees clockwise from north."""
    if heading_rad is None:
        return None
    return (90.0 - math.degrees(heading_rad)) % 360.0


def vehicle_panel(snap: VehicleSnapshot, fly: FlyRecord | None, loiter_radius_m: float,
                  link: str, telemetry_age_s: float | None,
                  budget: LinkBudget | None) -> dict[str, Any]:
    """The fields of the module docstring for one vehicle."""
    radio = budget.radio if budget is not None else None
    loiter = None
    if fly is not None:
        x_m, y_m = ((fly.x_m, fly.y_m), *fly.through)[-1]
        loiter = {"x_m": x_m, "y_m": y_m, "radius_m": loiter_radius_m}
    return {
        "airspeed_m_s": snap.airspeed_m_s,
        "groundspeed_m_s": snap.speed_m_s,
        "heading_deg": heading_deg(snap.heading_rad),
        "gps": gps_state(snap.sensors),
        "battery_v": snap.battery_voltage_v,
        "link_quality": {
            "state": link,
            "telemetry_age_s": telemetry_age_s,
            "rssi": radio.rssi if radio is not None else None,
            "remrssi": radio.remrssi if radio is not None else None,
        },
        "loiter": loiter,
    }
