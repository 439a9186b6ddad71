"""Issue 11: why uploads "retried 5 times" on a loss-free link, and the fix.

The cause, found in the run folders (flight.tlog + journal): every upload journalled with
``retries=5`` at 50x was a set-current whose waypoint the vehicle passed at once. ArduPlane
starts the item of ``DO_SET_MISSION_CURRENT`` while it still cross-tracks from the previous
waypoint, so a re-uploaded waypoint behind that finish line is "Passed" in the same loop.
The vehicle then showed ``MISSION_CURRENT`` = seq only *before* its COMMAND_ACK (ambiguous
when it was already on seq: ignored as possibly stale) and seq + 1 after it; the machine
waited for ``MISSION_CURRENT`` = seq that never came, timed out after 6 mission s (5 silent
"retries", nothing resent) and the job took the timeout as done. Now the vehicle's
``MISSION_ITEM_REACHED`` of seq after the ACK confirms (ArduPlane sends it when the item
completes). A later ``MISSION_CURRENT`` after the ACK does not: on a link that reorders
(UDP, two masters merged by MAVProxy or mavlink-router) it may be a stale frame of the
previous mission.

Sans-IO: the machine is fed the exact message order seen in the tlog, in mission time.
"""

from __future__ import annotations

import pytest
from test_mission_transfer_fake import GCS_COMP, GCS_SYS, VEH_COMP, VEH_SYS, via_wire

from groundstation.mavlink.codec import MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_commands import MissionSetCurrent, SetCurrentState
from groundstation.mavlink.mission_transfer import Finished, TransferCode, TransferResult

M = mavlink2


def wire(msg: MAVLinkMessage) -> MAVLinkMessage:
    return via_wire(msg, VEH_SYS, VEH_COMP)


def ack() -> MAVLinkMessage:
    return wire(
        M.MAVLink_command_ack_message(
            M.MAV_CMD_DO_SET_MISSION_CURRENT, M.MAV_RESULT_ACCEPTED, 0, 0, GCS_SYS, GCS_COMP
        )
    )


def current(seq: int, total: int = 2) -> MAVLinkMessage:
    return wire(M.MAVLink_mission_current_message(seq, total, 3, 1))


def passed_at_once() -> list[tuple[float, MAVLinkMessage]]:
    """The vehicle's answer to set-current 1 of a 3-item mission (home, waypoint, loiter
    unlimited) while it flew item 1 of the previous mission, as recorded (run at 50x)."""
    return [
        (0.05, current(1)),  # sent before the ACK: could be the old item 1 (stale)
        (0.05, wire(M.MAVLink_statustext_message(6, b"Mission: 1 WP", 0, 0))),
        (0.06, ack()),
        (0.06, wire(M.MAVLink_statustext_message(6, b"Passed waypoint #1 dist 397m", 0, 0))),
        (0.06, wire(M.MAVLink_mission_item_reached_message(1))),
        (0.06, current(2)),  # the loiter started: item 1 is behind it
        (1.0, current(2)),
        (2.0, current(2)),
    ]


def run(
    sc: MissionSetCurrent, script: list[tuple[float, MAVLinkMessage]], until_s: float = 20.0
) -> tuple[TransferResult, float]:
    """Feed ``script`` (mission time, message) and poll on deadlines; result and end time."""
    actions = sc.start(0.0)
    pending = list(script)
    now_s = 0.0
    while not sc.done and now_s < until_s:
        deadline = sc.next_deadline_s()
        assert deadline is not None
        if pending and pending[0][0] <= deadline:
            now_s, msg = pending.pop(0)
            actions = sc.receive(msg, now_s)
        else:
            now_s = deadline
            actions = sc.poll(now_s)
    assert sc.done and isinstance(actions[-1], Finished)
    assert sc.result is not None
    return sc.result, now_s


def test_a_waypoint_passed_at_once_is_confirmed_at_once() -> None:
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=1)
    result, end_s = run(sc, passed_at_once())
    assert result.ok and result.code is TransferCode.SUCCESS
    assert result.retries_used == 0
    assert end_s == pytest.approx(0.06)  # at the MISSION_ITEM_REACHED 1 after the ACK
    assert "MISSION_ITEM_REACHED 1" in result.message


def test_without_the_item_reached_the_stream_confirms() -> None:
    # MISSION_ITEM_REACHED lost (issue 28: every failed upload at 20 % loss): the vehicle
    # was seen on item 1 during the exchange, then on 2 after the ACK: it started 1 and
    # moved on. (Before, this waited out its 6 s and failed: "COMMAND_ACK ACCEPTED but
    # MISSION_CURRENT never showed 1".)
    script = [(t, m) for t, m in passed_at_once() if m.get_type() != "MISSION_ITEM_REACHED"]
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=1, timeout_s=1.0, retries=5)
    result, end_s = run(sc, script)
    assert result.ok and result.retries_used == 0, result
    assert end_s == pytest.approx(0.06)
    assert "MISSION_CURRENT 1 then 2" in result.message


def test_a_stale_later_mission_current_after_the_ack_does_not_confirm() -> None:
    # The vehicle held item 2 of its previous mission (the last target's unlimited loiter);
    # floe uploaded [home, loiter, loiter] and sets 1. A MISSION_CURRENT 2 sent before the
    # command but delivered after the ACK (a reordering link) satisfies 1 < 2 < 3; it must
    # not confirm (the loiter end of item 1 would be read from it at once). The real
    # MISSION_CURRENT 1 that follows does.
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=2)
    script = [(0.05, ack()), (0.08, current(2, 3)), (0.9, current(1, 3))]
    result, end_s = run(sc, script)
    assert result.ok and "COMMAND_ACK and MISSION_CURRENT" in result.message
    assert end_s == pytest.approx(0.9)
    # late frames in a burst are not the stream: no span
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=2, retries=2)
    result, _ = run(sc, [(0.05, ack()), (0.08, current(2, 3)), (0.1, current(2, 3))])
    assert result.code is TransferCode.TIMEOUT
    # the stream showing item 2 over a second after the ACK: it started 1 and moved on
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=2, retries=2)
    result, end_s = run(sc, [(0.05, ack()), (0.08, current(2, 3)), (1.0, current(2, 3))])
    assert result.ok and "2 MISSION_CURRENT past it" in result.message
    assert end_s == pytest.approx(1.0)


def test_item_reached_counts_only_after_the_ack_and_only_for_seq() -> None:
    # before the ACK it may be the previous mission's item 1 ending; after it, another
    # item's MISSION_ITEM_REACHED says nothing about ours
    reached = wire(M.MAVLink_mission_item_reached_message(1))
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=1, retries=1)
    result, _ = run(sc, [(0.05, reached), (0.1, ack())])
    assert result.code is TransferCode.TIMEOUT
    other = wire(M.MAVLink_mission_item_reached_message(2))
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=1, retries=1)
    result, _ = run(sc, [(0.05, ack()), (0.1, other), (0.2, current(2))])
    assert result.code is TransferCode.TIMEOUT


def test_a_later_item_before_the_ack_is_no_confirmation() -> None:
    # before the ACK a MISSION_CURRENT may predate our command: the vehicle could have been
    # on item 2 already. Then the command is resent, as for silence.
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=1, retries=1)
    result, _ = run(sc, [(0.05, current(2)), (0.5, current(2))])
    assert result.code is TransferCode.TIMEOUT and result.remote_code is None


@pytest.mark.parametrize("shown", [0, 3, 7])
def test_after_the_ack_no_other_mission_current_confirms(shown: int) -> None:
    # 0: before our item; 3 and 7: beyond the 2 items (total, home excluded) we uploaded (an
    # overwritten item still flown shows seq > total, design.md), however long it shows
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=2, retries=2)
    result, _ = run(sc, [(0.05, ack()), (0.1, current(shown)), (1.0, current(shown)),
                         (2.0, current(shown))])
    assert result.code is TransferCode.TIMEOUT
    assert sc.state is SetCurrentState.DONE


def test_the_equal_item_after_the_ack_still_confirms() -> None:
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=1)
    result, end_s = run(sc, [(0.05, ack()), (0.3, current(1))])
    assert result.ok and "COMMAND_ACK and MISSION_CURRENT" in result.message
    assert end_s == pytest.approx(0.3)
