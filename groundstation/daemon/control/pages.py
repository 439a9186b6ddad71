"""What the control server keeps for live pages: the numbered journal buffer and one bounded
outgoing queue per WebSocket page (no sockets here; the server sends).

Memory per page is bounded: at most ``CLIENT_QUEUE`` messages and ``CLIENT_QUEUE_BYTES``
characters wait for a page; a message that does not fit marks the page ``overflowed`` and the
server disconnects it (it reconnects and catches up with ``?since=``).
"""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from typing import Any

from groundstation.daemon.control.bodies import jsonable
from groundstation.daemon.log_lines import line_level

__all__ = ["CLIENT_QUEUE", "CLIENT_QUEUE_BYTES", "EventBuffer", "PageClient"]

EVENT_BUFFER = 5000
NOTABLE_BUFFER = 2000
CLIENT_QUEUE = 64
CLIENT_QUEUE_BYTES = 4 * 1024 * 1024


class EventBuffer:
    """Journal lines numbered 1, 2, ...: the last ``EVENT_BUFFER`` of all, and the last
    ``NOTABLE_BUFFER`` operator events (``log_lines.is_operator_event``: no ``track``,
    ``truth``, ``detection`` ... state updates)."""

    def __init__(self) -> None:
        self.events: deque[dict[str, Any]] = deque(maxlen=EVENT_BUFFER)
        self.notable: deque[dict[str, Any]] = deque(maxlen=NOTABLE_BUFFER)
        self.notable_evicted = 0  # seq of the newest notable event no longer buffered
        self.seq = 0

    def record(self, line: dict[str, Any], level: int | None = None) -> dict[str, Any]:
        """Number and keep ``line``; returns its entry ``{"seq", "line"}`` (and
        ``"warning": true`` for a problem). ``level``: the line's ``log_lines.line_level``
        when the caller has it (above DEBUG exactly for an operator event)."""
        if level is None:
            level = line_level(line)
        self.seq += 1
        entry: dict[str, Any] = {"seq": self.seq, "line": jsonable(line)}
        if level >= logging.WARNING:
            entry["warning"] = True  # pages colour it
        self.events.append(entry)
        if level > logging.DEBUG:  # an operator event
            if len(self.notable) == NOTABLE_BUFFER:
                self.notable_evicted = self.notable[0]["seq"]
            self.notable.append(entry)
        return entry

    def since(self, since: int, limit: int, notable: bool) -> dict[str, Any]:
        """``GET /api/events``: entries after ``since`` (at most ``limit``), the last number,
        and how many after ``since`` are no longer buffered (``missed``)."""
        buffer = self.notable if notable else self.events
        events = [e for e in buffer if e["seq"] > since][:limit]
        if notable:
            missed = max(0, self.notable_evicted - since)
        else:
            oldest = self.events[0]["seq"] if self.events else self.seq + 1
            missed = max(0, oldest - since - 1)
        return {"events": events, "last": self.seq, "missed": missed}

    def backlog(self, since: int | None, recent: int) -> tuple[list[dict[str, Any]], int]:
        """Notable entries for a page connecting: after ``since``, or the last ``recent``;
        and how many it missed."""
        entries = list(self.notable)
        if since is None:
            return entries[-recent:], 0
        return [e for e in entries if e["seq"] > since], max(0, self.notable_evicted - since)


class PageClient:
    """One WebSocket page: its socket, its transport (to abort) and a bounded queue."""

    def __init__(self, ws: Any, transport: asyncio.BaseTransport | None) -> None:
        self.ws = ws
        self.transport = transport
        self.queued_bytes = 0
        self.overflowed = False
        self.evicted = False
        self._queue: deque[str] = deque()
        self._ready = asyncio.Event()

    def __len__(self) -> int:
        return len(self._queue)

    def offer(self, text: str) -> bool:
        """Queue ``text``; False (and ``overflowed``) when the page is too far behind. One
        message is always accepted into an empty queue, whatever its size."""
        if self.overflowed:
            return False
        if self._queue and (len(self._queue) >= CLIENT_QUEUE
                            or self.queued_bytes + len(text) > CLIENT_QUEUE_BYTES):
            self.overflowed = True
            self._queue.clear()  # it will be disconnected: free the memory now
            self.queued_bytes = 0
            return False
        self._queue.append(text)
        self.queued_bytes += len(text)
        self._ready.set()
        return True

    async def next(self) -> str:
        """The oldest queued message (waits for one)."""
        while not self._queue:
            self._ready.clear()
            await self._ready.wait()
        text = self._queue.popleft()
        self.queued_bytes -= len(text)
        return text

    def abort(self) -> None:
        """Drop the connection at once (a page that reads nothing cannot be closed politely:
        a close frame would wait behind everything it has not read)."""
        if self.transport is not None:  # even when closing: close() waits to flush
            abort = getattr(self.transport, "abort", None)
            if abort is not None:
                abort()
            else:
                self.transport.close()
