"""Whose mode change was it: the controller fed a scripted ArduPlane-shaped exchange.

The frames are real MAVLink 2 bytes, shaped as ArduPlane 4.x sends them (HEARTBEAT,
SYS_STATUS, GLOBAL_POSITION_INT and MISSION_CURRENT at 1 Hz; MISSION_CURRENT's ``total``
excludes home, so on floe's target mission [home, timed loiter, unlimited loiter] it is 2 and
the last item has ``seq == total``; its ``mission_state`` PAUSED after a pilot's switch out of
AUTO, COMPLETE after the mission ran off its end). They go through the telemetry reducer into
the vehicle controller, which answers through its exchanges as floe would. Mission time is
the script's: nothing here depends on the host's speed.

The rule (docs/daemon.md, "Whose mode change it was"): a mission end needs ArduPilot's own
evidence ("Mission complete", the last item reached, or MISSION_STATE_COMPLETE); a battery
failsafe needs low battery readings; everything else, and anything unsure, is the operator's.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import pytest

from domain.geodesy import GeoOrigin
from domain.modes import ArduPlaneMode
from groundstation.core import events as ev
from groundstation.core.commands import FlyToTarget
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_items import MissionItem
from groundstation.mavlink.mission_transfer import TransferCode, TransferResult
from groundstation.mavlink.telemetry import VehicleTelemetry
from groundstation.vehicle import controller_io as vio
from groundstation.vehicle.controller import VehicleController, VehicleState
from groundstation.vehicle.settings import ControllerSettings

M = mavlink2
S = VehicleState
AUTO, RTL = int(ArduPlaneMode.AUTO), int(ArduPlaneMode.RTL)
ORIGIN = GeoOrigin(78.9, 11.9, 0.0)
ARMED_CUSTOM = M.MAV_MODE_FLAG_SAFETY_ARMED | M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
COMMANDS = (vio.UploadMission, vio.SetMode, vio.SetCurrent, vio.Arm, vio.SetParam)


@dataclass
class ScriptedPlane:
    """An ArduPlane-shaped vehicle on the other side of real MAVLink bytes."""

    mode: int = AUTO
    seq: int = 2  # MISSION_CURRENT seq
    total: int = 2  # items after home (MAVLink: on the last item, seq == total)
    state: int = M.MISSION_STATE_ACTIVE
    battery_pct: int = 80
    system_status: int = M.MAV_STATE_ACTIVE
    alt_m: float = 100.0
    boot_ms: int = 600_000
    enc: MavlinkEncoder = field(default_factory=lambda: MavlinkEncoder(1, 1))
    dec: MavlinkDecoder = field(default_factory=MavlinkDecoder)

    def wire(self, msg: MAVLinkMessage) -> MAVLinkMessage:
        (out,) = self.dec.feed(self.enc.encode(msg))
        return out

    def second(self) -> list[MAVLinkMessage]:
        """One second of ArduPlane's streams."""
        self.boot_ms += 1000
        lat, lon = int(ORIGIN.lat_deg * 1e7), int(ORIGIN.lon_deg * 1e7)
        msgs = [
            M.MAVLink_heartbeat_message(
                M.MAV_TYPE_FIXED_WING, M.MAV_AUTOPILOT_ARDUPILOTMEGA, ARMED_CUSTOM, self.mode,
                self.system_status, 3,
            ),
            M.MAVLink_sys_status_message(
                0, 0, 0x10000000, 500, 12000, 1000, self.battery_pct, 0, 0, 0, 0, 0, 0
            ),
            M.MAVLink_global_position_int_message(
                self.boot_ms, lat, lon, int(self.alt_m * 1000), int(self.alt_m * 1000),
                2200, 0, 0, 9000,
            ),
            M.MAVLink_mission_current_message(self.seq, self.total, self.state, 1),
        ]  # fmt: skip
        return [self.wire(m) for m in msgs]

    def text(self, severity: int, text: str) -> MAVLinkMessage:
        return self.wire(M.MAVLink_statustext_message(severity, text.encode()))

    def reached(self, seq: int) -> MAVLinkMessage:
        return self.wire(M.MAVLink_mission_item_reached_message(seq))


class Harness:
    """Reducer + controller; floe's exchanges answered as a cooperative ArduPlane would."""

    def __init__(self, plane: ScriptedPlane) -> None:
        self.plane = plane
        self.tel = VehicleTelemetry(1, ORIGIN)
        self.c = VehicleController("1", 1, ControllerSettings())
        self.t = 0.0
        self.out: list[vio.Output] = []
        self.commands: list[tuple[float, vio.Exchange]] = []
        self.defer = False  # leave exchanges unanswered (in flight) until answer_pending()
        self.pending: list[vio.Exchange] = []

    def receive(self, msg: MAVLinkMessage) -> None:
        events = self.tel.receive(msg, self.t)
        self._feed(vio.AutopilotFrame(self.t, msg.get_type(), self.tel.snapshot(), tuple(events)))

    def _feed(self, inp: vio.Input) -> None:
        out = self.c.handle(inp)
        self.out += out
        for o in out:
            if isinstance(o, vio.UploadMission | vio.Download | vio.SetCurrent | vio.SetMode
                          | vio.Arm | vio.SetParam | vio.ReadParam):  # fmt: skip
                if isinstance(o, COMMANDS):
                    self.commands.append((self.t, o))
                if self.defer:
                    self.pending.append(o)
                else:
                    self._feed(vio.ExchangeDone(self.t, o, self._answer(o)))

    def answer_pending(self) -> None:
        self.defer = False
        while self.pending:
            o = self.pending.pop(0)
            self._feed(vio.ExchangeDone(self.t, o, self._answer(o)))

    def _answer(self, o: vio.Exchange) -> Any:
        p = self.plane
        if isinstance(o, vio.UploadMission):
            p.total, p.state = len(o.steps), M.MISSION_STATE_ACTIVE
            return vio.UploadOutcome(True, 0, None, len(o.steps) + 1)
        if isinstance(o, vio.Download):  # floe's target mission, on its unlimited loiter
            items = tuple(MissionItem(i, c) for i, c in enumerate(
                (M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_LOITER_TIME, M.MAV_CMD_NAV_LOITER_UNLIM)))
            return TransferResult(True, TransferCode.SUCCESS, "ok", items=items)
        if isinstance(o, vio.SetCurrent):
            p.seq = o.seq
            return TransferResult(True, TransferCode.SUCCESS, "ok")
        if isinstance(o, vio.SetMode):
            p.mode = o.mode
            return M.MAV_RESULT_ACCEPTED
        if isinstance(o, vio.ReadParam):  # ArduPlane 4.5+: AIRSPEED_CRUISE, m/s
            return 22.0 if o.name == "AIRSPEED_CRUISE" else None
        return M.MAV_RESULT_ACCEPTED if isinstance(o, vio.Arm) else True

    def seconds(self, n: int) -> None:
        for _ in range(n):
            self.t = round(self.t + 1.0, 6)
            for msg in self.plane.second():
                self.receive(msg)
            self._feed(vio.TimePassed(self.t))

    def fly(self, target: str = "A") -> None:
        cmd = FlyToTarget(self.t, "1", target, 1500.0, 0.0, 0.0, 30.0, (target,))
        self._feed(vio.Fly(self.t, cmd, 1500.0, 0.0))

    def journal(self, name: str) -> list[vio.JournalLine]:
        return [o for o in self.out if isinstance(o, vio.JournalLine) and o.event == name]

    def core(self, kind: type) -> list[Any]:
        return [o.event for o in self.out
                if isinstance(o, vio.CoreEvent) and isinstance(o.event, kind)]  # fmt: skip

    def commands_after(self, t_s: float) -> list[vio.Exchange]:
        return [c for t, c in self.commands if t > t_s]


def active_on_item(seq: int) -> Harness:
    """A plane joined in AUTO (parked on its unlimited loiter), then given a target: floe's
    3-item mission uploaded and started at item 1; the plane flies item ``seq`` of it."""
    h = Harness(ScriptedPlane())
    h.seconds(8)
    assert h.c.state is S.ACTIVE, h.journal("vehicle_joined")
    h.fly()
    assert h.plane.seq == 1 and h.plane.total == 2  # [home, loiter time, loiter unlim]
    h.plane.seq = seq
    h.seconds(5)
    return h


@pytest.mark.parametrize("seq", [1, 2], ids=["target item", "last item"])
@pytest.mark.parametrize("mode", ["RTL", "FBWA", "MANUAL", "LOITER"])
def test_pilots_switch_on_any_item_is_an_override(seq: int, mode: str) -> None:
    h = active_on_item(seq)
    t_switch = h.t
    h.plane.mode = int(ArduPlaneMode[mode])
    h.plane.state = M.MISSION_STATE_PAUSED  # ArduPilot: AUTO's exit stops the mission
    h.seconds(30)
    (override,) = h.journal("override")
    assert override.fields["reason"] == f"mode {mode}"
    assert override.fields["mode"] == mode
    assert h.c.state is S.OVERRIDDEN
    assert not h.journal("autopilot_mode")
    assert h.core(ev.OperatorOverride) and not h.core(ev.VehicleRebooted)
    assert not h.commands_after(t_switch), "floe commanded a vehicle the pilot took"


def test_rtl_on_the_last_item_without_mission_state_is_still_the_operators() -> None:
    """An autopilot that does not report mission_state (older ArduPilot, other stacks): on
    the last item, an RTL with no "Mission complete" is not a mission end."""
    h = active_on_item(2)
    h.plane.state = 0
    h.seconds(2)
    t_switch = h.t
    h.plane.mode = RTL
    h.seconds(30)
    assert [j.fields["reason"] for j in h.journal("override")] == ["mode RTL"]
    assert not h.commands_after(t_switch)


@pytest.mark.parametrize("evidence", ["text", "reached", "state"])
def test_arduplanes_own_mission_end_is_taken_back(evidence: str) -> None:
    """A mission that really ran off its end (floe's was cut short, say, to a last timed
    loiter): ArduPlane completes it and switches to RTL on its own. Each of its signals alone
    is enough; floe takes the vehicle back with a fresh mission."""
    h = active_on_item(1)
    h.plane.total = 1  # the stored mission was [home, loiter time]
    if evidence == "state":
        h.plane.state = 0  # (the end shown by mission_state alone below)
    h.seconds(2)
    if evidence == "reached":
        h.receive(h.plane.reached(1))
    h.plane.mode = RTL
    h.plane.state = M.MISSION_STATE_COMPLETE if evidence == "state" else 0
    if evidence == "text":
        h.receive(h.plane.text(M.MAV_SEVERITY_INFO, "Mission complete, changing mode to RTL"))
    h.seconds(6)
    (line,) = h.journal("autopilot_mode")
    assert line.fields["reason"] == "mission end" and line.fields["evidence"]
    assert not h.journal("override")
    assert h.core(ev.VehicleRebooted)  # replanned as idle, taken back
    assert h.c.state is S.ACTIVE


def test_mission_state_paused_outweighs_a_stray_mission_complete_text() -> None:
    """A vehicle that says its mission is PAUSED did not end it, whatever a text says."""
    h = active_on_item(1)
    t_switch = h.t
    h.plane.mode = RTL
    h.plane.state = M.MISSION_STATE_PAUSED
    h.receive(h.plane.text(M.MAV_SEVERITY_INFO, "Mission complete, changing mode to RTL"))
    h.seconds(10)
    assert [j.fields["reason"] for j in h.journal("override")] == ["mode RTL"]
    assert not h.commands_after(t_switch)


def test_battery_failsafe_is_the_autopilots_with_low_readings() -> None:
    h = active_on_item(1)
    h.plane.battery_pct = 12
    h.seconds(12)
    h.plane.mode = RTL
    h.plane.system_status = M.MAV_STATE_CRITICAL
    h.plane.state = M.MISSION_STATE_PAUSED
    h.seconds(8)
    assert not h.journal("override")
    (line,) = h.journal("autopilot_mode")
    assert line.fields["reason"] == "battery failsafe"
    assert h.journal("battery_low")


def test_given_back_by_auto_after_an_operators_rtl() -> None:
    h = active_on_item(1)
    h.plane.mode = RTL
    h.plane.state = M.MISSION_STATE_PAUSED
    h.seconds(10)
    assert h.c.state is S.OVERRIDDEN
    t_auto = h.t
    h.plane.mode = AUTO
    h.seconds(10)
    assert [j.fields["reason"] for j in h.journal("resume")] == ["mode AUTO"]
    assert h.c.state is S.ACTIVE and h.core(ev.OperatorResume)
    assert not h.commands_after(t_auto)  # the core sends a target; nothing on its own


def test_pilots_rtl_during_floes_upload_is_not_undone_by_its_switch_to_auto() -> None:
    """The race of issue 25: floe's upload is in flight when the pilot's RTL shows. The
    upload's own set-current and switch to AUTO must wait for the attribution, and the
    override ends them: the pilot's RTL stands."""
    h = active_on_item(1)
    h.defer = True
    h.fly("B")  # the upload goes out
    (upload,) = h.pending
    assert isinstance(upload, vio.UploadMission)
    t_switch = h.t
    h.plane.mode = RTL
    h.plane.state = M.MISSION_STATE_PAUSED
    h.seconds(1)  # the pilot's RTL is seen; then the upload completes
    h.answer_pending()
    h.seconds(10)
    after = h.commands_after(t_switch)
    assert not [c for c in after if isinstance(c, vio.SetMode | vio.SetCurrent)], after
    assert h.plane.mode == RTL
    assert [j.fields["reason"] for j in h.journal("override")] == ["mode RTL"]


def test_resumed_through_the_api_in_the_pilots_mode_is_switched_to_auto() -> None:
    """``gcs vehicle resume`` of a vehicle still in the pilot's RTL: floe may change that
    mode now (it was given back in it); a later switch of the pilot's is theirs again."""
    h = active_on_item(1)
    h.plane.mode = RTL
    h.plane.state = M.MISSION_STATE_PAUSED
    h.seconds(10)
    assert h.c.state is S.OVERRIDDEN
    assert h.c.resume(h.t, "api")
    h.seconds(1)
    h.fly("C")  # the core's plan after OperatorResume
    h.seconds(5)
    assert h.plane.mode == AUTO and h.c.state is S.ACTIVE
    assert len(h.journal("override")) == 1
    h.plane.mode = int(ArduPlaneMode.FBWA)
    h.seconds(6)
    assert [j.fields["reason"] for j in h.journal("override")] == ["mode RTL", "mode FBWA"]
