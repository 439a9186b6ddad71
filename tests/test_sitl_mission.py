"""Mission protocol (vehicle side) and mission flight of SimVehicle, in virtual time."""

from __future__ import annotations

from typing import Any

import pytest

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import mavlink2 as M
from sitl.loopback import Loopback
from sitl.vehicle import SimVehicle, VehicleConfig

ORIGIN = GeoOrigin(78.93, 11.92)
REL = M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


def make(airborne: bool = True, **kw: Any) -> Loopback:
    cfg = VehicleConfig(
        system_id=1,
        origin=ORIGIN,
        home_lat_deg=78.93,
        home_lon_deg=11.92,
        airborne=airborne,
        fast_boot=True,
        launch_x_m=105.0,
        launch_y_m=0.0,
        launch_heading_rad=1.5708,
        **kw,
    )
    lb = Loopback(SimVehicle(cfg))
    lb.advance(3.0)
    lb.inbox.clear()
    return lb


def item(
    seq: int,
    cmd: int,
    east_m: float = 0.0,
    north_m: float = 0.0,
    alt_m: float = 100.0,
    p1: float = 0.0,
    p2: float = 0.0,
    p3: float = 0.0,
    frame: int = REL,
    lat_deg: float | None = None,
) -> Any:
    lat, lon, _ = ORIGIN.to_geodetic(east_m, north_m)
    if lat_deg is not None:
        lat = lat_deg
    return M.MAVLink_mission_item_int_message(
        1, 1, seq, frame, cmd, 0, 1, p1, p2, p3, 0.0, round(lat * 1e7), round(lon * 1e7), alt_m, 0
    )


def upload(lb: Loopback, items: list[Any]) -> Any:
    """Upload answering the vehicle's requests; returns the final MISSION_ACK."""
    out = lb.send(M.MAVLink_mission_count_message(1, 1, len(items), 0))
    for _ in range(len(items) + 1):
        reqs = [m for m in out if m.get_type() == "MISSION_REQUEST"]
        acks = [m for m in out if m.get_type() == "MISSION_ACK"]
        if acks:
            return acks[-1]
        assert reqs, out
        out = lb.send(items[reqs[-1].seq])
    raise AssertionError("upload did not finish")


def download(lb: Loopback, as_int: bool = True) -> list[Any]:
    out = lb.send(M.MAVLink_mission_request_list_message(1, 1, 0))
    count = next(m for m in out if m.get_type() == "MISSION_COUNT").count
    items = []
    for seq in range(count):
        req = (
            M.MAVLink_mission_request_int_message if as_int else M.MAVLink_mission_request_message
        )(1, 1, seq, 0)
        items.append(lb.send(req)[0])
    return items


HOME = item(0, M.MAV_CMD_NAV_WAYPOINT, alt_m=0.0)


def test_upload_uses_mission_request_and_download_roundtrip() -> None:
    lb = make()
    mission = [
        HOME,
        item(1, M.MAV_CMD_NAV_WAYPOINT, 1000, 0),
        item(2, M.MAV_CMD_NAV_LOITER_TIME, 1000, 1000, p1=30),
        item(3, M.MAV_CMD_NAV_LOITER_UNLIM, 0, 1000, p3=-150),
    ]
    out = lb.send(M.MAVLink_mission_count_message(1, 1, 4, 0))
    assert [m.get_type() for m in out] == ["MISSION_REQUEST"] and out[0].seq == 0
    ack = upload(lb, mission)
    assert ack.type == M.MAV_MISSION_ACCEPTED
    assert "Flight plan received" in lb.texts()
    got = download(lb)
    assert [m.get_type() for m in got] == ["MISSION_ITEM_INT"] * 4
    assert [m.command for m in got[1:]] == [16, 19, 17]
    assert got[3].param3 == -150 and got[2].param1 == 30
    assert got[1].x == mission[1].x and got[1].y == mission[1].y
    assert got[0].x == round(78.93e7)  # item 0 is home
    floats = download(lb, as_int=False)
    assert floats[1].get_type() == "MISSION_ITEM"
    assert floats[1].x == pytest.approx(mission[1].x * 1e-7, abs=1e-5)  # float32


def test_mission_item_float_accepted() -> None:
    lb = make()
    lat, lon, _ = ORIGIN.to_geodetic(500, 0)
    floats = [
        M.MAVLink_mission_item_message(
            1, 1, s, M.MAV_FRAME_GLOBAL_RELATIVE_ALT, 16, 0, 1, 0, 0, 0, 0, lat, lon, 100, 0
        )
        for s in range(2)
    ]
    assert upload(lb, floats).type == M.MAV_MISSION_ACCEPTED
    assert download(lb)[1].x == pytest.approx(lat * 1e7, abs=100)  # float32 on the wire


@pytest.mark.parametrize(
    ("bad", "result"),
    [
        (item(1, 31999), M.MAV_MISSION_UNSUPPORTED),
        (item(1, 16, frame=M.MAV_FRAME_BODY_NED), M.MAV_MISSION_UNSUPPORTED_FRAME),
        (item(1, 16, lat_deg=95.0), M.MAV_MISSION_INVALID_PARAM5_X),
    ],
)
def test_bad_items_rejected_and_old_mission_destroyed(bad: Any, result: int) -> None:
    lb = make()
    assert upload(lb, [HOME, item(1, 16, 500), item(2, 16, 900), item(3, 16, 1200)]).type == 0
    ack = upload(lb, [HOME, bad])
    assert ack.type == result
    assert len(download(lb)) == 2  # truncated at MISSION_COUNT: the old items 2, 3 are gone


def test_too_many_items_no_space() -> None:
    lb = make()
    out = lb.send(M.MAVLink_mission_count_message(1, 1, 656, 0))
    assert out[0].get_type() == "MISSION_ACK" and out[0].type == M.MAV_MISSION_NO_SPACE


def test_upload_before_ready_no_space() -> None:
    cfg = VehicleConfig(system_id=1, origin=ORIGIN, home_lat_deg=78.93, home_lon_deg=11.92)
    lb = Loopback(SimVehicle(cfg))
    out = lb.send(M.MAVLink_mission_count_message(1, 1, 3, 0))
    assert out[0].type == M.MAV_MISSION_NO_SPACE
    assert "Only 0 items are supported" in [m.text for m in out if m.get_type() == "STATUSTEXT"]


def test_wrong_seq_invalid_sequence_then_continues() -> None:
    lb = make()
    lb.send(M.MAVLink_mission_count_message(1, 1, 2, 0))
    out = lb.send(item(1, 16, 500))
    assert out[0].type == M.MAV_MISSION_INVALID_SEQUENCE
    out = lb.send(HOME)
    assert out[0].get_type() == "MISSION_REQUEST" and out[0].seq == 1
    out = lb.send(item(1, 16, 500))
    assert out[0].type == M.MAV_MISSION_ACCEPTED


def test_second_gcs_denied_and_stray_item_error() -> None:
    lb = make()
    other = Loopback(lb.vehicle, gcs_sysid=254, gcs_compid=1)
    other.t_s = lb.t_s
    out = lb.send(item(1, 16, 500))
    assert out[0].type == M.MAV_MISSION_ERROR  # stray item, no upload
    lb.send(M.MAVLink_mission_count_message(1, 1, 3, 0))
    out = other.send(M.MAVLink_mission_count_message(1, 1, 2, 0))
    assert out[0].type == M.MAV_MISSION_DENIED


def test_rerequest_every_second_and_cancel_after_8s() -> None:
    lb = make()
    lb.send(M.MAVLink_mission_count_message(1, 1, 3, 0))
    lb.send(HOME)
    lb.inbox.clear()
    lb.advance(7.5)
    reqs = lb.take("MISSION_REQUEST")
    assert 6 <= len(reqs) <= 8 and {r.seq for r in reqs} == {1}
    assert lb.take("MISSION_ACK") == []
    lb.advance(1.0)
    acks = lb.take("MISSION_ACK")
    assert [a.type for a in acks] == [M.MAV_MISSION_OPERATION_CANCELLED]
    assert "Mission upload timeout" in lb.texts()


def test_clear_all_keeps_home() -> None:
    lb = make()
    upload(lb, [HOME, item(1, 16, 500)])
    out = lb.send(M.MAVLink_mission_clear_all_message(1, 1, 0))
    assert out[0].type == M.MAV_MISSION_ACCEPTED
    assert len(download(lb)) == 1


def reached(lb: Loopback) -> list[int]:
    return [m.seq for m in lb.inbox if m.get_type() == "MISSION_ITEM_REACHED"]


def test_fly_waypoint_loiter_time_then_mission_complete_rtl() -> None:
    lb = make()
    mission = [
        HOME,
        item(1, 16, 1500, 0),
        item(2, M.MAV_CMD_NAV_LOITER_TIME, 1500, 1500, p1=30),
        item(3, 16, 0, 1500),
    ]
    assert upload(lb, mission).type == M.MAV_MISSION_ACCEPTED
    out = lb.send(M.MAVLink_mission_set_current_message(1, 1, 1))
    assert "Mission: 1 WP" in [m.text for m in out if m.get_type() == "STATUSTEXT"]
    lb.run_until(lambda m: m.get_type() == "MISSION_ITEM_REACHED", 200)
    assert reached(lb) == [1]
    assert any(
        t.startswith("Reached waypoint #1 dist") or t.startswith("Passed waypoint #1")
        for t in lb.texts()
    )
    assert "Mission: 2 LoitTime" in lb.texts()
    t_start = lb.t_s
    lb.run_until(lambda m: m.get_type() == "MISSION_ITEM_REACHED", 300)
    assert reached(lb) == [1, 2]
    assert "Loiter time complete" in lb.texts()
    assert lb.t_s - t_start > 30.0 + 1500 / 22 * 0.8
    lb.run_until(lambda m: m.get_type() == "MISSION_ITEM_REACHED", 300)
    lb.advance(1.0)
    assert reached(lb) == [1, 2, 3]  # each exactly once
    assert "Mission complete, changing mode to RTL" in lb.texts()
    assert lb.take("HEARTBEAT")[-1].custom_mode == 11
    last = lb.take("MISSION_CURRENT")[-1]
    # ArduPilot: total excludes home, so on (and after) the last item seq == total
    assert (last.seq, last.total, last.mission_state) == (3, 3, M.MISSION_STATE_COMPLETE)


def test_pilots_rtl_mid_mission_is_no_mission_end() -> None:
    """floe's target mission [home, timed loiter, unlimited loiter]: total 2 (home
    excluded); an RTL switched on the timed loiter leaves the mission unfinished (no
    "Mission complete", mission_state not COMPLETE), as ArduPlane's AUTO exit does."""
    lb = make()
    upload(lb, [HOME, item(1, M.MAV_CMD_NAV_LOITER_TIME, 1500, 0, p1=30),
                item(2, M.MAV_CMD_NAV_LOITER_UNLIM, 1500, 0)])  # fmt: skip
    lb.send(M.MAVLink_mission_set_current_message(1, 1, 1))
    lb.advance(10.0)
    current = lb.take("MISSION_CURRENT")[-1]
    assert (current.seq, current.total, current.mission_state) == (1, 2, M.MISSION_STATE_ACTIVE)
    lb.send(M.MAVLink_set_mode_message(1, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 11))
    lb.advance(5.0)
    assert lb.take("HEARTBEAT")[-1].custom_mode == 11
    current = lb.take("MISSION_CURRENT")[-1]
    assert current.total == 2 and current.mission_state != M.MISSION_STATE_COMPLETE
    assert not [t for t in lb.texts() if "Mission complete" in t]


def test_loiter_time_flies_wp_loiter_rad_enlarged_and_unlim_honours_param3() -> None:
    lb = make(min_turn_radius_m=50.0, params={"WP_LOITER_RAD": 80})
    upload(lb, [HOME, item(1, M.MAV_CMD_NAV_LOITER_TIME, 0, 0, p1=1000, p3=300)])
    lb.send(M.MAVLink_mission_set_current_message(1, 1, 1))
    lb.advance(200.0)
    v = lb.vehicle
    r = v.airframe.distance_to_m(*v.home_xy_m)
    assert r == pytest.approx(92.0, abs=6.0)  # 80 m commanded flies ~92 m, param3 ignored
    upload(lb, [HOME, item(1, M.MAV_CMD_NAV_LOITER_UNLIM, 0, 0, p3=200)])
    lb.send(M.MAVLink_mission_set_current_message(1, 1, 1))
    lb.advance(200.0)
    assert v.airframe.distance_to_m(*v.home_xy_m) == pytest.approx(230.0, abs=8.0)


def test_reupload_keeps_current_item_until_set_current() -> None:
    lb = make()
    upload(
        lb,
        [
            HOME,
            item(1, 16, 200, 0),
            item(2, 16, 400, 0),
            item(3, M.MAV_CMD_NAV_LOITER_UNLIM, 3000, 0),
        ],
    )
    lb.send(M.MAVLink_mission_set_current_message(1, 1, 3))
    lb.advance(10.0)
    upload(lb, [HOME, item(1, M.MAV_CMD_NAV_LOITER_UNLIM, -3000, 0)])
    lb.inbox.clear()
    lb.advance(20.0)
    mc = lb.take("MISSION_CURRENT")[-1]
    assert mc.seq == 3 and mc.total == 1  # seq > total after the overwrite
    x_before = lb.vehicle.airframe.x_m
    out = lb.send(
        M.MAVLink_command_long_message(
            1, 1, M.MAV_CMD_DO_SET_MISSION_CURRENT, 0, 1, 0, 0, 0, 0, 0, 0
        )
    )
    assert [m.result for m in out if m.get_type() == "COMMAND_ACK"] == [M.MAV_RESULT_ACCEPTED]
    lb.advance(60.0)
    assert lb.vehicle.airframe.x_m < x_before - 300  # diverted west at once
    assert lb.take("MISSION_CURRENT")[-1].seq == 1


def test_same_seq_set_current_restarts_loiter_timer() -> None:
    lb = make()
    upload(lb, [HOME, item(1, M.MAV_CMD_NAV_LOITER_TIME, 0, 0, p1=40)])
    lb.send(M.MAVLink_mission_set_current_message(1, 1, 1))
    lb.advance(30.0)
    out = lb.send(M.MAVLink_mission_set_current_message(1, 1, 1))
    assert "Mission: 1 LoitTime" in [m.text for m in out if m.get_type() == "STATUSTEXT"]
    lb.advance(30.0)
    assert reached(lb) == []  # 60 s in total, but the timer restarted


def test_takeoff_from_ground_in_auto() -> None:
    lb = make(airborne=False)
    upload(
        lb,
        [
            HOME,
            item(1, M.MAV_CMD_NAV_TAKEOFF, alt_m=60, p1=10),
            item(2, M.MAV_CMD_DO_CHANGE_SPEED, p2=18),
            item(3, M.MAV_CMD_NAV_LOITER_UNLIM, 0, 0, alt_m=80),
        ],
    )
    lb.send(M.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    lb.send(M.MAVLink_command_long_message(1, 1, 176, 0, 1, 10, 0, 0, 0, 0, 0))
    lb.run_until(lambda m: m.get_type() == "MISSION_ITEM_REACHED", 60)
    assert reached(lb) == [1]
    assert any(t.startswith("Takeoff complete") for t in lb.texts())
    assert "Mission: 2 ChangeSpeed" in lb.texts() and "Mission: 3 LoitUnlim" in lb.texts()
    lb.advance(30.0)
    assert lb.take("VFR_HUD")[-1].airspeed == pytest.approx(18.0, abs=0.5)


def test_nav_return_to_launch_switches_to_rtl() -> None:
    lb = make()
    upload(lb, [HOME, item(1, M.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0)])
    lb.send(M.MAVLink_mission_set_current_message(1, 1, 1))
    lb.advance(2.0)
    assert lb.take("HEARTBEAT")[-1].custom_mode == 11


def test_loiter_turns_completes() -> None:
    lb = make()
    upload(
        lb,
        [
            HOME,
            item(1, M.MAV_CMD_NAV_LOITER_TURNS, 0, 0, p1=2, p3=150),
            item(2, M.MAV_CMD_NAV_LOITER_UNLIM),
        ],
    )
    lb.send(M.MAVLink_mission_set_current_message(1, 1, 1))
    lb.run_until(lambda m: m.get_type() == "MISSION_ITEM_REACHED", 200)
    assert reached(lb) == [1] and "Loiter orbits complete" in lb.texts()
    assert lb.t_s > 2 * 2 * 3.14159 * 172 / 22 * 0.9


def cmd_int(
    command: int,
    p1: float = 0,
    p2: float = 0,
    p3: float = 0,
    east_m: float = 0,
    north_m: float = 0,
    alt_m: float = 100,
) -> Any:
    lat, lon, _ = ORIGIN.to_geodetic(east_m, north_m)
    return M.MAVLink_command_int_message(
        1, 1, REL, command, 0, 0, p1, p2, p3, 0, round(lat * 1e7), round(lon * 1e7), alt_m
    )


def test_guided_reposition_needs_change_mode_flag_and_arrives() -> None:
    lb = make()
    out = lb.send(cmd_int(M.MAV_CMD_DO_REPOSITION, -1, 0, 150, 1500, 0))
    assert [m.result for m in out if m.get_type() == "COMMAND_ACK"] == [M.MAV_RESULT_FAILED]
    out = lb.send(cmd_int(M.MAV_CMD_DO_REPOSITION, -1, 1, 150, 1500, 0))
    assert [m.result for m in out if m.get_type() == "COMMAND_ACK"] == [M.MAV_RESULT_ACCEPTED]
    lb.advance(1.0)
    assert lb.take("HEARTBEAT")[-1].custom_mode == 15
    assert lb.run_until(lambda m: m.get_type() == "MISSION_ITEM_REACHED", 200) is not None
    assert reached(lb) == [0]
    lb.advance(120.0)
    v = lb.vehicle
    x, y, _ = ORIGIN.to_local(*ORIGIN.to_geodetic(1500, 0)[:2])
    assert v.airframe.distance_to_m(x, y) == pytest.approx(172.5, abs=8.0)
    # guided MISSION_ITEM (current = 2) moves the point
    lat, lon, _ = ORIGIN.to_geodetic(0, 1500)
    out = lb.send(
        M.MAVLink_mission_item_int_message(
            1, 1, 0, REL, 16, 2, 1, 0, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), 100
        )
    )
    assert out[0].get_type() == "MISSION_ACK" and out[0].type == M.MAV_MISSION_ACCEPTED
    lb.advance(200.0)
    assert v.airframe.distance_to_m(0, 1500) < 200


def test_reposition_as_command_long_unsupported() -> None:
    lb = make()
    out = lb.send(
        M.MAVLink_command_long_message(
            1, 1, M.MAV_CMD_DO_REPOSITION, 0, -1, 1, 0, 0, 78.94, 11.92, 100
        )
    )
    assert [m.result for m in out if m.get_type() == "COMMAND_ACK"] == [M.MAV_RESULT_UNSUPPORTED]


def test_download_edge_cases_as_ardupilot() -> None:
    lb = make()
    upload(lb, [HOME, item(1, 16, 500)])
    out = lb.send(M.MAVLink_mission_request_int_message(1, 1, 5, 0))
    assert [m.get_type() for m in out] == ["MISSION_COUNT", "MISSION_ACK"]
    assert out[0].count == 2 and out[1].type == M.MAV_MISSION_INVALID_SEQUENCE
    lb.send(M.MAVLink_mission_count_message(1, 1, 3, 0))
    out = lb.send(M.MAVLink_mission_request_int_message(1, 1, 0, 0))
    assert out[0].type == M.MAV_MISSION_DENIED  # no download during an upload
    out = lb.send(M.MAVLink_mission_clear_all_message(1, 1, 0))
    assert out[0].type == M.MAV_MISSION_ERROR
    other = Loopback(lb.vehicle, gcs_sysid=254, gcs_compid=1)
    other.t_s = lb.t_s
    assert other.send(HOME)[0].type == M.MAV_MISSION_DENIED  # right seq, wrong sender
    assert lb.send(HOME)[0].get_type() == "MISSION_REQUEST"  # the uploader goes on


NAN = float("nan")
READBACK_CASES = [
    (16, REL, (7.0, 30.0, 5.0, NAN), 100.456),  # hold time and NaN yaw dropped
    (16, REL, (0.0, 300.0, -2.0, 0.0), 80.0),  # acceptance clamped to a byte
    (17, REL, (0.0, 0.0, -150.7, 0.0), 100.0),  # radius as uint16, sign kept
    (18, REL, (3.0, 0.0, 400.0, 1.0), 100.0),  # radius above 255 m: tens of metres
    (19, REL, (30.9, 0.0, -80.0, 0.0), 120.0),  # seconds uint16, param3 only its sign
    (19, M.MAV_FRAME_GLOBAL_INT, (45.0, 0.0, 0.0, 2.0), 130.0),  # INT frame -> GLOBAL
    (22, REL, (15.0, 0.0, 0.0, NAN), 60.0),  # takeoff pitch kept
    (178, M.MAV_FRAME_MISSION, (0.0, 18.5, 60.0, 0.0), 0.0),  # change speed
]


@pytest.mark.parametrize(("cmd", "frame", "params", "alt"), READBACK_CASES)
def test_download_returns_what_ardupilot_keeps(
    cmd: int, frame: int, params: tuple[float, ...], alt: float
) -> None:
    """The vehicle stores items as AP_Mission does; the daemon's independent predictor of
    ArduPlane's read-back (groundstation.mavlink.mission_verify) must agree with it."""
    from groundstation.mavlink.mission_items import MissionItem as GcsItem
    from groundstation.mavlink.mission_verify import arduplane_readback

    lb = make()
    lat, lon, _ = ORIGIN.to_geodetic(300.0, 200.0)
    x, y = (round(lat * 1e7), round(lon * 1e7)) if cmd != 178 else (0, 0)
    sent = M.MAVLink_mission_item_int_message(1, 1, 1, frame, cmd, 0, 1, *params, x, y, alt, 0)
    assert upload(lb, [HOME, sent]).type == M.MAV_MISSION_ACCEPTED
    got = download(lb)[1]
    p1, p2, p3, p4 = params
    predicted = arduplane_readback(
        GcsItem(1, cmd, frame, param1=p1, param2=p2, param3=p3, param4=p4, x=x, y=y, z=alt)
    )
    for name in ("frame", "x", "y", "autocontinue"):
        assert getattr(got, name) == getattr(predicted, name), name
    for name in ("param1", "param2", "param3", "param4", "z"):
        assert getattr(got, name) == pytest.approx(getattr(predicted, name), abs=1e-4), name


def test_nan_altitude_refused_and_nan_yaw_accepted() -> None:
    lb = make()
    assert upload(lb, [HOME, item(1, 16, 500, alt_m=NAN)]).type == M.MAV_MISSION_INVALID_PARAM7
    qgc_like = M.MAVLink_mission_item_int_message(
        1, 1, 1, REL, 16, 0, 1, 0, 0, 0, NAN, round(78.935e7), round(11.92e7), 100, 0
    )
    assert upload(lb, [HOME, qgc_like]).type == M.MAV_MISSION_ACCEPTED


def test_auto_after_mission_complete_restarts_at_item_1() -> None:
    lb = make()
    upload(lb, [HOME, item(1, 16, 300, 0), item(2, 16, 600, 0)])
    lb.send(M.MAVLink_mission_set_current_message(1, 1, 2))
    lb.run_until(lambda m: m.get_type() == "MISSION_ITEM_REACHED", 120)
    lb.advance(1.0)
    assert lb.take("HEARTBEAT")[-1].custom_mode == 11  # mission complete -> RTL
    lb.inbox.clear()
    lb.send(M.MAVLink_command_long_message(1, 1, 176, 0, 1, 10, 0, 0, 0, 0, 0))
    assert "Mission: 1 WP" in lb.texts()


def test_loiter_sense_follows_the_sign_of_the_radius() -> None:
    lb = make()
    upload(lb, [HOME, item(1, M.MAV_CMD_NAV_LOITER_UNLIM, 0, 0, p3=-200)])
    lb.send(M.MAVLink_mission_set_current_message(1, 1, 1))
    lb.advance(150.0)
    assert lb.take("ATTITUDE")[-1].roll < -0.1  # counter-clockwise: left wing down
    upload(lb, [HOME, item(1, M.MAV_CMD_NAV_LOITER_UNLIM, 0, 0, p3=200)])
    lb.send(M.MAVLink_mission_set_current_message(1, 1, 1))
    lb.advance(150.0)
    assert lb.take("ATTITUDE")[-1].roll > 0.1


def test_a_new_leg_already_past_its_finish_line_starts_where_the_vehicle_is() -> None:
    """ArduPlane's set_next_WP: a leg from the previous waypoint whose finish line the
    vehicle has already crossed starts at the vehicle instead, so the new waypoint is flown
    to, not 'passed' at once (the daemon's runs looped loiter_end -> upload every 0.3 s)."""
    lb = make()
    upload(lb, [HOME, item(1, 16, 0, 3000), item(2, M.MAV_CMD_NAV_LOITER_UNLIM, 0, 3000)])
    lb.send(M.MAVLink_mission_set_current_message(1, 1, 1))
    lb.advance(10.0)
    y_m = lb.vehicle.airframe.y_m
    assert 0.0 < y_m < 1000.0  # flying north, short of the new waypoint
    # the new waypoint lies between the vehicle and the old one: past the old leg's line
    upload(lb, [HOME, item(1, 16, 0, 1000), item(2, M.MAV_CMD_NAV_LOITER_UNLIM, 0, 1000)])
    lb.inbox.clear()
    lb.send(M.MAVLink_mission_set_current_message(1, 1, 1))
    lb.advance(2.0)
    assert reached(lb) == [] and not any(t.startswith("Passed waypoint") for t in lb.texts())
    lb.run_until(lambda m: m.get_type() == "MISSION_ITEM_REACHED", 120)
    assert reached(lb) == [1]
    assert abs(lb.vehicle.airframe.y_m - 1000.0) < 200.0
