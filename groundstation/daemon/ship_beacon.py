"""The ship as a MAVLink beacon: ``GLOBAL_POSITION_INT`` of the ship, from its own system id,
to every vehicle link at 1 Hz of mission time (docs/ship.md).

ArduPilot's follow library (``AP_Follow``: ``FOLL_ENABLE``, ``FOLL_SYSID``), and with it the
ship-landing script (``plane_ship_landing.lua``), takes the target's position from the
GLOBAL_POSITION_INT of the system ``FOLL_SYSID`` (any component; its own messages and a
latitude/longitude of exactly zero are ignored): ``lat``/``lon`` (degE7), ``alt`` (mm AMSL,
with ``FOLL_ALT_TYPE`` 0) or ``relative_alt``, the velocity ``vx, vy, vz`` (cm/s, north,
east, down) and ``hdg`` (cdeg, 65535 unknown). So the beacon sends exactly that, from
system ``ship_beacon`` (default 17; set ``FOLL_SYSID`` to it: with 0, ArduPilot follows the
first system it hears), component MAV_COMP_ID_USER1, with no HEARTBEAT (it is no vehicle,
and no ground station must take it for one).

The position is the decision core's track of the ship (``core/ship.py``, fed by every
``BoatPosition``: the scenario's ship, the detection feed's, an NMEA feed's) predicted to
now, with its velocity (the fixes' own, else the one the track learnt from their
positions); none is sent once the last fix is older than ``stale_s`` (a follower must lose
a lost ship, not chase a stale one), nor when its system id is a vehicle's
(``ship_beacon_conflict``, journalled once).
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable, Collection
from dataclasses import dataclass

from domain.geodesy import GeoOrigin, compass_deg_from_enu_rad
from groundstation.core.ship import ShipPrediction, ShipTrack
from groundstation.mavlink.codec import MavlinkEncoder, MAVLinkMessage, mavlink2

__all__ = ["BEACON_COMPONENT", "DEFAULT_SHIP_SYSID", "ShipBeacon", "beacon_message"]

M = mavlink2
DEFAULT_SHIP_SYSID = 17
BEACON_COMPONENT = M.MAV_COMP_ID_USER1
STALE_S = 10.0
_UINT16_UNKNOWN = 65535
_MIN_COURSE_SPEED_M_S = 0.5
"""Below this speed over ground a course says nothing: the heading is sent as unknown."""


@dataclass(frozen=True)
class BeaconClock:
    """What the beacon needs of the mission clock (``MissionClock``)."""

    now_s: Callable[[], float]
    wall_s: Callable[[float], float]


def beacon_message(ship: ShipPrediction | None, heading_rad: float | None,
                   origin: GeoOrigin, stale_s: float = STALE_S) -> MAVLinkMessage | None:
    """The GLOBAL_POSITION_INT of the ship predicted to ``ship.t_s`` (mission s), or None
    without a prediction or when its last fix is older than ``stale_s``. ``heading_rad``:
    the bow's (HDT), else the course when the ship moves. Altitude the origin's (the deck
    at sea level), ``time_boot_ms`` the mission time."""
    if ship is None or ship.fix_age_s > stale_s:
        return None
    lat_deg, lon_deg, _ = origin.to_geodetic(ship.x_m, ship.y_m)
    ve_m_s, vn_m_s = ship.vx_m_s, ship.vy_m_s
    heading = heading_rad
    if heading is None or not math.isfinite(heading):
        fast = math.hypot(ve_m_s, vn_m_s) >= _MIN_COURSE_SPEED_M_S
        heading = math.atan2(vn_m_s, ve_m_s) if fast else None
    hdg = (_UINT16_UNKNOWN if heading is None
           else round(compass_deg_from_enu_rad(heading) * 100) % 36000)
    return M.MAVLink_global_position_int_message(
        int(max(0.0, ship.t_s) * 1000) % 2**32,
        round(lat_deg * 1e7),
        round(lon_deg * 1e7),
        round(origin.alt_m * 1000),
        0,  # relative_alt: the deck
        _cm_s(vn_m_s),
        _cm_s(ve_m_s),
        0,
        hdg,
    )


def _cm_s(v_m_s: float) -> int:
    return max(-32768, min(32767, round(v_m_s * 100)))


class ShipBeacon:
    """The beacon's service (``async run``), see the module docstring. ``ship`` is the
    core's track of the ship, ``origin`` reads the daemon's mission origin, ``broadcast``
    sends a frame on every vehicle link, ``vehicle_ids`` the system ids with a session,
    ``journal`` the daemon's journal."""

    name = "ship beacon"

    def __init__(
        self,
        system_id: int,
        ship: ShipTrack,
        origin: Callable[[], GeoOrigin | None],
        broadcast: Callable[[bytes], int],
        clock: BeaconClock,
        vehicle_ids: Callable[[], Collection[int]],
        journal: Callable[..., None],
        *,
        period_s: float = 1.0,
        stale_s: float = STALE_S,
    ) -> None:
        self.encoder = MavlinkEncoder(system_id, BEACON_COMPONENT)
        self.system_id = system_id
        self._ship = ship
        self._origin = origin
        self._broadcast = broadcast
        self._clock = clock
        self._vehicle_ids = vehicle_ids
        self._journal = journal
        self.period_s = period_s
        self.stale_s = stale_s
        self.sent = 0
        """GLOBAL_POSITION_INTs sent (each on every vehicle link)."""
        self.conflict = False

    def step(self) -> bool:
        """Send one beacon frame if there is a fresh fix; True if one went out."""
        if self.conflict:
            return False
        if self.system_id in self._vehicle_ids():
            self.conflict = True
            self._journal("ship_beacon_conflict", system_id=self.system_id,
                          reason="a vehicle has the beacon's system id: beacon stopped")
            return False
        origin = self._origin()
        if origin is None:
            return False
        msg = beacon_message(self._ship.predict(self._clock.now_s()), self._ship.heading_rad,
                             origin, self.stale_s)
        if msg is None:
            return False
        self._broadcast(self.encoder.encode(msg))
        self.sent += 1
        return True

    async def run(self) -> None:
        while True:
            self.step()
            await asyncio.sleep(max(0.02, self._clock.wall_s(self.period_s)))
