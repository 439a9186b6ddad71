"""Catalogue of download, clear and set-current cases, and the composed upload ->
download-verify -> set-current sequence over a 20 % lossy link (see
test_mission_transfer_cases.py for the upload catalogue)."""

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
)

from groundstation.mavlink.codec import MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_commands import MissionClear, SetCurrent
from groundstation.mavlink.mission_download import MissionDownload
from groundstation.mavlink.mission_transfer import TransferCode
from groundstation.mavlink.mission_verify import compare_missions

M = mavlink2


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
    result = h.run(SetCurrent(VEH_SYS, VEH_COMP, 2, known_current_seq=4))
    assert result.ok and "ACK and MISSION_CURRENT" in result.message
    assert h.plane.current_seq == 2


def test_set_current_ack_lost_confirmed_by_mission_current() -> None:
    h = Harness(
        plane=FakePlane(mission=mission(), current_seq=4),
        drop=lambda d, m, n: d == "down" and m.get_type() == "COMMAND_ACK",
    )
    result = h.run(SetCurrent(VEH_SYS, VEH_COMP, 2))
    assert result.ok and "no ACK" in result.message


def test_set_current_stale_mission_current_is_not_confirmation() -> None:
    # the vehicle already shows seq 2 and never answers: a stale MISSION_CURRENT must not
    # count as "it reloaded item 2"
    plane = FakePlane(mission=mission(), current_seq=2)
    plane.receive = lambda msg, now: []  # type: ignore[method-assign]
    h = Harness(plane=plane)
    result = h.run(SetCurrent(VEH_SYS, VEH_COMP, 2, timeout_s=1.0, retries=2))
    assert result.code is TransferCode.TIMEOUT
    assert len(h.sent("COMMAND_LONG")) == 3
    assert [m.confirmation for m in h.sent("COMMAND_LONG")] == [0, 1, 2]


def test_set_current_command_failed() -> None:
    h = Harness(plane=FakePlane(mission=mission(), command_result=M.MAV_RESULT_FAILED))
    result = h.run(SetCurrent(VEH_SYS, VEH_COMP, 9))
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
    result = h3.run(SetCurrent(VEH_SYS, VEH_COMP, 2, known_current_seq=5), until_s=2000)
    assert result is not None
    assert result.ok or result.code is TransferCode.TIMEOUT
    if result.ok:
        assert plane.current_seq == 2
