"""Scripted ArduPlane-like vehicle and virtual link for the mission-transfer case tests.

Not a test module by itself (no tests); imported by ``test_mission_transfer_cases.py``
and ``test_vehicle_port.py``.
:class:`FakePlane` behaves as design.md records ArduPlane does (MISSION_REQUEST not _INT,
re-request every 1 s, cancel after 8 s of silence, INVALID_SEQUENCE for an out-of-order
item, DENIED to a second ground station, item 0 read back as home, items read back through
:func:`arduplane_readback`); :class:`Harness` runs one state machine against it through the
real codec (bytes on a virtual link with scripted loss and duplication) in virtual time.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

from domain.geodesy import GeoOrigin
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, MAVLinkMessage, mavlink2
from groundstation.mavlink.mission_items import (
    LoiterTime,
    LoiterUnlimited,
    MissionItem,
    Takeoff,
    Waypoint,
    build_mission_items,
)
from groundstation.mavlink.mission_transfer import Finished, Send
from groundstation.mavlink.mission_upload import MissionUpload
from groundstation.mavlink.mission_verify import arduplane_readback

GCS_SYS, GCS_COMP = 255, 190
VEH_SYS, VEH_COMP = 1, 1
ORIGIN = GeoOrigin(78.9, 11.9, 0.0)
M = mavlink2


def mission(n_loiters: int = 1) -> list[MissionItem]:
    steps: list[Any] = [Takeoff(alt_m=100.0), Waypoint(400.0, 300.0, 120.0)]
    steps += [LoiterTime(500.0 + 10 * i, -200.0, 120.0, time_s=30) for i in range(n_loiters)]
    steps.append(LoiterUnlimited(500.0, -200.0, 120.0, radius_m=80))
    return build_mission_items(steps, ORIGIN)


# --------------------------------------------------------------------------- fake vehicle


@dataclass
class FakePlane:
    """ArduPlane's mission protocol side, as observed on SITL (design.md)."""

    sysid: int = VEH_SYS
    compid: int = VEH_COMP
    request_int: bool = False
    max_items: int = 655
    rerequest_s: float = 1.0
    cancel_after_s: float = 8.0
    mission: list[MissionItem] = field(default_factory=list)
    home: MissionItem = field(
        default_factory=lambda: MissionItem(
            seq=0, command=16, frame=0, x=789000000, y=119000000, z=5.0
        )
    )
    # scripting hooks
    ack_on_count: int | None = None  # answer MISSION_COUNT with this ACK
    ack_on_item: dict[int, int] = field(default_factory=dict)  # seq -> ACK type
    early_ack_after: int | None = None  # ACK ACCEPTED after this item
    first_request_seq: int | None = None  # first request asks for this seq
    request_mission_type: int = 0
    ack_delay_s: float = 0.0
    reboot_after_item: int | None = None
    ignore_everything: bool = False
    command_result: int = M.MAV_RESULT_ACCEPTED
    current_seq: int = 1
    # state
    rebooted: bool = False
    upload: dict[str, Any] | None = None
    pending: list[tuple[float, MAVLinkMessage]] = field(default_factory=list)
    next_current_report_s: float = 0.0

    def _req(self, seq: int) -> MAVLinkMessage:
        cls = (
            M.MAVLink_mission_request_int_message
            if self.request_int
            else (M.MAVLink_mission_request_message)
        )
        assert self.upload is not None
        return cls(self.upload["gcs"][0], self.upload["gcs"][1], seq, self.request_mission_type)

    def _ack(self, to: tuple[int, int], ack_type: int) -> MAVLinkMessage:
        return M.MAVLink_mission_ack_message(to[0], to[1], ack_type, 0)

    def receive(self, msg: MAVLinkMessage, now: float) -> list[MAVLinkMessage]:
        if self.ignore_everything or self.rebooted:
            return []
        kind = msg.get_type()
        gcs = (msg.get_srcSystem(), msg.get_srcComponent())
        if kind == "MISSION_COUNT":
            if self.upload is not None and self.upload["gcs"] != gcs:
                return [self._ack(gcs, M.MAV_MISSION_DENIED)]
            if self.ack_on_count is not None:
                return [self._ack(gcs, self.ack_on_count)]
            if msg.count == 0:
                self.mission = []
                return [self._ack(gcs, M.MAV_MISSION_ACCEPTED)]
            if msg.count > self.max_items:
                return [self._ack(gcs, M.MAV_MISSION_NO_SPACE)]
            self.mission = self.mission[: msg.count]  # truncated at once (design.md)
            self.upload = {"gcs": gcs, "count": msg.count, "next": 0, "last": now, "got": []}
            first = 0 if self.first_request_seq is None else self.first_request_seq
            return [self._req(first)]
        if kind == "MISSION_ITEM_INT":
            if self.upload is None:
                return [self._ack(gcs, M.MAV_MISSION_ERROR)]
            up = self.upload
            if msg.seq != up["next"]:
                return [self._ack(gcs, M.MAV_MISSION_INVALID_SEQUENCE)]
            if msg.seq in self.ack_on_item:
                self.upload = None
                return [self._ack(gcs, self.ack_on_item[msg.seq])]
            item = MissionItem.from_message(msg)
            assert item is not None
            error = self._check(item)
            if error is not None:
                self.upload = None
                return [self._ack(gcs, error)]
            up["got"].append(item)
            up["next"] += 1
            up["last"] = now
            if self.reboot_after_item == msg.seq:
                self.rebooted = True
                self.upload = None
                self.mission = []
                return []
            if self.early_ack_after == msg.seq or up["next"] == up["count"]:
                self.mission = list(up["got"])
                self.upload = None
                ack = self._ack(gcs, M.MAV_MISSION_ACCEPTED)
                if self.ack_delay_s:
                    self.pending.append((now + self.ack_delay_s, ack))
                    return []
                return [ack]
            return [self._req(up["next"])]
        if kind == "MISSION_ACK" and self.upload is not None:
            if msg.type == M.MAV_MISSION_OPERATION_CANCELLED:
                self.upload = None
            return []
        if kind == "MISSION_REQUEST_LIST":
            return [M.MAVLink_mission_count_message(gcs[0], gcs[1], len(self.mission), 0)]
        if kind == "MISSION_REQUEST_INT":
            if msg.seq >= len(self.mission):
                return [self._ack(gcs, M.MAV_MISSION_INVALID_SEQUENCE)]
            stored = self.home if msg.seq == 0 else arduplane_readback(self.mission[msg.seq])
            return [replace(stored, seq=msg.seq).to_message(gcs[0], gcs[1])]
        if kind == "MISSION_CLEAR_ALL":
            self.mission = []
            return [self._ack(gcs, M.MAV_MISSION_ACCEPTED)]
        if kind == "COMMAND_LONG" and msg.command == M.MAV_CMD_DO_SET_MISSION_CURRENT:
            if self.command_result == M.MAV_RESULT_ACCEPTED:
                self.current_seq = int(msg.param1)
            return [
                M.MAVLink_command_ack_message(
                    msg.command, self.command_result, 0, 0, gcs[0], gcs[1]
                )
            ]
        return []

    def _check(self, item: MissionItem) -> int | None:
        if item.command not in (16, 17, 19, 22, 178):
            return M.MAV_MISSION_UNSUPPORTED
        if item.command != 178 and item.seq > 0 and item.frame not in (0, 3, 5, 6, 10, 11):
            return M.MAV_MISSION_UNSUPPORTED_FRAME
        return None

    def tick(self, now: float) -> list[MAVLinkMessage]:
        out = [m for t, m in self.pending if t <= now]
        self.pending = [(t, m) for t, m in self.pending if t > now]
        if self.rebooted or self.ignore_everything:
            return out
        up = self.upload
        if up is not None:
            if now >= up["last"] + self.cancel_after_s:
                self.upload = None
                out.append(self._ack(up["gcs"], M.MAV_MISSION_OPERATION_CANCELLED))
            elif now >= up.get("asked", up["last"]) + self.rerequest_s:
                up["asked"] = now
                out.append(self._req(up["next"]))
        if now >= self.next_current_report_s:
            self.next_current_report_s = now + 1.0
            out.append(M.MAVLink_mission_current_message(self.current_seq, len(self.mission)))
        return out

    def next_timer(self) -> float:
        times = [t for t, _ in self.pending] + [1e9]
        if self.rebooted or self.ignore_everything:
            return min(times)
        times.append(self.next_current_report_s)
        if self.upload is not None:
            up = self.upload
            times.append(up.get("asked", up["last"]) + self.rerequest_s)
            times.append(up["last"] + self.cancel_after_s)
        return min(times)


# --------------------------------------------------------------------------- virtual link

Rule = Callable[[str, MAVLinkMessage, int], bool]  # (direction, msg, nth of its type) -> hit


@dataclass
class Harness:
    """Runs one state machine against the vehicle over a virtual link, in virtual time."""

    plane: FakePlane = field(default_factory=FakePlane)
    latency_s: float = 0.02
    drop: Rule | None = None
    duplicate: Rule | None = None
    now: float = 0.0
    gcs_sent: list[tuple[float, MAVLinkMessage]] = field(default_factory=list)
    vehicle_sent: list[tuple[float, MAVLinkMessage]] = field(default_factory=list)
    extra: list[tuple[float, MAVLinkMessage, int, int]] = field(default_factory=list)
    on_rebooted: bool = True

    def __post_init__(self) -> None:
        self._enc = {
            "up": MavlinkEncoder(GCS_SYS, GCS_COMP),
            "down": MavlinkEncoder(self.plane.sysid, self.plane.compid),
        }
        self._dec = {"up": MavlinkDecoder(), "down": MavlinkDecoder()}
        self._counts: dict[tuple[str, str], int] = {}
        self._wire: list[tuple[float, int, str, bytes]] = []
        self._order = 0

    def _put(
        self, direction: str, msg: MAVLinkMessage, at: float, encoder: MavlinkEncoder | None = None
    ) -> None:
        key = (direction, msg.get_type())
        nth = self._counts.get(key, 0)
        self._counts[key] = nth + 1
        (self.gcs_sent if direction == "up" else self.vehicle_sent).append((at, msg))
        data = (encoder or self._enc[direction]).encode(msg)
        copies = 0 if self.drop and self.drop(direction, msg, nth) else 1
        if copies and self.duplicate and self.duplicate(direction, msg, nth):
            copies = 2
        for _ in range(copies):
            self._order += 1
            self._wire.append((at + self.latency_s, self._order, direction, data))

    def inject(
        self, at: float, msg: MAVLinkMessage, sysid: int = VEH_SYS, compid: int = VEH_COMP
    ) -> None:
        """Deliver ``msg`` to the ground station at ``at`` as if from (sysid, compid)."""
        self.extra.append((at, msg, sysid, compid))

    def run(self, sm: Any, *, until_s: float = 60.0, cancel_at: float | None = None) -> Any:
        def act(actions: list[Any]) -> None:
            for action in actions:
                if isinstance(action, Send):
                    self._put("up", action.msg, self.now)
                else:
                    assert isinstance(action, Finished)

        act(sm.start(self.now))
        steps = 0
        while not sm.done and self.now <= until_s:
            steps += 1
            assert steps < 100_000, "runaway"
            candidates = [t for t, *_ in self._wire] + [self.plane.next_timer()]
            candidates += [t for t, *_ in self.extra]
            deadline = sm.next_deadline_s()
            if deadline is not None:
                candidates.append(deadline)
            if cancel_at is not None:
                candidates.append(cancel_at)
            self.now = max(self.now, min(candidates))
            if cancel_at is not None and self.now >= cancel_at:
                act(sm.cancel(self.now))
                break
            for at, msg, sysid, compid in [e for e in self.extra if e[0] <= self.now]:
                self.extra.remove((at, msg, sysid, compid))
                self._put("down", msg, self.now, MavlinkEncoder(sysid, compid))
            due = sorted(w for w in self._wire if w[0] <= self.now)
            self._wire = [w for w in self._wire if w[0] > self.now]
            for _, _, direction, data in due:
                for msg in self._dec[direction].feed(data):
                    if direction == "up":
                        for reply in self.plane.receive(msg, self.now):
                            self._put("down", reply, self.now)
                    elif not sm.done:
                        act(sm.receive(msg, self.now))
            if sm.done:
                break
            if self.plane.rebooted and self.on_rebooted:
                act(sm.notify_vehicle_rebooted(self.now))
                break
            for msg in self.plane.tick(self.now):
                self._put("down", msg, self.now)
            act(sm.poll(self.now))
        return sm.result

    def sent(self, kind: str) -> list[MAVLinkMessage]:
        return [m for _, m in self.gcs_sent if m.get_type() == kind]

    def from_vehicle(self, kind: str) -> list[MAVLinkMessage]:
        return [m for _, m in self.vehicle_sent if m.get_type() == kind]


def upload(items: list[MissionItem] | None = None, **kw: Any) -> MissionUpload:
    return MissionUpload(
        VEH_SYS,
        VEH_COMP,
        mission() if items is None else items,
        own_system=GCS_SYS,
        own_component=GCS_COMP,
        **kw,
    )


def drop_nth(direction: str, kind: str, *nths: int) -> Rule:
    """Drop the nth (0-based) messages of type ``kind`` going ``direction``."""

    def rule(d: str, msg: MAVLinkMessage, nth: int) -> bool:
        return d == direction and msg.get_type() == kind and nth in nths

    return rule


def via_wire(msg: MAVLinkMessage, sysid: int, compid: int) -> MAVLinkMessage:
    """Round-trip ``msg`` through the codec as if sent by (sysid, compid)."""
    out = MavlinkDecoder().feed(MavlinkEncoder(sysid, compid).encode(msg))
    assert len(out) == 1
    return out[0]
