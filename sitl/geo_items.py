"""Vehicle side of the fence and rally mission types, as ArduPlane answers them (sans-IO).

ArduPlane runs the same mission-item protocol for ``MAV_MISSION_TYPE_FENCE`` (1) and
``MAV_MISSION_TYPE_RALLY`` (2) as for the mission, each with a store of its own:

* ``MISSION_REQUEST_LIST`` of that type -> ``MISSION_COUNT`` of that type (0 until
  something was uploaded: a freshly booted vehicle has no fence and no rally points);
* ``MISSION_COUNT`` N -> N = 0 clears the store (``MISSION_ACK ACCEPTED``); N above the
  capacity -> ``NO_SPACE``; otherwise ``MISSION_REQUEST`` seq 0, 1, ... (same type) until
  the last item, then ``MISSION_ACK ACCEPTED``. Unlike the mission, the stored items are
  replaced only when the upload completes (ArduPilot uploads into a new buffer);
* an item whose command does not belong to the type -> ``UNSUPPORTED``, a latitude or
  longitude out of range or not finite -> ``INVALID_PARAM5_X`` / ``INVALID_PARAM6_Y`` (the
  upload ends; items are checked and converted by :func:`sitl.mission_store.item_from_message`
  with the mission type), a wrong seq -> ``INVALID_SEQUENCE``, an item with no upload ->
  ``ERROR``, another ground station starting an upload during one -> ``DENIED``;
* re-request every ``rerequest_s``; cancel after ``upload_timeout_s`` without an item
  (``OPERATION_CANCELLED``): the mission's own timings, given by
  :class:`sitl.mission_protocol.MissionServer`;
* ``MISSION_REQUEST(_INT)`` -> the stored item as ``MISSION_ITEM(_INT)`` of that type
  (``INVALID_SEQUENCE`` beyond the end); ``MISSION_CLEAR_ALL`` -> empty, ``ACCEPTED``;
  ``MISSION_REQUEST_LIST`` and ``MISSION_REQUEST(_INT)`` during an upload of that type ->
  ``DENIED`` (``MissionItemProtocol::handle_mission_request_list`` / ``_int``).

Until ``FENCE_ENABLE`` is 1 the fence stays disabled whatever is uploaded; what the
vehicle does with it is :mod:`sitl.fence` (and SYS_STATUS: :mod:`sitl.vehicle_messages`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from groundstation.mavlink.codec import mavlink2
from sitl.mission_store import GEO_COMMANDS, StoredItem, item_from_message, item_to_message

__all__ = ["GEO_CAPACITY", "GeoItemsServer"]

M = mavlink2
GEO_CAPACITY = 100
"""Items per store (ArduPilot's limits depend on the board's storage; ~84-100 fence
items, RALLY_TOTAL up to 100 rally points)."""

@dataclass
class _Upload:
    peer: tuple[int, int]
    count: int
    items: list[StoredItem] = field(default_factory=list)
    last_request_t: float = 0.0
    last_receive_t: float = 0.0


class GeoItemsServer:
    """The fence and rally stores and their upload/download (module docstring)."""

    def __init__(self, *, rerequest_s: float, upload_timeout_s: float) -> None:
        self.rerequest_s = rerequest_s
        self.upload_timeout_s = upload_timeout_s
        self.stores: dict[int, list[StoredItem]] = {t: [] for t in GEO_COMMANDS}
        self._uploads: dict[int, _Upload] = {}

    @staticmethod
    def handles(mission_type: int) -> bool:
        return mission_type in GEO_COMMANDS

    def handle(self, msg: Any, t_s: float) -> list[Any]:
        """Answer one mission-protocol message of the fence or rally type."""
        kind = msg.get_type()
        peer = (int(msg.get_srcSystem()), int(msg.get_srcComponent()))
        mtype = int(msg.mission_type)
        store = self.stores[mtype]
        if kind in ("MISSION_REQUEST_LIST", "MISSION_REQUEST", "MISSION_REQUEST_INT") and (
                mtype in self._uploads):
            # MissionItemProtocol: no listing and no item while an upload is received
            return [self._ack(peer, M.MAV_MISSION_DENIED, mtype)]
        if kind == "MISSION_REQUEST_LIST":
            return [M.MAVLink_mission_count_message(peer[0], peer[1], len(store), mtype)]
        if kind == "MISSION_COUNT":
            return self._on_count(int(msg.count), peer, mtype, t_s)
        if kind in ("MISSION_ITEM", "MISSION_ITEM_INT"):
            return self._on_item(msg, peer, mtype, t_s)
        if kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
            seq = int(msg.seq)
            if not 0 <= seq < len(store):
                return [self._ack(peer, M.MAV_MISSION_INVALID_SEQUENCE, mtype)]
            return [item_to_message(store[seq], seq, peer, kind.endswith("_INT"), False, mtype)]
        if kind == "MISSION_CLEAR_ALL":
            if mtype in self._uploads:
                return [self._ack(peer, M.MAV_MISSION_ERROR, mtype)]
            store.clear()
            return [self._ack(peer, M.MAV_MISSION_ACCEPTED, mtype)]
        return []

    def step(self, t_s: float) -> list[Any]:
        """Re-request a missing item every ``rerequest_s``; cancel after
        ``upload_timeout_s`` of silence."""
        if not self._uploads:
            return []
        out: list[Any] = []
        for mtype, up in list(self._uploads.items()):
            if t_s - up.last_receive_t >= self.upload_timeout_s:
                del self._uploads[mtype]
                out.append(self._ack(up.peer, M.MAV_MISSION_OPERATION_CANCELLED, mtype))
            elif t_s - up.last_request_t >= self.rerequest_s:
                out.append(self._request(up, mtype, t_s))
        return out

    def reset(self) -> None:
        """Forget uploads in progress (reboot); the stores are kept (EEPROM)."""
        self._uploads.clear()

    # ------------------------------------------------------------------ internals
    @staticmethod
    def _ack(peer: tuple[int, int], result: int, mtype: int) -> Any:
        return M.MAVLink_mission_ack_message(peer[0], peer[1], result, mtype)

    @staticmethod
    def _request(up: _Upload, mtype: int, t_s: float) -> Any:
        up.last_request_t = t_s
        return M.MAVLink_mission_request_message(up.peer[0], up.peer[1], len(up.items), mtype)

    def _on_count(self, count: int, peer: tuple[int, int], mtype: int, t_s: float) -> list[Any]:
        current = self._uploads.get(mtype)
        if current is not None and current.peer != peer:
            return [self._ack(peer, M.MAV_MISSION_DENIED, mtype)]
        self._uploads.pop(mtype, None)
        if count > GEO_CAPACITY:
            return [self._ack(peer, M.MAV_MISSION_NO_SPACE, mtype)]
        if count == 0:
            self.stores[mtype].clear()
            return [self._ack(peer, M.MAV_MISSION_ACCEPTED, mtype)]
        up = _Upload(peer, count, last_receive_t=t_s)
        self._uploads[mtype] = up
        return [self._request(up, mtype, t_s)]

    def _on_item(self, msg: Any, peer: tuple[int, int], mtype: int, t_s: float) -> list[Any]:
        up = self._uploads.get(mtype)
        if up is None:
            return [self._ack(peer, M.MAV_MISSION_ERROR, mtype)]
        if int(msg.seq) != len(up.items):
            return [self._ack(peer, M.MAV_MISSION_INVALID_SEQUENCE, mtype)]
        if peer != up.peer:
            return [self._ack(peer, M.MAV_MISSION_DENIED, mtype)]
        item, result = item_from_message(msg, mtype)
        if item is None:
            del self._uploads[mtype]
            return [self._ack(peer, result, mtype)]
        up.items.append(item)
        up.last_receive_t = t_s
        if len(up.items) < up.count:
            return [self._request(up, mtype, t_s)]
        del self._uploads[mtype]
        self.stores[mtype] = up.items
        return [self._ack(peer, M.MAV_MISSION_ACCEPTED, mtype)]
