"""Issue 28: ``SetCurrent`` tolerates loss as well as the upload does.

At 20 % message loss the failed uploads of ``gcs run --sim-loss 0.2`` were all a
set-current "COMMAND_ACK ACCEPTED but MISSION_CURRENT never showed 1": the re-uploaded
waypoint was passed at once, its MISSION_ITEM_REACHED and the one MISSION_CURRENT showing
it were lost, and the machine, which resent nothing after the ACK, waited out its window.
Now it asks for MISSION_CURRENT on its timer (MAV_CMD_REQUEST_MESSAGE, never the
set-current again: that would restart the item) and takes the stream showing the vehicle
past the item, over time, as confirmation.

Sans-IO first (scripted exchanges with the frames the loss took out), then the same
exchange against the built-in simulator through the real codec with 20 % loss each way,
in virtual time.
"""

from __future__ import annotations

import random
from typing import Any

import pytest
from test_mission_transfer_fake import GCS_COMP, GCS_SYS, VEH_COMP, VEH_SYS, via_wire

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_commands import MissionSetCurrent
from groundstation.mavlink.mission_items import LoiterUnlimited, Waypoint, build_mission_items
from groundstation.mavlink.mission_transfer import Finished, Send, TransferResult
from groundstation.mavlink.mission_upload import MissionUpload
from sitl.loopback import Loopback
from sitl.vehicle import SimVehicle, VehicleConfig

M = mavlink2
ORIGIN = GeoOrigin(78.93, 11.92)


def wire(msg: MAVLinkMessage) -> MAVLinkMessage:
    return via_wire(msg, VEH_SYS, VEH_COMP)


def ack() -> MAVLinkMessage:
    return wire(M.MAVLink_command_ack_message(
        M.MAV_CMD_DO_SET_MISSION_CURRENT, M.MAV_RESULT_ACCEPTED, 0, 0, GCS_SYS, GCS_COMP))


def current(seq: int, total: int = 2) -> MAVLinkMessage:
    return wire(M.MAVLink_mission_current_message(seq, total, 3, 1))


def exchange(
    sc: MissionSetCurrent, script: list[tuple[float, MAVLinkMessage]], on_ask: int | None,
    until_s: float = 20.0,
) -> tuple[TransferResult, list[Any]]:
    """Feed ``script`` in mission time, poll on deadlines; a vehicle that answers a
    REQUEST_MESSAGE(MISSION_CURRENT) with MISSION_CURRENT ``on_ask`` at once (None: the
    answer is lost). Returns the result and everything the machine sent."""
    sent: list[Any] = []
    pending = list(script)
    actions = sc.start(0.0)
    now_s = 0.0
    while not sc.done and now_s < until_s:
        for action in actions:
            if isinstance(action, Send):
                sent.append(action.msg)
                if (on_ask is not None and action.msg.get_type() == "COMMAND_LONG"
                        and action.msg.command == M.MAV_CMD_REQUEST_MESSAGE):
                    pending.insert(0, (now_s, current(on_ask)))
        deadline = sc.next_deadline_s()
        if sc.done or deadline is None:
            break
        if pending and pending[0][0] <= deadline:
            now_s, msg = pending.pop(0)
            actions = sc.receive(msg, now_s)
        else:
            now_s = deadline
            actions = sc.poll(now_s)
    assert sc.result is not None
    return sc.result, sent


def test_passed_at_once_with_its_item_reached_and_current_lost_is_confirmed() -> None:
    # ArduPlane: ACK, the queued MISSION_CURRENT 1 (lost), MISSION_ITEM_REACHED 1 (lost),
    # then its ~1 Hz stream shows item 2 (one of those lost too)
    script = [(0.05, ack()), (0.08, current(2)), (2.1, current(2)), (3.0, current(2))]
    result, sent = exchange(MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=1),
                            script, on_ask=None)
    assert result.ok, result
    assert "MISSION_CURRENT past it" in result.message
    # the set-current itself was sent once: the item was not restarted
    assert [m.command for m in sent].count(M.MAV_CMD_DO_SET_MISSION_CURRENT) == 1


def test_after_the_ack_silence_asks_for_mission_current() -> None:
    # ACK, then every streamed MISSION_CURRENT lost for 4 s: the machine asks, the vehicle
    # answers MISSION_CURRENT 1
    result, sent = exchange(MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=2),
                            [(0.05, ack())], on_ask=1)
    assert result.ok and "COMMAND_ACK and MISSION_CURRENT" in result.message
    asks = [m for m in sent if m.command == M.MAV_CMD_REQUEST_MESSAGE]
    assert len(asks) == 1 and asks[0].param1 == M.MAVLINK_MSG_ID_MISSION_CURRENT
    assert [m.command for m in sent].count(M.MAV_CMD_DO_SET_MISSION_CURRENT) == 1


def test_the_command_is_tried_until_an_ack_comes_through() -> None:
    # the vehicle already shows item 1, so no MISSION_CURRENT is news: only an ACK tells;
    # at 20 % loss each way 6 round trips all fail 0.2 % of the time (the one failure left
    # in 181 uploads). The 7th try's ACK confirms.
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=1)
    sent: list[Any] = []
    actions = sc.start(0.0)
    now_s = 0.0
    while not sc.done and now_s < 30.0:
        sent += [a.msg for a in actions if isinstance(a, Send)]
        if len(sent) == 7:
            actions = sc.receive(ack(), now_s + 0.05)
            actions += sc.receive(current(1), now_s + 0.06)
            continue
        now_s = sc.next_deadline_s() or now_s
        actions = sc.poll(now_s)
    assert sc.result is not None and sc.result.ok, sc.result
    assert [m.confirmation for m in sent] == list(range(7))


def test_one_late_frame_after_the_ack_still_confirms_nothing() -> None:
    # the guarantee kept: a single MISSION_CURRENT past the item after the ACK (a frame of
    # the previous mission, delivered late) and nothing else: no confirmation
    sc = MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=2, retries=2)
    result, sent = exchange(sc, [(0.05, ack()), (0.06, current(2))], on_ask=None)
    assert not result.ok
    assert len([m for m in sent if m.command == M.MAV_CMD_REQUEST_MESSAGE]) == 2


# ---------------------------------------------------------------- on the simulator
class LossyLink:
    """A Loopback whose messages are each dropped with probability ``loss``, each way."""

    def __init__(self, lb: Loopback, loss: float, seed: int) -> None:
        self.lb, self.loss, self.rng = lb, loss, random.Random(seed)
        self.lossy = False

    def keep(self, msgs: list[Any]) -> list[Any]:
        if not self.lossy:
            return msgs
        return [m for m in msgs if self.rng.random() >= self.loss]

    def send(self, msg: Any) -> list[Any]:
        if self.lossy and self.rng.random() < self.loss:
            return []
        return self.keep(self.lb.send(msg))

    def advance(self, dt_s: float) -> list[Any]:
        return self.keep(self.lb.advance(dt_s, 0.05))


def drive(link: LossyLink, sm: Any, limit_s: float = 30.0) -> TransferResult:
    lb = link.lb
    end = lb.t_s + limit_s
    pending = sm.start(lb.t_s)
    while not sm.done and lb.t_s < end:
        replies: list[Any] = []
        for action in pending:
            if isinstance(action, Send):
                replies += link.send(action.msg)
            else:
                assert isinstance(action, Finished)
        replies += link.advance(0.05)
        pending = []
        for msg in replies:
            if not sm.done:
                pending += sm.receive(msg, lb.t_s)
        if not sm.done:
            pending += sm.poll(lb.t_s)
    assert isinstance(sm.result, TransferResult)
    return sm.result


def to(x_m: float, y_m: float) -> list[Any]:
    return build_mission_items(
        [Waypoint(x_m, y_m, 100.0), LoiterUnlimited(x_m, y_m, 100.0, radius_m=120)], ORIGIN)


def y_now(lb: Loopback) -> float:
    return lb.vehicle.airframe.y_m


@pytest.mark.timeout(60)
def test_set_current_at_20_percent_loss_on_the_simulator() -> None:
    """30 re-uploads of a waypoint the plane reaches at once (60 m ahead, within WP_RADIUS:
    the set-current that failed at 20 % loss, where the item is done before its
    MISSION_CURRENT can show it), each set-current through 20 % loss each way; every one
    confirmed (>= 99.5 %), the item never restarted by a resent set-current after the ACK.
    (A waypoint behind the plane is not passed at once: ArduPlane's set_next_WP starts the
    leg where the plane is; tests/test_sitl_mission.py.)"""
    cfg = VehicleConfig(
        system_id=VEH_SYS, origin=ORIGIN, home_lat_deg=78.93, home_lon_deg=11.92,
        airborne=True, fast_boot=True, launch_x_m=0.0, launch_y_m=0.0,
        launch_heading_rad=1.5708,
    )  # fmt: skip
    lb = Loopback(SimVehicle(cfg), gcs_sysid=GCS_SYS, gcs_compid=GCS_COMP)
    lb.advance(3.0)
    link = LossyLink(lb, 0.2, seed=28)
    results: list[TransferResult] = []
    passed = 0
    for _ in range(30):
        y0 = y_now(lb)
        assert drive(link, MissionUpload(VEH_SYS, VEH_COMP, to(0.0, y0 + 1500.0))).ok
        assert drive(link, MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=1)).ok
        link.advance(14.0)  # ~300 m on towards the far waypoint
        assert drive(link, MissionUpload(VEH_SYS, VEH_COMP, to(0.0, y_now(lb) + 60.0))).ok
        link.lossy = True
        results.append(drive(link, MissionSetCurrent(VEH_SYS, VEH_COMP, 1, known_current_seq=1)))
        link.lossy = False
        link.advance(1.0)
        passed += lb.vehicle.autopilot.current_seq == 2
    ok = sum(r.ok for r in results)
    failures = [r.message for r in results if not r.ok]
    assert passed >= 20  # the case under test: most waypoints were reached at once
    assert ok / len(results) >= 0.995, failures
