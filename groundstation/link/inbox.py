"""A link's bounded receive queue: raw bytes wait here until the link's drain decodes them.

Transport callbacks only append (``Inbox.put``); decoding and delivery happen later, a
bounded amount per event-loop turn, so a flooded link cannot hold the loop (see
``groundstation.link.base``). Order of arrival is kept.

Drop rule (datagram links): items are classified on arrival by a cheap header walk
(:func:`peek_frames`, no checksum): an item holding any frame whose message id is in
:data:`PRIORITY_MESSAGE_IDS` (the messages an exchange needs: HEARTBEAT, MISSION_*,
COMMAND_*, PARAM_VALUE, STATUSTEXT) is *priority*, anything else is *telemetry*. Each class
has its own bound; when one is full its **oldest** item is dropped, so telemetry floods
never push out protocol messages, and the newest telemetry always survives. Stream links
(TCP, serial) cannot drop bytes without breaking frames: their inbox is not bounded here;
the link stops reading the socket instead (back-pressure) while too many bytes wait.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any

from groundstation.mavlink.codec import mavlink2 as _M

__all__ = ["PRIORITY_MESSAGE_IDS", "Inbox", "RawChunk", "peek_frames"]

PRIORITY_MESSAGE_IDS = frozenset(
    {
        _M.MAVLINK_MSG_ID_HEARTBEAT,
        _M.MAVLINK_MSG_ID_PARAM_VALUE,
        _M.MAVLINK_MSG_ID_STATUSTEXT,
        _M.MAVLINK_MSG_ID_COMMAND_ACK,
        _M.MAVLINK_MSG_ID_COMMAND_LONG,
        _M.MAVLINK_MSG_ID_COMMAND_INT,
        _M.MAVLINK_MSG_ID_MISSION_ITEM,
        _M.MAVLINK_MSG_ID_MISSION_ITEM_INT,
        _M.MAVLINK_MSG_ID_MISSION_REQUEST,
        _M.MAVLINK_MSG_ID_MISSION_REQUEST_INT,
        _M.MAVLINK_MSG_ID_MISSION_REQUEST_LIST,
        _M.MAVLINK_MSG_ID_MISSION_COUNT,
        _M.MAVLINK_MSG_ID_MISSION_ACK,
        _M.MAVLINK_MSG_ID_MISSION_CLEAR_ALL,
        _M.MAVLINK_MSG_ID_MISSION_SET_CURRENT,
        _M.MAVLINK_MSG_ID_MISSION_CURRENT,
        _M.MAVLINK_MSG_ID_MISSION_ITEM_REACHED,
    }
)
"""Message ids kept in preference to telemetry when an inbox is full."""

_V2, _V1 = 0xFD, 0xFE


def peek_frames(data: bytes) -> tuple[int, bool]:
    """(number of frames, holds a priority message) by walking MAVLink headers.

    No checksums: a heuristic for queueing only (garbage may count as a frame). MAVLink 2
    frame length = 12 + payload (+13 if signed); MAVLink 1 = 8 + payload.
    """
    i, n, end = 0, 0, len(data)
    priority = False
    while i < end:
        marker = data[i]
        if marker == _V2:
            if i + 10 > end:
                break
            msgid = data[i + 7] | data[i + 8] << 8 | data[i + 9] << 16
            size = 12 + data[i + 1] + (13 if data[i + 2] & 1 else 0)
        elif marker == _V1:
            if i + 6 > end:
                break
            msgid = data[i + 5]
            size = 8 + data[i + 1]
        else:
            nxt = [j for j in (data.find(b"\xfd", i + 1), data.find(b"\xfe", i + 1)) if j >= 0]
            if not nxt:
                break
            i = min(nxt)
            continue
        n += 1
        priority = priority or msgid in PRIORITY_MESSAGE_IDS
        i += size
    return n, priority


@dataclass(slots=True)
class RawChunk:
    """Bytes as a transport handed them over: one datagram, or a slice of a stream."""

    data: bytes
    peer: Any
    t_unix_s: float
    datagram: bool
    frames: int = 1
    token: Any = None  # the stream protocol that read it (for back-pressure)


class Inbox:
    """Two bounded FIFO queues (priority, telemetry) popped in arrival order.

    Bounds are in frames (by header walk), so a datagram packed with 50 frames weighs 50:
    while a class would hold more than its bound, its oldest items are dropped (never the
    item being added). ``None``: unbounded (stream links). :meth:`put` returns
    how many frames it dropped (the link counts them).
    """

    def __init__(self, max_telemetry_frames: int | None, max_priority_frames: int | None) -> None:
        self.max_telemetry_frames = max_telemetry_frames
        self.max_priority_frames = max_priority_frames
        self._telemetry: deque[tuple[int, RawChunk]] = deque()
        self._priority: deque[tuple[int, RawChunk]] = deque()
        self._frames = [0, 0]  # waiting frames: telemetry, priority
        self._seq = 0
        self.bytes = 0

    def __len__(self) -> int:
        return len(self._telemetry) + len(self._priority)

    def put(self, chunk: RawChunk, priority: bool) -> int:
        """Append ``chunk``, dropping the oldest of its class beyond the bound; returns
        the number of frames dropped to make room."""
        k = 1 if priority else 0
        queue = self._priority if priority else self._telemetry
        bound = self.max_priority_frames if priority else self.max_telemetry_frames
        dropped = 0
        if bound is not None:
            while queue and self._frames[k] + chunk.frames > bound:
                _, old = queue.popleft()
                self._frames[k] -= old.frames
                self.bytes -= len(old.data)
                dropped += old.frames
        self._seq += 1
        queue.append((self._seq, chunk))
        self._frames[k] += chunk.frames
        self.bytes += len(chunk.data)
        return dropped

    def pop(self) -> RawChunk | None:
        """The oldest waiting item of either class, None if empty."""
        tq, pq = self._telemetry, self._priority
        if tq and (not pq or tq[0][0] < pq[0][0]):
            _, chunk = tq.popleft()
            self._frames[0] -= chunk.frames
        elif pq:
            _, chunk = pq.popleft()
            self._frames[1] -= chunk.frames
        else:
            return None
        self.bytes -= len(chunk.data)
        return chunk

    def clear(self) -> None:
        """Forget everything waiting (the link stopped)."""
        self._telemetry.clear()
        self._priority.clear()
        self._frames = [0, 0]
        self.bytes = 0
