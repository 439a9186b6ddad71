"""The ship beacon's message and service on their own (``groundstation.daemon.ship_beacon``):
no sockets; the e2e test on a vehicle link is ``test_daemon_ship_vehicles``."""

from __future__ import annotations

import math
from typing import Any

import pytest

from domain.geodesy import GeoOrigin
from groundstation.core import events as ev
from groundstation.core.ship import ShipTrack
from groundstation.daemon.ship_beacon import BeaconClock, ShipBeacon, beacon_message
from groundstation.mavlink.codec import MavlinkDecoder

ORIGIN = GeoOrigin(-64.8, -62.9, 3.0)


def beacon_of(fix: ev.BoatPosition, now_s: float) -> Any:
    """The beacon's message for the core's ship track after one ``fix``, at ``now_s``."""
    track = ShipTrack()
    track.fix(fix)
    return beacon_message(track.predict(now_s), track.heading_rad, ORIGIN)


def test_position_velocity_heading_and_altitude() -> None:
    fix = ev.BoatPosition(10.0, 1000.0, -500.0, 0.0, -4.0, math.pi / 2, None, "nmea")
    msg = beacon_of(fix, 12.0)
    assert msg is not None
    x_m, y_m, _ = ORIGIN.to_local(msg.lat * 1e-7, msg.lon * 1e-7)
    assert x_m == pytest.approx(1000.0, abs=0.02)
    assert y_m == pytest.approx(-508.0, abs=0.02)  # predicted 2 s at 4 m/s south
    assert (msg.vx, msg.vy, msg.vz) == (-400, 0, 0)
    assert msg.hdg == 0  # the bow's heading (north), not the course (south)
    assert msg.alt == 3000 and msg.relative_alt == 0 and msg.time_boot_ms == 12000


def test_course_from_velocity_unknown_when_still_and_none_when_stale() -> None:
    moving = beacon_of(ev.BoatPosition(0.0, 0.0, 0.0, 3.0, 3.0), 0.0)
    assert moving is not None and moving.hdg == 4500
    still = beacon_of(ev.BoatPosition(0.0, 0.0, 0.0), 0.0)
    assert still is not None and still.hdg == 65535 and (still.vx, still.vy) == (0, 0)
    assert beacon_of(ev.BoatPosition(0.0, 0.0, 0.0), 10.5) is None
    assert beacon_of(ev.BoatPosition(0.0, math.nan, 0.0), 0.0) is None


def test_service_sends_from_its_system_id_and_stops_on_a_conflict() -> None:
    frames: list[bytes] = []
    journal: list[tuple[str, dict[str, Any]]] = []
    ids: set[int] = {1, 2}
    track = ShipTrack()
    beacon = ShipBeacon(17, track, lambda: ORIGIN, lambda f: frames.append(f) or 1,
                        BeaconClock(lambda: 5.0, lambda s: s), lambda: ids,
                        lambda event, **fields: journal.append((event, fields)))
    assert not beacon.step() and frames == []  # no ship known
    track.fix(ev.BoatPosition(5.0, 10.0, 20.0))
    assert beacon.step()
    (msg,) = MavlinkDecoder().feed(frames[0])
    assert msg.get_type() == "GLOBAL_POSITION_INT" and msg.get_srcSystem() == 17
    ids.add(17)
    assert not beacon.step() and not beacon.step()
    assert [e for e, _ in journal] == ["ship_beacon_conflict"] and len(frames) == 1
