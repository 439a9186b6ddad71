"""The telemetry reducer's battery current and home (HOME_POSITION), for the ship watch."""

from __future__ import annotations

import pytest
from test_telemetry_reducer import ORIGIN, wire

from groundstation.mavlink.codec import mavlink2
from groundstation.mavlink.telemetry import VehicleTelemetry
from groundstation.mavlink.telemetry_events import InvalidTelemetry

M = mavlink2


def sys_status(current_ca: int, remaining: int = 80) -> object:
    return wire(M.MAVLink_sys_status_message(0, 0, 0, 0, 12_100, current_ca, remaining, 0, 0,
                                             0, 0, 0, 0))


def home(lat_e7: int, lon_e7: int, alt_mm: int) -> object:
    return wire(M.MAVLink_home_position_message(lat_e7, lon_e7, alt_mm, 0.0, 0.0, 0.0,
                                                [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0))


def test_battery_current_in_amperes_and_minus_one_is_unknown() -> None:
    tel = VehicleTelemetry(1, ORIGIN)
    tel.receive(sys_status(1234), 1.0)
    assert tel.snapshot().battery_current_a == pytest.approx(12.34)
    tel.receive(sys_status(-1), 2.0)
    assert tel.snapshot().battery_current_a is None
    tel.receive(sys_status(30_000), 3.0)  # 300 A: a reading (cA on the wire, int16)
    assert tel.snapshot().battery_current_a == 300.0


def test_home_position_is_kept_in_geodetic_and_local() -> None:
    tel = VehicleTelemetry(1, ORIGIN)
    lat, lon, _ = ORIGIN.to_geodetic(500.0, -300.0)
    tel.receive(home(round(lat * 1e7), round(lon * 1e7), 15_500), 1.0)
    snap = tel.snapshot()
    assert snap.home is not None and snap.home[2] == 15.5
    assert snap.home_xy_m == pytest.approx((500.0, -300.0), abs=0.02)
    assert snap.last_home_s == 1.0
    events = tel.receive(home(0, 0, 0), 2.0)  # no position: kept as it was
    assert [e.field for e in events if isinstance(e, InvalidTelemetry)] == ["lat/lon"]
    assert tel.snapshot().home == snap.home
    events = tel.receive(home(950_000_000, 0, 0), 3.0)
    assert [e.field for e in events if isinstance(e, InvalidTelemetry)] == ["lat/lon"]
