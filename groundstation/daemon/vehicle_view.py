"""The live map's vehicle panel: what the state document adds per vehicle for the operator
(docs/control.md), from what the daemon reads; the GPS fix is the one stream added for it,
GPS_RAW_INT at 0.5 Hz on a constrained link (docs/links.md: the rate plan's budget).

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
                   SYS_STATUS
``gps_fix``        GPS_RAW_INT (``mavlink/gps_message.py``): ``fix_type`` (GPS_FIX_TYPE
                   0..8), ``fix`` its name (``3D fix``, ``RTK fixed``, ``no fix``...),
                   ``satellites`` (``satellites_visible``), ``hdop`` (``eph`` / 100),
                   ``ok`` (a 3D fix or better: ``fix_type`` >= 3); an unknown or garbage
                   value is None (an unknown fix type: ``ok`` false).
                   None before the first GPS_RAW_INT, after a reboot, and when it is
                   :data:`GPS_STALE_S` older than the vehicle's newest frame (its stream
                   stopped): the panel then shows ``gps``
``gps_text``       the panel's GPS cell: ``3D fix, 14 sats, HDOP 0.8`` from ``gps_fix``,
                   else ``gps`` (``ok``, ``unhealthy``, ``absent``), else None
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

from groundstation.mavlink.gps_message import GpsFix, gps_fix_text
from groundstation.mavlink.link_budget import LinkBudget
from groundstation.mavlink.telemetry_events import VehicleSnapshot
from groundstation.vehicle.state import FlyRecord

__all__ = ["GPS_SENSOR_BIT", "GPS_STALE_S", "gps_fix_view", "gps_state", "standing_fix",
           "vehicle_panel"]

GPS_SENSOR_BIT = 0x20  # MAV_SYS_STATUS_SENSOR_GPS
GPS_STALE_S = 10.0
"""A GPS_RAW_INT this much older (mission s) than the vehicle's newest frame no longer
stands for its fix: five periods of the 0.5 Hz a constrained link asks for."""


def gps_state(sensors: tuple[int, int, int] | None) -> str | None:
    """``ok``, ``unhealthy`` or ``absent`` from SYS_STATUS' present/enabled/health masks."""
    if sensors is None:
        return None
    present, enabled, health = sensors
    if not present & GPS_SENSOR_BIT:
        return "absent"
    return "ok" if enabled & health & GPS_SENSOR_BIT else "unhealthy"


def standing_fix(snap: VehicleSnapshot) -> GpsFix | None:
    """The last GPS_RAW_INT's fix, unless it is :data:`GPS_STALE_S` older than the
    vehicle's newest frame (None: none that still stands)."""
    fix, at_s = snap.gps_fix, snap.last_gps_s
    if fix is None or at_s is None:
        return None
    heard_s = snap.last_heard_s if snap.last_heard_s is not None else at_s
    return None if heard_s - at_s > GPS_STALE_S else fix


def gps_fix_view(fix: GpsFix | None) -> dict[str, Any] | None:
    """``gps_fix`` of the module docstring."""
    if fix is None:
        return None
    return {"fix_type": fix.fix_type, "fix": fix.name, "satellites": fix.satellites,
            "hdop": fix.hdop, "ok": fix.has_fix}


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
    gps = gps_state(snap.sensors)
    fix = standing_fix(snap)
    return {
        "airspeed_m_s": snap.airspeed_m_s,
        "groundspeed_m_s": snap.speed_m_s,
        "heading_deg": heading_deg(snap.heading_rad),
        "gps": gps,
        "gps_fix": gps_fix_view(fix),
        "gps_text": gps_fix_text(fix) if fix is not None else gps,
        "battery_v": snap.battery_voltage_v,
        "link_quality": {
            "state": link,
            "telemetry_age_s": telemetry_age_s,
            "rssi": radio.rssi if radio is not None else None,
            "remrssi": radio.remrssi if radio is not None else None,
        },
        "loiter": loiter,
    }
