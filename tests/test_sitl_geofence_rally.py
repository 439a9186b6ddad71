"""The built-in vehicle as MAVProxy and QGroundControl see it: a healthy geofence in
SYS_STATUS, and the fence and rally mission types answered as ArduPlane answers them."""

from __future__ import annotations

import struct
from typing import Any

import pytest

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import mavlink2 as M
from sitl.geo_items import GEO_CAPACITY
from sitl.loopback import Loopback
from sitl.vehicle import SimVehicle, VehicleConfig

ORIGIN = GeoOrigin(78.93, 11.92)
FENCE, RALLY = M.MAV_MISSION_TYPE_FENCE, M.MAV_MISSION_TYPE_RALLY


def make() -> Loopback:
    cfg = VehicleConfig(
        system_id=1, origin=ORIGIN, home_lat_deg=78.93, home_lon_deg=11.92, fast_boot=True
    )
    lb = Loopback(SimVehicle(cfg))
    lb.advance(3.0)
    lb.take("SYS_STATUS")
    return lb


class MavproxyFenceWatch:
    """MAVProxy's fence module rule for SYS_STATUS (mavproxy_fence.py, restated): it
    starts believing the fence healthy and says "fence breach" whenever the
    MAV_SYS_STATUS_GEOFENCE health bit goes from set to clear ("fence OK" the other
    way); present/enabled changes are announced separately."""

    def __init__(self) -> None:
        self.present, self.enabled, self.healthy = False, False, True
        self.said: list[str] = []

    def feed(self, msg: Any) -> None:
        bit = M.MAV_SYS_STATUS_GEOFENCE
        present = msg.onboard_control_sensors_present & bit == bit
        enabled = msg.onboard_control_sensors_enabled & bit == bit
        healthy = msg.onboard_control_sensors_health & bit == bit
        if present != self.present:
            self.said.append("fence present" if present else "fence removed")
        if enabled != self.enabled:
            self.said.append("fence enabled" if enabled else "fence disabled")
        if healthy != self.healthy:
            self.said.append("fence OK" if healthy else "fence breach")
        self.present, self.enabled, self.healthy = present, enabled, healthy

    @property
    def breach(self) -> bool:
        """A breach as the newer rule states it: present and enabled but not healthy."""
        return self.present and self.enabled and not self.healthy


def test_mavproxy_sees_no_fence_breach_from_boot_to_flight() -> None:
    cfg = VehicleConfig(system_id=1, origin=ORIGIN, home_lat_deg=78.93, home_lon_deg=11.92)
    lb = Loopback(SimVehicle(cfg))
    watch = MavproxyFenceWatch()
    lb.advance(25.0)  # boot, GPS, EKF: every SYS_STATUS of the first 25 s
    statuses = lb.take("SYS_STATUS")
    assert len(statuses) >= 20
    for msg in statuses:
        watch.feed(msg)
        # as ArduPlane with FENCE_ENABLE 0: not present, not enabled, healthy
        assert not msg.onboard_control_sensors_present & M.MAV_SYS_STATUS_GEOFENCE
        assert not msg.onboard_control_sensors_enabled & M.MAV_SYS_STATUS_GEOFENCE
        assert msg.onboard_control_sensors_health & M.MAV_SYS_STATUS_GEOFENCE
        assert not watch.breach
    assert "fence breach" not in watch.said
    assert watch.said == []


def test_mavproxy_rule_does_report_a_breach_when_the_bit_is_clear() -> None:
    """The watch itself can fail: a SYS_STATUS without the health bit is a breach."""
    watch = MavproxyFenceWatch()
    bit = M.MAV_SYS_STATUS_GEOFENCE
    watch.feed(M.MAVLink_sys_status_message(bit, bit, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0))
    assert watch.said == ["fence present", "fence enabled", "fence breach"]
    assert watch.breach


@pytest.mark.parametrize("mission_type", [FENCE, RALLY])
def test_request_list_of_fence_and_rally_answers_count_zero(mission_type: int) -> None:
    lb = make()
    out = lb.send(M.MAVLink_mission_request_list_message(1, 1, mission_type))
    counts = [m for m in out if m.get_type() == "MISSION_COUNT"]
    assert [(c.count, c.mission_type) for c in counts] == [(0, mission_type)]


def _fence_items() -> list[Any]:
    lat, lon = round(78.93 * 1e7), round(11.92 * 1e7)
    vertices = [(lat + 1000, lon), (lat, lon + 3000), (lat - 1000, lon), (lat, lon - 3000)]
    return [
        M.MAVLink_mission_item_int_message(
            1,
            1,
            seq,
            M.MAV_FRAME_GLOBAL,
            M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            0,
            1,
            4,
            0,
            0,
            0,
            x,
            y,
            0,
            FENCE,
        )
        for seq, (x, y) in enumerate(vertices)
    ]


def _rally_items() -> list[Any]:
    return [
        M.MAVLink_mission_item_int_message(
            1,
            1,
            0,
            M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
            M.MAV_CMD_NAV_RALLY_POINT,
            0,
            1,
            0,
            0,
            0,
            0,
            round(78.94 * 1e7),
            round(11.93 * 1e7),
            120,
            RALLY,
        )
    ]


def _upload(lb: Loopback, mission_type: int, items: list[Any]) -> list[Any]:
    out = lb.send(M.MAVLink_mission_count_message(1, 1, len(items), mission_type))
    for item in items:
        requests = [m for m in out if m.get_type() == "MISSION_REQUEST"]
        assert [(r.seq, r.mission_type) for r in requests] == [(item.seq, mission_type)]
        out = lb.send(item)
    return out


@pytest.mark.parametrize(
    ("mission_type", "items"), [(FENCE, _fence_items()), (RALLY, _rally_items())]
)
def test_fence_and_rally_uploads_are_accepted_and_read_back(
    mission_type: int, items: list[Any]
) -> None:
    lb = make()
    out = _upload(lb, mission_type, items)
    acks = [m for m in out if m.get_type() == "MISSION_ACK"]
    assert [(a.type, a.mission_type) for a in acks] == [(M.MAV_MISSION_ACCEPTED, mission_type)]
    out = lb.send(M.MAVLink_mission_request_list_message(1, 1, mission_type))
    assert [m.count for m in out if m.get_type() == "MISSION_COUNT"] == [len(items)]
    for item in items:
        out = lb.send(M.MAVLink_mission_request_int_message(1, 1, item.seq, mission_type))
        (back,) = [m for m in out if m.get_type() == "MISSION_ITEM_INT"]
        assert (back.command, back.x, back.y, back.mission_type) == (
            item.command, item.x, item.y, mission_type,
        )  # fmt: skip
    # the mission itself is untouched: still only home
    out = lb.send(M.MAVLink_mission_request_list_message(1, 1, M.MAV_MISSION_TYPE_MISSION))
    assert [m.count for m in out if m.get_type() == "MISSION_COUNT"] == [1]
    # and a count of 0 clears that type again
    out = lb.send(M.MAVLink_mission_count_message(1, 1, 0, mission_type))
    assert [a.type for a in out if a.get_type() == "MISSION_ACK"] == [M.MAV_MISSION_ACCEPTED]
    out = lb.send(M.MAVLink_mission_request_list_message(1, 1, mission_type))
    assert [m.count for m in out if m.get_type() == "MISSION_COUNT"] == [0]


def test_fence_upload_refuses_a_rally_command_and_too_many_items() -> None:
    lb = make()
    wrong = _rally_items()[0]
    wrong.mission_type = FENCE
    out = _upload(lb, FENCE, [wrong])
    assert [a.type for a in out if a.get_type() == "MISSION_ACK"] == [M.MAV_MISSION_UNSUPPORTED]
    out = lb.send(M.MAVLink_mission_count_message(1, 1, GEO_CAPACITY + 1, FENCE))
    assert [a.type for a in out if a.get_type() == "MISSION_ACK"] == [M.MAV_MISSION_NO_SPACE]
    out = lb.send(M.MAVLink_mission_request_list_message(1, 1, FENCE))
    assert [m.count for m in out if m.get_type() == "MISSION_COUNT"] == [0]


def test_a_silent_fence_upload_is_cancelled_after_8_s() -> None:
    lb = make()
    lb.send(M.MAVLink_mission_count_message(1, 1, 3, FENCE))
    out = lb.advance(9.0)
    rerequests = [m for m in out if m.get_type() == "MISSION_REQUEST" and m.mission_type == FENCE]
    assert 6 <= len(rerequests) <= 9
    acks = [m for m in out if m.get_type() == "MISSION_ACK"]
    assert [(a.type, a.mission_type) for a in acks] == [(M.MAV_MISSION_OPERATION_CANCELLED, FENCE)]


def _float_item(mission_type: int, command: int, lat: float, lon: float) -> Any:
    return M.MAVLink_mission_item_message(
        1, 1, 0, M.MAV_FRAME_GLOBAL, command, 0, 1, 0, 0, 0, 0, lat, lon, 100.0, mission_type
    )


@pytest.mark.parametrize(
    ("mission_type", "command"),
    [(FENCE, M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION), (RALLY, M.MAV_CMD_NAV_RALLY_POINT)],
)
@pytest.mark.parametrize(
    ("lat", "lon", "result"),
    [
        (float("nan"), 11.92, M.MAV_MISSION_INVALID_PARAM5_X),
        (float("inf"), 11.92, M.MAV_MISSION_INVALID_PARAM5_X),
        (95.0, 11.92, M.MAV_MISSION_INVALID_PARAM5_X),
        (78.93, float("-inf"), M.MAV_MISSION_INVALID_PARAM6_Y),
        (78.93, float("nan"), M.MAV_MISSION_INVALID_PARAM6_Y),
    ],
)
def test_a_float_fence_or_rally_item_off_the_globe_is_refused_with_its_code(
    mission_type: int, command: int, lat: float, lon: float, result: int
) -> None:
    # a NaN in MISSION_ITEM (float degrees) made the old conversion raise: the error was
    # swallowed by the vehicle and the upload left unanswered. ArduPilot answers it as the
    # mission path does, and the upload ends with nothing stored.
    lb = make()
    out = _upload(lb, mission_type, [_float_item(mission_type, command, lat, lon)])
    acks = [m for m in out if m.get_type() == "MISSION_ACK"]
    assert [(a.type, a.mission_type) for a in acks] == [(result, mission_type)]
    assert lb.vehicle.handler_errors == 0
    out = lb.send(M.MAVLink_mission_request_list_message(1, 1, mission_type))
    assert [m.count for m in out if m.get_type() == "MISSION_COUNT"] == [0]
    assert not [m for m in lb.advance(2.0) if m.get_type() == "MISSION_REQUEST"]


def test_a_float_fence_item_is_stored_in_dege7_and_read_back_as_float() -> None:
    lb = make()
    item = _float_item(FENCE, M.MAV_CMD_NAV_FENCE_RETURN_POINT, 78.9312345, 11.9254321)
    out = _upload(lb, FENCE, [item])
    assert [a.type for a in out if a.get_type() == "MISSION_ACK"] == [M.MAV_MISSION_ACCEPTED]
    out = lb.send(M.MAVLink_mission_request_int_message(1, 1, 0, FENCE))
    (back,) = [m for m in out if m.get_type() == "MISSION_ITEM_INT"]
    # MISSION_ITEM carries float32 degrees: stored as that float rounded to degE7
    lat32, lon32 = struct.unpack("<2f", struct.pack("<2f", 78.9312345, 11.9254321))
    assert (back.x, back.y, back.mission_type) == (round(lat32 * 1e7), round(lon32 * 1e7), FENCE)
    out = lb.send(M.MAVLink_mission_request_message(1, 1, 0, FENCE))
    (back_f,) = [m for m in out if m.get_type() == "MISSION_ITEM"]
    assert (back_f.x, back_f.y) == pytest.approx((lat32, lon32), abs=1e-6)
    assert back_f.mission_type == FENCE
