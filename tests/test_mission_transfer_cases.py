"""The mission-transfer failure catalogue, against a scripted ArduPlane-like vehicle.

In the style of MAVSDK's mission_transfer_client tests and QGroundControl's MockLink
failure modes: each case drives a sans-IO machine through the real MAVLink codec (bytes
on a virtual link) against ``FakePlane`` (test_mission_transfer_fake.py) and asserts the
outcome. Sections: upload; download; clear and set current; the composed upload ->
download-verify -> set-current sequence over a 20 % lossy link. Virtual time: the whole
file runs in about a second.
"""

from __future__ import annotations

import random
from dataclasses import replace

import pytest
from test_mission_transfer_fake import (
    GCS_COMP,
    GCS_SYS,
    VEH_COMP,
    VEH_SYS,
    FakePlane,
    Harness,
    drop_nth,
    mission,
    upload,
    via_wire,
)

from domain.errors import LocalProtocolError, RemoteProtocolError
from groundstation.mavlink.codec import MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_commands import MissionClear, MissionSetCurrent
from groundstation.mavlink.mission_download import MissionDownload
from groundstation.mavlink.mission_transfer import TransferCode
from groundstation.mavlink.mission_upload import MissionUpload, UploadState
from groundstation.mavlink.mission_verify import compare_missions

M = mavlink2


# --------------------------------------------------------------------------- upload cases


def test_happy_path_upload() -> None:
    items = mission()
    h = Harness()
    result = h.run(sm := upload(items))
    assert result.ok and result.code is TransferCode.SUCCESS
    assert result.retries_used == 0
    assert h.plane.mission == items
    assert len(h.sent("MISSION_COUNT")) == 1
    assert [m.seq for m in h.sent("MISSION_ITEM_INT")] == list(range(len(items)))
    # ArduPlane asks with MISSION_REQUEST (not _INT); we answer with MISSION_ITEM_INT
    assert h.from_vehicle("MISSION_REQUEST") and not h.from_vehicle("MISSION_REQUEST_INT")
    assert not h.sent("MISSION_ITEM")
    assert sm.done and sm.next_deadline_s() is None
    assert h.now < 0.5  # 6 items over 20 ms latency: a few hundred ms, like SITL


def test_mission_request_int_is_answered_too() -> None:
    h = Harness(plane=FakePlane(request_int=True))
    result = h.run(upload())
    assert result.ok
    assert h.from_vehicle("MISSION_REQUEST_INT") and not h.from_vehicle("MISSION_REQUEST")


def test_no_answer_to_count_retries_then_times_out() -> None:
    h = Harness(plane=FakePlane(ignore_everything=True))
    result = h.run(upload(timeout_s=1.5, retries=5))
    assert result.code is TransferCode.TIMEOUT and not result.ok and result.retryable
    assert len(h.sent("MISSION_COUNT")) == 6  # first + 5 retries
    assert result.retries_used == 5
    assert h.now == pytest.approx(9.0)
    assert "MISSION_COUNT" in result.message and not result.maybe_stored


def test_lost_count_is_resent_and_upload_succeeds() -> None:
    h = Harness(drop=drop_nth("up", "MISSION_COUNT", 0))
    result = h.run(upload())
    assert result.ok and result.retries_used == 1
    assert len(h.sent("MISSION_COUNT")) == 2


def test_lost_request_vehicle_rerequests() -> None:
    h = Harness(drop=drop_nth("down", "MISSION_REQUEST", 2))  # the request for seq 2
    result = h.run(sm := upload())
    assert result.ok and result.retries_used == 0
    assert 1.0 <= h.now < 1.5  # recovered by ArduPlane's 1 s re-request
    assert sm.items_sent == len(sm.items)  # the lost request was never answered
    assert len(h.sent("MISSION_COUNT")) == 1  # no MISSION_COUNT after the first request


def test_lost_item_vehicle_rerequests_same_seq() -> None:
    h = Harness(drop=drop_nth("up", "MISSION_ITEM_INT", 3))
    result = h.run(sm := upload())
    assert result.ok
    seqs = [m.seq for m in h.sent("MISSION_ITEM_INT")]
    assert seqs.count(3) == 2 and sm.items_sent == len(sm.items) + 1
    assert any("duplicate" in note and "item 3" in note for note in result.notes)
    assert h.plane.mission == list(sm.items)


def test_duplicated_requests_answered_once_each_no_storm() -> None:
    h = Harness(duplicate=lambda d, m, n: d == "down" and m.get_type() == "MISSION_REQUEST")
    result = h.run(sm := upload())
    assert result.ok
    delivered_requests = 2 * len(h.from_vehicle("MISSION_REQUEST"))
    # exactly one answer per delivered request (the last request's duplicate may still be in
    # flight when the ACK ends the upload), and nothing else resent
    assert delivered_requests - 1 <= sm.items_sent <= delivered_requests
    assert len(h.sent("MISSION_ITEM_INT")) == sm.items_sent
    assert len(h.sent("MISSION_COUNT")) == 1
    # the vehicle flagged duplicate items with INVALID_SEQUENCE, which is not fatal
    acks = [m.type for m in h.from_vehicle("MISSION_ACK")]
    assert M.MAV_MISSION_INVALID_SEQUENCE in acks
    assert h.plane.mission == list(sm.items)


def test_out_of_range_request_fails_and_cancels() -> None:
    h = Harness(plane=FakePlane(first_request_seq=7))
    result = h.run(upload())  # 5 items
    assert result.code is TransferCode.PROTOCOL_ERROR
    assert "requested item 7" in result.message
    last = h.gcs_sent[-1][1]
    assert last.get_type() == "MISSION_ACK" and last.type == M.MAV_MISSION_OPERATION_CANCELLED


def test_early_ack_is_a_protocol_error() -> None:
    h = Harness(plane=FakePlane(early_ack_after=1))
    result = h.run(upload())
    assert result.code is TransferCode.PROTOCOL_ERROR and not result.ok
    assert "before 3 of 5 items" in result.message


def test_late_ack_within_retries_still_succeeds() -> None:
    h = Harness(plane=FakePlane(ack_delay_s=2.5))  # > timeout_s, < (retries+1) x timeout_s
    result = h.run(upload(timeout_s=1.5))
    assert result.ok and result.retries_used == 1


def test_lost_final_ack_times_out_saying_verify() -> None:
    h = Harness(drop=drop_nth("down", "MISSION_ACK", 0))
    result = h.run(upload(timeout_s=0.5, retries=2))
    assert result.code is TransferCode.TIMEOUT
    assert "verify by download" in result.message and result.maybe_stored
    assert h.plane.mission  # the vehicle did store it: the daemon must verify


@pytest.mark.parametrize(
    ("ack_type", "code", "retryable"),
    [
        (M.MAV_MISSION_NO_SPACE, TransferCode.NO_SPACE, True),
        (M.MAV_MISSION_DENIED, TransferCode.DENIED, True),
        (M.MAV_MISSION_UNSUPPORTED, TransferCode.UNSUPPORTED, False),
        (M.MAV_MISSION_UNSUPPORTED_FRAME, TransferCode.UNSUPPORTED_FRAME, False),
        (M.MAV_MISSION_INVALID, TransferCode.INVALID_PARAM, False),
        (M.MAV_MISSION_INVALID_PARAM1, TransferCode.INVALID_PARAM, False),
        (M.MAV_MISSION_INVALID_PARAM5_X, TransferCode.INVALID_PARAM, False),
        (M.MAV_MISSION_INVALID_PARAM6_Y, TransferCode.INVALID_PARAM, False),
        (M.MAV_MISSION_INVALID_PARAM7, TransferCode.INVALID_PARAM, False),
        (M.MAV_MISSION_ERROR, TransferCode.REMOTE_ERROR, True),
        (M.MAV_MISSION_OPERATION_CANCELLED, TransferCode.REMOTE_CANCELLED, True),
        (200, TransferCode.REMOTE_ERROR, True),  # garbage result code
    ],
)
def test_error_ack_of_each_kind(ack_type: int, code: TransferCode, retryable: bool) -> None:
    h = Harness(plane=FakePlane(ack_on_item={2: ack_type}))
    result = h.run(upload())
    assert result.code is code and not result.ok
    assert result.retryable is retryable
    expected = (
        mavlink2.enums["MAV_MISSION_RESULT"][ack_type].name
        if ack_type < 16
        else ("MAV_MISSION_RESULT_200")
    )
    assert result.remote_code == expected
    assert expected in result.message
    with pytest.raises(RemoteProtocolError):
        result.raise_for_failure()


def test_error_ack_to_the_count_no_space_when_not_ready() -> None:
    h = Harness(plane=FakePlane(ack_on_count=M.MAV_MISSION_NO_SPACE))
    result = h.run(upload())
    assert result.code is TransferCode.NO_SPACE and result.retryable
    assert not h.sent("MISSION_ITEM_INT")


def test_too_many_items_no_space() -> None:
    h = Harness(plane=FakePlane(max_items=3))
    assert h.run(upload()).code is TransferCode.NO_SPACE


def test_unknown_command_unsupported() -> None:
    items = mission()
    items[2] = replace(items[2], command=31000)
    assert Harness().run(upload(items)).code is TransferCode.UNSUPPORTED


def test_body_frame_unsupported_frame() -> None:
    items = mission()
    items[2] = replace(items[2], frame=M.MAV_FRAME_BODY_NED)
    assert Harness().run(upload(items)).code is TransferCode.UNSUPPORTED_FRAME


def test_upload_while_another_gcs_uploads_is_denied() -> None:
    plane = FakePlane()
    plane.upload = {"gcs": (200, 190), "count": 3, "next": 1, "last": 0.0, "got": []}
    h = Harness(plane=plane)
    result = h.run(upload())
    assert result.code is TransferCode.DENIED and result.retryable
    assert not h.sent("MISSION_ITEM_INT")


def test_invalid_sequence_ack_is_not_fatal() -> None:
    h = Harness()
    h.inject(
        0.045, M.MAVLink_mission_ack_message(GCS_SYS, GCS_COMP, M.MAV_MISSION_INVALID_SEQUENCE, 0)
    )
    result = h.run(upload())
    assert result.ok
    assert any("INVALID_SEQUENCE" in note for note in result.notes)


def test_wrong_mission_type_request_fails() -> None:
    h = Harness(plane=FakePlane(request_mission_type=M.MAV_MISSION_TYPE_FENCE))
    result = h.run(upload())
    assert result.code is TransferCode.MISSION_TYPE_MISMATCH and not result.retryable
    assert not h.sent("MISSION_ITEM_INT")


def test_vehicle_reboot_mid_upload() -> None:
    h = Harness(plane=FakePlane(reboot_after_item=2))
    result = h.run(upload())
    assert result.code is TransferCode.VEHICLE_REBOOTED and result.retryable
    assert h.plane.mission == []


def test_vehicle_cancels_when_our_answers_are_lost() -> None:
    # every answer after item 1 is lost: ArduPlane re-requests each second, cancels at 8 s
    h = Harness(
        drop=lambda d, m, n: d == "up" and m.get_type() == "MISSION_ITEM_INT" and m.seq >= 2
    )
    result = h.run(upload(timeout_s=1.5, retries=5))
    assert result.code is TransferCode.REMOTE_CANCELLED and result.retryable
    assert result.remote_code == "MAV_MISSION_OPERATION_CANCELLED"
    assert 8.0 <= h.now < 9.0  # the vehicle gave up before our own 9 s limit


def test_cancellation_sends_cancel_ack() -> None:
    h = Harness(latency_s=0.2)
    result = h.run(sm := upload(), cancel_at=0.5)
    assert result.code is TransferCode.CANCELLED and not result.retryable
    last = h.gcs_sent[-1][1]
    assert last.get_type() == "MISSION_ACK" and last.type == M.MAV_MISSION_OPERATION_CANCELLED
    assert sm.cancel(1.0) == []  # idempotent


def test_messages_from_another_vehicle_are_ignored() -> None:
    h = Harness(latency_s=0.05)
    # vehicle 2 asks for an out-of-range item and ACKs: none of it concerns our upload
    h.inject(0.06, M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 99, 0), sysid=2)
    h.inject(0.07, M.MAVLink_mission_ack_message(GCS_SYS, GCS_COMP, 0, 0), sysid=2)
    h.inject(0.08, M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 99, 0), compid=42)
    result = h.run(upload())
    assert result.ok


def test_messages_for_another_gcs_are_ignored() -> None:
    h = Harness(latency_s=0.05)
    # our vehicle serving a second GCS (sysid 200): seq 99 and an ACK, addressed to it
    h.inject(0.06, M.MAVLink_mission_request_message(200, 190, 99, 0))
    h.inject(0.07, M.MAVLink_mission_ack_message(200, 190, M.MAV_MISSION_ACCEPTED, 0))
    assert h.run(upload()).ok


def test_garbage_field_values_never_raise() -> None:
    h = Harness()
    h.inject(0.03, M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 65535, 0))
    result = h.run(upload())
    assert result.code is TransferCode.PROTOCOL_ERROR and "65535" in result.message


def test_empty_upload_completes_on_ack() -> None:
    h = Harness()
    result = h.run(MissionUpload(VEH_SYS, VEH_COMP, []))
    assert result.ok and h.plane.mission == []


def test_local_misuse_raises() -> None:
    sm = upload()
    msg = via_wire(M.MAVLink_mission_request_message(GCS_SYS, GCS_COMP, 0, 0), VEH_SYS, VEH_COMP)
    with pytest.raises(LocalProtocolError):
        sm.receive(msg, 0.0)
    sm.start(0.0)
    with pytest.raises(LocalProtocolError):
        sm.start(0.0)
    sm.cancel(0.1)
    # input after the end is harmless (h11: a state, not an exception), never a raise
    assert sm.state is UploadState.DONE
    assert sm.receive(msg, 0.2) == [] and sm.poll(5.0) == []
    items = mission()
    with pytest.raises(LocalProtocolError, match="seq"):
        upload([items[1], items[0]])
    with pytest.raises(LocalProtocolError, match="latitude"):
        upload([items[0], replace(items[1], command=16, x=950_000_000)])
    with pytest.raises(LocalProtocolError, match="target"):
        MissionUpload(0, 1, items)
    with pytest.raises(LocalProtocolError, match="timeout_s"):
        MissionUpload(1, 1, items, timeout_s=0.0)


# --------------------------------------------------------------------------- download cases


def test_download_happy_path_verifies_upload() -> None:
    items = mission()
    h = Harness()
    assert h.run(upload(items)).ok
    h2 = Harness(plane=h.plane)
    result = h2.run(MissionDownload(VEH_SYS, VEH_COMP, own_system=GCS_SYS))
    assert result.ok and result.items is not None and len(result.items) == len(items)
    assert compare_missions(items, list(result.items)) == []
    # the final ACK is ours
    last = h2.gcs_sent[-1][1]
    assert last.get_type() == "MISSION_ACK" and last.type == M.MAV_MISSION_ACCEPTED
    # a corrupted read-back is caught: one loiter moved by 2e-7 deg
    bad = list(result.items)
    bad[3] = replace(bad[3], x=bad[3].x + 2)
    assert [(m.seq, m.field) for m in compare_missions(items, bad)] == [(3, "x")]


def test_download_lost_item_is_rerequested() -> None:
    plane = FakePlane(mission=mission())
    h = Harness(plane=plane, drop=drop_nth("down", "MISSION_ITEM_INT", 2))
    result = h.run(MissionDownload(VEH_SYS, VEH_COMP, timeout_s=0.5))
    assert result.ok and result.retries_used == 1
    assert [m.seq for m in h.sent("MISSION_REQUEST_INT")].count(2) == 2


def test_download_count_timeout() -> None:
    h = Harness(plane=FakePlane(ignore_everything=True))
    result = h.run(MissionDownload(VEH_SYS, VEH_COMP, timeout_s=1.5, retries=5))
    assert result.code is TransferCode.TIMEOUT
    assert len(h.sent("MISSION_REQUEST_LIST")) == 6
    assert h.now == pytest.approx(9.0)


def test_download_duplicate_count_and_items_tolerated() -> None:
    plane = FakePlane(mission=mission())
    h = Harness(plane=plane, duplicate=lambda d, m, n: d == "down")
    result = h.run(MissionDownload(VEH_SYS, VEH_COMP))
    assert result.ok and result.items is not None and len(result.items) == len(plane.mission)
    assert len(h.sent("MISSION_REQUEST_INT")) == len(plane.mission)  # no re-requests


def test_download_empty_mission() -> None:
    h = Harness()
    result = h.run(MissionDownload(VEH_SYS, VEH_COMP))
    assert result.ok and result.items == ()


def test_download_count_changing_midway_is_protocol_error() -> None:
    h = Harness(plane=FakePlane(mission=mission()), latency_s=0.05)
    h.inject(0.12, M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 3, 0))
    result = h.run(MissionDownload(VEH_SYS, VEH_COMP))
    assert result.code is TransferCode.PROTOCOL_ERROR


def test_download_wrong_mission_type_fails() -> None:
    h = Harness(latency_s=0.05, plane=FakePlane(ignore_everything=True))
    h.inject(0.1, M.MAVLink_mission_count_message(GCS_SYS, GCS_COMP, 3, 1))
    result = h.run(MissionDownload(VEH_SYS, VEH_COMP))
    assert result.code is TransferCode.MISSION_TYPE_MISMATCH


# --------------------------------------------------------------------------- clear, set current


def test_clear_all() -> None:
    h = Harness(plane=FakePlane(mission=mission()))
    result = h.run(MissionClear(VEH_SYS, VEH_COMP))
    assert result.ok and h.plane.mission == []


def test_clear_lost_ack_resends() -> None:
    h = Harness(plane=FakePlane(mission=mission()), drop=drop_nth("down", "MISSION_ACK", 0))
    result = h.run(MissionClear(VEH_SYS, VEH_COMP, timeout_s=0.5))
    assert result.ok and result.retries_used == 1
    assert len(h.sent("MISSION_CLEAR_ALL")) == 2


def test_set_current_confirmed_by_ack_and_mission_current() -> None:
    h = Harness(plane=FakePlane(mission=mission(), current_seq=4))
    result = h.run(MissionSetCurrent(VEH_SYS, VEH_COMP, 2, known_current_seq=4))
    assert result.ok and "ACK and MISSION_CURRENT" in result.message
    assert h.plane.current_seq == 2


def test_set_current_ack_lost_confirmed_by_mission_current() -> None:
    h = Harness(
        plane=FakePlane(mission=mission(), current_seq=4),
        drop=lambda d, m, n: d == "down" and m.get_type() == "COMMAND_ACK",
    )
    result = h.run(MissionSetCurrent(VEH_SYS, VEH_COMP, 2))
    assert result.ok and "no ACK" in result.message


def test_set_current_stale_mission_current_is_not_confirmation() -> None:
    # the vehicle already shows seq 2 and never answers: a stale MISSION_CURRENT must not
    # count as "it reloaded item 2"
    plane = FakePlane(mission=mission(), current_seq=2)
    plane.receive = lambda msg, now: []  # type: ignore[method-assign]
    h = Harness(plane=plane)
    result = h.run(MissionSetCurrent(VEH_SYS, VEH_COMP, 2, timeout_s=1.0, retries=2,
                                     command_retries=2))
    assert result.code is TransferCode.TIMEOUT
    assert len(h.sent("COMMAND_LONG")) == 3
    assert [m.confirmation for m in h.sent("COMMAND_LONG")] == [0, 1, 2]
    # by default the command is tried twice as often as the retries (each try may be the
    # one the vehicle hears: before its ACK nothing is news when it already shows seq)
    h = Harness(plane=plane)
    result = h.run(MissionSetCurrent(VEH_SYS, VEH_COMP, 2, timeout_s=1.0, retries=2))
    assert result.code is TransferCode.TIMEOUT
    assert [m.confirmation for m in h.sent("COMMAND_LONG")] == [0, 1, 2, 3, 4]


def test_set_current_command_failed() -> None:
    h = Harness(plane=FakePlane(mission=mission(), command_result=M.MAV_RESULT_FAILED))
    result = h.run(MissionSetCurrent(VEH_SYS, VEH_COMP, 9))
    assert result.code is TransferCode.COMMAND_FAILED and result.remote_code == "MAV_RESULT_FAILED"


# --------------------------------------------------------------------------- lossy link


@pytest.mark.parametrize("seed", range(12))
def test_upload_verify_set_current_over_a_20_percent_lossy_link(seed: int) -> None:
    """What the daemon composes: upload -> download-verify -> set current, retried."""
    rng = random.Random(seed)
    items = mission(n_loiters=3)
    plane = FakePlane(current_seq=5)

    def lossy(d: str, m: MAVLinkMessage, n: int) -> bool:
        return rng.random() < 0.2

    verified = False
    for _attempt in range(6):
        h = Harness(plane=plane, drop=lossy)
        h.now = 100.0 * _attempt
        plane.upload = None
        plane.next_current_report_s = h.now
        up = h.run(upload(items), until_s=h.now + 60)
        assert up is not None and up.code in (
            TransferCode.SUCCESS,
            TransferCode.TIMEOUT,
            TransferCode.REMOTE_CANCELLED,
            TransferCode.INVALID_SEQUENCE,
        ), up
        h2 = Harness(plane=plane, drop=lossy)
        h2.now = h.now + 10
        down = h2.run(MissionDownload(VEH_SYS, VEH_COMP), until_s=h2.now + 60)
        assert down is not None
        if down.ok and down.items is not None and not compare_missions(items, list(down.items)):
            verified = True
            break
    assert verified
    h3 = Harness(plane=plane, drop=lossy)
    h3.now = 1000.0
    plane.next_current_report_s = h3.now
    result = h3.run(MissionSetCurrent(VEH_SYS, VEH_COMP, 2, known_current_seq=5), until_s=2000)
    assert result is not None
    assert result.ok or result.code is TransferCode.TIMEOUT
    if result.ok:
        assert plane.current_seq == 2
