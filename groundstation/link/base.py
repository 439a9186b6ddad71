"""What every link shares: received frames, counters, options, peer routing, the base class.

A link owns one transport (a UDP socket, a TCP connection or server, a serial port). It
decodes what arrives into MAVLink messages (one robust decoder per peer byte stream),
stamps each with the wall clock, and hands it on as a :class:`Received` to a callback and/or
an async iterator. ``send(frame, system_id)`` never blocks and never raises: a frame that
cannot go out (no peer yet, disconnected, socket error, full buffer) is counted and dropped.

Frames are bytes both ways: the layer above encodes with ``groundstation.mavlink.codec``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from abc import ABC, abstractmethod
from collections.abc import AsyncIterator, Callable, Hashable
from dataclasses import dataclass, field
from typing import Any, TypeAlias

from domain import errors
from groundstation.link.url import LinkSpec
from groundstation.mavlink.codec import MavlinkDecoder

__all__ = [
    "Backoff",
    "Link",
    "LinkCounters",
    "LinkError",
    "LinkOptions",
    "PeerTable",
    "ReceiveCallback",
    "Received",
]

log = logging.getLogger(__name__)

_WARN_INTERVAL_S = 5.0

MavMessage: TypeAlias = Any
"""A pymavlink ``MAVLink_message`` (pymavlink ships no type information)."""

Peer = Hashable
"""A transport address: a UDP ``(host, port)``, a TCP client number; None on 1:1 links."""


class LinkError(errors.LinkError):
    """A link could not start (e.g. its listening port is taken); one-line message."""


@dataclass(frozen=True, slots=True)
class Received:
    """One valid MAVLink frame as it arrived.

    ``raw`` is the exact frame on the wire (what a .tlog stores and what forwarding sends);
    ``t_unix_s`` is the wall-clock time of reception; ``peer`` says where on the link it
    came from (replies to ``system_id`` go there).
    """

    message: MavMessage
    raw: bytes
    link_id: str
    t_unix_s: float
    peer: Peer | None = None

    @property
    def system_id(self) -> int:
        """MAVLink source system id of the frame."""
        return int(self.message.get_srcSystem())

    @property
    def component_id(self) -> int:
        """MAVLink source component id of the frame."""
        return int(self.message.get_srcComponent())


ReceiveCallback = Callable[[Received], None]


@dataclass
class LinkCounters:
    """Traffic and health counters of one link (monotonic; read them, never reset)."""

    bytes_in: int = 0
    bytes_out: int = 0
    frames_in: int = 0
    frames_out: int = 0
    bad_frames: int = 0
    bad_bytes: int = 0
    send_errors: int = 0
    frames_dropped: int = 0
    rx_overflow: int = 0
    reconnects: int = 0
    connects: int = 0

    def as_dict(self) -> dict[str, int]:
        """The counters as a plain dict (for the journal and the status table)."""
        return dict(self.__dict__)


@dataclass(frozen=True)
class LinkOptions:
    """Tuning shared by all links.

    Back-off: the n-th consecutive failed (re)connect waits
    ``min(reconnect_max_s, reconnect_initial_s * 2**n)``; it resets once a valid frame
    arrives, so a server that accepts and drops at once cannot make the link spin.
    """

    reconnect_initial_s: float = 0.5
    reconnect_max_s: float = 10.0
    connect_timeout_s: float = 5.0
    max_write_buffer_bytes: int = 256 * 1024
    rx_queue_size: int = 4096


class Backoff:
    """Exponential back-off delays: ``initial * 2**n`` capped at ``maximum``."""

    def __init__(self, initial_s: float, maximum_s: float) -> None:
        self.initial_s = initial_s
        self.maximum_s = maximum_s
        self.failures = 0

    def next_delay_s(self) -> float:
        """Delay before the next attempt; counts one more failure."""
        delay = min(self.maximum_s, self.initial_s * (2.0 ** min(self.failures, 30)))
        self.failures += 1
        return delay

    def reset(self) -> None:
        """Forget past failures (after a healthy connection)."""
        self.failures = 0


@dataclass
class PeerTable:
    """Which peer each system id was last heard from, on one multi-peer link.

    ``peers_for(None)`` is every current peer (broadcast); ``peers_for(sysid)`` is the peer
    that system id was last heard from, or every peer while it has not been heard (so a
    first command still reaches it); system id 0 is MAVLink's broadcast.
    """

    by_system: dict[int, Peer] = field(default_factory=dict)
    extra: list[Peer] = field(default_factory=list)

    def heard(self, system_id: int, peer: Peer) -> None:
        """Record that ``system_id`` spoke from ``peer``."""
        self.by_system[system_id] = peer
        if peer in self.extra:
            self.extra.remove(peer)

    def add(self, peer: Peer) -> None:
        """A peer that has sent nothing valid yet (a fresh TCP client)."""
        if peer not in self.extra and peer not in self.by_system.values():
            self.extra.append(peer)

    def forget(self, peer: Peer) -> None:
        """Remove a peer that went away (a TCP client that disconnected)."""
        for sysid in [s for s, p in self.by_system.items() if p == peer]:
            del self.by_system[sysid]
        if peer in self.extra:
            self.extra.remove(peer)

    def all_peers(self) -> list[Peer]:
        """Every distinct current peer, in first-heard order."""
        out: list[Peer] = []
        for p in [*self.by_system.values(), *self.extra]:
            if p not in out:
                out.append(p)
        return out

    def peers_for(self, system_id: int | None) -> list[Peer]:
        """Where a frame for ``system_id`` (None or 0: everyone) should go."""
        if system_id:
            peer = self.by_system.get(system_id)
            if peer is not None:
                return [peer]
        return self.all_peers()


class Link(ABC):
    """One transport. Subclasses implement ``_open``, ``_close`` and ``_send``.

    Receive with ``on_receive`` (a plain function called on the event loop; exceptions
    are logged, never propagated into the transport) and/or ``async for rx in
    link.frames()``.
    """

    def __init__(
        self,
        spec: LinkSpec,
        link_id: str | None = None,
        on_receive: ReceiveCallback | None = None,
        options: LinkOptions | None = None,
    ) -> None:
        self.spec = spec
        self.link_id = link_id if link_id is not None else spec.canonical
        self.on_receive = on_receive
        self.options = options or LinkOptions()
        self.counters = LinkCounters()
        self._decoders: dict[Peer | None, MavlinkDecoder] = {}
        self._queue: asyncio.Queue[Received | None] | None = None
        self._running = False
        self._last_warning: dict[str, float] = {}

    # -- lifecycle -------------------------------------------------------------------
    @property
    def running(self) -> bool:
        """True between ``start()`` and ``stop()``."""
        return self._running

    def snapshot(self) -> dict[str, object]:
        """Status for the journal and the live table: id, URL, state and counters."""
        return {
            "link": self.link_id,
            "url": self.spec.canonical,
            "running": self._running,
            "connected": self.connected,
            **self.counters.as_dict(),
        }

    @property
    @abstractmethod
    def connected(self) -> bool:
        """True while frames can be sent somewhere (a peer or port is there)."""

    async def start(self) -> None:
        """Open the transport. Listeners raise :class:`LinkError` if they cannot bind;
        connecting kinds (tcp, serial) return at once and keep trying in the background."""
        if self._running:
            return
        await self._open()
        self._running = True
        log.info("link %s started (%s)", self.link_id, self.spec.canonical)

    async def stop(self) -> None:
        """Close the transport and end ``frames()`` iterators. Idempotent."""
        if not self._running:
            return
        self._running = False
        with contextlib.suppress(Exception):
            await self._close()
        if self._queue is not None:
            if self._queue.full():
                with contextlib.suppress(asyncio.QueueEmpty):
                    self._queue.get_nowait()
            self._queue.put_nowait(None)  # ends frames()
        log.info("link %s stopped", self.link_id)

    async def __aenter__(self) -> Link:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    @abstractmethod
    async def _open(self) -> None: ...

    @abstractmethod
    async def _close(self) -> None: ...

    # -- sending ---------------------------------------------------------------------
    def send(self, frame: bytes, system_id: int | None = None) -> bool:
        """Queue ``frame`` for ``system_id`` (None: every peer). Never blocks or raises.

        Returns True if it was handed to the transport for at least one peer.
        """
        if not self._running:
            self.counters.frames_dropped += 1
            return False
        try:
            ok = self._send(bytes(frame), system_id)
        except Exception as exc:  # a transport bug must not take the caller down
            self.counters.send_errors += 1
            log.warning("link %s: send failed: %s", self.link_id, exc)
            return False
        if not ok:
            self.counters.frames_dropped += 1
        return ok

    @abstractmethod
    def _send(self, frame: bytes, system_id: int | None) -> bool: ...

    def _warn(self, key: str, message: str, *args: object) -> None:
        """Log a warning at most once per ``_WARN_INTERVAL_S`` for each ``key``."""
        now = time.monotonic()
        if now - self._last_warning.get(key, -1e9) >= _WARN_INTERVAL_S:
            self._last_warning[key] = now
            log.warning("link %s: " + message, self.link_id, *args)

    def _count_out(self, nbytes: int) -> None:
        self.counters.bytes_out += nbytes
        self.counters.frames_out += 1

    # -- receiving -------------------------------------------------------------------
    def _feed(self, data: bytes, peer: Peer | None = None) -> list[Received]:
        """Decode stream bytes from ``peer`` (any chunking) and deliver every valid frame."""
        self.counters.bytes_in += len(data)
        decoder = self._decoders.get(peer)
        if decoder is None:
            decoder = self._decoders[peer] = MavlinkDecoder()
        bad_frames, bad_bytes = decoder.bad_frames, decoder.bad_bytes
        messages: list[MavMessage] = decoder.feed(data)
        self.counters.bad_frames += decoder.bad_frames - bad_frames
        self.counters.bad_bytes += decoder.bad_bytes - bad_bytes
        return self._emit(messages, peer)

    def _feed_datagram(self, data: bytes, peer: Peer | None) -> list[Received]:
        """Decode one datagram: whole frames only, as MAVLink over UDP sends them.

        A fresh decoder per datagram (5 us) means a damaged datagram cannot swallow the
        frames of the next ones; bytes left over at its end count as one bad frame.
        """
        self.counters.bytes_in += len(data)
        decoder = MavlinkDecoder()
        messages: list[MavMessage] = decoder.feed(data)
        self.counters.bad_frames += decoder.bad_frames
        self.counters.bad_bytes += decoder.bad_bytes
        out = self._emit(messages, peer)
        leftover = len(data) - decoder.bad_bytes - sum(len(rx.raw) for rx in out)
        if leftover > 0:
            self.counters.bad_frames += 1
            self.counters.bad_bytes += leftover
        return out

    def _emit(self, messages: list[MavMessage], peer: Peer | None) -> list[Received]:
        if not messages:
            return []
        t_unix_s = time.time()
        out: list[Received] = []
        for msg in messages:
            rx = Received(msg, bytes(msg.get_msgbuf()), self.link_id, t_unix_s, peer)
            self.counters.frames_in += 1
            self._on_valid(rx)
            self._deliver(rx)
            out.append(rx)
        return out

    def _forget_decoder(self, peer: Peer | None) -> None:
        self._decoders.pop(peer, None)

    def _on_valid(self, rx: Received) -> None:  # noqa: B027 (optional hook)
        """Hook for subclasses (peer learning, back-off reset)."""

    def _deliver(self, rx: Received) -> None:
        if self.on_receive is not None:
            try:
                self.on_receive(rx)
            except Exception:
                log.exception("link %s: receive callback failed", self.link_id)
        if self._queue is not None:
            try:
                self._queue.put_nowait(rx)
            except asyncio.QueueFull:
                self.counters.rx_overflow += 1

    async def frames(self) -> AsyncIterator[Received]:
        """Iterate received frames until ``stop()``. Frames that arrive while the queue
        (``options.rx_queue_size``) is full are dropped and counted in ``rx_overflow``."""
        if self._queue is None:
            self._queue = asyncio.Queue(maxsize=self.options.rx_queue_size)
        while self._running or not self._queue.empty():
            item = await self._queue.get()
            if item is None:
                return
            yield item
