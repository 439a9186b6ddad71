"""Vehicle side of the MAVLink mission protocol, as ArduPlane answers it (sans-IO).

Upload: MISSION_COUNT truncates the stored mission to the new count at once (so a failed or
partial upload destroys the old mission), then the vehicle asks for each item with
MISSION_REQUEST (not _INT) and accepts MISSION_ITEM or MISSION_ITEM_INT answers. It
re-requests about every second of simulated time and cancels after 8 s without an item
(MISSION_ACK OPERATION_CANCELLED, "Mission upload timeout"). The last item is answered with
MISSION_ACK ACCEPTED and STATUSTEXT "Flight plan received".

Errors: wrong seq -> INVALID_SEQUENCE (the upload goes on); a bad item (unknown command,
unsupported frame, lat/lon out of range) -> its result code, upload ends; too many items or
storage not ready -> NO_SPACE ("Only N items are supported"); another ground station
(sysid/compid) starting an upload during one -> DENIED; an item with no upload -> ERROR.

Download: MISSION_REQUEST_LIST -> MISSION_COUNT (DENIED during an upload, as
``MissionItemProtocol::handle_mission_request_list``); MISSION_REQUEST_INT -> MISSION_ITEM_INT
(DENIED during an upload; a seq beyond the end gets MISSION_COUNT then INVALID_SEQUENCE)
and MISSION_REQUEST -> MISSION_ITEM; item 0 is home. MISSION_CLEAR_ALL keeps home only
(ERROR during an upload). As ArduPilot, the first MISSION_REQUEST and the first MISSION_ITEM
get a one-time STATUSTEXT warning to use the _INT forms.

The fence and rally mission types are answered by :class:`sitl.geo_items.GeoItemsServer`
(MISSION_COUNT 0 of that type until something is uploaded; uploads accepted, as ArduPlane);
any other mission type is UNSUPPORTED.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from groundstation.mavlink.codec import mavlink2
from sitl.geo_items import GeoItemsServer
from sitl.mission_store import MissionStore, item_from_message, item_to_message
from sitl.statustext import StatusTextFactory

__all__ = ["MissionEvents", "MissionServer"]

M = mavlink2
REREQUEST_S = 1.0
"""Re-request a missing item after this long (simulated s; also the fence and rally's)."""
UPLOAD_TIMEOUT_S = 8.0
"""Cancel an upload after this long without an item (simulated s; also fence and rally)."""


@dataclass
class MissionEvents:
    """What a handled message did to the stored mission (for the autopilot)."""

    changed: bool = False
    upload_complete: bool = False


class MissionServer:
    """Answers mission-protocol messages for one vehicle; owns no clock (``t_s`` is passed)."""

    def __init__(
        self, store: MissionStore, text: StatusTextFactory, geo: GeoItemsServer | None = None
    ) -> None:
        self.store = store
        self._text = text
        self.receiving = False
        self._peer = (0, 0)
        self._count = 0
        self._next_seq = 0
        self._last_request_t = 0.0
        self._last_receive_t = 0.0
        self._request_warning_sent = False
        self._item_warning_sent = False
        self.geo = geo or GeoItemsServer(rerequest_s=REREQUEST_S, upload_timeout_s=UPLOAD_TIMEOUT_S)
        """The fence and rally stores (the vehicle's own, so they survive a reboot, as
        ArduPilot keeps them in EEPROM)."""

    def _ack(self, peer: tuple[int, int], result: int, mission_type: int = 0) -> Any:
        return M.MAVLink_mission_ack_message(peer[0], peer[1], result, mission_type)

    def _request(self, t_s: float) -> Any:
        self._last_request_t = t_s
        return M.MAVLink_mission_request_message(self._peer[0], self._peer[1], self._next_seq, 0)

    def handle(self, msg: Any, t_s: float, events: MissionEvents) -> list[Any]:
        """Answer one mission-protocol message (any other type returns [])."""
        kind = msg.get_type()
        peer = (int(msg.get_srcSystem()), int(msg.get_srcComponent()))
        mission_type = int(getattr(msg, "mission_type", 0) or 0)
        if self.geo.handles(mission_type) and kind.startswith("MISSION_"):
            return self.geo.handle(msg, t_s)
        if kind == "MISSION_COUNT":
            if mission_type != M.MAV_MISSION_TYPE_MISSION:
                return [self._ack(peer, M.MAV_MISSION_UNSUPPORTED, mission_type)]
            return self._on_count(int(msg.count), peer, t_s, events)
        if kind in ("MISSION_ITEM", "MISSION_ITEM_INT"):
            if mission_type != M.MAV_MISSION_TYPE_MISSION:
                return [self._ack(peer, M.MAV_MISSION_UNSUPPORTED, mission_type)]
            return self._on_item(msg, peer, t_s, events)
        if kind == "MISSION_REQUEST_LIST":
            if mission_type == M.MAV_MISSION_TYPE_MISSION and self.receiving:
                # handle_mission_request_list: no listing while an upload is received
                return [self._ack(peer, M.MAV_MISSION_DENIED, mission_type)]
            count = len(self.store) if mission_type == M.MAV_MISSION_TYPE_MISSION else 0
            return [M.MAVLink_mission_count_message(peer[0], peer[1], count, mission_type)]
        if kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
            return self._on_request(msg, peer, mission_type, kind == "MISSION_REQUEST_INT")
        if kind == "MISSION_CLEAR_ALL":
            if mission_type == M.MAV_MISSION_TYPE_MISSION:
                if self.receiving:
                    return [self._ack(peer, M.MAV_MISSION_ERROR, mission_type)]
                self.store.clear()
                events.changed = True
            return [self._ack(peer, M.MAV_MISSION_ACCEPTED, mission_type)]
        return []

    def _on_request(
        self, msg: Any, peer: tuple[int, int], mission_type: int, as_int: bool
    ) -> list[Any]:
        if as_int and self.receiving:  # no download during an upload
            return [self._ack(peer, M.MAV_MISSION_DENIED, mission_type)]
        seq = int(msg.seq)
        count = len(self.store) if mission_type == M.MAV_MISSION_TYPE_MISSION else 0
        if not 0 <= seq < count:
            out = (
                [M.MAVLink_mission_count_message(peer[0], peer[1], count, mission_type)]
                if as_int
                else []
            )  # "educate the GCS on the actual size"
            return [*out, self._ack(peer, M.MAV_MISSION_INVALID_SEQUENCE, mission_type)]
        out = []
        if not as_int and not self._request_warning_sent:
            self._request_warning_sent = True
            out = self._text.make(
                "got MISSION_REQUEST; use MISSION_REQUEST_INT!", M.MAV_SEVERITY_WARNING
            )
        item = self.store.items[seq]
        return [item_to_message(item, seq, peer, as_int, False), *out]

    def _on_count(
        self, count: int, peer: tuple[int, int], t_s: float, events: MissionEvents
    ) -> list[Any]:
        if self.receiving and peer != self._peer:
            return [self._ack(peer, M.MAV_MISSION_DENIED)]
        self.receiving = False
        if count > self.store.capacity:
            return [
                self._ack(peer, M.MAV_MISSION_NO_SPACE),
                *self._text.make(
                    f"Only {self.store.capacity} items are supported", M.MAV_SEVERITY_WARNING
                ),
            ]
        self.store.truncate(count)
        events.changed = True
        if count == 0:
            return [self._ack(peer, M.MAV_MISSION_ACCEPTED)]
        self.receiving = True
        self._peer = peer
        self._count = count
        self._next_seq = 0
        self._last_receive_t = t_s
        return [self._request(t_s)]

    def _on_item(
        self, msg: Any, peer: tuple[int, int], t_s: float, events: MissionEvents
    ) -> list[Any]:
        if not self.receiving:
            return [self._ack(peer, M.MAV_MISSION_ERROR)]
        if int(msg.seq) != self._next_seq:
            return [self._ack(peer, M.MAV_MISSION_INVALID_SEQUENCE)]
        if peer != self._peer:  # ArduPilot checks the sequence first, then the sender
            return [self._ack(peer, M.MAV_MISSION_DENIED)]
        warn: list[Any] = []
        if msg.get_type() == "MISSION_ITEM" and not self._item_warning_sent:
            self._item_warning_sent = True
            warn = self._text.make(
                "got MISSION_ITEM; GCS should send MISSION_ITEM_INT", M.MAV_SEVERITY_WARNING
            )
        item, result = item_from_message(msg)
        if item is None:
            self.receiving = False
            return [*warn, self._ack(peer, result)]
        self.store.write(self._next_seq, item)
        events.changed = True
        self._next_seq += 1
        self._last_receive_t = t_s
        if self._next_seq < self._count:
            return [*warn, self._request(t_s)]
        self.receiving = False
        events.upload_complete = True
        return [
            *warn,
            self._ack(peer, M.MAV_MISSION_ACCEPTED),
            *self._text.make("Flight plan received"),
        ]

    def step(self, t_s: float) -> list[Any]:
        """Re-request a missing item about every second; cancel after 8 s of silence."""
        geo = self.geo.step(t_s)
        if not self.receiving:
            return geo
        if t_s - self._last_receive_t >= UPLOAD_TIMEOUT_S:
            self.receiving = False
            return [
                *geo,
                self._ack(self._peer, M.MAV_MISSION_OPERATION_CANCELLED),
                *self._text.make("Mission upload timeout", M.MAV_SEVERITY_WARNING),
            ]
        if t_s - self._last_request_t >= REREQUEST_S:
            return [*geo, self._request(t_s)]
        return geo

    def reset(self) -> None:
        """Forget any upload in progress (reboot)."""
        self.receiving = False
        self.geo.reset()
