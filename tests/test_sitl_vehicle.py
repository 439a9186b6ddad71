"""SimVehicle in virtual time: boot, heartbeat, telemetry, modes, arming, params, streams."""

from __future__ import annotations

from typing import Any

import pytest

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import mavlink2 as M
from sitl.loopback import Loopback
from sitl.vehicle import SimVehicle, VehicleConfig

ORIGIN = GeoOrigin(78.93, 11.92)


def make(**kw: Any) -> Loopback:
    cfg = VehicleConfig(system_id=1, origin=ORIGIN, home_lat_deg=78.93, home_lon_deg=11.92, **kw)
    return Loopback(SimVehicle(cfg))


def cmd_long(command: int, *p: float, target: int = 1) -> M.MAVLink_command_long_message:
    params = list(p) + [0.0] * (7 - len(p))
    return M.MAVLink_command_long_message(target, 1, command, 0, *params)


def ack_of(msgs: list, command: int) -> int:
    acks = [m for m in msgs if m.get_type() == "COMMAND_ACK" and m.command == command]
    assert len(acks) == 1, msgs
    return int(acks[0].result)


def test_heartbeat_identity_and_one_hz() -> None:
    lb = make()
    lb.advance(10.0)
    hbs = lb.take("HEARTBEAT")
    assert 9 <= len(hbs) <= 11
    assert {(h.type, h.autopilot) for h in hbs} == {
        (M.MAV_TYPE_FIXED_WING, M.MAV_AUTOPILOT_ARDUPILOTMEGA)
    }
    assert hbs[0].custom_mode == 16  # INITIALISING at boot
    assert hbs[-1].custom_mode == 0  # then MANUAL
    assert hbs[-1].get_srcSystem() == 1


def test_prearm_bit_after_gps_and_ekf_and_arming_refused_before() -> None:
    lb = make()
    lb.advance(12.0)
    last = lb.take("SYS_STATUS")[-1]
    assert not last.onboard_control_sensors_health & M.MAV_SYS_STATUS_PREARM_CHECK
    out = lb.send(cmd_long(M.MAV_CMD_COMPONENT_ARM_DISARM, 1))
    assert ack_of(out, M.MAV_CMD_COMPONENT_ARM_DISARM) == M.MAV_RESULT_FAILED
    assert any(m.get_type() == "STATUSTEXT" and m.text.startswith("Arm: ") for m in out)
    lb.advance(9.0)
    last = lb.take("SYS_STATUS")[-1]
    assert last.onboard_control_sensors_health & M.MAV_SYS_STATUS_PREARM_CHECK
    assert lb.take("HOME_POSITION")
    out = lb.send(cmd_long(M.MAV_CMD_COMPONENT_ARM_DISARM, 1))
    assert ack_of(out, M.MAV_CMD_COMPONENT_ARM_DISARM) == M.MAV_RESULT_ACCEPTED
    lb.advance(1.0)
    assert lb.take("HEARTBEAT")[-1].base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED


def test_fast_boot_is_ready_in_seconds() -> None:
    lb = make(fast_boot=True)
    lb.advance(2.5)
    assert lb.take("SYS_STATUS")[-1].onboard_control_sensors_health & (
        M.MAV_SYS_STATUS_PREARM_CHECK
    )


def test_modes_by_command_and_set_mode() -> None:
    lb = make(fast_boot=True)
    lb.advance(3.0)
    out = lb.send(cmd_long(M.MAV_CMD_DO_SET_MODE, 1, 5))
    assert ack_of(out, M.MAV_CMD_DO_SET_MODE) == M.MAV_RESULT_ACCEPTED
    lb.advance(1.0)
    assert lb.take("HEARTBEAT")[-1].custom_mode == 5
    out = lb.send(cmd_long(M.MAV_CMD_DO_SET_MODE, 1, 9))
    assert ack_of(out, M.MAV_CMD_DO_SET_MODE) == M.MAV_RESULT_FAILED
    assert "No such mode 9" in [m.text for m in out if m.get_type() == "STATUSTEXT"]
    out = lb.send(M.MAVLink_set_mode_message(1, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 11))
    assert ack_of(out, M.MAVLINK_MSG_ID_SET_MODE) == M.MAV_RESULT_ACCEPTED
    lb.advance(1.0)
    assert lb.take("HEARTBEAT")[-1].custom_mode == 11


def test_messages_for_other_systems_are_ignored() -> None:
    lb = make(fast_boot=True)
    lb.advance(3.0)
    assert lb.send(cmd_long(M.MAV_CMD_DO_SET_MODE, 1, 5, target=7)) == []


def test_unknown_command_unsupported_and_nan_params_refused() -> None:
    lb = make(fast_boot=True)
    lb.advance(3.0)
    out = lb.send(cmd_long(31999, 1))
    assert ack_of(out, 31999) == M.MAV_RESULT_UNSUPPORTED
    out = lb.send(cmd_long(M.MAV_CMD_DO_SET_MODE, 1, float("nan")))
    assert ack_of(out, M.MAV_CMD_DO_SET_MODE) == M.MAV_RESULT_FAILED
    out = lb.send(cmd_long(M.MAV_CMD_DO_CHANGE_SPEED, 0, 1e9))
    assert ack_of(out, M.MAV_CMD_DO_CHANGE_SPEED) == M.MAV_RESULT_FAILED


def test_autopilot_version_has_mission_int() -> None:
    lb = make(fast_boot=True)
    out = lb.send(cmd_long(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION))
    av = [m for m in out if m.get_type() == "AUTOPILOT_VERSION"]
    assert av and av[0].capabilities & M.MAV_PROTOCOL_CAPABILITY_MISSION_INT


def test_params_list_read_set() -> None:
    lb = make()
    out = lb.send(M.MAVLink_param_request_list_message(1, 1))
    names = {m.param_id for m in out}
    assert {
        "WP_LOITER_RAD",
        "MAV_SYSID",
        "AIRSPEED_CRUISE",
        "BATT_CAPACITY",
        "FS_LONG_ACTN",
    } <= names
    assert all(m.param_count == len(out) for m in out)
    assert sorted(m.param_index for m in out) == list(range(len(out)))
    out = lb.send(M.MAVLink_param_set_message(1, 1, b"WP_LOITER_RAD", 80.0, M.MAV_PARAM_TYPE_INT16))
    assert out[0].param_id == "WP_LOITER_RAD" and out[0].param_value == 80.0
    out = lb.send(
        M.MAVLink_param_set_message(1, 1, b"WP_LOITER_RAD", 1e12, M.MAV_PARAM_TYPE_REAL32)
    )
    assert out[0].param_value == 80.0  # out of range: refused, current value answered
    out = lb.send(M.MAVLink_param_request_read_message(1, 1, b"MAV_SYSID", -1))
    assert out[0].param_value == 1.0
    assert lb.send(M.MAVLink_param_request_read_message(1, 1, b"NO_SUCH", -1)) == []


def test_set_message_interval_and_request_data_stream() -> None:
    lb = make(fast_boot=True)
    out = lb.send(
        cmd_long(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 200_000)
    )
    assert ack_of(out, M.MAV_CMD_SET_MESSAGE_INTERVAL) == M.MAV_RESULT_ACCEPTED
    lb.advance(10.0)
    assert 45 <= len(lb.take("GLOBAL_POSITION_INT")) <= 55
    lb.send(M.MAVLink_request_data_stream_message(1, 1, M.MAV_DATA_STREAM_EXTRA1, 4, 1))
    lb.inbox.clear()
    lb.advance(10.0)
    assert 35 <= len(lb.take("ATTITUDE")) <= 45
    lb.send(M.MAVLink_request_data_stream_message(1, 1, M.MAV_DATA_STREAM_ALL, 0, 0))
    lb.inbox.clear()
    lb.advance(5.0)
    assert lb.take("ATTITUDE") == [] and lb.take("HEARTBEAT")


def test_time_boot_follows_virtual_time() -> None:
    lb = make(fast_boot=True)
    lb.advance(100.0, step_s=1.0)
    gp = lb.take("GLOBAL_POSITION_INT")[-1]
    assert gp.time_boot_ms == pytest.approx(100_000, abs=1000)


def test_garbage_and_bad_crc_never_raise() -> None:
    lb = make(fast_boot=True)
    lb.send_raw(bytes(range(256)) * 4)
    frame = bytearray(lb.mav.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0).pack(lb.mav))
    frame[-1] ^= 0xFF
    assert lb.send_raw(bytes(frame)) == []
    lb.advance(2.0)
    assert lb.take("HEARTBEAT")


def test_airborne_start_loiters_over_home_in_auto() -> None:
    lb = make(airborne=True, airborne_alt_m=120.0, launch_x_m=300.0, launch_y_m=0.0)
    lb.advance(120.0)
    hb = lb.take("HEARTBEAT")[-1]
    assert hb.custom_mode == 10 and hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
    gp = lb.take("GLOBAL_POSITION_INT")[-1]
    assert gp.relative_alt == pytest.approx(120_000, abs=2000)
    x, y, _ = ORIGIN.to_local(gp.lat * 1e-7, gp.lon * 1e-7)
    assert 90.0 < (x * x + y * y) ** 0.5 < 130.0  # on the loiter circle (>= min turn radius)
    assert lb.take("MISSION_CURRENT")[-1].seq == 1


def test_low_battery_warns_and_rtl_when_configured() -> None:
    lb = make(airborne=True, params={"BATT_FS_LOW_ACT": 1})
    lb.advance(2.0)
    lb.vehicle.set_battery_remaining(0.05)
    lb.advance(2.0)
    assert any(t.startswith("Battery 1 is low") for t in lb.texts())
    assert lb.take("HEARTBEAT")[-1].custom_mode == 11
    assert lb.take("BATTERY_STATUS")[-1].battery_remaining <= 5


def test_battery_drains_in_flight() -> None:
    lb = make(airborne=True)
    lb.advance(2.0)
    first = lb.take("BATTERY_STATUS")[-1]
    lb.advance(600.0, step_s=1.0)
    last = lb.take("BATTERY_STATUS")[-1]
    assert last.current_consumed > first.current_consumed + 2000
    assert last.battery_remaining < first.battery_remaining


def test_attitude_in_a_clockwise_loiter_banks_right() -> None:
    lb = make(airborne=True, launch_x_m=150.0, launch_y_m=0.0, launch_heading_rad=-1.5708)
    lb.advance(120.0)
    att = lb.take("ATTITUDE")[-1]
    assert att.roll > 0.1 and att.yawspeed > 0.05  # right wing down, heading increasing


def test_mission_start_timesync_and_loiter_command() -> None:
    lb = make(fast_boot=True)
    lb.advance(3.0)
    out = lb.send(cmd_long(M.MAV_CMD_MISSION_START))
    assert ack_of(out, M.MAV_CMD_MISSION_START) == M.MAV_RESULT_ACCEPTED
    lb.advance(1.0)
    assert lb.take("HEARTBEAT")[-1].custom_mode in (10, 11)  # AUTO (empty mission: RTL)
    out = lb.send(cmd_long(M.MAV_CMD_NAV_LOITER_UNLIM))
    assert ack_of(out, M.MAV_CMD_NAV_LOITER_UNLIM) == M.MAV_RESULT_ACCEPTED
    out = lb.send(M.MAVLink_timesync_message(0, 123456))
    assert out[0].ts1 == 123456 and out[0].tc1 == pytest.approx(lb.t_s * 1e9, rel=1e-3)


def test_long_statustext_is_chunked() -> None:
    from sitl.statustext import StatusTextFactory

    text = "PreArm: " + "x" * 120
    chunks = StatusTextFactory().make(text)
    assert len(chunks) == 3 and len({c.id for c in chunks}) == 1 and chunks[0].id != 0
    assert [c.chunk_seq for c in chunks] == [0, 1, 2]
    parts = [c.text.decode() if isinstance(c.text, bytes) else c.text for c in chunks]
    assert "".join(parts) == text
    assert StatusTextFactory().make("short")[0].id == 0
