"""Transfer machines' explicit states, input after the end, and the command exchanges.

Every machine: ``IDLE`` before start (``receive`` raises LocalProtocolError, the rest
return ``[]``), its own working states, and ``DONE`` after any end, where every input
(``receive``, ``poll``, ``cancel``, ``notify_vehicle_rebooted``) returns ``[]`` and the
result stays as it was. Also: frames with a wrong payload length but a valid CRC (issue
10.4) decode as real messages with truncated or zero-filled fields; no machine raises on
them in any state.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from test_mission_transfer_fake import (
    GCS_COMP,
    GCS_SYS,
    VEH_COMP,
    VEH_SYS,
    FakePlane,
    Harness,
    mission,
    upload,
    via_wire,
)

from domain.errors import LocalProtocolError
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_commands import (
    ClearState,
    MissionClear,
    MissionSetCurrent,
    SetCurrentState,
)
from groundstation.mavlink.mission_download import DownloadState, MissionDownload
from groundstation.mavlink.mission_transfer import Finished, Send, TransferBase, TransferCode
from groundstation.mavlink.mission_upload import UploadState
from groundstation.mavlink.vehicle_commands import (
    CommandLong,
    CommandState,
    ParamRead,
    ParamReadState,
    ParamSet,
    ParamSetState,
)

M = mavlink2

MACHINES: dict[str, Callable[[], TransferBase[Any]]] = {
    "upload": lambda: upload(),
    "download": lambda: MissionDownload(VEH_SYS, VEH_COMP, own_system=GCS_SYS),
    "clear": lambda: MissionClear(VEH_SYS, VEH_COMP, own_system=GCS_SYS),
    "set_current": lambda: MissionSetCurrent(VEH_SYS, VEH_COMP, 2, own_system=GCS_SYS),
    "command": lambda: CommandLong(VEH_SYS, VEH_COMP, M.MAV_CMD_DO_SET_MODE, [1.0, 10.0]),
    "param_set": lambda: ParamSet(VEH_SYS, VEH_COMP, "WP_LOITER_RAD", 80.0),
    "param_read": lambda: ParamRead(VEH_SYS, VEH_COMP, "AIRSPEED_CRUISE", own_system=GCS_SYS),
}


def wire(msg: MAVLinkMessage) -> MAVLinkMessage:
    return via_wire(msg, VEH_SYS, VEH_COMP)


# Everything a vehicle might say to any of the machines, addressed to us.
ANY_INPUT = [
    wire(M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 0, 0)),
    wire(M.MAVLink_mission_request_int_message(GCS_SYS, GCS_COMP, 1, 0)),
    wire(M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 65535, 0)),
    wire(M.MAVLink_mission_ack_message(GCS_SYS, GCS_COMP, M.MAV_MISSION_ACCEPTED, 0)),
    wire(M.MAVLink_mission_ack_message(GCS_SYS, GCS_COMP, M.MAV_MISSION_ERROR, 0)),
    wire(M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 3, 0)),
    wire(mission()[0].to_message(GCS_SYS, GCS_COMP)),
    wire(M.MAVLink_mission_current_message(2, 5)),
    wire(M.MAVLink_command_ack_message(M.MAV_CMD_DO_SET_MISSION_CURRENT, 0, 0, 0, 255, 190)),
    wire(M.MAVLink_command_ack_message(M.MAV_CMD_DO_SET_MODE, 0, 0, 0, 255, 190)),
    wire(M.MAVLink_param_value_message(b"WP_LOITER_RAD", 80.0, 9, 1, 0)),
    wire(M.MAVLink_heartbeat_message(1, 3, 0, 10, 4, 3)),
]


def assert_inert(sm: TransferBase[Any], now_s: float) -> None:
    """After the end every input returns [] and changes nothing."""
    result, state = sm.result, sm.state
    assert sm.done and result is not None and state.name == "DONE"
    for msg in ANY_INPUT:
        assert sm.receive(msg, now_s) == []
    assert sm.poll(now_s + 1e6) == []
    assert sm.cancel(now_s) == []
    assert sm.notify_vehicle_rebooted(now_s) == []
    assert sm.result is result and sm.state is state and sm.next_deadline_s() is None


@pytest.mark.parametrize("kind", MACHINES)
def test_idle_machine_rejects_receive_and_ignores_the_rest(kind: str) -> None:
    sm = MACHINES[kind]()
    assert sm.state.name == "IDLE" and not sm.done and sm.next_deadline_s() is None
    with pytest.raises(LocalProtocolError, match="before start"):
        sm.receive(ANY_INPUT[0], 0.0)
    assert sm.poll(100.0) == [] and sm.cancel(0.0) == []
    assert sm.notify_vehicle_rebooted(0.0) == []
    assert sm.state.name == "IDLE"
    sm.start(0.0)
    with pytest.raises(LocalProtocolError, match="twice"):
        sm.start(0.0)


@pytest.mark.parametrize("kind", MACHINES)
@pytest.mark.parametrize("end", ["cancel", "reboot", "timeout"])
def test_every_input_after_the_end_returns_nothing(kind: str, end: str) -> None:
    sm = MACHINES[kind]()
    sm.start(0.0)
    if end == "cancel":
        actions = sm.cancel(0.5)
        code = TransferCode.CANCELLED
    elif end == "reboot":
        actions = sm.notify_vehicle_rebooted(0.5)
        code = TransferCode.VEHICLE_REBOOTED
        assert not any(isinstance(a, Send) for a in actions)  # nobody left to tell
    else:
        actions = []
        while not sm.done:
            deadline = sm.next_deadline_s()
            assert deadline is not None
            actions = sm.poll(deadline)
        code = TransferCode.TIMEOUT
    assert isinstance(actions[-1], Finished) and actions[-1].result.code is code
    assert_inert(sm, 100.0)


@pytest.mark.parametrize("kind", ["upload", "download", "clear", "set_current"])
def test_every_input_after_success_returns_nothing(kind: str) -> None:
    plane = FakePlane(mission=mission(), current_seq=4)
    sm = (
        MissionSetCurrent(VEH_SYS, VEH_COMP, 2, known_current_seq=4)
        if kind == "set_current"
        else MACHINES[kind]()
    )
    result = Harness(plane=plane).run(sm)
    assert result is not None and result.ok
    assert_inert(sm, 100.0)


def test_upload_states() -> None:
    sm = upload(mission()[:2])
    assert sm.state is UploadState.IDLE
    sm.start(0.0)
    assert sm.state is UploadState.SENDING_COUNT
    assert sm.poll(1.5) != [] and sm.state is UploadState.SENDING_COUNT  # count resent
    sm.receive(wire(M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 0, 0)), 2.0)
    assert sm.state is UploadState.SENDING_ITEMS
    assert sm.poll(3.5) == []  # the vehicle drives now: nothing resent
    sm.receive(wire(M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 1, 0)), 4.0)
    assert sm.state is UploadState.WAITING_ACK
    sm.receive(wire(M.MAVLink_mission_ack_message(GCS_SYS, GCS_COMP, 0, 0)), 4.1)
    assert sm.state is UploadState.DONE and sm.result is not None and sm.result.ok


def test_download_states() -> None:
    sm = MissionDownload(VEH_SYS, VEH_COMP)
    sm.start(0.0)
    assert sm.state is DownloadState.REQUESTING_LIST
    # unreadable counts are ignored, not fatal
    for bad in (-1, 70000, None, 2.5, "3"):
        count = M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 0, 0)
        count._header.srcSystem, count._header.srcComponent = VEH_SYS, VEH_COMP
        count.count = bad
        assert sm.receive(count, 0.1) == []
    assert sm.state is DownloadState.REQUESTING_LIST
    sm.receive(wire(M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 1, 0)), 0.2)
    assert sm.state is DownloadState.REQUESTING_ITEMS and sm.count == 1
    sm.receive(wire(mission()[0].to_message(GCS_SYS, GCS_COMP)), 0.3)
    assert sm.state is DownloadState.DONE and sm.result is not None and sm.result.ok


@pytest.mark.parametrize("stale", [M.MAV_MISSION_ERROR, M.MAV_MISSION_INVALID_SEQUENCE])
def test_a_stale_item_error_before_the_count_does_not_end_the_download(stale: int) -> None:
    """Issue 28: the verifying download after an upload got the vehicle's MISSION_ACK
    ERROR to the upload's duplicate item in the same millisecond as its MISSION_COUNT, and
    ended. An item error before the count answers an earlier exchange; the download goes on.
    A refusal of the list itself (UNSUPPORTED, DENIED) still ends it."""
    sm = MissionDownload(VEH_SYS, VEH_COMP)
    sm.start(0.0)
    assert sm.receive(wire(M.MAVLink_mission_ack_message(GCS_SYS, GCS_COMP, stale, 0)),
                      0.1) == []
    assert sm.state is DownloadState.REQUESTING_LIST
    sm.receive(wire(M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 1, 0)), 0.1)
    sm.receive(wire(mission()[0].to_message(GCS_SYS, GCS_COMP)), 0.2)
    assert sm.state is DownloadState.DONE and sm.result is not None and sm.result.ok
    denied = MissionDownload(VEH_SYS, VEH_COMP)
    denied.start(0.0)
    denied.receive(wire(M.MAVLink_mission_ack_message(GCS_SYS, GCS_COMP,
                                                      M.MAV_MISSION_DENIED, 0)), 0.1)
    assert denied.state is DownloadState.DONE and denied.result is not None
    assert not denied.result.ok
    # once the count is in, an item error answers this download's request: it ends
    late = MissionDownload(VEH_SYS, VEH_COMP)
    late.start(0.0)
    late.receive(wire(M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 2, 0)), 0.1)
    late.receive(wire(M.MAVLink_mission_ack_message(GCS_SYS, GCS_COMP, stale, 0)), 0.2)
    assert late.state is DownloadState.DONE and late.result is not None
    assert not late.result.ok


def test_clear_and_set_current_states() -> None:
    clear = MissionClear(VEH_SYS, VEH_COMP)
    clear.start(0.0)
    assert clear.state is ClearState.WAITING_ACK
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 2, known_current_seq=4)
    sc.start(0.0)
    assert sc.state is SetCurrentState.SENDING_COMMAND
    ack = M.MAVLink_command_ack_message(M.MAV_CMD_DO_SET_MISSION_CURRENT, 0, 0, 0, 255, 190)
    assert sc.receive(wire(ack), 0.1) == []
    assert sc.state is SetCurrentState.CONFIRMING
    asked = sc.poll(1.1)  # after the ACK the command is not resent: MISSION_CURRENT asked
    assert len(asked) == 1 and isinstance(asked[0], Send)
    assert asked[0].msg.command == M.MAV_CMD_REQUEST_MESSAGE
    assert asked[0].msg.param1 == M.MAVLINK_MSG_ID_MISSION_CURRENT
    sc.receive(wire(M.MAVLink_mission_current_message(2, 5)), 1.2)
    assert sc.state is SetCurrentState.DONE and sc.result is not None and sc.result.ok


# --------------------------------------------------------------------------- command, param


def test_command_long_accepted_failed_in_progress_and_strays() -> None:
    sm = CommandLong(VEH_SYS, VEH_COMP, M.MAV_CMD_DO_SET_MODE, [1.0, 10.0], own_system=GCS_SYS)
    (send,) = sm.start(0.0)
    assert isinstance(send, Send) and send.msg.param2 == 10.0 and send.msg.confirmation == 0
    assert sm.state is CommandState.WAITING_ACK
    other_cmd = M.MAVLink_command_ack_message(M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 0, 255, 0)
    other_gcs = M.MAVLink_command_ack_message(M.MAV_CMD_DO_SET_MODE, 0, 0, 0, 200, 0)
    in_progress = M.MAVLink_command_ack_message(M.MAV_CMD_DO_SET_MODE, 5, 0, 0, 255, 0)
    for msg in (other_cmd, other_gcs, in_progress):
        assert sm.receive(wire(msg), 0.1) == []
    (resend,) = sm.poll(1.0)
    assert isinstance(resend, Send) and resend.msg.confirmation == 1
    failed = M.MAVLink_command_ack_message(M.MAV_CMD_DO_SET_MODE, M.MAV_RESULT_FAILED, 0, 0, 0, 0)
    (fin,) = sm.receive(wire(failed), 1.1)
    assert isinstance(fin, Finished) and fin.result.code is TransferCode.COMMAND_FAILED
    assert sm.ack_result == M.MAV_RESULT_FAILED and fin.result.remote_code == "MAV_RESULT_FAILED"

    ok = CommandLong(VEH_SYS, VEH_COMP, M.MAV_CMD_DO_SET_MODE)
    ok.start(0.0)
    ok.receive(wire(M.MAVLink_command_ack_message(M.MAV_CMD_DO_SET_MODE, 0, 0, 0, 0, 0)), 0.1)
    assert ok.result is not None and ok.result.ok and ok.ack_result == M.MAV_RESULT_ACCEPTED


def test_param_set_needs_its_value_echoed() -> None:
    sm = ParamSet(VEH_SYS, VEH_COMP, "WP_LOITER_RAD", 80.0, timeout_s=1.0, retries=1)
    sm.start(0.0)
    assert sm.state is ParamSetState.WAITING_VALUE
    clamped = wire(M.MAVLink_param_value_message(b"WP_LOITER_RAD", 60.0, 9, 1, 0))
    other = wire(M.MAVLink_param_value_message(b"WP_RADIUS", 80.0, 9, 1, 0))
    assert sm.receive(clamped, 0.1) == [] and sm.receive(other, 0.2) == []
    assert len(sm.poll(1.0)) == 1  # resent
    (fin,) = sm.poll(2.0)
    assert isinstance(fin, Finished) and fin.result.code is TransferCode.TIMEOUT
    assert any("60" in note for note in fin.result.notes)
    good = ParamSet(VEH_SYS, VEH_COMP, "WP_LOITER_RAD", 80.0)
    good.start(0.0)
    echo = wire(M.MAVLink_param_value_message(b"WP_LOITER_RAD", 80.0, 9, 1, 0))
    (fin,) = good.receive(echo, 0.1)
    assert isinstance(fin, Finished) and fin.result.ok and good.result is fin.result


def test_param_read_by_name_takes_the_value_of_that_name_and_times_out_on_silence() -> None:
    sm = ParamRead(VEH_SYS, VEH_COMP, "AIRSPEED_CRUISE", timeout_s=1.0, retries=2,
                   own_system=GCS_SYS)
    (first,) = sm.start(0.0)
    assert sm.state is ParamReadState.WAITING_VALUE and isinstance(first, Send)
    request = first.msg
    assert request.get_type() == "PARAM_REQUEST_READ" and request.param_index == -1
    assert request.param_id.rstrip("\x00") == "AIRSPEED_CRUISE"
    assert (request.target_system, request.target_component) == (VEH_SYS, VEH_COMP)
    other = wire(M.MAVLink_param_value_message(b"AIRSPEED_MIN", 12.0, 9, 60, 14))
    assert sm.receive(other, 0.2) == [] and not sm.done
    assert sm.poll(0.9) == []
    (resend,) = sm.poll(1.0)
    assert isinstance(resend, Send) and resend.msg.get_type() == "PARAM_REQUEST_READ"
    # ArduPilot answers a read by name with param_index -1 (65535 on the wire)
    answer = wire(M.MAVLink_param_value_message(b"AIRSPEED_CRUISE", 22.0, 9, 60, 65535))
    (fin,) = sm.receive(answer, 1.2)
    assert isinstance(fin, Finished) and fin.result.ok and sm.value == 22.0
    assert fin.result.retries_used == 1
    # an unknown name: ArduPilot stays silent, the retries end it
    silent = ParamRead(VEH_SYS, VEH_COMP, "TRIM_ARSPD_CM", timeout_s=1.0, retries=2)
    silent.start(0.0)
    assert len(silent.poll(1.0)) == 1 and len(silent.poll(2.0)) == 1
    (fin,) = silent.poll(3.0)
    assert isinstance(fin, Finished) and fin.result.code is TransferCode.TIMEOUT
    assert silent.value is None and "does not answer" in fin.result.message


def test_param_read_against_the_built_in_vehicle_over_the_wire() -> None:
    """The simulator answers as ArduPilot: by name with index 65535, nothing for a name
    it lacks, by index with that index."""
    from domain.geodesy import GeoOrigin
    from sitl.vehicle import SimVehicle
    from sitl.vehicle_state import VehicleConfig

    vehicle = SimVehicle(VehicleConfig(VEH_SYS, GeoOrigin(78.0, 15.0), 78.0, 15.0,
                                       cruise_speed_m_s=21.0))
    encoder = MavlinkEncoder(GCS_SYS, GCS_COMP)

    def ask(msg: MAVLinkMessage) -> list[MAVLinkMessage]:
        sent = MavlinkDecoder().feed(encoder.encode(msg))
        return [via_wire(m, VEH_SYS, VEH_COMP) for m in vehicle.receive(sent[0], 0.0)
                if m.get_type() == "PARAM_VALUE"]

    sm = ParamRead(VEH_SYS, VEH_COMP, "AIRSPEED_CRUISE", own_system=GCS_SYS)
    (request,) = sm.start(0.0)
    assert isinstance(request, Send)
    (reply,) = ask(request.msg)
    assert reply.param_index == 65535 and reply.param_count == len(vehicle.params)
    (fin,) = sm.receive(reply, 0.1)
    assert isinstance(fin, Finished) and sm.value == 21.0
    unknown = ParamRead(VEH_SYS, VEH_COMP, "TRIM_ARSPD_CM")
    (request,) = unknown.start(0.0)
    assert isinstance(request, Send) and ask(request.msg) == []
    index = vehicle.params.index_of("WP_RADIUS")
    assert index is not None
    (by_index,) = ask(M.MAVLink_param_request_read_message(VEH_SYS, VEH_COMP, b"", index))
    assert by_index.param_index == index and by_index.param_id.rstrip("\x00") == "WP_RADIUS"
    assert ask(M.MAVLink_param_request_read_message(VEH_SYS, VEH_COMP, b"WP_RADIUS", -2)) == []


@pytest.mark.parametrize(
    "make",
    [
        lambda: ParamRead(1, 1, ""),
        lambda: ParamRead(1, 1, "A_NAME_LONGER_THAN_16"),
        lambda: ParamSet(1, 1, "", 1.0),
        lambda: ParamSet(1, 1, "A_NAME_LONGER_THAN_16", 1.0),
        lambda: ParamSet(1, 1, "RADIUS_\u00e9", 1.0),
        lambda: ParamSet(1, 1, "WP_LOITER_RAD", 1e40),
        lambda: CommandLong(1, 1, 70000),
        lambda: CommandLong(1, 1, 176, [0.0] * 8),
    ],
)
def test_command_and_param_local_misuse_raises(make: Callable[[], Any]) -> None:
    with pytest.raises(LocalProtocolError):
        make()


# --------------------------------------------------------------------------- issue 10.4


def reframe(frame: bytes, length: int, fill: int = 0) -> bytes:
    """``frame`` (MAVLink 2) with its payload cut or padded to ``length``, CRC made valid."""
    msgid = int.from_bytes(frame[7:10], "little")
    payload = frame[10 : 10 + frame[1]][:length].ljust(length, bytes([fill]))
    header = bytes([frame[0], length]) + frame[2:10]
    crc = M.x25crc(header[1:] + payload)
    crc.accumulate(bytes([M.mavlink_map[msgid].crc_extra]))
    return header + payload + crc.crc.to_bytes(2, "little")


def _active(kind: str, stage: int) -> TransferBase[Any]:
    """Machine ``kind`` started and, for stage 1, one step further into its exchange."""
    sm = MACHINES[kind]()
    sm.start(0.0)
    if stage == 1:
        step = {
            "upload": M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 0, 0),
            "download": M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 3, 0),
            "set_current": M.MAVLink_command_ack_message(
                M.MAV_CMD_DO_SET_MISSION_CURRENT, 0, 0, 0, 255, 190
            ),
        }.get(kind)
        if step is not None:
            sm.receive(wire(step), 0.1)
    return sm


def test_wrong_length_frames_with_a_valid_crc_never_raise() -> None:
    messages = [m for m in ANY_INPUT if m.get_type() != "HEARTBEAT"]
    decoded = 0
    for msg in messages:
        frame = MavlinkEncoder(VEH_SYS, VEH_COMP).encode(msg)
        for length in range(0, frame[1] + 6):
            for fill in (0x00, 0xFF):
                for mangled in MavlinkDecoder().feed(reframe(frame, length, fill)):
                    decoded += 1
                    for kind in MACHINES:
                        for stage in (0, 1):
                            sm = _active(kind, stage)
                            actions = sm.receive(mangled, 0.2) + sm.poll(0.3)
                            assert all(isinstance(a, Send | Finished) for a in actions)
                            if sm.done:
                                assert_inert(sm, 0.4)
    assert decoded > 100  # pymavlink did decode most of them as real messages
