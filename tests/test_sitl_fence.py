"""The built-in vehicle enforces an uploaded geofence as ArduPlane 4.x does (sitl/fence.py):
a new breach of an enabled fence acts by FENCE_ACTION, FENCE_STATUS and SYS_STATUS tell it,
and a pilot who takes the vehicle after the fence acted keeps it."""

from __future__ import annotations

import math
from typing import Any

from domain.geodesy import GeoOrigin
from domain.modes import ArduPlaneMode
from groundstation.mavlink.codec import mavlink2 as M
from groundstation.mavlink.fence_items import FenceCircle, build_fence_items
from sitl.loopback import Loopback
from sitl.vehicle import SimVehicle, VehicleConfig

ORIGIN = GeoOrigin(78.93, 11.92)
FENCE = M.MAV_MISSION_TYPE_FENCE
BIT = M.MAV_SYS_STATUS_GEOFENCE


def airborne() -> Loopback:
    cfg = VehicleConfig(system_id=1, origin=ORIGIN, home_lat_deg=78.93, home_lon_deg=11.92,
                        airborne=True, fast_boot=True)
    lb = Loopback(SimVehicle(cfg))
    lb.advance(1.0)
    return lb


def upload_fence(lb: Loopback, fence: FenceCircle) -> None:
    items = build_fence_items(fence, ORIGIN)
    out = lb.send(M.MAVLink_mission_count_message(1, 1, len(items), FENCE))
    for item in items:
        assert [r.seq for r in out if r.get_type() == "MISSION_REQUEST"] == [item.seq]
        out = lb.send(item.to_message(1, 1))
    assert [a.type for a in out if a.get_type() == "MISSION_ACK"] == [M.MAV_MISSION_ACCEPTED]


def set_param(lb: Loopback, name: str, value: float) -> None:
    out = lb.send(M.MAVLink_param_set_message(1, 1, name.encode(), value,
                                              M.MAV_PARAM_TYPE_INT8))
    assert [p.param_value for p in out if p.get_type() == "PARAM_VALUE"] == [value]


def fly_to(lb: Loopback, x_m: float, y_m: float) -> None:
    lat, lon, _ = ORIGIN.to_geodetic(x_m, y_m)
    out = lb.send(M.MAVLink_command_int_message(
        1, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_CMD_DO_REPOSITION, 0, 0, -1,
        M.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, 0, 0, round(lat * 1e7), round(lon * 1e7), 100))
    assert [a.result for a in out if a.get_type() == "COMMAND_ACK"] == [M.MAV_RESULT_ACCEPTED]


def mode(lb: Loopback) -> int:
    return int(lb.vehicle.autopilot.mode)


def distance_m(lb: Loopback) -> float:
    af = lb.vehicle.airframe
    return math.hypot(af.x_m, af.y_m)


def is_breach_text(msg: Any) -> bool:
    return msg.get_type() == "STATUSTEXT" and msg.text == "Fence breached: Polygon"


def test_a_breach_of_the_enabled_fence_sends_the_vehicle_home_in_rtl() -> None:
    lb = airborne()
    upload_fence(lb, FenceCircle(0.0, 0.0, 800.0))
    fly_to(lb, 3000.0, 0.0)
    # uploaded but not enabled (FENCE_ENABLE 0, ArduPlane's default): nothing happens
    assert lb.run_until(is_breach_text, 80.0) is None
    assert distance_m(lb) > 900.0 and mode(lb) == ArduPlaneMode.GUIDED
    [status] = lb.take("SYS_STATUS")[-1:]
    assert status.onboard_control_sensors_present & BIT
    assert not status.onboard_control_sensors_enabled & BIT
    assert not lb.take("FENCE_STATUS")
    # enabled: the vehicle, outside, breaches at once and goes home in RTL
    fly_to(lb, 0.0, 0.0)
    for _ in range(150):
        if distance_m(lb) < 300.0:
            break
        lb.advance(1.0)
    assert distance_m(lb) < 300.0
    set_param(lb, "FENCE_ENABLE", 1)
    lb.inbox.clear()
    fly_to(lb, 3000.0, 0.0)
    text = lb.run_until(is_breach_text, 80.0)
    assert text is not None and text.severity == M.MAV_SEVERITY_NOTICE
    assert 790.0 <= distance_m(lb) <= 830.0  # at the fence (10 Hz check, ~20 m/s)
    assert mode(lb) == ArduPlaneMode.RTL
    lb.advance(2.0)  # still outside, turning back
    statuses = lb.take("FENCE_STATUS")
    assert statuses and (statuses[-1].breach_status, statuses[-1].breach_count,
                         statuses[-1].breach_type) == (1, 1, M.FENCE_BREACH_BOUNDARY)
    sys_status = lb.take("SYS_STATUS")[-1]
    assert sys_status.onboard_control_sensors_enabled & BIT
    assert not sys_status.onboard_control_sensors_health & BIT  # MAVProxy: "fence breach"
    # RTL brings it back inside: the breach clears, the health bit comes back
    cleared = lb.run_until(lambda m: m.get_type() == "STATUSTEXT"
                           and m.text == "Fence breach cleared", 120.0)
    assert cleared is not None and distance_m(lb) <= 800.0
    lb.advance(2.0)
    assert lb.take("SYS_STATUS")[-1].onboard_control_sensors_health & BIT
    assert lb.take("FENCE_STATUS")[-1].breach_status == 0


def test_the_pilot_who_takes_over_after_the_fence_acted_keeps_the_vehicle() -> None:
    lb = airborne()
    upload_fence(lb, FenceCircle(0.0, 0.0, 600.0))
    set_param(lb, "FENCE_ENABLE", 1)
    fly_to(lb, 3000.0, 0.0)
    assert lb.run_until(is_breach_text, 80.0) is not None
    assert mode(lb) == ArduPlaneMode.RTL
    # the pilot switches to FBWA while still outside: the breach is not new, nothing acts
    out = lb.send(M.MAVLink_set_mode_message(1, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                                             ArduPlaneMode.FBWA))
    assert [a.result for a in out if a.get_type() == "COMMAND_ACK"] == [M.MAV_RESULT_ACCEPTED]
    lb.advance(20.0)
    assert mode(lb) == ArduPlaneMode.FBWA
    assert distance_m(lb) > 600.0


def test_fence_action_guided_flies_to_the_fence_return_point() -> None:
    lb = airborne()
    fence = FenceCircle(200.0, 100.0, 700.0)
    upload_fence(lb, fence)
    set_param(lb, "FENCE_ACTION", 6)
    out = lb.send(M.MAVLink_command_long_message(1, 1, M.MAV_CMD_DO_FENCE_ENABLE, 0,
                                                 1, 0, 0, 0, 0, 0, 0))
    assert [a.result for a in out if a.get_type() == "COMMAND_ACK"] == [M.MAV_RESULT_ACCEPTED]
    fly_to(lb, -3000.0, 0.0)
    assert lb.run_until(is_breach_text, 80.0) is not None
    assert mode(lb) == ArduPlaneMode.GUIDED
    nav = lb.vehicle.autopilot.nav
    assert nav is not None
    assert (round(nav.x_m), round(nav.y_m)) == (200, 100)  # the return point, not home


def test_a_fence_cleared_in_place_is_no_longer_enforced() -> None:
    """The simulator's store is cleared in place (MISSION_CLEAR_ALL, or a count of 0): the
    fence it held is gone, whatever was cached of it."""
    from domain.geodesy import GeoOrigin
    from sitl.fence import SimFence
    from sitl.mission_store import StoredItem

    origin = GeoOrigin(78.93, 11.92)
    lat, lon, _ = origin.to_geodetic(0.0, 0.0, 0.0)
    store = [StoredItem(command=5003, param1=500.0, x=round(lat * 1e7), y=round(lon * 1e7))]
    params = {"FENCE_TYPE": 4.0, "FENCE_ENABLE": 1.0}
    fence = SimFence(origin, lambda: store, params.__getitem__)
    assert fence.present and fence.outside(900.0, 0.0) and not fence.outside(100.0, 0.0)
    store.clear()
    assert not fence.present and not fence.outside(900.0, 0.0)
