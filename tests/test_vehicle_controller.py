"""The vehicle controller on its own: fake time, fake frames, fake exchange results.

A :class:`Rig` plays the vehicle: it sends HEARTBEATs (1 Hz), positions (2 Hz),
SYS_STATUS and MISSION_CURRENT (1 Hz) from a snapshot the test shapes, ticks the
controller, and answers each exchange it asks for (one at a time) as a cooperative
ArduPlane would, unless the test answers it itself.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import pytest

from domain.modes import ArduPlaneMode
from groundstation.core import events as ev
from groundstation.core.commands import FlyToTarget, ThroughPoint
from groundstation.mavlink.codec import mavlink2
from groundstation.mavlink.mission_items import MissionItem
from groundstation.mavlink.mission_transfer import TransferCode, TransferResult
from groundstation.mavlink.telemetry_events import (
    MissionItemReached,
    ModeChanged,
    Rebooted,
    VehicleSnapshot,
)
from groundstation.vehicle import controller_io as vio
from groundstation.vehicle.controller import VehicleController, VehicleState
from groundstation.vehicle.settings import ControllerSettings

M = mavlink2
S = VehicleState
ACCEPTED = M.MAV_RESULT_ACCEPTED
FLYING: dict[str, Any] = dict(
    x_m=0.0, y_m=0.0, alt_m=100.0, speed_m_s=22.0, heading_rad=0.0, armed=True,
    mode=ArduPlaneMode.AUTO, mode_name="AUTO", mission_current_seq=1, mission_total=3,
    battery_remaining_pct=80.0, prearm_ok=True, time_boot_ms=100_000, system_status=4,
)  # fmt: skip
ON_GROUND: dict[str, Any] = dict(
    FLYING, alt_m=0.0, speed_m_s=0.0, armed=False, system_status=3, landed_state=1
)


def ok_transfer(items: tuple[MissionItem, ...] | None = None) -> TransferResult:
    return TransferResult(True, TransferCode.SUCCESS, "ok", items=items)


class Rig:
    def __init__(self, auto_answer: bool = True, **settings: Any) -> None:
        self.c = VehicleController("v1", 1, ControllerSettings(**settings))
        self.snap = VehicleSnapshot(1, **FLYING)
        self.t = 0.0
        self.out: list[vio.Output] = []
        self.pending: vio.Exchange | None = None
        self.asked: list[vio.Exchange] = []
        self.auto_answer = auto_answer
        self.holding_mission = False
        self.params: dict[str, float] = {"AIRSPEED_CRUISE": 22.0}
        """What the vehicle answers to a ParamRead (a name not here: silence, None)."""
        self.reads: list[vio.ReadParam] = []

    # -- the vehicle's side
    def frame(self, kind: str, *events: Any, **changes: Any) -> list[vio.Output]:
        self.snap = replace(self.snap, last_heard_s=self.t, **changes)
        if kind == "HEARTBEAT":
            self.snap = replace(self.snap, last_heartbeat_s=self.t)
        return self.feed(vio.AutopilotFrame(self.t, kind, self.snap, tuple(events)))

    def feed(self, inp: vio.Input) -> list[vio.Output]:
        out = self.c.handle(inp)
        self._collect(out)
        return out

    def _collect(self, out: list[vio.Output]) -> None:
        self.out += out
        for o in out:
            if isinstance(o, vio.UploadMission | vio.Download | vio.SetCurrent | vio.SetMode
                          | vio.Arm | vio.SetParam | vio.ReadParam):
                assert self.pending is None, "two exchanges at once"
                self.pending = o
                # reads (the cruise airspeed, before the first assessment) apart: ``asked``
                # holds what commands the vehicle
                (self.reads if isinstance(o, vio.ReadParam) else self.asked).append(o)

    def answer(self, result: Any) -> list[vio.Output]:
        request = self.pending
        assert request is not None
        self.pending = None
        return self.feed(vio.ExchangeDone(self.t, request, result))

    def auto(self) -> None:
        """Answer as a cooperative vehicle would (parameter reads even without
        ``auto_answer``: the tests that answer by hand are about commands)."""
        while self.pending is not None and (
            self.auto_answer or isinstance(self.pending, vio.ReadParam)
        ):
            r = self.pending
            if isinstance(r, vio.UploadMission):
                self.answer(vio.UploadOutcome(True, 0, None, len(r.steps) + 1))
            elif isinstance(r, vio.Download):
                items = (_item(), _item(), _item(M.MAV_CMD_NAV_LOITER_UNLIM))
                self.answer(ok_transfer(items if self.holding_mission else (_item(), _item())))
            elif isinstance(r, vio.SetCurrent):
                self.snap = replace(self.snap, mission_current_seq=r.seq)
                self.answer(ok_transfer())
            elif isinstance(r, vio.SetMode):
                name = ArduPlaneMode(r.mode).name
                self.snap = replace(self.snap, mode=int(r.mode), mode_name=name)
                self.answer(ACCEPTED)
            elif isinstance(r, vio.Arm):
                self.snap = replace(self.snap, armed=True)
                self.answer(ACCEPTED)
            elif isinstance(r, vio.ReadParam):
                self.answer(self.params.get(r.name))
            else:
                self.answer(True)

    def run(self, seconds: float, step_s: float = 0.5, **changes: Any) -> None:
        """Let ``seconds`` of mission time pass with regular telemetry."""
        end = self.t + seconds
        self.snap = replace(self.snap, **changes)
        while self.t < end - 1e-9:
            before = self.t
            self.t = round(self.t + step_s, 6)
            if math.floor(self.t + 1e-9) != math.floor(before + 1e-9):  # 1 Hz messages
                self.frame("HEARTBEAT", **changes)
                self.frame("SYS_STATUS")
                self.frame("MISSION_CURRENT")
            self.frame("GLOBAL_POSITION_INT")
            self.feed(vio.TimePassed(self.t))
            self.auto()

    # -- reading the outputs
    def journal(self, name: str) -> list[vio.JournalLine]:
        return [o for o in self.out if isinstance(o, vio.JournalLine) and o.event == name]

    def core(self, kind: type) -> list[Any]:
        return [o.event for o in self.out if isinstance(o, vio.CoreEvent)
                and isinstance(o.event, kind)]  # fmt: skip

    def requests(self, kind: type) -> list[Any]:
        return [r for r in self.asked if isinstance(r, kind)]

    def fly(self, target: str = "A", x_m: float = 2000.0, y_m: float = 0.0,
            through: tuple[ThroughPoint, ...] = ()) -> None:
        cmd = FlyToTarget(self.t, "v1", target, x_m, y_m, 0.0, 120.0, (target,),
                          through=through)
        self.feed(vio.Fly(self.t, cmd, x_m, y_m))
        self.auto()


def _item(command: int = M.MAV_CMD_NAV_WAYPOINT) -> MissionItem:
    return MissionItem(0, command)


def active_rig(**settings: Any) -> Rig:
    rig = Rig(**settings)
    rig.run(4.0)
    assert rig.c.state is S.ACTIVE, rig.out
    return rig


# ------------------------------------------------------------------ joining
def test_flying_in_auto_is_parked_then_joins() -> None:
    rig = Rig()
    rig.run(4.0)
    assert [type(r) for r in rig.asked] == [vio.Download, vio.UploadMission, vio.SetCurrent]
    assert rig.asked[1].purpose == "park"  # type: ignore[union-attr]
    assert rig.journal("vehicle_joined")[0].fields["how"] == "parked"
    assert len(rig.core(ev.VehicleJoined)) == 1


def test_holding_an_unlimited_loiter_joins_without_upload() -> None:
    rig = Rig()
    rig.holding_mission = True
    rig.snap = replace(rig.snap, mission_current_seq=2)
    rig.run(4.0, mission_current_seq=2)
    assert rig.requests(vio.UploadMission) == []
    assert rig.journal("vehicle_joined")[0].fields["how"] == "holding"


def test_guided_joins_at_once_and_manual_waits() -> None:
    rig = Rig()
    rig.run(4.0, mode=ArduPlaneMode.GUIDED, mode_name="GUIDED")
    assert rig.journal("vehicle_joined")[0].fields["how"] == "guided" and rig.asked == []
    manual = Rig()
    manual.run(4.0, mode=ArduPlaneMode.FBWA, mode_name="FBWA")
    assert manual.c.state is S.MANUAL and manual.asked == [] and manual.journal("waiting")


@pytest.mark.parametrize(
    "changes",
    [
        {"armed": False},
        {"alt_m": 3.0},
        {"speed_m_s": 0.0},
        {"landed_state": 1},  # the autopilot says: on the ground
    ],
)
def test_not_flying_never_joins(changes: dict[str, Any]) -> None:
    rig = Rig()
    rig.run(10.0, **changes)
    assert rig.c.state is S.ON_GROUND and rig.asked == [] and not rig.core(ev.VehicleJoined)


def test_one_flying_frame_is_not_enough_to_join() -> None:
    rig = Rig()
    rig.snap = replace(rig.snap, **ON_GROUND)
    rig.run(5.0)
    rig.t += 1.0
    rig.frame("HEARTBEAT", **FLYING, landed_state=None)
    rig.frame("GLOBAL_POSITION_INT", **ON_GROUND)
    rig.run(5.0)
    assert rig.asked == [] and not rig.core(ev.VehicleJoined)


def test_launch_only_when_asked_and_the_guard_lets_it_through() -> None:
    rig = Rig()
    rig.snap = replace(rig.snap, **ON_GROUND)
    rig.run(5.0)
    assert rig.c.state is S.ON_GROUND and rig.asked == []
    ok, _ = rig.c.launch()
    rig._collect(rig.c.take_outputs())
    assert ok
    rig.run(2.0)
    kinds = [type(r) for r in rig.asked]
    assert kinds == [vio.UploadMission, vio.Arm, vio.SetCurrent, vio.SetMode]
    assert rig.c.state is S.LAUNCHING
    rig.run(10.0, **{**FLYING, "landed_state": None})
    assert rig.journal("vehicle_joined")[0].fields["how"] == "launched"
    assert rig.c.launch() == (False, "vehicle v1 is active, not on the ground")


def _launching_in_manual(**settings: Any) -> Rig:
    rig = Rig(auto_answer=False, **settings)
    rig.snap = replace(rig.snap, **ON_GROUND)
    rig.run(5.0, mode=ArduPlaneMode.MANUAL, mode_name="MANUAL")
    ok, _ = rig.c.launch()
    rig._collect(rig.c.take_outputs())
    assert ok and rig.c.state is S.LAUNCHING and isinstance(rig.pending, vio.UploadMission)
    return rig


def test_the_mode_it_waited_in_on_the_ground_is_no_override_while_launching() -> None:
    # issue 11 at 200x: the launch exchanges took longer than the 2 s override grace in
    # mission time, and the plane's MANUAL from before the launch was taken for an operator's
    rig = _launching_in_manual()
    rig.run(10.0, mode=ArduPlaneMode.MANUAL, mode_name="MANUAL")  # the upload takes 10 s
    assert not rig.journal("override") and rig.c.state is S.LAUNCHING
    rig.auto_answer = True
    rig.auto()
    rig.run(10.0, **{**FLYING, "landed_state": None})
    assert rig.journal("vehicle_joined")[0].fields["how"] == "launched"


def test_another_mode_while_launching_is_still_an_override() -> None:
    rig = _launching_in_manual()
    rig.run(5.0, mode=ArduPlaneMode.FBWA, mode_name="FBWA")
    assert [o.fields["reason"] for o in rig.journal("override")] == ["mode FBWA"]


MANUAL = dict(mode=ArduPlaneMode.MANUAL, mode_name="MANUAL")
FBWA = dict(mode=ArduPlaneMode.FBWA, mode_name="FBWA")


def _switch(rig: Rig, old: dict[str, Any], new: dict[str, Any]) -> None:
    """The operator switches modes: the reducer's ModeChanged with the next heartbeat."""
    rig.t = round(rig.t + 0.25, 6)
    change = ModeChanged(rig.t, old["mode"], new["mode"], old["mode_name"], new["mode_name"])
    rig.frame("HEARTBEAT", change, **new)


def test_an_operators_round_trip_through_another_mode_ends_the_launch() -> None:
    # gap (i): MANUAL -> FBWA -> MANUAL within the override grace, before floe's AUTO. The
    # MANUAL it comes back to is the operator's, not the one floe found it in: an override
    # once it lasts, and floe neither arms it nor sets AUTO.
    rig = _launching_in_manual()
    _switch(rig, MANUAL, FBWA)
    rig.run(1.0, **FBWA)  # shorter than the 2 s grace
    _switch(rig, FBWA, MANUAL)
    rig.run(4.0, **MANUAL)  # the takeoff upload is still running
    assert [o.fields["reason"] for o in rig.journal("override")] == ["mode MANUAL"]
    assert rig.c.state is S.OVERRIDDEN
    rig.answer(vio.UploadOutcome(True, 0, None, 3))  # the upload ends after all
    rig.auto_answer = True
    rig.run(20.0, **MANUAL)
    assert rig.requests(vio.Arm) == [] and rig.requests(vio.SetMode) == []


def test_manual_after_auto_was_accepted_is_an_override_not_a_relaunch() -> None:
    # gap (ii): floe's SetMode(AUTO) was accepted, but the operator went back to MANUAL
    # before any heartbeat showed AUTO. That MANUAL is not floe's: an override, and the
    # launch that never flew is not started again when launch_timeout_s runs out.
    rig = _launching_in_manual(launch_timeout_s=30.0)
    rig.answer(vio.UploadOutcome(True, 0, None, 3))
    assert isinstance(rig.pending, vio.Arm)
    rig.snap = replace(rig.snap, armed=True)
    rig.answer(ACCEPTED)
    assert isinstance(rig.pending, vio.SetCurrent)
    rig.answer(ok_transfer())
    assert isinstance(rig.pending, vio.SetMode) and rig.pending.mode == ArduPlaneMode.AUTO
    rig.answer(ACCEPTED)  # no heartbeat ever shows AUTO: the vehicle stays in MANUAL
    rig.run(5.0, **MANUAL, armed=True)
    assert [o.fields["reason"] for o in rig.journal("override")] == ["mode MANUAL"]
    assert rig.c.state is S.OVERRIDDEN
    rig.auto_answer = True
    rig.run(60.0, **MANUAL, armed=True)
    assert len(rig.requests(vio.UploadMission)) == 1 and len(rig.requests(vio.Arm)) == 1
    assert not rig.journal("launch_timeout") and rig.c.state is S.OVERRIDDEN


# ------------------------------------------------------------------ the cruise airspeed
def test_the_cruise_airspeed_is_read_before_joining_and_planned_with_not_the_climbs() -> None:
    rig = Rig()
    rig.run(4.0, airspeed_m_s=28.0)  # flying in AUTO at the climb-out's airspeed
    assert [r.name for r in rig.reads] == ["AIRSPEED_CRUISE"]
    read_at = rig.out.index(rig.reads[0])
    assert all(rig.out.index(r) > read_at for r in rig.asked)  # before the park exchanges
    assert [line.fields for line in rig.journal("cruise_speed")] == [
        {"speed_m_s": 22.0, "source": "AIRSPEED_CRUISE"}]
    joined = rig.core(ev.VehicleJoined)
    assert len(joined) == 1 and joined[0].speed_m_s == 22.0
    rig.run(2.0, airspeed_m_s=28.0)
    speeds = {e.speed_m_s for e in rig.core(ev.Telemetry)}
    assert speeds == {22.0}
    assert len(rig.reads) == 1  # read once


@pytest.mark.parametrize(
    ("params", "speed_m_s", "source", "asked"),
    [
        ({"TRIM_ARSPD_CM": 2000.0}, 20.0, "TRIM_ARSPD_CM", ["AIRSPEED_CRUISE", "TRIM_ARSPD_CM"]),
        ({"AIRSPEED_CRUISE": 0.0, "TRIM_ARSPD_CM": 1800.0}, 18.0, "TRIM_ARSPD_CM",
         ["AIRSPEED_CRUISE", "TRIM_ARSPD_CM"]),  # 0 m/s is not believed
        ({}, 19.0, "config", ["AIRSPEED_CRUISE", "TRIM_ARSPD_CM"]),  # neither answers
    ],
)
def test_the_cruise_airspeed_of_older_firmware_or_else_the_configured_one(
    params: dict[str, float], speed_m_s: float, source: str, asked: list[str]
) -> None:
    rig = Rig(speed_m_s=19.0)
    rig.params = params
    rig.run(4.0, airspeed_m_s=27.0)
    assert [r.name for r in rig.reads] == asked
    assert [line.fields for line in rig.journal("cruise_speed")] == [
        {"speed_m_s": speed_m_s, "source": source}]
    assert len(rig.journal("cruise_speed_refused")) == (1 if 0.0 in params.values() else 0)
    assert [e.speed_m_s for e in rig.core(ev.VehicleJoined)] == [speed_m_s]


def test_advisory_reads_no_parameter_and_plans_with_the_configured_speed() -> None:
    rig = Rig(advisory=True, speed_m_s=21.0)
    rig.run(4.0, airspeed_m_s=27.0)
    assert rig.reads == [] and rig.asked == []
    assert [line.fields for line in rig.journal("cruise_speed")] == [
        {"speed_m_s": 21.0, "source": "config"}]
    assert [e.speed_m_s for e in rig.core(ev.VehicleJoined)] == [21.0]


def test_a_cruise_read_cut_short_by_a_lost_link_is_asked_again() -> None:
    rig = Rig(auto_answer=False)
    rig.snap = replace(rig.snap, **ON_GROUND)
    rig.frame("HEARTBEAT")
    rig.feed(vio.TimePassed(rig.t))
    assert isinstance(rig.pending, vio.ReadParam)
    rig.t = 20.0  # silence: the link is lost, the read aborted
    rig.feed(vio.TimePassed(rig.t))
    assert rig.c.link == "lost" and any(isinstance(o, vio.CancelExchange) for o in rig.out)
    rig.answer(None)  # the driver's result of the cancelled read: it only frees the runner
    assert rig.c.cruise_source is None
    rig.params = {"AIRSPEED_CRUISE": 25.0}
    rig.run(3.0)
    assert [r.name for r in rig.reads] == ["AIRSPEED_CRUISE", "AIRSPEED_CRUISE"]
    assert [line.fields["source"] for line in rig.journal("cruise_speed")] == ["AIRSPEED_CRUISE"]
    assert rig.c.cruise_speed_m_s == 25.0


# ------------------------------------------------------------------ flying to targets
def test_fly_uploads_sets_current_and_counts() -> None:
    rig = active_rig()
    rig.asked.clear()
    rig.fly()
    assert [type(r) for r in rig.asked] == [vio.UploadMission, vio.SetCurrent]
    assert rig.c.uploads_ok == 1 and rig.c.fly is not None and rig.c.fly.target == "A"
    upload = rig.journal("upload")[-1].fields
    assert upload["ok"] and upload["purpose"] == "target" and upload["target"] == "A"


def test_a_newer_command_overtakes_a_pending_one() -> None:
    rig = active_rig(auto_answer=True)
    rig.auto_answer = False
    rig.fly("A")
    rig.fly("B")
    rig.fly("C")
    rig.auto_answer = True
    rig.auto()
    targets = [r.target for r in rig.requests(vio.UploadMission) if r.purpose == "target"]
    assert targets == ["A", "C"]


def test_a_newer_command_during_a_retry_pause_is_flown_not_the_old_one() -> None:
    rig = active_rig()
    rig.auto_answer = False
    rig.fly("A")
    rig.answer(vio.UploadOutcome(False, 5, "upload timeout", 3))  # A failed: its job pauses
    assert rig.pending is None
    rig.fly("B")  # the core moves on while A waits to be retried
    rig.auto_answer = True
    rig.run(5.0)
    targets = [r.target for r in rig.requests(vio.UploadMission) if r.purpose == "target"]
    assert targets == ["A", "B"]  # A is not uploaded again before B
    assert rig.c.fly is not None and rig.c.fly.target == "B"


@pytest.mark.parametrize(
    ("code", "remote", "seq_after", "ok"),
    [
        # ACK seen, the vehicle shows a later item: that may be a stale frame of the previous
        # mission (a reordering link); the machine alone decides (MISSION_ITEM_REACHED)
        (TransferCode.TIMEOUT, "MAV_RESULT_ACCEPTED", 2, False),
        (TransferCode.TIMEOUT, None, 2, False),  # no ACK: the item 2 may be the old mission's
        (TransferCode.TIMEOUT, "MAV_RESULT_ACCEPTED", 1, False),  # not moved past
        (TransferCode.DENIED, "MAV_RESULT_DENIED", 2, False),
        (TransferCode.SUCCESS, "MAV_RESULT_ACCEPTED", 2, True),  # passed at once, confirmed
    ],
)
def test_set_current_decided_on_result_codes(
    code: TransferCode, remote: str | None, seq_after: int, ok: bool
) -> None:
    rig = active_rig()
    rig.auto_answer = False
    rig.fly()
    rig.answer(vio.UploadOutcome(True, 0, None, 3))
    rig.snap = replace(rig.snap, mission_current_seq=seq_after)
    rig.frame("MISSION_CURRENT")
    message = "COMMAND_ACK ACCEPTED but MISSION_CURRENT never showed 1"  # never grepped
    success = code is TransferCode.SUCCESS
    rig.answer(TransferResult(success, code, message, remote_code=remote))
    assert rig.journal("upload")[-1].fields["ok"] is ok


# ------------------------------------------------------------------ the guard
def test_guard_refuses_a_target_upload_to_a_disarmed_vehicle() -> None:
    rig = active_rig()
    rig.frame("HEARTBEAT", armed=False)
    rig.asked.clear()
    rig.fly()
    assert rig.requests(vio.UploadMission) == [] and rig.journal("command_refused")


def test_guard_refuses_auto_after_an_upload_when_the_vehicle_disarmed_meanwhile() -> None:
    rig = active_rig()
    rig.snap = replace(rig.snap, mode=ArduPlaneMode.GUIDED, mode_name="GUIDED")
    rig.auto_answer = False
    rig.fly()
    rig.answer(vio.UploadOutcome(True, 0, None, 3))
    rig.frame("HEARTBEAT", armed=False)
    rig.snap = replace(rig.snap, mission_current_seq=1)
    rig.answer(ok_transfer())
    assert rig.requests(vio.SetMode) == [] and rig.journal("command_refused")


def test_guard_refuses_the_park_upload_when_the_vehicle_disarmed_meanwhile() -> None:
    rig = Rig(auto_answer=False)
    rig.run(4.0)
    assert [type(r) for r in rig.asked] == [vio.Download]
    rig.frame("HEARTBEAT", armed=False)
    rig.answer(ok_transfer((_item(), _item())))
    assert rig.requests(vio.UploadMission) == [] and rig.journal("command_refused")
    assert rig.c.state is S.CONNECTING


def test_guard_refuses_rtl_for_a_disarmed_vehicle() -> None:
    rig = active_rig()
    rig.frame("HEARTBEAT", armed=False)
    rig.feed(vio.Release(rig.t, "battery low", home=True))
    assert rig.requests(vio.SetMode) == [] and rig.journal("command_refused")
    armed = active_rig()
    armed.feed(vio.Release(armed.t, "battery low", home=True))
    armed.auto()
    assert [r.mode for r in armed.requests(vio.SetMode)] == [ArduPlaneMode.RTL]
    assert armed.journal("rtl")[0].fields["ok"] is True


# ------------------------------------------------------------------ overrides and take-back
def test_sustained_mode_change_is_an_override_one_frame_is_not() -> None:
    rig = active_rig()
    rig.t += 0.5
    rig.frame("HEARTBEAT", mode=ArduPlaneMode.FBWA, mode_name="FBWA")  # one forged frame
    rig.run(10.0, mode=ArduPlaneMode.AUTO, mode_name="AUTO")
    assert rig.c.state is S.ACTIVE and not rig.journal("override")
    rig.run(5.0, mode=ArduPlaneMode.FBWA, mode_name="FBWA")
    assert rig.journal("override")[0].fields["reason"] == "mode FBWA"
    assert len(rig.core(ev.OperatorOverride)) == 1


def test_auto_again_takes_back_a_flying_vehicle() -> None:
    rig = active_rig()
    rig.run(5.0, mode=ArduPlaneMode.FBWA, mode_name="FBWA")
    rig.asked.clear()
    rig.run(5.0, mode=ArduPlaneMode.AUTO, mode_name="AUTO")
    assert rig.journal("resume")[0].fields["reason"] == "mode AUTO"
    assert rig.c.state is S.ACTIVE and len(rig.core(ev.OperatorResume)) == 1


def test_an_override_in_auto_is_not_taken_back_until_auto_is_selected_again() -> None:
    rig = active_rig()
    rig.c.override(rig.t, "mission MISSION_COUNT from GCS system 255")
    rig._collect(rig.c.take_outputs())
    rig.run(20.0)  # still in AUTO: the other ground station flies it
    assert rig.c.state is S.OVERRIDDEN and not rig.journal("resume")
    rig.run(3.0, mode=ArduPlaneMode.LOITER, mode_name="LOITER")
    rig.run(5.0, mode=ArduPlaneMode.AUTO, mode_name="AUTO")
    assert rig.c.state is S.ACTIVE and rig.journal("resume")[0].fields["reason"] == "mode AUTO"


def test_auto_again_on_the_ground_is_not_a_take_back() -> None:
    # issue 10.1: overridden to FBWA, glided in, switched back to AUTO at 0 m
    rig = active_rig()
    rig.run(5.0, mode=ArduPlaneMode.FBWA, mode_name="FBWA")
    rig.run(10.0, mode=ArduPlaneMode.FBWA, mode_name="FBWA", alt_m=0.0, speed_m_s=0.0,
            landed_state=1)  # fmt: skip
    rig.asked.clear()
    rig.run(30.0, mode=ArduPlaneMode.AUTO, mode_name="AUTO", alt_m=0.0, speed_m_s=0.0,
            landed_state=1)  # fmt: skip
    assert not rig.journal("resume") and rig.journal("resume_refused")
    assert rig.c.state is S.ON_GROUND and rig.asked == [] and not rig.core(ev.OperatorResume)
    assert rig.c.resume(rig.t, "api") is False


def test_battery_failsafe_rtl_is_not_an_override() -> None:
    rig = active_rig()
    rig.run(6.0, mode=ArduPlaneMode.RTL, mode_name="RTL", battery_remaining_pct=10.0,
            system_status=5)  # fmt: skip
    assert not rig.journal("override")
    assert rig.journal("battery_low") and len(rig.core(ev.BatteryLow)) == 1


# ------------------------------------------------------------------ battery evidence
def test_one_low_battery_frame_changes_nothing() -> None:
    rig = active_rig()
    rig.t += 0.2
    rig.frame("SYS_STATUS", battery_remaining_pct=5.0)
    rig.frame("HEARTBEAT", system_status=5)
    rig.run(30.0, battery_remaining_pct=80.0, system_status=4)
    assert not rig.journal("battery_low") and not rig.core(ev.BatteryLow)


def test_low_battery_needs_the_autopilot_or_a_long_time() -> None:
    rig = active_rig()
    rig.run(10.0, battery_remaining_pct=10.0)
    assert not rig.core(ev.BatteryLow)  # low readings only, not for long
    rig.run(15.0, battery_remaining_pct=10.0)
    assert len(rig.core(ev.BatteryLow)) == 1  # low for more than battery_alone_span_s
    fast = active_rig()
    fast.run(3.0, battery_remaining_pct=10.0, system_status=5)
    assert len(fast.core(ev.BatteryLow)) == 1


# ------------------------------------------------------------------ reboot and link
def test_reboot_cancels_the_transfer_and_leaves_the_plan() -> None:
    rig = active_rig()
    rig.auto_answer = False
    rig.fly()
    assert rig.pending is not None
    rig.t += 0.1
    rig.frame("SYSTEM_TIME", Rebooted(rig.t, 100_000, 800), time_boot_ms=800, armed=None,
              mode=None, mission_current_seq=None)  # fmt: skip
    assert any(isinstance(o, vio.NotifyRebooted) for o in rig.out)
    assert rig.c.state is S.CONNECTING and len(rig.core(ev.VehicleLost)) == 1
    rig.answer(TransferResult(False, TransferCode.VEHICLE_REBOOTED, "rebooted"))
    # the aborted job says nothing more
    assert [j for j in rig.journal("upload") if j.fields["purpose"] == "target"] == []


def test_a_stray_small_boot_time_holds_the_upload_it_does_not_drop_it() -> None:
    # one forged frame with a small time_boot_ms just as a new mission is due: the upload
    # waits for the next frames (which clear the suspicion) instead of being refused
    rig = active_rig()
    rig.asked.clear()
    rig.frame("SYSTEM_TIME", time_boot_ms=100_000, reboot_suspected=True)
    rig.fly("B")
    assert rig.asked == [] and rig.pending is None
    assert not rig.journal("command_refused")
    rig.t += 0.2
    rig.frame("ATTITUDE", reboot_suspected=False)  # back on the vehicle's own timeline
    rig.feed(vio.TimePassed(rig.t))
    rig.auto()
    uploads = rig.requests(vio.UploadMission)
    assert [u.target for u in uploads] == ["B"] and rig.c.fly is not None
    assert rig.c.fly.verified_t_s is not None and not rig.journal("command_refused")


def test_link_restore_watches_before_any_command_and_a_rebooted_vehicle_is_not_commanded() -> None:
    # issue 10.2: a vehicle rebooted (on the ground, disarmed) while the link was down
    rig = active_rig()
    rig.fly("A")
    rig.auto_answer = False
    rig.fly("B")  # owed when the link goes
    rig.t += 10.0
    rig.feed(vio.TimePassed(rig.t))
    assert rig.c.link == "lost" and len(rig.core(ev.VehicleLost)) == 1
    assert any(isinstance(o, vio.CancelExchange) for o in rig.out)
    rig.answer(None)  # the cancelled exchange
    rig.auto_answer = True
    rig.asked.clear()
    rig.t += 0.5
    rig.frame("HEARTBEAT", **ON_GROUND, reboot_suspected=True)  # first frame: boot time back
    assert rig.journal("link_restored") and rig.asked == []
    rig.run(1.0, **ON_GROUND, reboot_suspected=True)
    assert rig.asked == []
    rig.t += 0.5
    rig.frame("HEARTBEAT", Rebooted(rig.t, 100_000, 2_000), **ON_GROUND, reboot_suspected=False)
    rig.run(20.0, **ON_GROUND)
    assert rig.asked == [] and rig.c.state is S.ON_GROUND
    assert not rig.core(ev.VehicleReturned)


def test_link_restore_of_a_flying_vehicle_sends_the_owed_mission_after_settling() -> None:
    rig = active_rig()
    rig.auto_answer = False
    rig.fly("B")
    rig.t += 10.0
    rig.feed(vio.TimePassed(rig.t))
    rig.answer(None)
    rig.auto_answer = True
    rig.asked.clear()
    rig.t += 0.5
    rig.frame("HEARTBEAT")
    assert rig.asked == []
    t_back = rig.t
    rig.run(5.0)
    returned = rig.core(ev.VehicleReturned)
    assert returned and returned[0].t_s >= t_back + 2.0
    assert [r.target for r in rig.requests(vio.UploadMission)] == ["B"]


# ------------------------------------------------------------------ progress and landing
def test_no_progress_takes_the_vehicle_out_of_the_plan() -> None:
    rig = active_rig(progress_timeout_s=60.0)
    rig.fly("A", x_m=3000.0)
    rig.run(50.0)  # circling far away: no nearer
    assert rig.c.state is S.ACTIVE
    rig.run(15.0)
    assert rig.journal("no_progress") and any(isinstance(o, vio.Warn) for o in rig.out)
    assert len(rig.core(ev.VehicleLost)) == 1 and rig.c.state is S.CONNECTING


def test_approaching_loitering_at_the_aim_or_advancing_items_is_progress() -> None:
    rig = active_rig(progress_timeout_s=60.0)
    rig.fly("A", x_m=3000.0)
    for k in range(40):  # approach at ~22 m/s for 80 s
        rig.run(2.0, x_m=44.0 * (k + 1))
    rig.run(100.0, x_m=3000.0 + 100.0)  # loitering at the aim point
    assert not rig.journal("no_progress")
    far = active_rig(progress_timeout_s=60.0)
    far.fly("A", x_m=3000.0)
    for seq in (1, 2) * 5:  # the mission advances every 20 s
        far.run(20.0, mission_current_seq=seq)
    assert not far.journal("no_progress")


def test_on_the_ground_while_active_is_out() -> None:
    rig = active_rig()
    rig.t += 0.5
    rig.frame("EXTENDED_SYS_STATE", landed_state=1)  # one frame: nothing
    rig.run(3.0, landed_state=None)
    assert rig.c.state is S.ACTIVE
    rig.run(4.0, landed_state=1, alt_m=0.0, speed_m_s=0.0)
    assert rig.journal("landed") and rig.c.state is S.ON_GROUND
    assert len(rig.core(ev.VehicleLost)) == 1


# ------------------------------------------------------------------ loiter ends
def test_loiter_end_needs_agreeing_signals_over_time() -> None:
    rig = active_rig()
    rig.fly()
    rig.t += 0.1
    rig.frame("MISSION_ITEM_REACHED", MissionItemReached(rig.t, 1))  # forged
    rig.run(3.0, mission_current_seq=1)
    rig.t += 0.1
    rig.frame("MISSION_CURRENT", mission_current_seq=2)  # forged
    rig.run(3.0, mission_current_seq=1)
    rig.t += 0.1  # a forged burst: both signals at once, then the vehicle's own frames
    rig.frame("MISSION_ITEM_REACHED", MissionItemReached(rig.t, 1))
    for seq in (2, 3, 2, 3):
        rig.frame("MISSION_CURRENT", mission_current_seq=seq)
    rig.run(3.0, mission_current_seq=1)
    assert not rig.core(ev.LoiterEnded) and not rig.journal("loiter_end")
    rig.t += 0.1  # the real end: reached, and the mission goes on to item 2 and stays
    rig.frame("MISSION_ITEM_REACHED", MissionItemReached(rig.t, 1))
    rig.frame("MISSION_CURRENT", mission_current_seq=2)
    assert not rig.core(ev.LoiterEnded)
    rig.run(1.0, mission_current_seq=2)
    ended = rig.core(ev.LoiterEnded)
    assert len(ended) == 1 and rig.journal("loiter_end")[0].fields["how"] == "reached"


def test_a_routed_pass_ends_at_its_last_cell_and_is_journalled_there() -> None:
    """A pass through search cells ends where its last cell is (the item before the hold):
    the loiter end names that cell, not the head the mission began with."""
    rig = active_rig()
    rig.fly("C1", through=(ThroughPoint("C2", 2300.0, 0.0), ThroughPoint("C3", 2600.0, 0.0)))
    rig.t += 0.1
    rig.frame("MISSION_ITEM_REACHED", MissionItemReached(rig.t, 3))
    rig.frame("MISSION_CURRENT", mission_current_seq=4)
    rig.run(1.0, mission_current_seq=4)
    assert len(rig.core(ev.LoiterEnded)) == 1
    [end] = rig.journal("loiter_end")
    assert end.fields["target"] == "C3", end.fields


def test_foreign_frames_are_counted_and_change_nothing() -> None:
    rig = active_rig()
    rig.fly()
    before = list(rig.out)
    for _ in range(50):
        rig.feed(vio.ForeignFrame(rig.t, "MISSION_ITEM_REACHED", 2))
    assert rig.c.foreign_frames == 50 and rig.out == before


def test_commands_wait_while_stopping() -> None:
    rig = active_rig()
    rig.feed(vio.Stop(rig.t))
    rig.asked.clear()
    rig.fly()
    rig.run(3.0)
    assert rig.asked == []
    assert math.isfinite(rig.t)


def test_a_target_mission_does_not_wait_behind_the_parameter_snapshot() -> None:
    """The snapshot is the lowest priority: a target arriving while it downloads (~20 s of
    a real ArduPlane's ~1 000 parameters over a SiK radio) cancels it; the mission goes
    first, and the snapshot is read again later, the cancelled try not counted."""
    rig = Rig(params_snapshot=True)
    rig.run(2.0)
    (first,) = [o for o in rig.out if isinstance(o, vio.ReadAllParams)]
    rig.feed(vio.ExchangeDone(rig.t, first, ({}, None)))  # a failed try: again 30 s later
    rig.auto()
    rig.run(3.0)
    assert rig.c.state is S.ACTIVE and rig.c._params_tries == 1
    rig.run(30.0)
    reads = [o for o in rig.out if isinstance(o, vio.ReadAllParams)]
    assert len(reads) == 2  # the second try runs: this rig never answers it
    rig.fly()
    rig.run(0.5)
    cancels = [o for o in rig.out if isinstance(o, vio.CancelExchange)]
    assert cancels, "the snapshot's download was not cancelled for the target mission"
    rig.feed(vio.ExchangeDone(rig.t, reads[1], None))  # the driver: the exchange ended
    rig.auto()
    rig.run(1.0)
    assert [r.purpose for r in rig.requests(vio.UploadMission)][-1] == "target"
    assert rig.c._params_tries == 1 and not rig.c.params_snapshot
