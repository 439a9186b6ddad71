"""The DO_SET_HOME exchange on its own (``groundstation.mavlink.vehicle_commands.HomeSet``):
messages in, sends out, mission time passed by hand; no sockets, no clock."""

from __future__ import annotations

import math
from typing import Any

import pytest

from domain.errors import LocalProtocolError
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_transfer import Finished, Send, TransferCode
from groundstation.mavlink.vehicle_commands import (
    MSG_ID_HOME_POSITION,
    HomeSet,
    HomeSetState,
    ground_distance_m,
)

M = mavlink2
VEH_SYS, VEH_COMP, GCS_SYS = 1, 1, 245
LAT, LON, ALT = 78.2, 15.6, 12.5


def from_vehicle(msg: MAVLinkMessage, sysid: int = VEH_SYS) -> Any:
    (decoded,) = MavlinkDecoder().feed(MavlinkEncoder(sysid, VEH_COMP).encode(msg))
    return decoded


def ack(result: int, command: int = M.MAV_CMD_DO_SET_HOME) -> Any:
    return from_vehicle(M.MAVLink_command_ack_message(command, result, 0, 0, GCS_SYS, 0))


def home_position(lat_deg: float, lon_deg: float, alt_m: float = ALT) -> Any:
    return from_vehicle(M.MAVLink_home_position_message(
        round(lat_deg * 1e7), round(lon_deg * 1e7), round(alt_m * 1000), 0.0, 0.0, 0.0,
        [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0,
    ))  # fmt: skip


def sent(actions: list[Any]) -> list[Any]:
    return [a.msg for a in actions if isinstance(a, Send)]


def finished(actions: list[Any]) -> Any:
    results = [a.result for a in actions if isinstance(a, Finished)]
    return results[0] if results else None


def machine(alt_m: float | None = ALT, **options: Any) -> HomeSet:
    return HomeSet(VEH_SYS, VEH_COMP, LAT, LON, alt_m, own_system=GCS_SYS, **options)


def test_set_home_is_a_command_int_in_the_global_frame_then_ack_and_home_position_confirm() -> None:
    m = machine()
    (msg,) = sent(m.start(0.0))
    assert msg.get_type() == "COMMAND_INT"
    assert msg.command == M.MAV_CMD_DO_SET_HOME and msg.frame == M.MAV_FRAME_GLOBAL
    assert msg.param1 == 0.0  # use the location given
    assert (msg.x, msg.y) == (round(LAT * 1e7), round(LON * 1e7))
    assert msg.z == pytest.approx(ALT)
    assert (msg.target_system, msg.target_component) == (VEH_SYS, VEH_COMP)
    assert m.receive(ack(M.MAV_RESULT_ACCEPTED), 0.1) == []
    assert m.state is HomeSetState.CONFIRMING
    result = finished(m.receive(home_position(LAT + 1e-6, LON), 0.2))
    assert result.ok and result.code is TransferCode.SUCCESS
    assert m.home is not None and m.home[0] == pytest.approx(LAT + 1e-6)
    assert m.error_m == pytest.approx(0.111, abs=0.01)
    assert m.ack_result == M.MAV_RESULT_ACCEPTED


def test_a_home_position_before_the_ack_confirms_once_the_ack_accepts() -> None:
    m = machine()
    m.start(0.0)
    assert m.receive(home_position(LAT, LON), 0.05) == []
    assert not m.done  # the ACK decides
    assert finished(m.receive(ack(M.MAV_RESULT_ACCEPTED), 0.1)).ok


def test_silence_resends_the_command_then_asks_for_home_position_then_gives_up() -> None:
    m = machine(retries=2)
    m.start(0.0)
    again = sent(m.poll(1.0))
    assert [x.get_type() for x in again] == ["COMMAND_INT"]
    m.receive(ack(M.MAV_RESULT_ACCEPTED), 1.1)
    ask = sent(m.poll(2.1))
    assert [x.get_type() for x in ask] == ["COMMAND_LONG"]
    assert ask[0].command == M.MAV_CMD_REQUEST_MESSAGE and ask[0].param1 == MSG_ID_HOME_POSITION
    m.receive(home_position(LAT + 0.01, LON), 2.2)  # the old home, ~1.1 km away: not ours
    assert not m.done
    m.poll(3.1)
    result = finished(m.poll(4.1))
    assert result is not None and not result.ok and result.code is TransferCode.TIMEOUT
    assert "no HOME_POSITION within 5 m" in result.message and "1111.9 m off" in result.message
    assert m.home is None and m.error_m == pytest.approx(1112, abs=2)


def test_no_ack_at_all_ends_with_a_timeout_after_the_retries() -> None:
    m = machine(retries=1)
    m.start(0.0)
    m.poll(1.0)
    result = finished(m.poll(2.0))
    assert result.code is TransferCode.TIMEOUT and "no COMMAND_ACK" in result.message


def test_a_refusing_vehicle_ends_it_with_its_code() -> None:
    m = machine()
    m.start(0.0)
    assert m.receive(ack(M.MAV_RESULT_IN_PROGRESS), 0.1) == []
    assert m.receive(ack(M.MAV_RESULT_ACCEPTED, M.MAV_CMD_REQUEST_MESSAGE), 0.1) == []
    result = finished(m.receive(ack(M.MAV_RESULT_DENIED), 0.2))
    assert not result.ok and result.code is TransferCode.DENIED
    assert result.remote_code == "MAV_RESULT_DENIED"
    assert m.receive(home_position(LAT, LON), 0.3) == []  # after the end: nothing


def test_unknown_altitude_is_read_from_home_position_first() -> None:
    m = machine(alt_m=None)
    (ask,) = sent(m.start(0.0))
    assert ask.command == M.MAV_CMD_REQUEST_MESSAGE and ask.param1 == MSG_ID_HOME_POSITION
    assert m.state is HomeSetState.READING_HOME
    (cmd,) = sent(m.receive(home_position(LAT + 0.02, LON - 0.02, 31.0), 0.1))
    assert cmd.get_type() == "COMMAND_INT" and cmd.z == pytest.approx(31.0)
    m.receive(ack(M.MAV_RESULT_ACCEPTED), 0.2)
    result = finished(m.receive(home_position(LAT, LON, 31.0), 0.3))
    assert result.ok and m.home == pytest.approx((LAT, LON, 31.0))


def test_other_systems_and_garbage_are_ignored() -> None:
    m = machine()
    m.start(0.0)
    assert m.receive(from_vehicle(M.MAVLink_command_ack_message(
        M.MAV_CMD_DO_SET_HOME, M.MAV_RESULT_ACCEPTED, 0, 0, GCS_SYS, 0), sysid=7), 0.1) == []
    assert m.receive(from_vehicle(M.MAVLink_command_ack_message(  # for another GCS
        M.MAV_CMD_DO_SET_HOME, M.MAV_RESULT_ACCEPTED, 0, 0, 255, 0)), 0.1) == []
    m.receive(ack(M.MAV_RESULT_ACCEPTED), 0.2)
    assert m.receive(home_position(0.0, 0.0), 0.3) == []  # no position
    assert not m.done


def test_a_reboot_ends_it() -> None:
    m = machine()
    m.start(0.0)
    assert finished(m.notify_vehicle_rebooted(0.5)).code is TransferCode.VEHICLE_REBOOTED


def test_bad_arguments_are_local_errors() -> None:
    with pytest.raises(LocalProtocolError):
        HomeSet(VEH_SYS, VEH_COMP, math.nan, LON, ALT)
    with pytest.raises(LocalProtocolError):
        HomeSet(VEH_SYS, VEH_COMP, LAT, 200.0, ALT)
    with pytest.raises(LocalProtocolError):
        HomeSet(VEH_SYS, VEH_COMP, LAT, LON, math.inf)


def test_ground_distance() -> None:
    assert ground_distance_m(LAT, LON, LAT, LON) == 0.0
    assert ground_distance_m(0.0, 0.0, 0.001, 0.0) == pytest.approx(111.19, abs=0.01)
    assert ground_distance_m(60.0, 0.0, 60.0, 0.002) == pytest.approx(111.19, abs=0.02)
